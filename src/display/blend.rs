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
        let u = (x as f64 + 0.5) / width as f64;
        let v = (y as f64 + 0.5) / height as f64;
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

    /// Factor on the pixel value: `light_weight^(1/gamma)`.
    pub fn pixel_factor(&self, x: u32, y: u32, width: u32, height: u32) -> f64 {
        self.light_weight(x, y, width, height)
            .powf(1.0 / self.gamma)
    }

    /// Blends an RGBA8 image (row 0 at the top) in place, as the GPU pass does: colour
    /// channels times the pixel factor, rounded; alpha kept.
    pub fn apply_rgba8(&self, rgba: &mut [u8], width: u32, height: u32) {
        for (k, px) in rgba.chunks_exact_mut(4).enumerate() {
            let f = self.pixel_factor(k as u32 % width, k as u32 / width, width, height);
            for c in &mut px[..3] {
                *c = (*c as f64 * f).round() as u8;
            }
        }
    }
}
