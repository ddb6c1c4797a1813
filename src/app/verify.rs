//! `relief warp verify`: the closed-loop check of a display configuration, and the two-pass
//! (planar/cube image + bilinear warp) comparison mode.
//!
//! Closed loop: the GPU renders the test pattern ([`crate::display::pattern`]) through each
//! channel's ray table. For every pixel of an eye view (equidistant fisheye around the
//! channels' field, as seen from the eye), the eye ray is intersected with the screen, the
//! screen point is projected back into each projector (lens inverse; for a mirror dome through
//! the mirror point that reflects the projector onto it) and the channel's frame is sampled
//! there bilinearly: that is the image "as seen from the eye". The geometric error of a pixel
//! is the angle between its eye ray and the ray the GPU table assigns to that projector
//! position (bilinear in the table). The same eye view rendered directly (no projector) is
//! the undistorted reference. Sharpness: a grating in elevation at a median 0.4 cycles per
//! projector pixel; the contrast retained is the least-squares slope of the measured values
//! against the exact ones (1 = nothing lost).
//!
//! Two-pass mode renders a pinhole image around the channel (or a cube when the channel spans
//! more than 65° from its axis) at about the table's pixel density, then warps it into the
//! projector image through the table with bilinear filtering, as conventional warping
//! software does.

use crate::cpu::distortion::{projector_coord, ScreenPoints};
use crate::display::pattern::{pattern_colour, PatternParams};
use crate::display::{DisplayConfig, Projector, Screen};
use crate::gpu::{FrameOutput, Gpu, RenderSettings, TerrainRenderer};
use crate::scene::{Camera, Pose, Scene, SceneDesc};
use crate::terrain::{Heightfield, Terrain, TerrainFrame};
use crate::{Error, Result};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;

const ARCMIN: f64 = std::f64::consts::PI / (180.0 * 60.0);

/// Median local grating frequency in the projector image (cycles per pixel).
pub const GRATING_CYCLES_PER_PIXEL: f64 = 0.4;

/// Right, down, forward basis of a view looking along `fwd` (image up = display +z, or
/// display +y when looking nearly straight up or down).
pub fn view_basis(fwd: DVec3) -> (DVec3, DVec3, DVec3) {
    let fwd = fwd.normalize();
    let up = if fwd.z.abs() < 0.9 {
        DVec3::Z
    } else {
        DVec3::Y
    };
    let right = fwd.cross(up).normalize();
    let down = fwd.cross(right);
    (right, down, fwd)
}

/// One planar image of the two-pass intermediate: a pinhole view along `fwd` covering
/// `tan_x`, `tan_y` (half extents of the image plane at unit distance).
#[derive(Clone, Copy, Debug)]
pub struct Face {
    pub right: DVec3,
    pub down: DVec3,
    pub fwd: DVec3,
    pub tan_x: f64,
    pub tan_y: f64,
    pub width: u32,
    pub height: u32,
}

impl Face {
    /// Unit direction through image point (x, y) (pixel centres at +0.5).
    pub fn dir(&self, x: f64, y: f64) -> DVec3 {
        let a = (x / self.width as f64 * 2.0 - 1.0) * self.tan_x;
        let b = (y / self.height as f64 * 2.0 - 1.0) * self.tan_y;
        (self.fwd + self.right * a + self.down * b).normalize()
    }

    /// Image point of direction `d`, `None` outside the image.
    pub fn coord(&self, d: DVec3) -> Option<(f64, f64)> {
        let z = d.dot(self.fwd);
        if z <= 1e-9 {
            return None;
        }
        let a = d.dot(self.right) / z / self.tan_x;
        let b = d.dot(self.down) / z / self.tan_y;
        (a.abs() <= 1.0 && b.abs() <= 1.0).then_some((
            (a + 1.0) * 0.5 * self.width as f64,
            (b + 1.0) * 0.5 * self.height as f64,
        ))
    }

    /// The face's pixels as virtual screen points (unit directions from an eye at the origin).
    pub fn points(&self) -> ScreenPoints {
        view_points(self.width, self.height, |x, y| Some(self.dir(x, y)))
    }
}

/// Virtual "screen points" of a view seen from the origin: per pixel centre the direction
/// `dir(x, y)`; rendering them with the eye at the origin casts exactly those directions.
pub fn view_points(
    width: u32,
    height: u32,
    dir: impl Fn(f64, f64) -> Option<DVec3> + Sync,
) -> ScreenPoints {
    let points = (0..width * height)
        .into_par_iter()
        .map(|k| dir((k % width) as f64 + 0.5, (k / width) as f64 + 0.5))
        .collect();
    ScreenPoints {
        width,
        height,
        points,
    }
}

