//! `relief bench primary`: the primary rays of the product configuration alone (pyramid + tile
//! pre-pass), for scripts that alternate relief with another renderer
//! (`benches/embree_compare.py`) so that this machine's slow spells fall on both.

use super::table::{Figures, Row, RunInfo, Table};
use super::terrain::product_settings;
use super::timing::{scene_at_size, FrameSetup};
use crate::gpu::{Stage, TerrainRenderer};
use crate::Result;
use serde::Serialize;
use std::path::Path;

/// What `relief bench primary` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct PrimaryTiming {
    /// Median milliseconds of ray table + tile pre-pass + cast (frame pairs, as `terrain`).
    pub primary_ms: f64,
    pub rays_per_second: f64,
}

/// Times the primary rays of `scene_path` at `size` (`frames` timed frames), nothing else;
/// `lod` overrides the scene's `[render] lod`.
pub fn run(
    scene_path: &Path,
    size: (u32, u32),
    frames: u32,
    lod: Option<crate::scene::Lod>,
) -> Result<(RunInfo, PrimaryTiming)> {
    let mut scene = scene_at_size(scene_path, size)?;
    if let Some(lod) = lod {
        scene.desc.render.lod = lod;
    }
    let terrain = scene.load_terrain()?;
    let gpu = crate::app::gpu_options::open()?;
    let mut renderer = TerrainRenderer::new(&gpu, &terrain)?;
    let cam = scene.camera(0, &terrain);
    let s = product_settings(&scene);
    let frame = FrameSetup {
        gpu: &gpu,
        terrain: &terrain,
        desc: &scene.desc,
        cam: &cam,
        settings: &s,
        frames,
    };
    frame.capture(&mut renderer)?;
    let primary_ms = frame.median_ms(&mut renderer, Stage::Cast)?;
    let details = PrimaryTiming {
        primary_ms,
        rays_per_second: (size.0 * size.1) as f64 / (primary_ms * 1e-3),
    };
    Ok((RunInfo::new(&gpu, scene_path, size, frames), details))
}

impl PrimaryTiming {
    /// One row: the product configuration.
    pub fn table(&self) -> Table {
        let figures = Figures::default()
            .with("primary_ms", self.primary_ms)
            .with("rays_per_second", self.rays_per_second);
        Table {
            rows: vec![Row::new("pyramid+tiles", figures)],
            ..Table::default()
        }
    }
}
