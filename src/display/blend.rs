//! Edge blends: soft edges where projector images overlap, applied in display space after the
//! warp. Each edge ramps the light from 0 at the image border to 1 at `width` (a fraction of
//! the image) with Bourke's curve `f(x) = ½(2x)^p` below ½, `1 − ½(2(1−x))^p` above, which
//! satisfies `f(x) + f(1 − x) = 1`: two mirrored ramps over the same overlap add up to full
//! light. The projector's `gamma` turns light weights into pixel factors (`w^(1/γ)`).

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// `[channel.blend]`: `left`, `right`, `top`, `bottom` edges and the projector gamma.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Blend {
    pub left: Option<BlendEdge>,
    pub right: Option<BlendEdge>,
    pub top: Option<BlendEdge>,
    pub bottom: Option<BlendEdge>,
    /// Projector gamma (light ∝ pixel value^gamma).
    #[serde(default = "default_gamma")]
    pub gamma: f64,
    /// Geometric blend: weights from where the other channels of the configuration light the
    /// same screen point (see [`geometric_weights`]); the edges above multiply on top.
    #[serde(default)]
    pub auto: bool,
    /// Exponent of the geometric blend's falloff towards the image border.
    #[serde(default = "default_exponent")]
    pub auto_exponent: f64,
}

/// One edge: ramp `width` (fraction of the image width or height) and curve exponent.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BlendEdge {
    pub width: f64,
    #[serde(default = "default_exponent")]
    pub exponent: f64,
}

fn default_gamma() -> f64 {
    2.2
}
fn default_exponent() -> f64 {
    2.0
}

/// Bourke's blend curve on 0..1 (clamped): `f(x) + f(1 − x) = 1`.
pub fn ramp(x: f64, p: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    if x < 0.5 {
        0.5 * (2.0 * x).powf(p)
    } else {
        1.0 - 0.5 * (2.0 * (1.0 - x)).powf(p)
    }
}

impl Blend {
    /// Checks widths (0..=0.5), exponents (0.5..=10) and gamma (1..=4); errors name `field`.
    pub fn validate(&self, field: &str) -> Result<()> {
        for (name, e) in self.edges() {
            if let Some(e) = e {
                if !(e.width > 0.0 && e.width <= 0.5) {
                    return Err(Error::invalid(
                        format!("{field}.{name}.width"),
                        format!("must be in (0, 0.5] of the image, got {}", e.width),
                    ));
                }
                if !(0.5..=10.0).contains(&e.exponent) {
                    return Err(Error::invalid(
                        format!("{field}.{name}.exponent"),
                        format!("must be in 0.5..=10, got {}", e.exponent),
                    ));
                }
            }
        }
        if !(0.5..=10.0).contains(&self.auto_exponent) {
            return Err(Error::invalid(
                format!("{field}.auto_exponent"),
                format!("must be in 0.5..=10, got {}", self.auto_exponent),
            ));
        }
        if !(1.0..=4.0).contains(&self.gamma) {
            return Err(Error::invalid(
                format!("{field}.gamma"),
                format!("must be in 1..=4, got {}", self.gamma),
            ));
        }
        Ok(())
    }

    fn edges(&self) -> [(&'static str, Option<BlendEdge>); 4] {
        [
            ("left", self.left),
            ("right", self.right),
            ("top", self.top),
            ("bottom", self.bottom),
        ]
    }

    /// Light weight at the centre of pixel (x, y) of a `width x height` image (row 0 at the
    /// top): the product of the edges' ramps.
    pub fn light_weight(&self, x: u32, y: u32, width: u32, height: u32) -> f64 {
        self.light_weight_uv(
            (x as f64 + 0.5) / width as f64,
            (y as f64 + 0.5) / height as f64,
        )
    }

    /// Light weight at image point (u, v) in fractions of the image (0..1, v down).
    pub fn light_weight_uv(&self, u: f64, v: f64) -> f64 {
        let mut w = 1.0;
        for (d, e) in [
            (u, self.left),
            (1.0 - u, self.right),
            (v, self.top),
            (1.0 - v, self.bottom),
        ] {
            if let Some(e) = e {
                w *= ramp(d / e.width, e.exponent);
            }
        }
        w
    }

    /// Factor on the pixel value: `(light_weight · mask)^(1/gamma)`, `mask` being the
    /// pixel's geometric weight (1 without one).
    pub fn pixel_factor(&self, x: u32, y: u32, width: u32, height: u32, mask: f64) -> f64 {
        (self.light_weight(x, y, width, height) * mask).powf(1.0 / self.gamma)
    }

    /// Blends an RGBA8 image (row 0 at the top) in place, as the GPU pass does: colour
    /// channels times the pixel factor, rounded; alpha kept. `mask`: the geometric weights
    /// (one per pixel) of an `auto` blend.
    pub fn apply_rgba8(&self, rgba: &mut [u8], width: u32, height: u32, mask: Option<&[f32]>) {
        for (k, px) in rgba.chunks_exact_mut(4).enumerate() {
            let m = mask.map_or(1.0, |m| m[k] as f64);
            let f = self.pixel_factor(k as u32 % width, k as u32 / width, width, height, m);
            for c in &mut px[..3] {
                *c = (*c as f64 * f).round() as u8;
            }
        }
    }
}

/// Distance (pixels) of image point (u, v) from the nearest border of a `w x h` image, or
/// `None` outside it.
pub fn border_margin(u: f64, v: f64, w: u32, h: u32) -> Option<f64> {
    let m = u.min(w as f64 - u).min(v).min(h as f64 - v);
    (m >= 0.0).then_some(m)
}

/// The geometric blend weight of projector `own` (image point `(u, v)`) at screen point `s`
/// among `others`: `m^p / Σ m_j^p`, `m` being each image point's distance from its image
/// border relative to the image's smaller side.
pub fn geometric_weight<'a>(
    screen: &super::Screen,
    own: &super::Projector,
    (u, v): (f64, f64),
    s: glam::DVec3,
    others: impl Iterator<Item = &'a super::Projector>,
    p: f64,
) -> f64 {
    let rel = |m: f64, pr: &super::Projector| m / pr.width.min(pr.height) as f64;
    let Some(m) = border_margin(u, v, own.width, own.height) else {
        return 0.0;
    };
    let mine = rel(m, own).powf(p);
    let mut total = mine;
    for q in others {
        if let Some((qu, qv)) = super::screen_points::projector_coord(screen, q, s) {
            if let Some(mq) = border_margin(qu, qv, q.width, q.height) {
                total += rel(mq, q).powf(p);
            }
        }
    }
    if total > 0.0 {
        mine / total
    } else {
        1.0
    }
}

