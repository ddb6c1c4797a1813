//! `relief bench volume`: the density-volume pass with empty-space skipping and early ray
//! termination against plain marching of the same lattice, measured in the same run.

use super::table::{Figures, Row, RunInfo, Table};
use super::timing::{scene_at_size, FrameSetup};
use crate::gpu::{RenderSettings, Stage, TerrainRenderer};
use crate::volume::{Volume, VolumeSettings};
use crate::world::World;
use crate::{Error, Result};
use serde::Serialize;
use std::path::Path;

/// One sampling configuration's figures.
#[derive(Clone, Debug, Serialize)]
pub struct VolumeRun {
    pub name: String,
    /// Median frame time, each frame timed alone from submit to GPU idle (ms).
    pub frame_ms: f64,
    /// Fastest volume pass alone, submitted and waited for on its own (ms).
    pub volume_ms: f64,
    /// Texture samples taken in the frame.
    pub samples: u64,
    /// Samples taken per second of volume pass.
    pub samples_per_s: f64,
    /// Lattice points covered per second of volume pass (sampled or skipped; the plain
    /// march samples all of them).
    pub lattice_per_s: f64,
}

/// What `relief bench volume` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct VolumeBench {
    pub volume: String,
    pub voxels: [u32; 3],
    /// Fraction of voxels the transfer function gives no opacity.
    pub hidden_fraction: f64,
    /// Frame time without the volume (ms).
    pub no_volume_frame_ms: f64,
    /// Lattice points inside the volume along all rays (what plain marching samples).
    pub lattice_points: u64,
    pub runs: Vec<VolumeRun>,
    /// Plain marching's volume-pass time over skipping + termination's.
    pub speedup: f64,
}

/// The sampling configurations measured, by name: `base` with skipping and early termination
/// off and on.
fn configurations(base: VolumeSettings) -> [(&'static str, VolumeSettings); 4] {
    [
        (
            "plain marching",
            VolumeSettings {
                skip: false,
                early_termination: false,
                ..base
            },
        ),
        (
            "empty-space skipping",
            VolumeSettings {
                early_termination: false,
                ..base
            },
        ),
        (
            "early termination",
            VolumeSettings {
                skip: false,
                ..base
            },
        ),
        (
            "skipping + termination",
            VolumeSettings {
                skip: true,
                early_termination: true,
                ..base
            },
        ),
    ]
}

impl FrameSetup<'_> {
    /// Measures each sampling configuration; `lattice_points` is what the first (plain
    /// marching) samples.
    fn runs(&self, r: &mut TerrainRenderer, volume: &Volume) -> Result<(Vec<VolumeRun>, u64)> {
        let (gpu, terrain, desc, cam) = (self.gpu, self.terrain, self.desc, self.cam);
        let mut runs = Vec::new();
        let mut lattice_points = 0;
        for (name, cfg) in configurations(volume.settings) {
            r.set_volume_settings(gpu, cfg);
            let mut volume_ms = f64::INFINITY;
            let mut samples = 0;
            for _ in 0..self.frames.clamp(2, 5) {
                let out = r.capture(gpu, terrain, desc, cam, self.settings)?;
                volume_ms = volume_ms.min(out.times.volume_ms);
                samples = out.volume_samples.iter().map(|&v| v as u64).sum::<u64>();
                if runs.is_empty() {
                    lattice_points = samples;
                }
            }
            let frame = self.median_ms(r, Stage::Shade)?;
            log::info!(
                "{name}: frame {frame:.1} ms, volume pass {volume_ms:.1} ms, {samples} samples"
            );
            runs.push(VolumeRun {
                name: name.into(),
                frame_ms: frame,
                volume_ms,
                samples,
                samples_per_s: samples as f64 / (volume_ms * 1e-3),
                lattice_per_s: lattice_points as f64 / (volume_ms * 1e-3),
            });
        }
        Ok((runs, lattice_points))
    }
}

/// Runs the benchmark on the scene's (first) volume at `size`.
pub fn run(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<(RunInfo, VolumeBench)> {
    let scene = scene_at_size(scene_path, size)?;
    let world = World::load(&scene)?;
    let volume = world.volumes.first().ok_or_else(|| {
        Error::invalid(
            "volumes",
            format!(
                "{} has no [[volumes]] table to benchmark",
                scene_path.display()
            ),
        )
    })?;
    let gpu = crate::app::gpu_options::open()?;
    let mut renderer = TerrainRenderer::new(&gpu, &world.terrain)?;
    renderer.set_objects(&gpu, &world.objects)?;
    let cam = scene.camera(0, &world.terrain);
    let settings = RenderSettings::from_scene(&scene.desc);
    let bench = FrameSetup {
        gpu: &gpu,
        terrain: &world.terrain,
        desc: &scene.desc,
        cam: &cam,
        settings: &settings,
        frames,
    };
    let no_volume_frame_ms = bench.median_ms(&mut renderer, Stage::Shade)?;
    renderer.set_volumes(&gpu, std::slice::from_ref(volume))?;
    let (runs, lattice_points) = bench.runs(&mut renderer, volume)?;
    let details = VolumeBench {
        volume: volume.name.clone(),
        voxels: volume.grid.dims,
        hidden_fraction: volume.hidden_fraction(),
        no_volume_frame_ms,
        lattice_points,
        speedup: runs[0].volume_ms / runs[3].volume_ms,
        runs,
    };
    Ok((RunInfo::new(&gpu, scene_path, size, frames), details))
}

impl VolumeBench {
    /// One row per sampling configuration, the speedup as the summary.
    pub fn table(&self) -> Table {
        let rows = (self.runs.iter())
            .map(|run| {
                let figures = Figures::default()
                    .with("frame_ms", run.frame_ms)
                    .with("volume_ms", run.volume_ms)
                    .with("samples", run.samples as f64)
                    .with("samples_per_s", run.samples_per_s)
                    .with("lattice_per_s", run.lattice_per_s);
                Row::new(&run.name, figures)
            })
            .collect();
        let summary = Figures::default()
            .with("no_volume_frame_ms", self.no_volume_frame_ms)
            .with("lattice_points", self.lattice_points as f64)
            .with("hidden_fraction", self.hidden_fraction)
            .with("speedup", self.speedup);
        let [x, y, z] = self.voxels;
        let notes = vec![
            format!("volume {:?}: {x}x{y}x{z} voxels", self.volume),
            "speedup: plain marching's volume pass over skipping + termination's".into(),
        ];
        Table {
            rows,
            summary,
            notes,
        }
    }
}
