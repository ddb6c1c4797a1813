//! `relief bench antialias`: the frame with edge anti-aliasing against the same frame without
//! (at `--size`, the scene's first camera), the extra rays it casts, and the image-quality
//! figures (`app::quality`) of each choice on the scene's first `--frames` frames in motion
//! at 320x180 against relief's 16-rays-per-pixel reference.

use super::table::{Figures, Row, RunInfo, Table};
use super::timing::FrameSetup;
use crate::app::quality::{self, Quality};
use crate::gpu::{Antialias, Stage};
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
}

fn name(a: Antialias) -> String {
    match (a.samples, a.every_pixel, a.adaptive) {
        (0, _, _) => "off".into(),
        (_, false, true) => "edges".into(),
        (n, false, false) => format!("edges {n}"),
        (n, true, _) => format!("every pixel {n}"),
    }
}

/// Times `scene_path` at `size` with each of [`CHOICES`] (`frames` timed frames each), then
/// the quality figures on `frames` frames at [`QUALITY_SIZE`].
pub fn run(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<(RunInfo, AntialiasBench)> {
    let scene_arg = scene_path.to_string_lossy();
    let size_arg = format!("{}x{}", size.0, size.1);
    let job = quality::render_job(&[&scene_arg, "--size", &size_arg])?;
    let (mut p, mut renderer) = crate::app::capture::prepare(&job)?;
    let cam = p.scene.camera(0, &p.world.terrain);
    let pixels = f64::from(size.0 * size.1);
    let mut timings: Vec<AaTiming> = Vec::new();
    for choice in CHOICES {
        p.settings.antialias = choice;
        let frame = FrameSetup {
            gpu: &p.gpu,
            terrain: &p.world.terrain,
            desc: &p.scene.desc,
            cam: &cam,
            settings: &p.settings,
            frames,
        };
        let extra = frame.capture(&mut renderer)?.antialias_rays();
        let frame_ms = frame.median_ms(&mut renderer, Stage::Shade)?;
        let base = timings.first().map_or(frame_ms, |t| t.frame_ms);
        timings.push(AaTiming {
            antialias: choice,
            frame_ms,
            ratio: frame_ms / base,
            extra_rays: extra,
            extra_rays_per_pixel: extra as f64 / pixels,
        });
    }
    let run = RunInfo::new(&p.gpu, scene_path, size, frames);
    drop((p, renderer));
    let q_size = format!("{}x{}", QUALITY_SIZE.0, QUALITY_SIZE.1);
    let q_job = quality::render_job(&[&scene_arg, "--size", &q_size])?;
    let quality = quality::measure(&q_job, frames.max(2), &CHOICES)?;
    let details = AntialiasBench {
        timings,
        quality,
        quality_size: QUALITY_SIZE,
        quality_frames: frames.max(2),
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
                    .with("temporal_excess", q.temporal_excess);
                Row::new(name(t.antialias), figures)
            })
            .collect();
        let summary = Figures::default().with("reference_change", self.quality.reference_change);
        let notes = vec![
            format!(
                "frame_ms, ratio, extra rays: the scene's first camera at the run's size; p99_error, mean_error, temporal_excess (8-bit sRGB): {} frames in motion at {}x{} against 16 rays per pixel",
                self.quality_frames, self.quality_size.0, self.quality_size.1
            ),
            "reference_change: the reference's own mean change between consecutive frames".into(),
        ];
        Table {
            rows,
            summary,
            notes,
        }
    }
}
