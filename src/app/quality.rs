//! Image quality in motion (`docs/antialiasing.md`): frames against a reference of the same
//! frames, in 8-bit sRGB values.
//!
//! * **error** of a pixel: the largest of its three channel differences from the reference;
//!   the p99 is pooled over every pixel of every frame;
//! * **temporal excess**: the mean, over pixels, channels and consecutive frame pairs, of
//!   |(I(t+1) − I(t)) − (R(t+1) − R(t))|: how much more (or less) the image changes from
//!   frame to frame than the reference does (crawling edges).
//!
//! [`measure`] renders a run's frames with each anti-aliasing choice and relief's own
//! reference (16 rays per pixel, `antialias = "reference"`).

use super::capture::{Frames, Prepared};
use crate::gpu::{Antialias, FrameOutput, TerrainRenderer, FLAG_ANTIALIASED};
use crate::scene::Camera;
use crate::{Error, Result};
use serde::Serialize;

/// Per-pixel errors (max channel difference, 0..=255) of RGBA8 `image` against `reference`.
pub fn pixel_errors(image: &[u8], reference: &[u8]) -> Vec<u8> {
    image
        .chunks_exact(4)
        .zip(reference.chunks_exact(4))
        .map(|(a, b)| (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0))
        .collect()
}

/// The `q` quantile (0..=1) of integer errors: the smallest value at or below which at least
/// that fraction of them lie (0 for none).
pub fn quantile(errors: &[u8], q: f64) -> f64 {
    let mut counts = [0u64; 256];
    for &e in errors {
        counts[e as usize] += 1;
    }
    let need = (q * errors.len() as f64).ceil() as u64;
    let mut seen = 0;
    for (v, c) in counts.iter().enumerate() {
        seen += c;
        if seen >= need.max(1) {
            return v as f64;
        }
    }
    0.0
}

