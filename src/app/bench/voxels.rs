//! `relief bench voxels`: voxel models against terrain only: each `[[voxels]]` model alone
//! filling the view, and the simplified-voxel paper's two model sizes at one voxel per pixel.

use super::table::{Figures, Row, RunInfo, Table};
use super::timing::{scene_at_size, FrameSetup};
use crate::app::figures::median;
use crate::gpu::{RenderSettings, Stage, TerrainRenderer};
use crate::scene::Camera;
use crate::voxel::VoxelInstance;
use crate::world::World;
use crate::{Error, Result};
use serde::Serialize;
use std::path::Path;

/// Voxel counts of the simplified-voxel paper's two models (seed 000: 355 fps and 63 fps).
pub const PAPER_SMALL: usize = 49_152;
pub const PAPER_LARGE: usize = 1_548_288;

/// Timings of one set of placed models.
#[derive(Clone, Debug, Serialize)]
pub struct VoxelRun {
    pub name: String,
    pub instances: usize,
    pub voxels: usize,
    /// Pixels showing a voxel.
    pub voxel_pixels: usize,
    /// Mean DDA steps (bricks and voxels visited, jumps counted once, entering an occupied
    /// brick a step of its own) per voxel pixel.
    pub mean_steps: f64,
    /// Median per-pass times over the timed frames (each pass waited for on its own).
    pub cast_ms: f64,
    pub shadow_ms: f64,
    /// Median frame time (ray table, terrain, voxel passes, shading with shadows).
    pub frame_ms: f64,
}

/// What `relief bench voxels` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct VoxelBench {
    pub terrain_only_ms: f64,
    /// Each model alone, scaled to fill the view.
    pub fill: Vec<VoxelRun>,
    /// The paper's sizes, one voxel per pixel 60 m ahead.
    pub paper: Vec<VoxelRun>,
}

/// Models of the paper's sizes at one voxel per pixel, `distance` metres ahead of `cam` in a
/// row across the view: the smallest scene model upsampled to at least [`PAPER_SMALL`] voxels;
/// and copies of the largest (then the upsampled small one) until at least [`PAPER_LARGE`].
fn paper_sets(
    models: &[VoxelInstance],
    cam: &Camera,
    distance: f64,
) -> Result<Vec<(String, Vec<VoxelInstance>)>> {
    let count = |m: &VoxelInstance| m.frames[0].voxels.len();
    let small = models
        .iter()
        .min_by_key(|m| count(m))
        .expect("models exist");
    let large = models
        .iter()
        .max_by_key(|m| count(m))
        .expect("models exist");
    let k = (1..=16u32)
        .find(|k| count(small) * (k * k * k) as usize >= PAPER_SMALL)
        .unwrap_or(16);
    let mut up = small.clone();
    up.frames = vec![std::sync::Arc::new(small.frames[0].upsampled(k)?)];
    up.name = format!("{} x{k}", small.name);
    let mut big = Vec::new();
    while big.iter().map(count).sum::<usize>() < PAPER_LARGE {
        let next = if big.is_empty()
            || big.iter().map(count).sum::<usize>() + count(large) <= PAPER_LARGE
        {
            large.clone()
        } else {
            up.clone()
        };
        big.push(next);
    }
    // One voxel per pixel at `distance`, on the view axis's vertical, side by side.
    let (fx, _, _, _) = cam.intrinsics();
    let vs = distance / fx;
    let (right, _, _) = cam.basis();
    let right = glam::DVec3::new(right.x, right.y, 0.0).normalize();
    let ahead = glam::DVec3::new(-right.y, right.x, 0.0);
    let rotation = glam::DMat3::from_cols(right, ahead, glam::DVec3::Z);
    let place = |set: &[VoxelInstance]| -> Vec<VoxelInstance> {
        let widths: Vec<f64> = set.iter().map(|m| m.dims()[0] as f64 * vs).collect();
        let gap = 0.05 * widths.iter().cloned().fold(0.0, f64::max);
        let total = widths.iter().sum::<f64>() + gap * (set.len() as f64 - 1.0);
        let mut x = -0.5 * total;
        set.iter()
            .zip(&widths)
            .map(|(m, w)| {
                let h = m.dims()[2] as f64 * vs;
                let mut m = m.clone();
                m.rotation = rotation;
                m.voxel_size = vs;
                m.position = cam.pose.position + ahead * distance + right * (x + 0.5 * w)
                    - glam::DVec3::Z * (0.5 * h);
                x += w + gap;
                m
            })
            .collect()
    };
    let name = |set: &[VoxelInstance]| {
        set.iter()
            .map(|m| m.name.clone())
            .collect::<Vec<_>>()
            .join(" + ")
    };
    let one = vec![up];
    Ok(vec![(name(&one), place(&one)), (name(&big), place(&big))])
}

