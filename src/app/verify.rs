//! `relief warp verify`: the closed-loop check of a display configuration, with the two-pass
//! comparison ([`super::two_pass`]).
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

use super::output::{write_json, write_png};
use super::pattern_rig::{PatternRig, PatternView};
use super::sampling::{quantise, sample_rgba8};
use super::two_pass::{two_pass_faces, view_basis, view_points, warp_faces};
use crate::display::blend::ChannelBlend;
use crate::display::pattern::{pattern_colour, PatternParams};
use crate::display::screen_points::{projector_coord, screen_points, ScreenPoints};
use crate::display::{DisplayConfig, Projector, Screen};
use crate::gpu::Gpu;
use crate::{Error, Result};
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

const ARCMIN: f64 = std::f64::consts::PI / (180.0 * 60.0);

/// Median local grating frequency in the projector image (cycles per pixel).
pub const GRATING_CYCLES_PER_PIXEL: f64 = 0.4;

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

/// What to verify (the options of `relief warp verify`).
#[derive(Clone, Debug, clap::Args)]
pub struct VerifyOptions {
    /// Only this channel (default: all).
    #[arg(long = "channel", action = clap::ArgAction::Set, value_name = "CHANNEL")]
    pub channels: Vec<usize>,
    /// Eye in the display frame (the config's when not given).
    #[arg(long, value_parser = super::args::parse_dvec3, allow_hyphen_values = true)]
    pub eye: Option<DVec3>,
    /// Eye-view (fisheye) image size.
    #[arg(long, value_parser = super::args::parse_size, default_value = "480x480")]
    pub size: (u32, u32),
    /// Skip the two-pass comparison.
    #[arg(long = "no-two-pass", action = clap::ArgAction::SetFalse)]
    pub two_pass: bool,
    /// Generate the tables for this eye instead (display frame): the error a stale
    /// head-tracked table leaves.
    #[arg(long, value_parser = super::args::parse_dvec3, allow_hyphen_values = true)]
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
    let chans = checked_channels(cfg, name, opts)?;
    let eye = opts.eye.unwrap_or(DVec3::from(cfg.eye.position));
    let table_eye = opts.table_eye.unwrap_or(eye);
    let points: Vec<ScreenPoints> = chans
        .iter()
        .map(|&c| screen_points(&cfg.screen, &cfg.channels[c].projector))
        .collect();
    let view = eye_view(&points, eye, opts.size, name)?;
    let axis = DVec3::from(view.axis);
    let grating_f = grating_frequency(&points, eye, name)?;
    let patterns = Patterns {
        grid: PatternParams::grid(axis),
        grating: PatternParams {
            boresight: axis,
            grating: grating_f,
        },
    };
    let shots = render_channels(gpu, rig, cfg, &chans, &points, table_eye, &patterns, opts)?;

    // The undistorted reference: the eye view rendered directly.
    let (ew, eh) = opts.size;
    let eye_pts = view_points(ew, eh, |x, y| view.dir(x, y));
    let reference = rig.render(
        gpu,
        &eye_pts,
        DVec3::ZERO,
        &patterns.grid,
        &patterns.grating,
    )?;