/// Median angle between horizontally and vertically neighbouring table directions (radians).
pub fn median_pitch(width: u32, dirs: &[Option<DVec3>]) -> f64 {
    let w = width as usize;
    let mut a: Vec<f64> = (0..dirs.len())
        .filter_map(|k| {
            let d = dirs[k]?;
            let r = (k % w + 1 < w).then(|| dirs[k + 1]).flatten();
            let b = dirs.get(k + w).copied().flatten();
            let v: Vec<f64> = [r, b]
                .iter()
                .flatten()
                .map(|n| d.angle_between(*n))
                .collect();
            (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
        })
        .collect();
    if a.is_empty() {
        return 0.0;
    }
    a.sort_by(f64::total_cmp);
    a[a.len() / 2]
}

/// The intermediate images of two-pass warping for a channel whose table holds `dirs`
/// (display frame): one pinhole image around the channel's axis when every ray lies within
/// 65° of it, a cube otherwise; centre pixel pitch = the table's median pitch.
pub fn two_pass_faces(width: u32, dirs: &[Option<DVec3>]) -> Result<Vec<Face>> {
    let lit: Vec<DVec3> = dirs.iter().flatten().copied().collect();
    let pitch = median_pitch(width, dirs);
    if lit.is_empty() || pitch <= 0.0 {
        return Err(Error::invalid("two-pass", "the channel shows no screen"));
    }
    let sum: DVec3 = lit.iter().sum();
    let axis = sum.try_normalize().unwrap_or(DVec3::Y);
    let max_angle = lit
        .iter()
        .map(|d| d.angle_between(axis))
        .fold(0.0, f64::max);
    let cap = |n: f64| -> Result<u32> {
        if n > 4096.0 {
            Err(Error::Limit {
                what: "two-pass intermediate image".into(),
                msg: format!("{n:.0} pixels wide at the table's density; the limit is 4096"),
            })
        } else {
            Ok(n.max(2.0) as u32)
        }
    };
    if max_angle < 65f64.to_radians() {
        let (right, down, fwd) = view_basis(axis);
        let (mut tx, mut ty) = (0.0f64, 0.0f64);
        for d in &lit {
            let z = d.dot(fwd);
            tx = tx.max((d.dot(right) / z).abs());
            ty = ty.max((d.dot(down) / z).abs());
        }
        // Two pixels of guard band around the channel.
        let (tx, ty) = (tx + 2.0 * pitch, ty + 2.0 * pitch);
        return Ok(vec![Face {
            right,
            down,
            fwd,
            tan_x: tx,
            tan_y: ty,
            width: cap((2.0 * tx / pitch).ceil())?,
            height: cap((2.0 * ty / pitch).ceil())?,
        }]);
    }
    let n = cap((2.0 / pitch).ceil())?;
    let t = 1.0 + 4.0 / n as f64;
    let size = n + 4;
    Ok([
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::NEG_Y,
        DVec3::Z,
        DVec3::NEG_Z,
    ]
    .iter()
    .map(|&f| {
        let (right, down, fwd) = view_basis(f);
        Face {
            right,
            down,
            fwd,
            tan_x: t,
            tan_y: t,
            width: size,
            height: size,
        }
    })
    .collect())
}

/// Bilinear sample of an RGBA8 image at image point (x, y) (pixel centres at +0.5), edges
/// clamped; values 0..1.
pub fn sample_rgba8(rgba: &[u8], width: u32, height: u32, x: f64, y: f64) -> [f64; 3] {
    let (w, h) = (width as i64, height as i64);
    let (fx, fy) = (x - 0.5, y - 0.5);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (ax, ay) = (fx - x0, fy - y0);
    let px = |i: i64, j: i64| -> [f64; 3] {
        let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
        let k = ((j * w + i) * 4) as usize;
        [
            rgba[k] as f64 / 255.0,
            rgba[k + 1] as f64 / 255.0,
            rgba[k + 2] as f64 / 255.0,
        ]
    };
    let (x0, y0) = (x0 as i64, y0 as i64);
    let (a, b, c, d) = (
        px(x0, y0),
        px(x0 + 1, y0),
        px(x0, y0 + 1),
        px(x0 + 1, y0 + 1),
    );
    std::array::from_fn(|i| {
        (a[i] * (1.0 - ax) + b[i] * ax) * (1.0 - ay) + (c[i] * (1.0 - ax) + d[i] * ax) * ay
    })
}

/// Bilinear interpolation of a GPU ray table's directions at image point (x, y); `None` unless
/// all four neighbouring pixels show screen.
pub fn sample_table(table: &[[f32; 4]], width: u32, height: u32, x: f64, y: f64) -> Option<DVec3> {
    let (fx, fy) = (x - 0.5, y - 0.5);
    let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
    if x0 < 0 || y0 < 0 || x0 + 1 >= width as i64 || y0 + 1 >= height as i64 {
        return None;
    }
    let (ax, ay) = (fx - x0 as f64, fy - y0 as f64);
    let e = |i: i64, j: i64| -> Option<DVec3> {
        let t = table[(j * width as i64 + i) as usize];
        (t[3] >= 0.0).then(|| DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64))
    };
    let (a, b, c, d) = (
        e(x0, y0)?,
        e(x0 + 1, y0)?,
        e(x0, y0 + 1)?,
        e(x0 + 1, y0 + 1)?,
    );
    ((a * (1.0 - ax) + b * ax) * (1.0 - ay) + (c * (1.0 - ax) + d * ax) * ay).try_normalize()
}

fn quantise(c: [f64; 3]) -> [u8; 4] {
    let q = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c[0]), q(c[1]), q(c[2]), 255]
}

/// Warps rendered faces into a projector image: per pixel with a display-frame direction, the
/// bilinear sample of the face that holds it (the face it is most central in); black where the
/// pixel shows no screen.
pub fn warp_faces(faces: &[(Face, Vec<u8>)], dirs: &[Option<DVec3>]) -> Vec<u8> {
    dirs.par_iter()
        .flat_map_iter(|d| {
            let px = d
                .and_then(|d| {
                    let (f, img) = faces
                        .iter()
                        .max_by(|a, b| d.dot(a.0.fwd).total_cmp(&d.dot(b.0.fwd)))?;
                    let (x, y) = f.coord(d)?;
                    Some(quantise(sample_rgba8(img, f.width, f.height, x, y)))
                })
                .unwrap_or([0, 0, 0, 255]);
            px.into_iter()
        })
        .collect()
}