impl FrameSetup<'_> {
    /// Renders the models `m` (none: terrain only) and times them.
    fn run(&self, r: &mut TerrainRenderer, name: String, m: &[VoxelInstance]) -> Result<VoxelRun> {
        let (gpu, terrain, desc, cam, s) =
            (self.gpu, self.terrain, self.desc, self.cam, self.settings);
        r.set_voxels(gpu, m)?;
        let out = r.capture(gpu, terrain, desc, cam, s)?;
        let hits: Vec<usize> = (0..out.flags.len())
            .filter(|&k| out.flags[k] & 32 != 0)
            .collect();
        let steps: u64 = hits.iter().map(|&k| out.steps[k] as u64).sum();
        let (mut cast, mut shadow) = (Vec::new(), Vec::new());
        for _ in 0..self.frames {
            let t = r.capture(gpu, terrain, desc, cam, s)?.times;
            cast.push(t.voxels_ms);
            shadow.push(t.voxel_shadow_ms);
        }
        let frame_ms = self.median_ms(r, Stage::Shade)?;
        Ok(VoxelRun {
            name,
            instances: m.len(),
            voxels: m.iter().map(|i| i.frames[0].voxels.len()).sum(),
            voxel_pixels: hits.len(),
            mean_steps: steps as f64 / hits.len().max(1) as f64,
            cast_ms: median(cast),
            shadow_ms: median(shadow),
            frame_ms,
        })
    }
}

/// Runs the benchmark on the `[[voxels]]` models of `scene_path` at `size`.
pub fn run(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<(RunInfo, VoxelBench)> {
    let scene = scene_at_size(scene_path, size)?;
    let world = World::load(&scene)?;
    let models = &world.voxels;
    if models.is_empty() {
        return Err(Error::invalid(
            "voxels",
            format!(
                "{} places no [[voxels]] model to measure",
                scene_path.display()
            ),
        ));
    }
    let gpu = crate::app::gpu_options::open()?;
    let mut r = TerrainRenderer::new(&gpu, &world.terrain)?;
    let cam = scene.camera(0, &world.terrain);
    let settings = RenderSettings::from_scene(&scene.desc);
    let frames = frames.max(1);
    let bench = FrameSetup {
        gpu: &gpu,
        terrain: &world.terrain,
        desc: &scene.desc,
        cam: &cam,
        settings: &settings,
        frames,
    };
    let terrain_only_ms = bench.run(&mut r, "terrain only".into(), &[])?.frame_ms;
    let mut fill = Vec::new();
    for m in models {
        // Each model alone, scaled to the first model's height so it fills the same view.
        let mut m = m.clone();
        let h0 = models[0].dims()[2] as f64 * models[0].voxel_size;
        m.voxel_size = h0 / m.dims()[2] as f64;
        m.position = models[0].position;
        fill.push(bench.run(&mut r, m.name.clone(), std::slice::from_ref(&m))?);
    }
    let mut paper = Vec::new();
    for (name, set) in paper_sets(models, &cam, 60.0)? {
        paper.push(bench.run(&mut r, name, &set)?);
    }
    let details = VoxelBench {
        terrain_only_ms,
        fill,
        paper,
    };
    Ok((RunInfo::new(&gpu, scene_path, size, frames), details))
}

impl VoxelBench {
    /// One row per set of models measured, terrain only as the summary.
    pub fn table(&self) -> Table {
        let row = |set: &str, v: &VoxelRun| {
            let figures = Figures::default()
                .with("instances", v.instances as f64)
                .with("voxels", v.voxels as f64)
                .with("voxel_pixels", v.voxel_pixels as f64)
                .with("steps_per_pixel", v.mean_steps)
                .with("cast_ms", v.cast_ms)
                .with("shadow_ms", v.shadow_ms)
                .with("frame_ms", v.frame_ms)
                .with("frame_vs_terrain_only", v.frame_ms / self.terrain_only_ms);
            Row::new(format!("{set}: {}", v.name), figures)
        };
        let rows = (self.fill.iter().map(|v| row("fill", v)))
            .chain(self.paper.iter().map(|v| row("paper", v)))
            .collect();
        let notes = vec![
            "fill: each model alone, scaled to fill the view".into(),
            format!("paper: the simplified-voxel paper's sizes (seed 000: {PAPER_SMALL} voxels at 355 fps, {PAPER_LARGE} at 63 fps), one voxel per pixel 60 m ahead"),
        ];
        Table {
            rows,
            summary: Figures::default().with("terrain_only_ms", self.terrain_only_ms),
            notes,
        }
    }
}