    let landed = land_eye_pixels(cfg, &chans, eye, &eye_pts, &shots.views);
    let sums: Vec<f64> = landed.iter().filter_map(|l| l.1).collect();
    let blend_sum = (!sums.is_empty()).then(|| {
        [
            sums.iter().copied().fold(f64::INFINITY, f64::min),
            sums.iter().sum::<f64>() / sums.len() as f64,
            sums.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ]
    });
    let tally = close_loop(
        &eye_pts,
        &landed,
        &shots,
        &reference,
        chans.len(),
        opts.two_pass,
    );
    if tally.covered == 0 {
        return Err(Error::invalid(
            name,
            "no eye pixel sees screen lit by a projector: check the eye position and the channels",
        ));
    }
    let Shots {
        views,
        two,
        mut figures,
    } = shots;
    for (f, (cnt, sum, max)) in figures.iter_mut().zip(&tally.per) {
        f.eye_pixels = *cnt;
        f.mean_error_arcmin = if *cnt > 0 { sum / *cnt as f64 } else { 0.0 };
        f.max_error_arcmin = *max;
    }
    let covered = tally.covered as f64;
    let report = VerifyReport {
        config: name.to_string(),
        eye: eye.to_array(),
        eye_view: view,
        covered_pixels: tally.covered,
        uncovered_pixels: tally.uncovered,
        mean_error_arcmin: tally.sum_err / covered,
        max_error_arcmin: tally.max_err,
        grating_cycles_per_radian: grating_f,
        seen_contrast_direct: contrast_slope(&tally.seen_pairs).unwrap_or(0.0),
        seen_contrast_two_pass: opts
            .two_pass
            .then(|| contrast_slope(&tally.seen_pairs_two).unwrap_or(0.0)),
        grid_mean_abs_diff: tally.grid_diff / covered,
        grid_mean_abs_diff_two_pass: opts.two_pass.then(|| tally.grid_diff_two / covered),
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
    let images = VerifyImages {
        as_seen: tally.as_seen,
        reference: reference.grid,
        diff: tally.diff,
        as_seen_two_pass: tally.as_seen_two,
        frames,
    };
    Ok((report, images))
}

/// The channels to verify (all when none are asked for), after checking the request.
fn checked_channels(cfg: &DisplayConfig, name: &str, opts: &VerifyOptions) -> Result<Vec<usize>> {
    let chans: Vec<usize> = if opts.channels.is_empty() {
        (0..cfg.channels.len()).collect()
    } else {
        opts.channels.clone()
    };
    for &c in &chans {
        super::channel::channel(cfg, name, c)?;
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
    Ok(chans)
}

/// The eye view that covers every screen point the channels light.
fn eye_view(points: &[ScreenPoints], eye: DVec3, size: (u32, u32), name: &str) -> Result<EyeView> {
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
    Ok(EyeView {
        axis: axis.to_array(),
        radius_deg: (radius.to_degrees() + 1.0).min(180.0),
        width: size.0,
        height: size.1,
    })
}

/// Grating frequency (cycles per radian of elevation): a median 0.4 cycles per projector pixel
/// along the elevation gradient.
fn grating_frequency(points: &[ScreenPoints], eye: DVec3, name: &str) -> Result<f64> {
    let mut grads: Vec<f64> = Vec::new();
    for p in points {
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
    Ok(GRATING_CYCLES_PER_PIXEL / grad)
}

/// The two test patterns: the grid (what is seen) and the grating (sharpness).
struct Patterns {
    grid: PatternParams,
    grating: PatternParams,
}

/// Every channel rendered: the direct views, the two-pass grid and grating images, and the
/// figures known before the loop is closed.
struct Shots {
    views: Vec<PatternView>,
    two: Vec<(Vec<u8>, Vec<u8>)>,
    figures: Vec<ChannelFigures>,
}

/// Renders each channel directly through its table (and two-pass, when asked) and measures the
/// grating contrast kept in the projector image.
#[allow(clippy::too_many_arguments)]
fn render_channels(
    gpu: &Gpu,
    rig: &mut PatternRig,
    cfg: &DisplayConfig,
    chans: &[usize],
    points: &[ScreenPoints],
    table_eye: DVec3,
    patterns: &Patterns,
    opts: &VerifyOptions,
) -> Result<Shots> {
    let exact = |d: DVec3| pattern_colour(d, 0.0, &patterns.grating)[0];
    let mut shots = Shots {
        views: Vec::new(),
        two: Vec::new(),
        figures: Vec::new(),
    };
    for (i, &c) in chans.iter().enumerate() {
        let v = rig.render(
            gpu,
            &points[i],
            table_eye,
            &patterns.grid,
            &patterns.grating,
        )?;
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
            let (g2, r2, intermediate) = render_two_pass_channel(gpu, rig, &v, &tdirs, patterns)?;
            let pairs: Vec<(f64, f64)> = tdirs
                .iter()
                .enumerate()
                .filter_map(|(k, d)| Some((exact((*d)?), r2[k * 4] as f64 / 255.0)))
                .collect();
            contrast_two = contrast_slope(&pairs);
            inter = Some(intermediate);
            shots.two.push((g2, r2));
        }
        shots.figures.push(ChannelFigures {
            channel: c,
            name: cfg.channels[c].name.clone(),
            eye_pixels: 0,
            mean_error_arcmin: 0.0,
            max_error_arcmin: 0.0,
            contrast_direct,
            contrast_two_pass: contrast_two,
            two_pass_intermediate: inter,
        });
        shots.views.push(v);
    }
    Ok(shots)
}

/// The channel's grid and grating as two-pass warping makes them from its table's directions
/// `tdirs`, and the intermediate ("planar WxH" or "cube 6xNxN").
fn render_two_pass_channel(
    gpu: &Gpu,
    rig: &mut PatternRig,
    v: &PatternView,
    tdirs: &[Option<DVec3>],
    patterns: &Patterns,
) -> Result<(Vec<u8>, Vec<u8>, String)> {
    let faces = two_pass_faces(v.width, tdirs)?;
    let mut grid_faces = Vec::new();
    let mut grating_faces = Vec::new();
    for f in &faces {
        let fv = rig.render(
            gpu,
            &f.points(),
            DVec3::ZERO,
            &patterns.grid,
            &patterns.grating,
        )?;
        grid_faces.push((*f, fv.grid));
        grating_faces.push((*f, fv.grating));
    }
    let g2 = warp_faces(&grid_faces, tdirs);
    let r2 = warp_faces(&grating_faces, tdirs);
    let intermediate = if faces.len() == 1 {
        format!("planar {}x{}", faces[0].width, faces[0].height)
    } else {
        format!("cube 6x{}x{}", faces[0].width, faces[0].height)
    };
    Ok((g2, r2, intermediate))
}

/// Per eye pixel: where it lands, where several channels light its screen point the sum of
/// their blend light weights, and (when the channels blend) the light they add up to.
type Landed = (Landing, Option<f64>, Option<[f64; 3]>);

/// Per eye pixel: the landing in the channel that holds the point deepest; where several
/// channels light the point, the sum of their blend light weights; and, when the channels
/// blend, the light they add up to there: (Σ w_i · value_i^γ)^(1/γ).
fn land_eye_pixels(
    cfg: &DisplayConfig,
    chans: &[usize],
    eye: DVec3,
    eye_pts: &ScreenPoints,
    views: &[PatternView],
) -> Vec<Landed> {
    let projectors: Vec<Projector> = chans.iter().map(|&c| cfg.channels[c].projector).collect();
    let blends: Vec<_> = chans.iter().map(|&c| ChannelBlend::new(cfg, c)).collect();
    let blended = blends.iter().any(|b| b.is_some());
    (0..eye_pts.width * eye_pts.height)
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
                let Some((u, v, m)) = land(&cfg.screen, p, s) else {
                    continue;
                };
                if sample_table(&views[i].table, p.width, p.height, u, v).is_none() {
                    continue;
                }
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
            (
                best.map(|(i, u, v, _)| (i, u, v)),
                (lit > 1).then_some(weight),
                (blended && lit > 0).then(|| light.map(|l| l.powf(1.0 / gamma))),
            )
        })
        .collect()
}