/// Least-squares slope of `got` against `want` (the contrast retained when `want` is the exact
/// signal); `None` without variation.
pub fn contrast_slope(pairs: &[(f64, f64)]) -> Option<f64> {
    let n = pairs.len() as f64;
    if n < 2.0 {
        return None;
    }
    let (mw, mg) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), (w, g)| (a + w / n, b + g / n));
    let (mut num, mut den) = (0.0, 0.0);
    for (w, g) in pairs {
        num += (w - mw) * (g - mg);
        den += (w - mw) * (w - mw);
    }
    (den > 1e-12).then(|| num / den)
}

/// Renders the test pattern through virtual or real ray tables (no terrain is cast).
pub struct PatternRig {
    terrain: Terrain,
    scene: SceneDesc,
    renderer: TerrainRenderer,
}

/// A view rendered by a [`PatternRig`]: the grid, the grating and the GPU ray table.
pub struct PatternView {
    pub width: u32,
    pub height: u32,
    pub grid: Vec<u8>,
    pub grating: Vec<u8>,
    pub table: Vec<[f32; 4]>,
}

impl PatternRig {
    pub fn new(gpu: &Gpu) -> Result<PatternRig> {
        let field = Heightfield::from_samples_with_voids(
            "pattern",
            2,
            2,
            vec![Some(0.0); 4],
            [1.0, 1.0],
            None,
        )?;
        let frame = TerrainFrame {
            origin: DVec3::ZERO,
            axis_x: DVec3::X,
            axis_y: DVec3::Y,
            normal: DVec3::Z,
            spacing: [1.0, 1.0],
        };
        let terrain = Terrain::new(field, frame, 1.0)?;
        let scene = Scene::parse(
            "[terrain.procedural]\nsize = 2\n[camera]\nposition = [0.5, 0.5, 100.0]\n",
            Path::new("pattern.toml"),
        )?
        .desc;
        let renderer = TerrainRenderer::new(gpu, &terrain)?;
        Ok(PatternRig {
            terrain,
            scene,
            renderer,
        })
    }

    /// Renders grid and grating through the table of `points` seen from `eye` (vehicle
    /// attitude zero: world = display frame).
    pub fn render(
        &mut self,
        gpu: &Gpu,
        points: &ScreenPoints,
        eye: DVec3,
        grid: &PatternParams,
        grating: &PatternParams,
    ) -> Result<PatternView> {
        self.renderer.set_display(gpu, points, eye)?;
        let pose = Pose {
            position: DVec3::new(0.5, 0.5, 100.0),
            heading: 0.0,
            pitch: 0.0,
            roll: 0.0,
            fov: 60.0,
        };
        let cam = Camera::new(pose, points.width, points.height);
        let settings = RenderSettings::from_scene(&self.scene);
        let mut shot = |p: &PatternParams| -> Result<FrameOutput> {
            self.renderer.set_pattern(gpu, Some(*p));
            self.renderer
                .capture(gpu, &self.terrain, &self.scene, &cam, &settings)
        };
        let g = shot(grid)?;
        let r = shot(grating)?;
        Ok(PatternView {
            width: points.width,
            height: points.height,
            grid: g.rgba,
            grating: r.rgba,
            table: self.renderer.read_ray_table(gpu)?,
        })
    }
}

/// The eye view of a verification: an equidistant fisheye from the eye around `axis` out to
/// `radius` (radians) at the edge of the inscribed circle.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct EyeView {
    pub axis: [f64; 3],
    pub radius_deg: f64,
    pub width: u32,
    pub height: u32,
}

impl EyeView {
    /// Display-frame direction of pixel centre (x, y); `None` outside the fisheye circle.
    pub fn dir(&self, x: f64, y: f64) -> Option<DVec3> {
        let (right, down, fwd) = view_basis(DVec3::from(self.axis));
        let (du, dv) = (x - 0.5 * self.width as f64, y - 0.5 * self.height as f64);
        let rmax = 0.5 * self.width.min(self.height) as f64;
        let rho = du.hypot(dv);
        if rho > rmax {
            return None;
        }
        let theta = rho / rmax * self.radius_deg.to_radians();
        if rho == 0.0 {
            return Some(fwd);
        }
        Some(fwd * theta.cos() + (right * du + down * dv) * (theta.sin() / rho))
    }
}

/// Per-channel figures.
#[derive(Clone, Debug, Serialize)]
pub struct ChannelFigures {
    pub channel: usize,
    pub name: String,
    /// Eye pixels this channel shows (the most central channel wins overlaps).
    pub eye_pixels: usize,
    pub mean_error_arcmin: f64,
    pub max_error_arcmin: f64,
    /// Grating contrast retained in the projector image, direct ray casting.
    pub contrast_direct: f64,
    /// The same for the two-pass image (None when two-pass was not run).
    pub contrast_two_pass: Option<f64>,
    /// Two-pass intermediate: "planar WxH" or "cube 6xNxN".
    pub two_pass_intermediate: Option<String>,
}

