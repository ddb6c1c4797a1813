//! `relief bench antialias`: the frame with edge anti-aliasing against the same frame without
//! (at `--size`, the scene's first camera), the extra rays it casts, and the image-quality
//! figures (`app::quality`) of each choice on the scene's first `--frames` frames in motion
//! at 320x180 against relief's 16-rays-per-pixel reference.

use super::table::{Figures, Row, RunInfo, Table};
use super::timing::interleaved_ms;
use crate::app::figures::median;
use crate::app::quality::{self, Quality};
use crate::gpu::{Antialias, RenderSettings, Stage};
use crate::Result;
use serde::Serialize;
use std::path::Path;

/// Size of the quality figures' frames (the reference casts 16 rays a pixel).
pub const QUALITY_SIZE: (u32, u32) = (320, 180);

/// The choices measured: off, then 4, 8 and 16 rays per edge pixel, then `"edges"` (4 to 16
/// by contrast).
pub const CHOICES: [Antialias; 5] = [
    Antialias::OFF,
    Antialias::edges(4),
    Antialias::edges(8),
    Antialias::edges(16),
    Antialias::EDGES,
];

/// One choice's frame time.
#[derive(Clone, Debug, Serialize)]
pub struct AaTiming {
    pub antialias: Antialias,
    pub frame_ms: f64,
    /// Against the frame without anti-aliasing.
    pub ratio: f64,
    pub extra_rays: u64,
    pub extra_rays_per_pixel: f64,
}

/// What `relief bench antialias` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct AntialiasBench {
    pub timings: Vec<AaTiming>,
    pub quality: Quality,
    pub quality_size: (u32, u32),
    pub quality_frames: u32,
    /// Where the timed frames built their list of marked pixels: `"cpu"` or `"gpu"`
    /// (`--aa-list`).
    pub list: &'static str,
}

/// Times `scene_path` at `size` with each of [`CHOICES`] (`frames` timed frames each), then
/// the quality figures on `frames` frames at [`QUALITY_SIZE`].
///
/// Each choice's frames alternate one by one with frames without anti-aliasing (each timed
/// alone, submit to idle), and its ratio is the median of its frames over the median of the
/// plain frames between them: on a shared machine the plain frame's time drifts by a fifth
/// over the minutes a run takes, and a baseline measured once at the start would put that
/// drift into every ratio. The `off` row gives the median of all plain frames.
pub fn run(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<(RunInfo, AntialiasBench)> {
    let scene_arg = scene_path.to_string_lossy();
    let size_arg = format!("{}x{}", size.0, size.1);
    let job = quality::render_job(&[&scene_arg, "--size", &size_arg])?;
    let (p, mut renderer) = crate::app::capture::prepare(&job)?;
    let cam = p.scene.camera(0, &p.world.terrain);
    let pixels = f64::from(size.0 * size.1);
    let (gpu, terrain, desc) = (&p.gpu, &p.world.terrain, &p.scene.desc);
    let settings = CHOICES.map(|antialias| RenderSettings {
        antialias,
        ..p.settings
    });
    let mut timings: Vec<AaTiming> = Vec::new();
    let mut plain = Vec::new();
    for (k, choice) in CHOICES.into_iter().enumerate() {
        // A warm-up (shader compilation on first use, the atlas's size) and the extra rays.
        let extra = (renderer.capture(gpu, terrain, desc, &cam, &settings[k])?).antialias_rays();
        let (mut frame_ms, mut ratio) = (0.0, 1.0);
        if k > 0 {
            let [off, with] = interleaved_ms(frames, |i| {
                let s = &settings[if i == 0 { 0 } else { k }];
                renderer.render(gpu, terrain, desc, &cam, s, Stage::Shade)?;
                gpu.wait()
            })?;
            plain.extend_from_slice(&off);
            frame_ms = median(with);
            ratio = frame_ms / median(off);
        }
        timings.push(AaTiming {
            antialias: choice,
            frame_ms,
            ratio,
            extra_rays: extra,
            extra_rays_per_pixel: extra as f64 / pixels,
        });
    }
    timings[0].frame_ms = median(plain);
    let run = RunInfo::new(&p.gpu, scene_path, size, frames);
    let list = if gpu.options.aa_list.on_gpu(&gpu.info) {
        "gpu"
    } else {
        "cpu"
    };
    drop((p, renderer));
    let q_size = format!("{}x{}", QUALITY_SIZE.0, QUALITY_SIZE.1);
    let q_job = quality::render_job(&[&scene_arg, "--size", &q_size])?;
    let quality = quality::measure(&q_job, frames.max(2), &CHOICES)?;
    let details = AntialiasBench {
        timings,
        quality,
        quality_size: QUALITY_SIZE,
        quality_frames: frames.max(2),
        list,
    };
    Ok((run, details))
}

impl AntialiasBench {
    /// One row per choice: frame time, ratio, extra rays, and the quality figures.
    pub fn table(&self) -> Table {
        let rows = self
            .timings
            .iter()
            .zip(&self.quality.rows)
            .map(|(t, q)| {
                let figures = Figures::default()
                    .with("frame_ms", t.frame_ms)
                    .with("ratio", t.ratio)
                    .with("extra_rays", t.extra_rays as f64)
                    .with("extra_per_pixel", t.extra_rays_per_pixel)
                    .with("p99_error", q.p99_error)
                    .with("mean_error", q.mean_error)
                    .with("temporal_excess", q.temporal_excess)
                    .with("te_marked", q.temporal_excess_parts.marked)
                    .with("te_sky", q.temporal_excess_parts.sky)
                    .with("te_smooth", q.temporal_excess_parts.smooth)
                    .with("te_detail", q.temporal_excess_parts.detail);
                Row::new(t.antialias.name(), figures)
            })
            .collect();
        let summary = Figures::default().with("reference_change", self.quality.reference_change);
        let notes = vec![
            format!(
                "frame_ms, ratio, extra rays: the scene's first camera at the run's size; p99_error, mean_error, temporal_excess (8-bit sRGB): {} frames in motion at {}x{} against 16 rays per pixel",
                self.quality_frames, self.quality_size.0, self.quality_size.1
            ),
            "reference_change: the reference's own mean change between consecutive frames".into(),
            format!(
                "the list of marked pixels built on the {} (--aa-list)",
                self.list.to_uppercase()
            ),
            format!(
                "te_marked, te_sky, te_smooth, te_detail: the temporal excess from pixels anti-aliased in either frame of a pair, else sky, else surfaces at most {} levels from every neighbour, else the rest (they add up to temporal_excess)",
                quality::SMOOTH_STEP
            ),
        ];
        Table {
            rows,
            summary,
            notes,
        }
    }
}
