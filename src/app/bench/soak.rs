//! `relief bench soak`: a long headless run that watches for leaks and stalls.
//!
//! Renders N frames of a scene the way `relief render` does (camera along the scene's path,
//! every pass timed, colour and data read back; no files written) and records after each
//! frame the process's resident set size. Reports the RSS slope fitted over a window of
//! frames (100–500 by default: the first frames warm caches and compile pipelines), wgpu's
//! count of live objects per kind at both ends of the window, and frame-time percentiles.
//! A leak shows as a slope of kilobytes per frame; objects created per frame and never
//! dropped show as counts that differ.

use super::table::{Figures, RunInfo, Table};
use super::timing::scene_at_size;
use crate::app::figures::percentile;
use crate::app::figures::{resident_kib, slope, window};
use crate::gpu::{Antialias, Gpu, RenderSettings};
use crate::scene::AntialiasOption;
use crate::world::World;
use crate::Result;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

// The soak run's statistics, where they have always been found.

/// What `relief bench soak` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct SoakBench {
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
    /// Anti-aliasing's sub-pixel rays over all frames (0 without anti-aliasing).
    pub antialias_extra_rays: u64,
    /// A paged terrain (`[terrain] memory`): its pool and the last frame's paging.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub paging: Option<SoakPaging>,
}

/// The paging of a soak over a paged terrain.
#[derive(Clone, Debug, Serialize)]
pub struct SoakPaging {
    pub pool_bytes: u64,
    /// Frames rendered with a wanted tile not yet resident (from coarser levels, not waiting).
    pub frames_with_missing: u32,
    /// The last frame's paging, as in the frame JSON.
    pub last: serde_json::Value,
}

fn counts(gpu: &Gpu) -> Vec<(String, usize)> {
    gpu.resource_counts()
        .unwrap_or_default()
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

/// Renders `frames` frames of `scene_path` at `size` (anti-aliased as `antialias` says, else
/// as the scene does) and reports memory and frame times.
pub fn run(
    scene_path: &Path,
    size: (u32, u32),
    frames: u32,
    antialias: Option<AntialiasOption>,
) -> Result<(RunInfo, SoakBench)> {
    let scene = scene_at_size(scene_path, size)?;
    // `[terrain] memory = MB`: through the paged tile pool, the window held hollow, the pager
    // stepped every frame as `render --terrain-memory` does.
    let memory = scene.desc.terrain.memory;
    let world = World::load_as(&scene, memory.is_some())?;
    let gpu = crate::app::gpu_options::open()?;
    let (mut renderer, mut paging) = match memory {
        Some(mb) => {
            let (r, p) = crate::app::paged::renderer(&gpu, &scene, &world, mb)?;
            (r, Some(p))
        }
        None => (crate::app::upload::renderer(&gpu, &world)?, None),
    };
    let mut settings = RenderSettings::from_scene(&scene.desc);
    if let Some(a) = antialias {
        settings.antialias = Antialias::from_option(a);
    }
    let fps = scene.desc.path.as_ref().map_or(30.0, |p| p.fps);
    let [w0, w1] = window(frames);
    let mut rss = Vec::with_capacity(frames as usize);
    let mut times = Vec::with_capacity(frames as usize);
    let (mut start_counts, mut end_counts) = (Vec::new(), Vec::new());
    let mut missing_frames = 0;
    let mut extra_rays = 0;
    for frame in 0..frames {
        if frame == w0 {
            start_counts = counts(&gpu);
        }
        if frame == w1 {
            end_counts = counts(&gpu);
        }
        let start = Instant::now();
        let cam = scene.camera(frame, &world.terrain);
        renderer.set_time(frame as f64 / fps);
        if let Some(p) = &mut paging {
            let st = p.step(&gpu, &mut renderer, &world.terrain, &cam)?;
            missing_frames += (st.missing > 0) as u32;
        }
        let out = renderer.capture(&gpu, &world.terrain, &scene.desc, &cam, &settings)?;
        std::hint::black_box(&out.rgba);
        extra_rays += out.antialias_rays();
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
    let details = SoakBench {
        rss_slope_kib_per_frame: slope(&fitted),
        rss_kib: rss,
        window: [w0, w1],
        resources_equal: start_counts == end_counts,
        resources_start: start_counts,
        resources_end: end_counts,
        frame_ms_p50: percentile(&times, 50.0).unwrap_or(0.0),
        frame_ms_p99: percentile(&times, 99.0).unwrap_or(0.0),
        frame_ms_max: times.iter().copied().fold(0.0, f64::max),
        antialias_extra_rays: extra_rays,
        paging: paging.as_ref().map(|p| SoakPaging {
            pool_bytes: p.pool_bytes,
            last: p.json(),
            frames_with_missing: missing_frames,
        }),
    };
    Ok((RunInfo::new(&gpu, scene_path, size, frames), details))
}

impl SoakBench {
    /// No rows: memory and frame times as the summary, the window and wgpu's objects as notes.
    pub fn table(&self) -> Table {
        let mib = |k: Option<&u64>| k.copied().unwrap_or(0) as f64 / 1024.0;
        let summary = Figures::default()
            .with("rss_first_mib", mib(self.rss_kib.first()))
            .with("rss_last_mib", mib(self.rss_kib.last()))
            .with("rss_slope_kib_per_frame", self.rss_slope_kib_per_frame)
            .with("frame_ms_p50", self.frame_ms_p50)
            .with("frame_ms_p99", self.frame_ms_p99)
            .with("frame_ms_max", self.frame_ms_max);
        let changed: Vec<String> = (self.resources_start.iter().zip(&self.resources_end))
            .filter(|(a, b)| a.1 != b.1)
            .map(|(a, b)| format!("{} {} -> {}", a.0, a.1, b.1))
            .collect();
        let total: usize = self.resources_end.iter().map(|(_, n)| n).sum();
        let [w0, w1] = self.window;
        let mut notes = vec![
            format!("RSS slope fitted over frames {w0}..{w1}"),
            format!(
                "wgpu objects at frames {w0} and {w1}: {}",
                if changed.is_empty() {
                    format!("unchanged ({total} live)")
                } else {
                    changed.join(", ")
                }
            ),
        ];
        if self.antialias_extra_rays > 0 {
            notes.push(format!(
                "anti-aliased: {} sub-pixel rays over the run",
                self.antialias_extra_rays
            ));
        }
        if let Some(p) = &self.paging {
            notes.push(format!(
                "paged terrain, pool {} MiB: {} frame(s) rendered with a wanted tile missing; last frame {}",
                p.pool_bytes >> 20,
                p.frames_with_missing,
                p.last
            ));
        }
        Table {
            rows: Vec::new(),
            summary,
            notes,
        }
    }
}