/// The result of a closed-loop verification.
#[derive(Clone, Debug, Serialize)]
pub struct VerifyReport {
    pub config: String,
    pub eye: [f64; 3],
    pub eye_view: EyeView,
    /// Eye pixels inside the fisheye circle that see the screen through some projector.
    pub covered_pixels: usize,
    /// Eye pixels inside the circle that see screen no projector reaches (or no screen).
    pub uncovered_pixels: usize,
    pub mean_error_arcmin: f64,
    pub max_error_arcmin: f64,
    /// Grating frequency: cycles per radian of elevation (median 0.4 cycles per projector
    /// pixel).
    pub grating_cycles_per_radian: f64,
    /// Grating contrast retained in the eye view: as seen (direct) against the direct render
    /// of the eye view.
    pub seen_contrast_direct: f64,
    pub seen_contrast_two_pass: Option<f64>,
    /// Mean absolute difference of the grid pattern as seen vs the reference (0..255).
    pub grid_mean_abs_diff: f64,
    pub grid_mean_abs_diff_two_pass: Option<f64>,
    /// Eye pixels whose screen point two or more projectors light.
    pub overlap_pixels: usize,
    /// Over those pixels, the sum of the channels' edge-blend light weights at the point
    /// (ideal 1: the blends hand the light over without a seam): min, mean, max. `None`
    /// without overlaps.
    pub blend_sum: Option<[f64; 3]>,
    pub channels: Vec<ChannelFigures>,
}

/// A channel's frames: width, height, direct grid image, two-pass grid image.
pub type ChannelFrames = (u32, u32, Vec<u8>, Option<Vec<u8>>);

/// Images of a verification (RGBA8, the eye view's size unless said otherwise).
pub struct VerifyImages {
    pub as_seen: Vec<u8>,
    pub reference: Vec<u8>,
    pub diff: Vec<u8>,
    pub as_seen_two_pass: Option<Vec<u8>>,
    /// Per channel: (width, height, direct grid frame, two-pass grid frame).
    pub frames: Vec<ChannelFrames>,
}

/// What to verify.
#[derive(Clone, Debug)]
pub struct VerifyOptions {
    /// Channel indices (all when empty).
    pub channels: Vec<usize>,
    /// Eye in the display frame (the config's when `None`).
    pub eye: Option<DVec3>,
    /// Eye-view image size.
    pub size: (u32, u32),
    pub two_pass: bool,
    /// Eye the ray tables are generated for, when it differs from the viewer's (head-tracking
    /// lag); `None` = the viewer's eye.
    pub table_eye: Option<DVec3>,
}

/// Where each covered eye pixel lands: channel and projector image point.
type Landing = Option<(usize, f64, f64)>;

/// The projector position where the eye sees screen point `s` in channel `p`, if the channel
/// lights it with all four neighbouring pixels (so bilinear sampling is defined).
fn land(screen: &Screen, p: &Projector, s: DVec3) -> Option<(f64, f64, f64)> {
    let (u, v) = projector_coord(screen, p, s)?;
    let (w, h) = (p.width as f64, p.height as f64);
    let margin = (u - 0.5).min(w - 0.5 - u).min(v - 0.5).min(h - 0.5 - v);
    (margin >= 0.0).then_some((u, v, margin))
}