/// Mean over pixels, channels (RGB) and consecutive pairs of |(I(t+1) − I(t)) − (R(t+1) −
/// R(t))| (0 with fewer than two frames).
pub fn temporal_excess(images: &[Vec<u8>], reference: &[Vec<u8>]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0u64);
    for t in 1..images.len().min(reference.len()) {
        let (i0, i1, r0, r1) = (&images[t - 1], &images[t], &reference[t - 1], &reference[t]);
        for k in (0..i1.len()).filter(|k| k % 4 != 3) {
            let di = f64::from(i1[k]) - f64::from(i0[k]);
            let dr = f64::from(r1[k]) - f64::from(r0[k]);
            sum += (di - dr).abs();
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// Largest channel step (levels) to a neighbour at most this counts as smooth
/// ([`ExcessParts::smooth`]).
pub const SMOOTH_STEP: u8 = 2;

/// Where a run's temporal excess comes from: its sum split by the pixels' kind, each part
/// divided by the same count (pixels × channels × consecutive pairs), so that the parts add
/// up to [`temporal_excess`]. A pixel of a pair counts as
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ExcessParts {
    /// anti-aliased (flag 128) in either frame of the pair;
    pub marked: f64,
    /// else sky (no surface) in the first frame: 8-bit rounding of the centre ray's colour
    /// against the reference's mean of 16;
    pub sky: f64,
    /// else a surface whose largest channel step to a 4-neighbour is at most [`SMOOTH_STEP`]
    /// levels in the first frame (the same rounding, on surfaces);
    pub smooth: f64,
    /// else detail finer than the pixel that the edge rules leave unmarked.
    pub detail: f64,
}

/// [`temporal_excess`] of `frames` against `reference` (the same cameras), split into
/// [`ExcessParts`].
pub fn excess_parts(frames: &[FrameOutput], reference: &[FrameOutput]) -> ExcessParts {
    let mut parts = ExcessParts::default();
    let mut n = 0u64;
    for t in 1..frames.len().min(reference.len()) {
        let (i0, i1, r0, r1) = (&frames[t - 1], &frames[t], &reference[t - 1], &reference[t]);
        let (w, h) = (i0.width as usize, i0.height as usize);
        for k in 0..w * h {
            let excess: f64 = (0..3)
                .map(|c| {
                    let di = f64::from(i1.rgba[4 * k + c]) - f64::from(i0.rgba[4 * k + c]);
                    let dr = f64::from(r1.rgba[4 * k + c]) - f64::from(r0.rgba[4 * k + c]);
                    (di - dr).abs()
                })
                .sum();
            n += 3;
            let part = if (i0.flags[k] | i1.flags[k]) & FLAG_ANTIALIASED != 0 {
                &mut parts.marked
            } else if !i0.depth[k].is_finite() {
                &mut parts.sky
            } else if largest_step(&i0.rgba, w, h, k) <= SMOOTH_STEP {
                &mut parts.smooth
            } else {
                &mut parts.detail
            };
            *part += excess;
        }
    }
    let n = n.max(1) as f64;
    ExcessParts {
        marked: parts.marked / n,
        sky: parts.sky / n,
        smooth: parts.smooth / n,
        detail: parts.detail / n,
    }
}

/// Largest channel difference of pixel `k` of the RGBA8 `w` x `h` image `rgba` to its
/// 4-neighbours.
fn largest_step(rgba: &[u8], w: usize, h: usize, k: usize) -> u8 {
    let (x, y) = (k % w, k / w);
    let neighbours = [
        (x > 0).then(|| k - 1),
        (x + 1 < w).then(|| k + 1),
        (y > 0).then(|| k - w),
        (y + 1 < h).then(|| k + w),
    ];
    neighbours
        .into_iter()
        .flatten()
        .flat_map(|q| (0..3).map(move |c| rgba[4 * k + c].abs_diff(rgba[4 * q + c])))
        .max()
        .unwrap_or(0)
}

/// Mean over pixels and channels of the change between consecutive frames (the reference's
/// own motion, for scale).
pub fn temporal_change(images: &[Vec<u8>]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0u64);
    for t in 1..images.len() {
        for k in (0..images[t].len()).filter(|k| k % 4 != 3) {
            sum += f64::from(images[t][k].abs_diff(images[t - 1][k]));
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// The frames of one anti-aliasing choice.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub antialias: Antialias,
    pub frames: Vec<FrameOutput>,
}

impl Rendered {
    pub fn images(&self) -> Vec<Vec<u8>> {
        self.frames.iter().map(|f| f.rgba.clone()).collect()
    }
    /// Extra rays per frame, mean.
    pub fn extra_rays(&self) -> f64 {
        let n = self.frames.len().max(1) as f64;
        let rays: u64 = self.frames.iter().map(|f| f.antialias_rays()).sum();
        rays as f64 / n
    }
}

/// The figures of one choice against the reference.
#[derive(Clone, Debug, Serialize)]
pub struct QualityRow {
    pub antialias: Antialias,
    pub p99_error: f64,
    pub mean_error: f64,
    pub temporal_excess: f64,
    /// The temporal excess by the pixels' kind.
    pub temporal_excess_parts: ExcessParts,
    /// Extra rays per frame, and as a fraction of the frame's pixels.
    pub extra_rays: f64,
    pub extra_rays_per_pixel: f64,
}

/// Renders `cams` with `choice` (the run's other settings kept).
pub fn render_all(
    prepared: &mut Prepared,
    renderer: &mut TerrainRenderer,
    job: &super::capture::RenderJob,
    cams: &[Camera],
    choice: Antialias,
) -> Result<Rendered> {
    prepared.settings.antialias = choice;
    let frames: Frames = prepared.frames(job);
    let out = cams
        .iter()
        .map(|c| frames.render_camera(renderer, c))
        .collect::<Result<Vec<_>>>()?;
    Ok(Rendered {
        antialias: choice,
        frames: out,
    })
}

/// The figures of `r` against `reference` (the same cameras).
pub fn compare(r: &Rendered, reference: &Rendered) -> Result<QualityRow> {
    if r.frames.len() != reference.frames.len() {
        return Err(Error::invalid("quality", "frame counts differ"));
    }
    let mut errors = Vec::new();
    for (a, b) in r.frames.iter().zip(&reference.frames) {
        errors.extend(pixel_errors(&a.rgba, &b.rgba));
    }
    let pixels = r.frames.first().map_or(1, |f| f.width * f.height) as f64;
    let extra = r.extra_rays();
    Ok(QualityRow {
        antialias: r.antialias,
        p99_error: quantile(&errors, 0.99),
        mean_error: errors.iter().map(|&e| f64::from(e)).sum::<f64>() / errors.len().max(1) as f64,
        temporal_excess: temporal_excess(&r.images(), &reference.images()),
        temporal_excess_parts: excess_parts(&r.frames, &reference.frames),
        extra_rays: extra,
        extra_rays_per_pixel: extra / pixels,
    })
}

/// `relief render`'s options from command-line words (the scene first), for the benchmark
/// and tests.
pub fn render_job(words: &[&str]) -> Result<super::capture::RenderJob> {
    #[derive(clap::Parser)]
    struct Words {
        #[command(flatten)]
        job: super::capture::RenderJob,
    }
    use clap::Parser as _;
    let words = std::iter::once("render").chain(words.iter().copied());
    Words::try_parse_from(words)
        .map(|w| w.job)
        .map_err(|e| Error::invalid("render options", e.to_string()))
}

/// `n` cameras in motion for the quality figures: the scene's path frames 0..n where it has
/// a path, else its camera turning 0.05° and moving 1 m forward a frame (a slow taxi).
pub fn motion_cameras(
    scene: &crate::scene::Scene,
    terrain: &crate::terrain::Terrain,
    n: u32,
) -> Vec<Camera> {
    (0..n)
        .map(|k| {
            let mut c = scene.camera(k, terrain);
            if scene.desc.path.is_none() {
                let h = c.pose.heading.to_radians();
                c.pose.position += glam::DVec3::new(h.sin(), h.cos(), 0.0) * f64::from(k);
                c.pose.heading += 0.05 * f64::from(k);
            }
            c
        })
        .collect()
}

/// Every figure of one run: each choice against the reference, and the reference's own
/// frame-to-frame change (for scale).
#[derive(Clone, Debug, Serialize)]
pub struct Quality {
    pub rows: Vec<QualityRow>,
    pub reference_change: f64,
}

/// Renders `job`'s run at `cams` as the reference and with each of `choices`; the figures.
pub fn measure(
    job: &super::capture::RenderJob,
    frames: u32,
    choices: &[Antialias],
) -> Result<Quality> {
    let (mut p, mut r) = super::capture::prepare(job)?;
    let cams = motion_cameras(&p.scene, &p.world.terrain, frames);
    let reference = render_all(&mut p, &mut r, job, &cams, Antialias::REFERENCE)?;
    let rows = choices
        .iter()
        .map(|&c| compare(&render_all(&mut p, &mut r, job, &cams, c)?, &reference))
        .collect::<Result<Vec<_>>>()?;
    Ok(Quality {
        rows,
        reference_change: temporal_change(&reference.images()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::PassTimes;

    /// A 4x1 frame: pixel colours (grey levels), sky where `depth` is infinite, flags.
    fn frame(grey: [u8; 4], depth: [f32; 4], flags: [u32; 4]) -> FrameOutput {
        FrameOutput {
            width: 4,
            height: 1,
            rgba: grey.iter().flat_map(|&g| [g, g, g, 255]).collect(),
            depth: depth.to_vec(),
            steps: vec![0; 4],
            patch_tests: vec![0; 4],
            shadow_steps: vec![0; 4],
            flags: flags.to_vec(),
            objects: vec![0; 4],
            volume_samples: Vec::new(),
            volume_segments: Vec::new(),
            volume_sun: Vec::new(),
            times: PassTimes::default(),
        }
    }

    #[test]
    fn the_parts_add_up_to_the_temporal_excess_and_sort_pixels_by_kind() {
        let inf = f32::INFINITY;
        let depth = [inf, 10.0, 10.0, 10.0];
        // Pixel 0: sky; 1: a surface 2 levels from both neighbours (smooth); 2: anti-aliased
        // in the second frame, 20 levels from pixel 3; 3: detail.
        let first = frame([100, 102, 104, 124], depth, [0, 1, 1, 1]);
        let frames = [
            first.clone(),
            frame([101, 104, 107, 127], depth, [0, 1, 1 | 128, 1]),
        ];
        let reference = [
            first.clone(),
            frame([100, 102, 104, 126], depth, [0, 1, 1, 1]),
        ];
        let parts = excess_parts(&frames, &reference);
        // Excess per channel: sky 1, smooth 2, marked 3, detail 1; 12 channel values.
        assert_eq!(
            parts,
            ExcessParts {
                marked: 9.0 / 12.0,
                sky: 3.0 / 12.0,
                smooth: 6.0 / 12.0,
                detail: 3.0 / 12.0,
            }
        );
        let images = |f: &[FrameOutput]| f.iter().map(|f| f.rgba.clone()).collect::<Vec<_>>();
        let total = temporal_excess(&images(&frames), &images(&reference));
        let sum = parts.marked + parts.sky + parts.smooth + parts.detail;
        assert!((sum - total).abs() < 1e-12, "{sum} against {total}");
        // Not anti-aliased, pixel 2 (20 levels from pixel 3) is detail.
        let plain = [first, frame([101, 104, 107, 127], depth, [0, 1, 1, 1])];
        let parts = excess_parts(&plain, &reference);
        assert_eq!((parts.marked, parts.detail), (0.0, 12.0 / 12.0));
    }
}
