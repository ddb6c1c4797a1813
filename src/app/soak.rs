//! `relief bench --soak`: a long headless run that watches for leaks and stalls.
//!
//! Renders N frames of a scene the way `relief render` does (camera along the scene's path,
//! every pass timed, colour and data read back; no files written) and records after each
//! frame the process's resident set size. Reports the RSS slope fitted over a window of
//! frames (100–500 by default: the first frames warm caches and compile pipelines), wgpu's
//! count of live objects per kind at both ends of the window, and frame-time percentiles.
//! A leak shows as a slope of kilobytes per frame; objects created per frame and never
//! dropped show as counts that differ.

use super::view::stats::percentile;
use crate::gpu::{Gpu, RenderSettings};
use crate::Result;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The soak run's results (`relief bench --soak --json`).
#[derive(Clone, Debug, Serialize)]
pub struct SoakReport {
    pub adapter: String,
    pub backend: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// Resident set size after each frame (KiB; empty where the OS does not say).
    pub rss_kib: Vec<u64>,
    /// First and last frame (inclusive, exclusive) of the window the slope is fitted over.
    pub window: [u32; 2],
    /// Least-squares slope of RSS over the window (KiB per frame).
    pub rss_slope_kib_per_frame: f64,
    /// Live wgpu objects per kind before the first and the last frame of the window.
    pub resources_start: Vec<(String, usize)>,
    pub resources_end: Vec<(String, usize)>,
    /// Whether every count is the same at both ends of the window.
    pub resources_equal: bool,
    /// Frame wall time (render, wait, read back), ms.
    pub frame_ms_p50: f64,
    pub frame_ms_p99: f64,
    pub frame_ms_max: f64,
}

/// The process's resident set size in KiB (Linux: `VmRSS` of `/proc/self/status`).
pub fn resident_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Least-squares slope of `y` over `x = 0, 1, 2, ...` (0 for fewer than two points).
pub fn slope(y: &[f64]) -> f64 {
    let n = y.len() as f64;
    if y.len() < 2 {
        return 0.0;
    }
    let mx = (n - 1.0) / 2.0;
    let my = y.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in y.iter().enumerate() {
        let dx = i as f64 - mx;
        sxy += dx * (v - my);
        sxx += dx * dx;
    }
    sxy / sxx
}

/// The frame window the slope is fitted over: 100..500, shrunk for shorter runs.
pub fn window(frames: u32) -> [u32; 2] {
    if frames >= 500 {
        [100, 500]
    } else {
        [frames / 5, frames]
    }
}

fn counts(gpu: &Gpu) -> Vec<(String, usize)> {
    gpu.resource_counts()
        .unwrap_or_default()
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

/// Renders `frames` frames of `scene_path` at `size` and reports memory and frame times.
pub fn run(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<SoakReport> {
    let mut scene = crate::scene::Scene::load(scene_path)?;
    scene.desc.output.width = size.0;
    scene.desc.output.height = size.1;
    scene.desc.validate()?;
    let terrain = scene.load_terrain()?;
    let objects = scene.free_forms(&terrain)?;
    let volumes = scene.volumes(&terrain)?;
    let voxels = scene.voxel_models(&terrain)?;
    let gpu = Gpu::new()?;
    let mut renderer = crate::gpu::TerrainRenderer::new(&gpu, &terrain)?;
    renderer.set_objects(&gpu, &objects)?;
    renderer.set_volumes(&gpu, &volumes)?;
    renderer.set_voxels(&gpu, &voxels)?;
    let settings = RenderSettings::from_scene(&scene.desc);
    let fps = scene.desc.path.as_ref().map_or(30.0, |p| p.fps);
    let [w0, w1] = window(frames);
    let mut rss = Vec::with_capacity(frames as usize);
    let mut times = Vec::with_capacity(frames as usize);
    let (mut start_counts, mut end_counts) = (Vec::new(), Vec::new());
    for frame in 0..frames {
        if frame == w0 {
            start_counts = counts(&gpu);
        }
        if frame == w1 {
            end_counts = counts(&gpu);
        }
        let start = Instant::now();
        let cam = scene.camera(frame, &terrain);
        renderer.set_time(frame as f64 / fps);
        let out = renderer.capture(&gpu, &terrain, &scene.desc, &cam, &settings)?;
        std::hint::black_box(&out.rgba);
        times.push(start.elapsed().as_secs_f64() * 1e3);
        if let Some(kib) = resident_kib() {
            rss.push(kib);
        }
        if frame % 100 == 99 {
            log::info!(
                "soak: frame {} of {frames}, RSS {} MiB",
                frame + 1,
                rss.last().copied().unwrap_or(0) / 1024
            );
        }
    }
    if frames == w1 {
        end_counts = counts(&gpu);
    }
    let fitted: Vec<f64> = rss
        .get(w0 as usize..w1 as usize)
        .unwrap_or(&[])
        .iter()
        .map(|&k| k as f64)
        .collect();
    Ok(SoakReport {
        adapter: gpu.info.name.clone(),
        backend: format!("{:?}", gpu.info.backend),
        scene: scene_path.display().to_string(),
        width: size.0,
        height: size.1,
        frames,
        rss_slope_kib_per_frame: slope(&fitted),
        rss_kib: rss,
        window: [w0, w1],
        resources_equal: start_counts == end_counts,
        resources_start: start_counts,
        resources_end: end_counts,
        frame_ms_p50: percentile(&times, 50.0).unwrap_or(0.0),
        frame_ms_p99: percentile(&times, 99.0).unwrap_or(0.0),
        frame_ms_max: times.iter().copied().fold(0.0, f64::max),
    })
}

/// Prints the report as a few lines of text.
pub fn print(r: &SoakReport) {
    println!(
        "relief bench --soak on {} at {}x{}, {} frames, {} ({})",
        r.scene, r.width, r.height, r.frames, r.adapter, r.backend
    );
    let first = r.rss_kib.first().copied().unwrap_or(0);
    let last = r.rss_kib.last().copied().unwrap_or(0);
    println!(
        "  RSS {:.1} MiB after the first frame, {:.1} MiB after the last; slope over frames {}..{}: {:.2} KiB/frame",
        first as f64 / 1024.0,
        last as f64 / 1024.0,
        r.window[0],
        r.window[1],
        r.rss_slope_kib_per_frame
    );
    let changed: Vec<String> = r
        .resources_start
        .iter()
        .zip(&r.resources_end)
        .filter(|(a, b)| a.1 != b.1)
        .map(|(a, b)| format!("{} {} -> {}", a.0, a.1, b.1))
        .collect();
    let total: usize = r.resources_end.iter().map(|(_, n)| n).sum();
    println!(
        "  wgpu objects at frames {} and {}: {}",
        r.window[0],
        r.window[1],
        if changed.is_empty() {
            format!("unchanged ({total} live)")
        } else {
            changed.join(", ")
        }
    );
    println!(
        "  frame time p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
        r.frame_ms_p50, r.frame_ms_p99, r.frame_ms_max
    );
}