/// Runs the closed loop (and, with `two_pass`, the two-pass comparison) on `cfg`.
pub fn verify(
    gpu: &Gpu,
    rig: &mut PatternRig,
    cfg: &DisplayConfig,
    name: &str,
    opts: &VerifyOptions,
) -> Result<(VerifyReport, VerifyImages)> {
    let chans: Vec<usize> = if opts.channels.is_empty() {
        (0..cfg.channels.len()).collect()
    } else {
        opts.channels.clone()
    };
    for &c in &chans {
        if c >= cfg.channels.len() {
            return Err(Error::invalid(
                "--channel",
                format!(
                    "{name} has {} channel(s), asked for index {c}",
                    cfg.channels.len()
                ),
            ));
        }
    }
    let (ew, eh) = opts.size;
    if !(8..=4096).contains(&ew) || !(8..=4096).contains(&eh) {
        return Err(Error::invalid(
            "--size",
            format!("eye view must be 8..=4096 pixels per side, got {ew}x{eh}"),
        ));
    }
    if let Some(&c) = chans.iter().find(|&&c| cfg.channels[c].warp.is_some()) {
        return Err(Error::invalid(
            format!("{name} channel {c}"),
            "uses a measured warp file: the closed loop inverts the projector model, so verify \
             the model the warp was measured against",
        ));
    }
    let eye = opts.eye.unwrap_or(DVec3::from(cfg.eye.position));
    let table_eye = opts.table_eye.unwrap_or(eye);
    let points: Vec<ScreenPoints> = chans
        .iter()
        .map(|&c| crate::cpu::distortion::screen_points(&cfg.screen, &cfg.channels[c].projector))
        .collect();
    // The eye view covers every screen point the channels light.
    let dirs: Vec<DVec3> = points
        .iter()
        .flat_map(|p| p.points.iter().step_by(3).flatten())
        .filter_map(|s| (*s - eye).try_normalize())
        .collect();
    if dirs.is_empty() {
        return Err(Error::invalid(
            name,
            "no projector pixel reaches the screen: nothing to verify",
        ));
    }
    let axis = dirs
        .iter()
        .sum::<DVec3>()
        .try_normalize()
        .unwrap_or(DVec3::Z);
    let radius = dirs
        .iter()
        .map(|d| d.angle_between(axis))
        .fold(0.0, f64::max);
    let view = EyeView {
        axis: axis.to_array(),
        radius_deg: (radius.to_degrees() + 1.0).min(180.0),
        width: ew,
        height: eh,
    };
    // Grating frequency: median 0.4 cycles per projector pixel along the elevation gradient.
    let mut grads: Vec<f64> = Vec::new();
    for p in &points {
        let w = p.width as usize;
        let el = |k: usize| -> Option<f64> {
            let d = (p.points[k]? - eye).normalize();
            Some(d.z.clamp(-1.0, 1.0).asin())
        };
        for k in (0..p.points.len()).step_by(7) {
            if k % w + 1 >= w || k + w >= p.points.len() {
                continue;
            }
            if let (Some(a), Some(b), Some(c)) = (el(k), el(k + 1), el(k + w)) {
                grads.push((b - a).hypot(c - a));
            }
        }
    }
    grads.sort_by(f64::total_cmp);
    let grad = grads.get(grads.len() / 2).copied().unwrap_or(0.0);
    if grad <= 0.0 {
        return Err(Error::invalid(name, "degenerate projector geometry"));
    }
    let grating_f = GRATING_CYCLES_PER_PIXEL / grad;
    let grid = PatternParams::grid(axis);
    let grating = PatternParams {
        boresight: axis,
        grating: grating_f,
    };
    let exact = |d: DVec3| pattern_colour(d, 0.0, &grating)[0];

    // Direct renders of every channel, and the two-pass images.
    let mut views = Vec::new();
    let mut two = Vec::new();
    let mut figures = Vec::new();
    for (i, &c) in chans.iter().enumerate() {
        let v = rig.render(gpu, &points[i], table_eye, &grid, &grating)?;
        let tdirs: Vec<Option<DVec3>> = v
            .table
            .iter()
            .map(|t| (t[3] >= 0.0).then(|| DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64)))
            .collect();
        let pairs: Vec<(f64, f64)> = tdirs
            .iter()
            .enumerate()
            .filter_map(|(k, d)| Some((exact((*d)?), v.grating[k * 4] as f64 / 255.0)))
            .collect();
        let contrast_direct = contrast_slope(&pairs).unwrap_or(0.0);
        let (mut contrast_two, mut inter) = (None, None);
        if opts.two_pass {
            let faces = two_pass_faces(v.width, &tdirs)?;
            let mut grid_faces = Vec::new();
            let mut grating_faces = Vec::new();
            for f in &faces {
                let fv = rig.render(gpu, &f.points(), DVec3::ZERO, &grid, &grating)?;
                grid_faces.push((*f, fv.grid));
                grating_faces.push((*f, fv.grating));
            }
            let g2 = warp_faces(&grid_faces, &tdirs);
            let r2 = warp_faces(&grating_faces, &tdirs);
            let pairs: Vec<(f64, f64)> = tdirs
                .iter()
                .enumerate()
                .filter_map(|(k, d)| Some((exact((*d)?), r2[k * 4] as f64 / 255.0)))
                .collect();
            contrast_two = contrast_slope(&pairs);
            inter = Some(if faces.len() == 1 {
                format!("planar {}x{}", faces[0].width, faces[0].height)
            } else {
                format!("cube 6x{}x{}", faces[0].width, faces[0].height)
            });
            two.push((g2, r2));
        }
        figures.push(ChannelFigures {
            channel: c,
            name: cfg.channels[c].name.clone(),
            eye_pixels: 0,
            mean_error_arcmin: 0.0,
            max_error_arcmin: 0.0,
            contrast_direct,
            contrast_two_pass: contrast_two,
            two_pass_intermediate: inter,
        });
        views.push(v);
    }

    // The undistorted reference: the eye view rendered directly.
    let eye_pts = view_points(ew, eh, |x, y| view.dir(x, y));
    let reference = rig.render(gpu, &eye_pts, DVec3::ZERO, &grid, &grating)?;

    // Close the loop per eye pixel.
    let projectors: Vec<Projector> = chans.iter().map(|&c| cfg.channels[c].projector).collect();
    let blends: Vec<_> = chans
        .iter()
        .map(|&c| crate::display::blend::ChannelBlend::new(cfg, c))
        .collect();
    // Per eye pixel: the landing in the channel that holds the point deepest; where several
    // channels light the point, the sum of their blend light weights; and, when the channels
    // blend, the light they add up to there: (Σ w_i · value_i^γ)^(1/γ).
    let blended = blends.iter().any(|b| b.is_some());
    let landed: Vec<(Landing, Option<f64>, Option<[f64; 3]>)> = (0..ew * eh)
        .into_par_iter()
        .map(|k| {
            let Some(s) = eye_pts.points[k as usize].and_then(|e| cfg.screen.seen_from(eye, e))
            else {
                return (None, None, None);
            };
            let mut best: Option<(usize, f64, f64, f64)> = None;
            let (mut lit, mut weight) = (0, 0.0);
            let mut light = [0.0f64; 3];
            let mut gamma = 2.2;
            for (i, p) in projectors.iter().enumerate() {
                if let Some((u, v, m)) = land(&cfg.screen, p, s) {
                    let t = &views[i].table;
                    if sample_table(t, p.width, p.height, u, v).is_some() {
                        lit += 1;
                        let w = blends[i].as_ref().map_or(1.0, |b| b.light_weight_at(u, v));
                        weight += w;
                        if blended {
                            gamma = blends[i].as_ref().map_or(gamma, |b| b.blend.gamma);
                            let c = sample_rgba8(&views[i].grid, p.width, p.height, u, v);
                            for ch in 0..3 {
                                light[ch] += w * c[ch].powf(gamma);
                            }
                        }
                        if best.is_none_or(|b| m > b.3) {
                            best = Some((i, u, v, m));
                        }
                    }
                }
            }
            (
                best.map(|(i, u, v, _)| (i, u, v)),
                (lit > 1).then_some(weight),
                (blended && lit > 0).then(|| light.map(|l| l.powf(1.0 / gamma))),
            )
        })
        .collect();
    let landings: Vec<Landing> = landed.iter().map(|l| l.0).collect();
    let sums: Vec<f64> = landed.iter().filter_map(|l| l.1).collect();
    let blend_sum = (!sums.is_empty()).then(|| {
        [
            sums.iter().copied().fold(f64::INFINITY, f64::min),
            sums.iter().sum::<f64>() / sums.len() as f64,
            sums.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ]
    });
    let n = (ew * eh) as usize;
    let mut as_seen = vec![0u8; n * 4];
    let mut as_seen_two = opts.two_pass.then(|| vec![0u8; n * 4]);
    let mut diff = vec![0u8; n * 4];
    let (mut sum_err, mut max_err, mut covered, mut uncovered) = (0.0, 0.0f64, 0usize, 0usize);
    let (mut seen_pairs, mut seen_pairs_two) = (Vec::new(), Vec::new());
    let (mut grid_diff, mut grid_diff_two) = (0.0, 0.0);
    let mut per: Vec<(usize, f64, f64)> = vec![(0, 0.0, 0.0); chans.len()];
    for k in 0..n {
        for c in 0..3 {
            diff[k * 4 + c] = 0;
        }
        diff[k * 4 + 3] = 255;
        as_seen[k * 4 + 3] = 255;
        if let Some(a) = as_seen_two.as_mut() {
            a[k * 4 + 3] = 255;
        }
        let Some(e) = eye_pts.points[k] else { continue };
        let Some((i, u, v)) = landings[k] else {
            uncovered += 1;
            continue;
        };
        let (pw, ph) = (views[i].width, views[i].height);
        let t = sample_table(&views[i].table, pw, ph, u, v).expect("checked when landing");
        let err = e.angle_between(t) / ARCMIN;
        covered += 1;
        sum_err += err;
        max_err = max_err.max(err);
        per[i].0 += 1;
        per[i].1 += err;
        per[i].2 = per[i].2.max(err);
        // With blends, what the eye sees is the channels' light added up.
        let seen = landed[k]
            .2
            .unwrap_or_else(|| sample_rgba8(&views[i].grid, pw, ph, u, v));
        let want = &reference.grid[k * 4..k * 4 + 3];
        let px = quantise(seen);
        as_seen[k * 4..k * 4 + 4].copy_from_slice(&px);
        let mut d = 0.0;
        for c in 0..3 {
            let delta = (px[c] as f64 - want[c] as f64).abs();
            d += delta / 3.0;
            diff[k * 4 + c] = (delta * 4.0).min(255.0) as u8;
        }
        grid_diff += d;
        let ref_grating = reference.grating[k * 4] as f64 / 255.0;
        seen_pairs.push((
            ref_grating,
            sample_rgba8(&views[i].grating, pw, ph, u, v)[0],
        ));
        if let Some(a) = as_seen_two.as_mut() {
            let (g2, r2) = &two[i];
            let px = quantise(sample_rgba8(g2, pw, ph, u, v));
            a[k * 4..k * 4 + 4].copy_from_slice(&px);
            grid_diff_two += (0..3)
                .map(|c| (px[c] as f64 - want[c] as f64).abs() / 3.0)
                .sum::<f64>();
            seen_pairs_two.push((ref_grating, sample_rgba8(r2, pw, ph, u, v)[0]));
        }
    }
    if covered == 0 {
        return Err(Error::invalid(
            name,
            "no eye pixel sees screen lit by a projector: check the eye position and the channels",
        ));
    }
    for (f, (cnt, sum, max)) in figures.iter_mut().zip(&per) {
        f.eye_pixels = *cnt;
        f.mean_error_arcmin = if *cnt > 0 { sum / *cnt as f64 } else { 0.0 };
        f.max_error_arcmin = *max;
    }
    let report = VerifyReport {
        config: name.to_string(),
        eye: eye.to_array(),
        eye_view: view,
        covered_pixels: covered,
        uncovered_pixels: uncovered,
        mean_error_arcmin: sum_err / covered as f64,
        max_error_arcmin: max_err,
        grating_cycles_per_radian: grating_f,
        seen_contrast_direct: contrast_slope(&seen_pairs).unwrap_or(0.0),
        seen_contrast_two_pass: opts
            .two_pass
            .then(|| contrast_slope(&seen_pairs_two).unwrap_or(0.0)),
        grid_mean_abs_diff: grid_diff / covered as f64,
        grid_mean_abs_diff_two_pass: opts.two_pass.then(|| grid_diff_two / covered as f64),
        overlap_pixels: sums.len(),
        blend_sum,
        channels: figures,
    };
    let mut two_iter = two.into_iter();
    let frames = views
        .into_iter()
        .map(|v| {
            let t = two_iter.next().map(|(g, _)| g);
            (v.width, v.height, v.grid, t)
        })
        .collect();
    Ok((
        report,
        VerifyImages {
            as_seen,
            reference: reference.grid,
            diff,
            as_seen_two_pass: as_seen_two,
            frames,
        },
    ))
}