/// The eye view's images and error sums, filled pixel by pixel.
struct Tally {
    as_seen: Vec<u8>,
    as_seen_two: Option<Vec<u8>>,
    diff: Vec<u8>,
    sum_err: f64,
    max_err: f64,
    covered: usize,
    uncovered: usize,
    seen_pairs: Vec<(f64, f64)>,
    seen_pairs_two: Vec<(f64, f64)>,
    grid_diff: f64,
    grid_diff_two: f64,
    /// Per channel: eye pixels, sum and maximum of their errors (arc-min).
    per: Vec<(usize, f64, f64)>,
}

/// Closes the loop per eye pixel: what the eye sees there against the reference, and the
/// angle between the eye ray and the table's ray where it lands.
fn close_loop(
    eye_pts: &ScreenPoints,
    landed: &[Landed],
    shots: &Shots,
    reference: &PatternView,
    channels: usize,
    two_pass: bool,
) -> Tally {
    let n = (eye_pts.width * eye_pts.height) as usize;
    let black: Vec<u8> = [0, 0, 0, 255].repeat(n);
    let mut t = Tally {
        as_seen: black.clone(),
        as_seen_two: two_pass.then(|| black.clone()),
        diff: black,
        sum_err: 0.0,
        max_err: 0.0,
        covered: 0,
        uncovered: 0,
        seen_pairs: Vec::new(),
        seen_pairs_two: Vec::new(),
        grid_diff: 0.0,
        grid_diff_two: 0.0,
        per: vec![(0, 0.0, 0.0); channels],
    };
    let views = &shots.views;
    for k in 0..n {
        let Some(e) = eye_pts.points[k] else { continue };
        let Some((i, u, v)) = landed[k].0 else {
            t.uncovered += 1;
            continue;
        };
        let (pw, ph) = (views[i].width, views[i].height);
        let dir = sample_table(&views[i].table, pw, ph, u, v).expect("checked when landing");
        let err = e.angle_between(dir) / ARCMIN;
        t.covered += 1;
        t.sum_err += err;
        t.max_err = t.max_err.max(err);
        t.per[i].0 += 1;
        t.per[i].1 += err;
        t.per[i].2 = t.per[i].2.max(err);
        // With blends, what the eye sees is the channels' light added up.
        let seen = landed[k]
            .2
            .unwrap_or_else(|| sample_rgba8(&views[i].grid, pw, ph, u, v));
        let want = &reference.grid[k * 4..k * 4 + 3];
        let px = quantise(seen);
        t.as_seen[k * 4..k * 4 + 4].copy_from_slice(&px);
        let mut d = 0.0;
        for c in 0..3 {
            let delta = (px[c] as f64 - want[c] as f64).abs();
            d += delta / 3.0;
            t.diff[k * 4 + c] = (delta * 4.0).min(255.0) as u8;
        }
        t.grid_diff += d;
        let ref_grating = reference.grating[k * 4] as f64 / 255.0;
        t.seen_pairs.push((
            ref_grating,
            sample_rgba8(&views[i].grating, pw, ph, u, v)[0],
        ));
        if let Some(a) = t.as_seen_two.as_mut() {
            let (g2, r2) = &shots.two[i];
            let px = quantise(sample_rgba8(g2, pw, ph, u, v));
            a[k * 4..k * 4 + 4].copy_from_slice(&px);
            t.grid_diff_two += (0..3)
                .map(|c| (px[c] as f64 - want[c] as f64).abs() / 3.0)
                .sum::<f64>();
            t.seen_pairs_two
                .push((ref_grating, sample_rgba8(r2, pw, ph, u, v)[0]));
        }
    }
    t
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
) -> Result<(VerifyReport, Vec<PathBuf>)> {
    let cfg = DisplayConfig::load(config)?;
    let gpu = crate::app::gpu_options::open()?;
    log::info!("adapter: {}", gpu.describe());
    let mut rig = PatternRig::new(&gpu)?;
    let (report, img) = verify(&gpu, &mut rig, &cfg, &config.display().to_string(), opts)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let (w, h) = opts.size;
    let mut written = Vec::new();
    let mut put = |name: String, pw: u32, ph: u32, rgba: &[u8]| -> Result<()> {
        let p = out.join(name);
        write_png(&p, pw, ph, rgba)?;
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
    write_json(&json, &report)?;
    written.push(json);
    Ok((report, written))
}
