//! `relief bench display`: a display configuration's channel (resized to the benchmark's size,
//! same lens): ray-table regeneration and the direct-mode frame against a pinhole frame of the
//! same size and scene.

use super::table::{Figures, Row, RunInfo, Table};
use crate::display::DisplayConfig;
use crate::gpu::{RenderSettings, Stage, TerrainRenderer};
use crate::scene::Scene;
use crate::{Error, Result};
use glam::DVec3;
use serde::Serialize;
use std::path::Path;

/// What `relief bench display` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct DisplayBench {
    pub config: String,
    pub channel: usize,
    /// Mean time of the table-generation pass alone (the eye moves every frame).
    pub table_ms: f64,
    /// Mean full frame (table, pre-pass, cast, shade) through the table.
    pub direct_frame_ms: f64,
    /// Mean full frame of the scene's pinhole camera at the same size.
    pub pinhole_frame_ms: f64,
    pub direct_over_pinhole: f64,
}

/// Channel `channel` of `config` resized to `size` (same lens), camera of frame 0 of
/// `scene_path`, `frames` timed frames after a warm-up.
pub fn run(
    scene_path: &Path,
    config: &Path,
    channel: usize,
    size: (u32, u32),
    frames: u32,
) -> Result<(RunInfo, DisplayBench)> {
    let cfg = DisplayConfig::load(config)?;
    let ch = crate::app::channel::channel(&cfg, &config.display().to_string(), channel)?;
    if frames == 0 {
        return Err(Error::invalid("--frames", "must be at least 1"));
    }
    let mut p = ch.projector;
    (p.width, p.height) = size;
    let scene = Scene::load(scene_path)?;
    let terrain = scene.load_terrain()?;
    let gpu = crate::app::gpu_options::open()?;
    let mut cam = scene.camera(0, &terrain);
    (cam.width, cam.height) = size;
    let s = RenderSettings::from_scene(&scene.desc);
    let eye = DVec3::from(cfg.eye.position);
    let points = crate::display::screen_points::screen_points(&cfg.screen, &p);
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
            r.render(&gpu, &terrain, &scene.desc, &cam, &s, Stage::Shade)?;
        }
        gpu.wait()?;
        let f = frames as f64;
        Ok((table / f, start.elapsed().as_secs_f64() * 1e3 / f))
    };
    let (table_ms, direct_frame_ms) = frame_ms(true)?;
    let (_, pinhole_frame_ms) = frame_ms(false)?;
    let details = DisplayBench {
        config: config.display().to_string(),
        channel,
        table_ms,
        direct_frame_ms,
        pinhole_frame_ms,
        direct_over_pinhole: direct_frame_ms / pinhole_frame_ms,
    };
    Ok((RunInfo::new(&gpu, scene_path, size, frames), details))
}

impl DisplayBench {
    /// The direct and pinhole frames as rows, the table pass and the ratio as the summary.
    pub fn table(&self) -> Table {
        let row = |ms: f64| Figures::default().with("frame_ms", ms);
        Table {
            rows: vec![
                Row::new("direct (ray table)", row(self.direct_frame_ms)),
                Row::new("pinhole", row(self.pinhole_frame_ms)),
            ],
            summary: Figures::default()
                .with("table_ms", self.table_ms)
                .with("direct_over_pinhole", self.direct_over_pinhole),
            notes: vec![format!(
                "{} channel {}, its lens at the benchmark's size; a new table every frame (the eye moves)",
                self.config, self.channel
            )],
        }
    }
}
