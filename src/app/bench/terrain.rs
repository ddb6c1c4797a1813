//! `relief bench terrain`: primary-ray throughput of the pyramid traversal (with and without
//! the tile pre-pass) against a fixed-step march (½ cell + 10 bisections) on the same rays,
//! same run, same adapter, plus the full frame with shadows. Depth error of each method is
//! measured against the f64 CPU traversal on a grid of sample pixels. `--dump-rays` writes the
//! rays and depths for outside comparisons (`benches/embree_compare.py`).

use super::table::{Figures, Row, RunInfo, Table};
use super::timing::{scene_at_size, FrameSetup};
use crate::cpu;
use crate::gpu::{FrameOutput, Gpu, RenderSettings, Stage, TerrainRenderer, TraceMode};
use crate::scene::{Camera, Scene};
use crate::terrain::Terrain;
use crate::{Error, Result};
use rayon::prelude::*;
use serde::Serialize;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// One measured configuration.
#[derive(Clone, Debug, Serialize)]
pub struct ConfigResult {
    /// Short name: `pyramid+tiles`, `pyramid`, `march`, `pyramid+tiles+shadows`.
    pub name: String,
    /// Median wall-clock milliseconds to find every primary hit (ray table, tile pre-pass,
    /// cast), submit to GPU idle, no readback.
    pub primary_ms: f64,
    /// Primary rays per second (pixels / `primary_ms`).
    pub rays_per_second: f64,
    /// Median wall-clock milliseconds for the whole frame (all passes, shading included).
    pub frame_ms: f64,
    /// Mean traversal steps (cells visited, or march samples) per primary ray.
    pub mean_steps_per_ray: f64,
    /// Mean exact patch tests per primary ray.
    pub mean_patch_tests_per_ray: f64,
    /// Depth error against the f64 CPU traversal over the sample pixels.
    pub depth_error: DepthError,
}

/// Depth agreement with the CPU reference.
#[derive(Clone, Debug, Default, Serialize)]
pub struct DepthError {
    /// Sample pixels compared.
    pub pixels: usize,
    /// Pixels where GPU and CPU disagree on hit vs sky.
    pub class_mismatches: usize,
    /// Relative depth error |gpu - cpu| / cpu over pixels both hit: median, 99th percentile, max.
    pub median_rel: f64,
    pub p99_rel: f64,
    pub max_rel: f64,
    /// Pixels with relative error above 1e-3.
    pub over_1e3: usize,
}

/// What `relief bench terrain` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct TerrainBench {
    pub configs: Vec<ConfigResult>,
    /// rays/s of `pyramid+tiles` over rays/s of `march`.
    pub speedup_vs_march: f64,
    /// mean steps per ray of `march` over `pyramid+tiles`.
    pub step_ratio_vs_march: f64,
    /// rays/s of `pyramid+tiles` over `pyramid` (what the tile pre-pass buys).
    pub tile_prepass_speedup: f64,
    /// Milliseconds to build the maximum pyramid on the CPU.
    pub pyramid_build_ms: f64,
}

/// A pixel of the CPU reference: (x, y, ray distance to the terrain or `None` for sky).
type Reference = (u32, u32, Option<f64>);

