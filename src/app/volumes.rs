//! `relief bench --volume`: the density-volume pass with empty-space skipping and early ray
//! termination against plain marching of the same lattice, measured in the same run.

use crate::gpu::{Gpu, RenderSettings, Stage, TerrainRenderer};
use crate::volume::VolumeSettings;
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

/// What `relief bench --volume` reports.
#[derive(Clone, Debug, Serialize)]
pub struct VolumeReport {
    pub adapter: String,
    pub backend: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
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

/// Runs the benchmark on the scene's (first) volume at `size`.
pub fn bench(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<VolumeReport> {
    let (scene, terrain) = super::bench::load_at_size(scene_path, size)?;
    let volumes = scene.volumes(&terrain)?;
    let volume = volumes.first().ok_or_else(|| {
        Error::invalid(
            "volumes",
            format!(
                "{} has no [[volumes]] table to benchmark",
                scene_path.display()
            ),
        )
    })?;
    let objects = scene.free_forms(&terrain)?;
    let gpu = Gpu::new()?;
    let mut renderer = TerrainRenderer::new(&gpu, &terrain)?;
    renderer.set_objects(&gpu, &objects)?;
    let cam = scene.camera(0, &terrain);
    let s = RenderSettings::from_scene(&scene.desc);
    let frame_ms = |r: &mut TerrainRenderer| -> Result<f64> {
        super::bench::median_frame_ms(
            r,
            &gpu,
            &terrain,
            &scene.desc,
            &cam,
            &s,
            Stage::Shade,
            frames,
        )
    };
    let no_volume_frame_ms = frame_ms(&mut renderer)?;
    renderer.set_volumes(&gpu, std::slice::from_ref(volume))?;
    let base = volume.settings;
    let configs = [
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
    ];
    let mut runs = Vec::new();
    let mut lattice_points = 0;
    for (name, cfg) in configs {
        renderer.set_volume_settings(&gpu, cfg);
        let mut volume_ms = f64::INFINITY;
        let mut samples = 0;
        for _ in 0..frames.clamp(2, 5) {
            let out = renderer.capture(&gpu, &terrain, &scene.desc, &cam, &s)?;
            volume_ms = volume_ms.min(out.times.volume_ms);
            samples = out.volume_samples.iter().map(|&v| v as u64).sum::<u64>();
            if runs.is_empty() {
                lattice_points = samples;
            }
        }
        let frame = frame_ms(&mut renderer)?;
        log::info!("{name}: frame {frame:.1} ms, volume pass {volume_ms:.1} ms, {samples} samples");
        runs.push(VolumeRun {
            name: name.into(),
            frame_ms: frame,
            volume_ms,
            samples,
            samples_per_s: samples as f64 / (volume_ms * 1e-3),
            lattice_per_s: lattice_points as f64 / (volume_ms * 1e-3),
        });
    }
    Ok(VolumeReport {
        adapter: gpu.info.name.clone(),
        backend: format!("{:?}", gpu.info.backend),
        scene: scene_path.display().to_string(),
        width: size.0,
        height: size.1,
        frames,
        volume: volume.name.clone(),
        voxels: volume.grid.dims,
        hidden_fraction: volume.hidden_fraction(),
        no_volume_frame_ms,
        lattice_points,
        speedup: runs[0].volume_ms / runs[3].volume_ms,
        runs,
    })
}

/// Prints the volume report.
pub fn print(r: &VolumeReport) {
    println!(
        "relief bench --volume: {} at {}x{}, {} frames per configuration",
        r.scene, r.width, r.height, r.frames
    );
    println!("adapter: {} ({})", r.adapter, r.backend);
    println!(
        "volume {:?}: {}x{}x{} voxels, transfer function hides {:.1}% of them; {} lattice points on screen",
        r.volume,
        r.voxels[0],
        r.voxels[1],
        r.voxels[2],
        100.0 * r.hidden_fraction,
        r.lattice_points
    );
    println!("frame without the volume: {:.1} ms", r.no_volume_frame_ms);
    println!(
        "{:<24} {:>10} {:>11} {:>12} {:>12} {:>13}",
        "configuration", "frame ms", "volume ms", "samples", "samples/s", "lattice pt/s"
    );
    for run in &r.runs {
        println!(
            "{:<24} {:>10.1} {:>11.1} {:>12} {:>11.1}M {:>12.1}M",
            run.name,
            run.frame_ms,
            run.volume_ms,
            run.samples,
            run.samples_per_s * 1e-6,
            run.lattice_per_s * 1e-6
        );
    }
    println!(
        "skipping + termination vs plain marching (volume pass): {:.2}x faster",
        r.speedup
    );
}
