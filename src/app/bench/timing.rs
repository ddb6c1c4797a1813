//! What the benchmark modes share: the scene resized to the benchmark's size, and the frame
//! timing (frame pairs, median).

use crate::app::figures::median;
use crate::gpu::{FrameOutput, Gpu, RenderSettings, Stage, TerrainRenderer};
use crate::scene::{Camera, Scene, SceneDesc};
use crate::terrain::Terrain;
use crate::Result;
use std::path::Path;
use std::time::Instant;

/// The scene at `size` (validated again).
pub fn scene_at_size(scene_path: &Path, size: (u32, u32)) -> Result<Scene> {
    let mut scene = Scene::load(scene_path)?;
    scene.desc.output.width = size.0;
    scene.desc.output.height = size.1;
    scene.desc.validate()?;
    Ok(scene)
}

/// What a benchmark's frames are rendered with: the adapter, the terrain, the scene
/// description, the camera, the render settings and the timed frames per measurement. The
/// modes add their own measurements in `impl FrameSetup` blocks of their files.
#[derive(Clone, Copy)]
pub struct FrameSetup<'a> {
    pub gpu: &'a Gpu,
    pub terrain: &'a Terrain,
    pub desc: &'a SceneDesc,
    pub cam: &'a Camera,
    pub settings: &'a RenderSettings,
    pub frames: u32,
}

impl FrameSetup<'_> {
    /// One frame rendered and read back (a warm-up: shader compilation on first use, target
    /// allocation; or a frame a mode inspects).
    pub fn capture(&self, r: &mut TerrainRenderer) -> Result<FrameOutput> {
        r.capture(self.gpu, self.terrain, self.desc, self.cam, self.settings)
    }

    /// Wall-clock milliseconds per frame up to `stage` (submit to GPU idle, no readback),
    /// after one untimed frame: `frames` frames in pairs, each pair submitted back to back as
    /// a frame loop does (the CPU side of one frame overlaps the other's rendering), the
    /// median over the pairs. The median, not the mean: on a shared machine slow spells come
    /// and go, and one of them should not decide a figure.
    pub fn median_ms(&self, r: &mut TerrainRenderer, stage: Stage) -> Result<f64> {
        let (gpu, terrain, desc, cam, s) =
            (self.gpu, self.terrain, self.desc, self.cam, self.settings);
        r.render(gpu, terrain, desc, cam, s, stage)?;
        gpu.wait()?;
        let mut times = Vec::new();
        for _ in 0..(self.frames / 2).max(1) {
            let start = Instant::now();
            for _ in 0..2 {
                r.render(gpu, terrain, desc, cam, s, stage)?;
            }
            gpu.wait()?;
            times.push(start.elapsed().as_secs_f64() * 1e3 / 2.0);
        }
        Ok(median(times))
    }
}

/// `rounds` frames of each of two configurations, one of each in turn (the order swapped every
/// round), each timed alone: `frame(k)` renders configuration k and waits for the GPU.
/// Milliseconds of each. Interleaving keeps the slow spells of a shared machine from landing
/// on one configuration only.
pub fn interleaved_ms(
    rounds: u32,
    mut frame: impl FnMut(usize) -> Result<()>,
) -> Result<[Vec<f64>; 2]> {
    let mut times = [Vec::new(), Vec::new()];
    for round in 0..rounds.max(1) as usize {
        for k in [round % 2, 1 - round % 2] {
            let start = Instant::now();
            frame(k)?;
            times[k].push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    Ok(times)
}