fn depth_error(out: &FrameOutput, reference: &[Reference]) -> DepthError {
    let mut rel = Vec::new();
    let mut mism = 0;
    for &(x, y, cpu_t) in reference {
        let g = out.depth[(y * out.width + x) as usize];
        match (cpu_t, g.is_finite()) {
            (Some(c), true) => rel.push(((g as f64 - c).abs() / c.max(1e-9)).min(1e9)),
            (None, false) => {}
            _ => mism += 1,
        }
    }
    rel.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| {
        rel.get(((rel.len() as f64 - 1.0) * f).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    DepthError {
        pixels: reference.len(),
        class_mismatches: mism,
        median_rel: q(0.5),
        p99_rel: q(0.99),
        max_rel: rel.last().copied().unwrap_or(0.0),
        over_1e3: rel.iter().filter(|r| **r > 1e-3).count(),
    }
}

/// The CPU reference on a grid of sample pixels (every 8th pixel in each direction).
fn cpu_reference(terrain: &Terrain, cam: &Camera, (w, h): (u32, u32)) -> Vec<Reference> {
    let samples: Vec<(u32, u32)> = (0..h)
        .step_by(8)
        .flat_map(|y| (0..w).step_by(8).map(move |x| (x + 3, y + 5)))
        .filter(|&(x, y)| x < w && y < h)
        .collect();
    samples
        .par_iter()
        .map(|&(x, y)| {
            (
                x,
                y,
                cpu::cast_ray(
                    terrain,
                    cam.pose.position,
                    cam.pixel_ray(x, y),
                    0.0,
                    f64::INFINITY,
                )
                .map(|hit| hit.t),
            )
        })
        .collect()
}

/// The product configuration the primary rays are timed in: pyramid traversal with the tile
/// pre-pass, no shadows (`pyramid+tiles`).
pub fn product_settings(scene: &Scene) -> RenderSettings {
    RenderSettings {
        mode: TraceMode::Pyramid,
        shadows: false,
        tile_prepass: true,
        max_steps: scene.desc.render.max_steps,
        lod: scene.desc.render.lod.scale(),
        antialias: crate::gpu::Antialias::OFF,
    }
}

/// The configurations measured, by name.
fn configurations(scene: &Scene) -> [(&'static str, RenderSettings); 4] {
    let base = product_settings(scene);
    let march = TraceMode::March {
        step_cells: 0.5,
        bisections: 10,
    };
    [
        ("pyramid+tiles", base),
        (
            "pyramid",
            RenderSettings {
                tile_prepass: false,
                ..base
            },
        ),
        (
            "march",
            RenderSettings {
                mode: march,
                tile_prepass: false,
                max_steps: 1 << 20,
                ..base
            },
        ),
        (
            "pyramid+tiles+shadows",
            RenderSettings {
                shadows: true,
                ..base
            },
        ),
    ]
}

/// Everything the configurations are measured on.
struct Bench<'a> {
    gpu: &'a Gpu,
    terrain: &'a Terrain,
    scene: &'a Scene,
    cam: &'a Camera,
    frames: u32,
    reference: &'a [Reference],
}

impl Bench<'_> {
    /// Measures configuration `name` with settings `s`; also returns its warm-up frame.
    fn measure(
        &self,
        renderer: &mut TerrainRenderer,
        name: &str,
        s: &RenderSettings,
    ) -> Result<(ConfigResult, FrameOutput)> {
        let frame = FrameSetup {
            gpu: self.gpu,
            terrain: self.terrain,
            desc: &self.scene.desc,
            cam: self.cam,
            settings: s,
            frames: self.frames,
        };
        let out = frame.capture(renderer)?;
        let primary_ms = frame.median_ms(renderer, Stage::Cast)?;
        let frame_ms = frame.median_ms(renderer, Stage::Shade)?;
        let px = (out.width * out.height) as f64;
        let r = ConfigResult {
            name: name.to_string(),
            primary_ms,
            rays_per_second: px / (primary_ms * 1e-3),
            frame_ms,
            mean_steps_per_ray: out.steps.iter().map(|&v| v as f64).sum::<f64>() / px,
            mean_patch_tests_per_ray: out.patch_tests.iter().map(|&v| v as f64).sum::<f64>() / px,
            depth_error: depth_error(&out, self.reference),
        };
        log::info!(
            "{name}: primary {:.2} ms ({:.2} M rays/s), frame {:.2} ms, {:.1} steps/ray",
            r.primary_ms,
            r.rays_per_second / 1e6,
            r.frame_ms,
            r.mean_steps_per_ray
        );
        Ok((r, out))
    }
}

/// Runs the benchmark on `scene_path` at `size` with `frames` timed frames per configuration;
/// `lod` overrides the scene's `[render] lod`; with `dump`, writes the `pyramid+tiles` rays and
/// depths there.
pub fn run(
    scene_path: &Path,
    size: (u32, u32),
    frames: u32,
    lod: Option<crate::scene::Lod>,
    dump: Option<&Path>,
) -> Result<(RunInfo, TerrainBench)> {
    let mut scene = scene_at_size(scene_path, size)?;
    if let Some(lod) = lod {
        scene.desc.render.lod = lod;
    }
    let terrain = scene.load_terrain()?;
    let t = Instant::now();
    let _ = crate::terrain::MaxPyramid::build(&terrain.field);
    let pyramid_build_ms = t.elapsed().as_secs_f64() * 1e3;
    let gpu = crate::app::gpu_options::open()?;
    let mut renderer = TerrainRenderer::new(&gpu, &terrain)?;
    let cam = scene.camera(0, &terrain);
    let reference = cpu_reference(&terrain, &cam, size);
    let bench = Bench {
        gpu: &gpu,
        terrain: &terrain,
        scene: &scene,
        cam: &cam,
        frames,
        reference: &reference,
    };
    let mut configs = Vec::new();
    for (name, s) in configurations(&scene) {
        let (r, out) = bench.measure(&mut renderer, name, &s)?;
        if let (Some(dir), "pyramid+tiles") = (dump, name) {
            dump_rays(dir, &terrain, &cam, &out)?;
        }
        configs.push(r);
    }
    let get = |n: &str| {
        configs
            .iter()
            .find(|r| r.name == n)
            .expect("configuration measured")
    };
    let (pt, p, m) = (get("pyramid+tiles"), get("pyramid"), get("march"));
    let details = TerrainBench {
        speedup_vs_march: pt.rays_per_second / m.rays_per_second,
        step_ratio_vs_march: m.mean_steps_per_ray / pt.mean_steps_per_ray.max(1e-9),
        tile_prepass_speedup: pt.rays_per_second / p.rays_per_second,
        pyramid_build_ms,
        configs,
    };
    Ok((RunInfo::new(&gpu, scene_path, size, frames), details))
}

impl TerrainBench {
    /// The configurations as rows, the ratios as the summary.
    pub fn table(&self) -> Table {
        let rows = (self.configs.iter())
            .map(|c| {
                let figures = Figures::default()
                    .with("primary_ms", c.primary_ms)
                    .with("rays_per_second", c.rays_per_second)
                    .with("frame_ms", c.frame_ms)
                    .with("steps_per_ray", c.mean_steps_per_ray)
                    .with("patch_tests_per_ray", c.mean_patch_tests_per_ray)
                    .with("depth_error_median", c.depth_error.median_rel)
                    .with("depth_error_p99", c.depth_error.p99_rel)
                    .with("class_mismatches", c.depth_error.class_mismatches as f64);
                Row::new(&c.name, figures)
            })
            .collect();
        let summary = Figures::default()
            .with("speedup_vs_march", self.speedup_vs_march)
            .with("step_ratio_vs_march", self.step_ratio_vs_march)
            .with("tile_prepass_speedup", self.tile_prepass_speedup)
            .with("pyramid_build_ms", self.pyramid_build_ms);
        Table {
            rows,
            summary,
            notes: vec![
                "depth error: relative, against the f64 CPU traversal on every 8th pixel".into(),
            ],
        }
    }
}

/// Writes, for outside comparisons (benches/embree_compare.py): `rays.f32` (per pixel: origin
/// xyz, direction xyz, row-major from the top-left), `depth.f32` (relief's ray distance, +inf
/// for sky), `heights.f32` (the height grid, row 0 south) and `grid.json` (its size and
/// world placement).
fn dump_rays(dir: &Path, terrain: &Terrain, cam: &Camera, out: &FrameOutput) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let o = cam.pose.position;
    let mut rays = Vec::with_capacity((out.width * out.height * 6) as usize);
    for y in 0..out.height {
        for x in 0..out.width {
            let d = cam.pixel_ray(x, y);
            rays.extend([
                o.x as f32, o.y as f32, o.z as f32, d.x as f32, d.y as f32, d.z as f32,
            ]);
        }
    }
    let write = |name: &str, data: &[f32]| -> Result<()> {
        let p = dir.join(name);
        let mut f =
            std::io::BufWriter::new(std::fs::File::create(&p).map_err(|e| Error::io(&p, e))?);
        f.write_all(bytemuck::cast_slice(data))
            .map_err(|e| Error::io(&p, e))
    };
    write("rays.f32", &rays)?;
    write("depth.f32", &out.depth)?;
    write("heights.f32", &terrain.field.heights)?;
    let grid = serde_json::json!({
        "width": terrain.field.width,
        "height": terrain.field.height,
        "world_from_grid": terrain.frame.world_from_grid().transpose().to_cols_array_2d(),
        "image": [out.width, out.height],
    });
    let p = dir.join("grid.json");
    std::fs::write(&p, grid.to_string()).map_err(|e| Error::io(&p, e))
}