/// Geometric blend weights of `channel` of `cfg`, one per projector pixel (row 0 at the top;
/// see [`geometric_weight`]): where several projectors light the same screen point their
/// weights add up to 1 and each falls to 0 at its image border. 1 where only this channel
/// lights the screen, 0 where it lights none.
pub fn geometric_weights(cfg: &super::DisplayConfig, channel: usize, p: f64) -> Vec<f32> {
    use rayon::prelude::*;
    let own = cfg.channels[channel].projector;
    let pts = super::screen_points::screen_points(&cfg.screen, &own);
    pts.points
        .par_iter()
        .enumerate()
        .map(|(k, s)| {
            let Some(s) = s else { return 0.0 };
            let uv = (
                (k as u32 % own.width) as f64 + 0.5,
                (k as u32 / own.width) as f64 + 0.5,
            );
            let others = cfg
                .channels
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != channel)
                .map(|(_, c)| &c.projector);
            geometric_weight(&cfg.screen, &own, uv, *s, others, p) as f32
        })
        .collect()
}

/// A channel's blend ready to apply: its ramps and, for an `auto` blend, the per-pixel
/// geometric weights.
#[derive(Clone, Debug)]
pub struct ChannelBlend {
    pub blend: Blend,
    /// Geometric weights, `width x height`, row 0 at the top.
    pub mask: Option<Vec<f32>>,
    pub width: u32,
    pub height: u32,
}

impl ChannelBlend {
    /// The blend of `channel` of `cfg`, if it has one.
    pub fn new(cfg: &super::DisplayConfig, channel: usize) -> Option<ChannelBlend> {
        let c = cfg.channels.get(channel)?;
        let blend = c.blend?;
        let p = c.projector;
        Some(ChannelBlend {
            blend,
            mask: blend
                .auto
                .then(|| geometric_weights(cfg, channel, blend.auto_exponent)),
            width: p.width,
            height: p.height,
        })
    }

    /// Light weight at pixel (x, y): ramps times the geometric weight.
    pub fn light_weight(&self, x: u32, y: u32) -> f64 {
        let m = self.mask.as_ref().map_or(1.0, |m| {
            m[(y.min(self.height - 1) * self.width + x.min(self.width - 1)) as usize] as f64
        });
        self.blend.light_weight(x, y, self.width, self.height) * m
    }

    /// Light weight at the image point (u, v) (pixels, centres at +0.5) as the screen receives
    /// it: the ramps at that point times the geometric weights interpolated bilinearly
    /// between pixel centres (a pixel's light spreads over its footprint).
    pub fn light_weight_at(&self, u: f64, v: f64) -> f64 {
        let (w, h) = (self.width as f64, self.height as f64);
        let ramps = self.blend.light_weight_uv(u / w, v / h);
        let Some(m) = &self.mask else {
            return ramps;
        };
        let (fx, fy) = (u - 0.5, v - 0.5);
        let (x0, y0) = (fx.floor(), fy.floor());
        let (ax, ay) = (fx - x0, fy - y0);
        let at = |x: f64, y: f64| {
            let x = x.clamp(0.0, w - 1.0) as usize;
            let y = y.clamp(0.0, h - 1.0) as usize;
            m[y * self.width as usize + x] as f64
        };
        let top = at(x0, y0) * (1.0 - ax) + at(x0 + 1.0, y0) * ax;
        let bottom = at(x0, y0 + 1.0) * (1.0 - ax) + at(x0 + 1.0, y0 + 1.0) * ax;
        ramps * (top * (1.0 - ay) + bottom * ay)
    }

    /// Blends an RGBA8 image of the channel's size in place (see [`Blend::apply_rgba8`]).
    pub fn apply_rgba8(&self, rgba: &mut [u8]) {
        self.blend
            .apply_rgba8(rgba, self.width, self.height, self.mask.as_deref());
    }
}