/// A human-readable summary of a report.
pub fn summary(r: &VerifyReport) -> String {
    let mut s = format!(
        "{}: eye {:?}, eye view {}x{} fisheye, {:.1}° around {:?}\n  covered {} eye pixels ({} inside the view see no lit screen)\n  geometric error: mean {:.4} arc-min, max {:.4} arc-min\n  grating {:.1} cycles/rad (median {} cycles per projector pixel): contrast retained as seen {:.3}",
        r.config,
        r.eye,
        r.eye_view.width,
        r.eye_view.height,
        r.eye_view.radius_deg,
        r.eye_view.axis.map(|v| (v * 1000.0).round() / 1000.0),
        r.covered_pixels,
        r.uncovered_pixels,
        r.mean_error_arcmin,
        r.max_error_arcmin,
        r.grating_cycles_per_radian,
        GRATING_CYCLES_PER_PIXEL,
        r.seen_contrast_direct,
    );
    if let Some(t) = r.seen_contrast_two_pass {
        s += &format!(" direct, {t:.3} two-pass");
    }
    s += &format!(
        "\n  grid as seen vs reference: mean |diff| {:.2}/255",
        r.grid_mean_abs_diff
    );
    if let Some(t) = r.grid_mean_abs_diff_two_pass {
        s += &format!(" direct, {t:.2}/255 two-pass");
    }
    if let Some([lo, mean, hi]) = r.blend_sum {
        s += &format!(
            "\n  overlaps: {} eye pixels lit by 2+ projectors; blended light sum min {lo:.3} / mean {mean:.3} / max {hi:.3} (ideal 1)",
            r.overlap_pixels
        );
    }
    for c in &r.channels {
        s += &format!(
            "\n  channel {} \"{}\": {} eye pixels, error mean {:.4} / max {:.4} arc-min; projector-image contrast at 0.4 cycles/pixel: direct {:.3}",
            c.channel, c.name, c.eye_pixels, c.mean_error_arcmin, c.max_error_arcmin, c.contrast_direct
        );
        if let (Some(t), Some(i)) = (c.contrast_two_pass, &c.two_pass_intermediate) {
            s += &format!(", two-pass {t:.3} ({i})");
        }
    }
    s
}

/// `relief warp verify`: runs [`verify`] and writes the images and `verify.json` to `out`.
pub fn run(
    config: &Path,
    opts: &VerifyOptions,
    out: &Path,
) -> Result<(VerifyReport, Vec<std::path::PathBuf>)> {
    let cfg = DisplayConfig::load(config)?;
    let gpu = Gpu::new()?;
    log::info!("adapter: {}", gpu.describe());
    let mut rig = PatternRig::new(&gpu)?;
    let (report, img) = verify(&gpu, &mut rig, &cfg, &config.display().to_string(), opts)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let (w, h) = opts.size;
    let png = super::capture::write_png;
    let mut written = Vec::new();
    let mut put = |name: String, pw: u32, ph: u32, rgba: &[u8]| -> Result<()> {
        let p = out.join(name);
        png(&p, pw, ph, rgba)?;
        written.push(p);
        Ok(())
    };
    put("as_seen_from_eye.png".into(), w, h, &img.as_seen)?;
    put("reference_from_eye.png".into(), w, h, &img.reference)?;
    put("diff_from_eye.png".into(), w, h, &img.diff)?;
    if let Some(t) = &img.as_seen_two_pass {
        put("as_seen_from_eye_two_pass.png".into(), w, h, t)?;
    }
    for (c, (fw, fh, g, t)) in report.channels.iter().zip(&img.frames) {
        put(format!("channel_{}_direct.png", c.channel), *fw, *fh, g)?;
        if let Some(t) = t {
            put(format!("channel_{}_two_pass.png", c.channel), *fw, *fh, t)?;
        }
    }
    let json = out.join("verify.json");
    super::capture::write_json(&json, &report)?;
    written.push(json);
    Ok((report, written))
}

/// Two-pass rendering of a scene for one projector: renders each intermediate face (pinhole
/// views from the eye, rotated by the camera's attitude like the table) and warps them into
/// the projector image through the display-frame directions `dirs` with bilinear filtering.
/// Depth is the nearest face pixel's (approximate near silhouettes); the per-pixel statistics
/// are zero. Leaves the renderer in table mode for the last face: call `set_display` again
/// for direct frames.
#[allow(clippy::too_many_arguments)]
pub fn render_two_pass(
    gpu: &Gpu,
    renderer: &mut TerrainRenderer,
    terrain: &Terrain,
    scene: &SceneDesc,
    pose: Pose,
    settings: &RenderSettings,
    faces: &[Face],
    dirs: &[Option<DVec3>],
    width: u32,
    height: u32,
) -> Result<FrameOutput> {
    let mut rendered = Vec::new();
    let mut depths = Vec::new();
    let mut times = crate::gpu::PassTimes::default();
    for f in faces {
        renderer.set_display(gpu, &f.points(), DVec3::ZERO)?;
        let cam = Camera::new(pose, f.width, f.height);
        let out = renderer.capture(gpu, terrain, scene, &cam, settings)?;
        let t = out.times;
        times.raygen_ms += t.raygen_ms;
        times.tile_ms += t.tile_ms;
        times.cast_ms += t.cast_ms;
        times.objects_ms += t.objects_ms;
        times.voxels_ms += t.voxels_ms;
        times.voxel_shadow_ms += t.voxel_shadow_ms;
        times.shade_ms += t.shade_ms;
        times.volume_shadow_ms += t.volume_shadow_ms;
        times.volume_ms += t.volume_ms;
        times.readback_ms += t.readback_ms;
        rendered.push((*f, out.rgba));
        depths.push(out.depth);
    }
    let start = std::time::Instant::now();
    let rgba = warp_faces(&rendered, dirs);
    let depth = dirs
        .par_iter()
        .map(|d| {
            d.and_then(|d| {
                let (i, (f, _)) = rendered
                    .iter()
                    .enumerate()
                    .max_by(|a, b| d.dot(a.1 .0.fwd).total_cmp(&d.dot(b.1 .0.fwd)))?;
                let (x, y) = f.coord(d)?;
                let (px, py) = ((x as u32).min(f.width - 1), (y as u32).min(f.height - 1));
                Some(depths[i][(py * f.width + px) as usize])
            })
            .unwrap_or(f32::INFINITY)
        })
        .collect();
    times.readback_ms += start.elapsed().as_secs_f64() * 1e3;
    let n = (width * height) as usize;
    Ok(FrameOutput {
        width,
        height,
        rgba,
        depth,
        steps: vec![0; n],
        patch_tests: vec![0; n],
        shadow_steps: vec![0; n],
        flags: dirs
            .iter()
            .map(|d| if d.is_some() { 0 } else { 8 })
            .collect(),
        objects: vec![0; n],
        volume_samples: Vec::new(),
        volume_segments: Vec::new(),
        volume_sun: Vec::new(),
        times,
    })
}

/// `relief bench --display`: ray-table regeneration and direct-mode frame time against a
/// pinhole frame of the same size and scene.
#[derive(Clone, Debug, Serialize)]
pub struct DisplayBench {
    pub adapter: String,
    pub backend: String,
    pub scene: String,
    pub config: String,
    pub channel: usize,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// Mean time of the table-generation pass alone (the eye moves every frame).
    pub table_ms: f64,
    /// Mean full frame (table, pre-pass, cast, shade) through the table.
    pub direct_frame_ms: f64,
    /// Mean full frame of the scene's pinhole camera at the same size.
    pub pinhole_frame_ms: f64,
    pub direct_over_pinhole: f64,
}

/// Runs [`DisplayBench`]: channel `channel` of `config` resized to `size` (same lens), camera
/// of frame 0 of `scene_path`, `frames` timed frames after a warm-up.
pub fn bench_display(
    scene_path: &Path,
    config: &Path,
    channel: usize,
    size: (u32, u32),
    frames: u32,
) -> Result<DisplayBench> {
    let cfg = DisplayConfig::load(config)?;
    let ch = cfg.channels.get(channel).ok_or_else(|| {
        Error::invalid(
            "--channel",
            format!(
                "{} has {} channel(s), asked for index {channel}",
                config.display(),
                cfg.channels.len()
            ),
        )
    })?;
    if frames == 0 {
        return Err(Error::invalid("--frames", "must be at least 1"));
    }
    let mut p = ch.projector;
    (p.width, p.height) = size;
    let scene = Scene::load(scene_path)?;
    let terrain = scene.load_terrain()?;
    let gpu = Gpu::new()?;
    let mut cam = scene.camera(0, &terrain);
    (cam.width, cam.height) = size;
    let s = RenderSettings::from_scene(&scene.desc);
    let eye = DVec3::from(cfg.eye.position);
    let points = crate::cpu::distortion::screen_points(&cfg.screen, &p);
    let frame_ms = |display: bool| -> Result<(f64, f64)> {
        let mut r = TerrainRenderer::new(&gpu, &terrain)?;
        if display {
            r.set_display(&gpu, &points, eye)?;
        }
        r.capture(&gpu, &terrain, &scene.desc, &cam, &s)?;
        let mut table = 0.0;
        for k in 0..frames {
            // The head moves: a new table every frame.
            r.set_eye(eye + DVec3::new(0.01 * k as f64, 0.0, 0.0));
            table += r
                .capture(&gpu, &terrain, &scene.desc, &cam, &s)?
                .times
                .raygen_ms;
        }
        gpu.wait()?;
        let start = std::time::Instant::now();
        for k in 0..frames {
            r.set_eye(eye + DVec3::new(0.01 * k as f64, 0.0, 0.0));
            r.render(
                &gpu,
                &terrain,
                &scene.desc,
                &cam,
                &s,
                crate::gpu::Stage::Shade,
            )?;
        }
        gpu.wait()?;
        let f = frames as f64;
        Ok((table / f, start.elapsed().as_secs_f64() * 1e3 / f))
    };
    let (table_ms, direct_frame_ms) = frame_ms(true)?;
    let (_, pinhole_frame_ms) = frame_ms(false)?;
    Ok(DisplayBench {
        adapter: gpu.info.name.clone(),
        backend: format!("{:?}", gpu.info.backend),
        scene: scene_path.display().to_string(),
        config: config.display().to_string(),
        channel,
        width: size.0,
        height: size.1,
        frames,
        table_ms,
        direct_frame_ms,
        pinhole_frame_ms,
        direct_over_pinhole: direct_frame_ms / pinhole_frame_ms,
    })
}
