//! `relief bench`: primary-ray throughput of the pyramid traversal (with and without the tile
//! pre-pass) against a fixed-step march (½ cell + 10 bisections) on the same rays, same run,
//! same adapter, plus the full frame with shadows. Depth error of each method is measured
//! against the f64 CPU traversal on a grid of sample pixels.

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
    /// Mean wall-clock milliseconds to find every primary hit (ray table, tile pre-pass,
    /// cast), submit to GPU idle, no readback.
    pub primary_ms: f64,
    /// Primary rays per second (pixels / `primary_ms`).
    pub rays_per_second: f64,
    /// Mean wall-clock milliseconds for the whole frame (all passes, shading included).
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

/// The whole benchmark report (`relief bench --json`).
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub adapter: String,
    pub backend: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
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

fn depth_error(out: &FrameOutput, reference: &[(u32, u32, Option<f64>)]) -> DepthError {
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

/// Wall-clock milliseconds per frame up to `stage` (submit to GPU idle, no readback), after
/// one untimed frame: `frames` frames in pairs, each pair submitted back to back as a frame
/// loop does (the CPU side of one frame overlaps the other's rendering), the median over the
/// pairs. The median, not the mean: on a shared machine slow spells come and go, and one of
/// them should not decide a figure.
#[allow(clippy::too_many_arguments)]
pub(crate) fn median_frame_ms(
    r: &mut TerrainRenderer,
    gpu: &Gpu,
    terrain: &Terrain,
    desc: &crate::scene::SceneDesc,
    cam: &Camera,
    s: &RenderSettings,
    stage: Stage,
    frames: u32,
) -> Result<f64> {
    r.render(gpu, terrain, desc, cam, s, stage)?;
    gpu.wait()?;
    let mut times = Vec::new();
    for _ in 0..(frames / 2).max(1) {
        let start = Instant::now();
        for _ in 0..2 {
            r.render(gpu, terrain, desc, cam, s, stage)?;
        }
        gpu.wait()?;
        times.push(start.elapsed().as_secs_f64() * 1e3 / 2.0);
    }
    Ok(median(times))
}

/// The scene at `size` (validated again) and its terrain.
pub(crate) fn load_at_size(scene_path: &Path, size: (u32, u32)) -> Result<(Scene, Terrain)> {
    let mut scene = Scene::load(scene_path)?;
    scene.desc.output.width = size.0;
    scene.desc.output.height = size.1;
    scene.desc.validate()?;
    let terrain = scene.load_terrain()?;
    Ok((scene, terrain))
}

/// Runs the benchmark on `scene_path` at `size` with `frames` timed frames per configuration.
pub fn run(
    scene_path: &Path,
    size: (u32, u32),
    frames: u32,
    dump: Option<&Path>,
) -> Result<BenchReport> {
    let (scene, terrain) = load_at_size(scene_path, size)?;
    let t = Instant::now();
    let _ = crate::terrain::MaxPyramid::build(&terrain.field);
    let pyramid_build_ms = t.elapsed().as_secs_f64() * 1e3;
    let gpu = Gpu::new()?;
    let mut renderer = TerrainRenderer::new(&gpu, &terrain)?;
    let cam = scene.camera(0, &terrain);
    let (w, h) = size;

    // CPU reference on a grid of sample pixels (every 8th pixel in each direction).
    let samples: Vec<(u32, u32)> = (0..h)
        .step_by(8)
        .flat_map(|y| (0..w).step_by(8).map(move |x| (x + 3, y + 5)))
        .filter(|&(x, y)| x < w && y < h)
        .collect();
    let reference: Vec<(u32, u32, Option<f64>)> = samples
        .par_iter()
        .map(|&(x, y)| {
            (
                x,
                y,
                cpu::cast_ray(
                    &terrain,
                    cam.pose.position,
                    cam.pixel_ray(x, y),
                    0.0,
                    f64::INFINITY,
                )
                .map(|hit| hit.t),
            )
        })
        .collect();

    let base = product_settings(&scene);
    let march = TraceMode::March {
        step_cells: 0.5,
        bisections: 10,
    };
    let configs = [
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
    ];
    let mut results = Vec::new();
    for (name, s) in configs {
        // Warm-up: shader compilation on first use, target allocation.
        let out = renderer.capture(&gpu, &terrain, &scene.desc, &cam, &s)?;
        let mut time = |stage: Stage| -> Result<f64> {
            median_frame_ms(
                &mut renderer,
                &gpu,
                &terrain,
                &scene.desc,
                &cam,
                &s,
                stage,
                frames,
            )
        };
        let primary_ms = time(Stage::Cast)?;
        let frame_ms = time(Stage::Shade)?;
        let px = (w * h) as f64;
        let r = ConfigResult {
            name: name.to_string(),
            primary_ms,
            rays_per_second: px / (primary_ms * 1e-3),
            frame_ms,
            mean_steps_per_ray: out.steps.iter().map(|&v| v as f64).sum::<f64>() / px,
            mean_patch_tests_per_ray: out.patch_tests.iter().map(|&v| v as f64).sum::<f64>() / px,
            depth_error: depth_error(&out, &reference),
        };
        log::info!(
            "{name}: primary {:.2} ms ({:.2} M rays/s), frame {:.2} ms, {:.1} steps/ray",
            r.primary_ms,
            r.rays_per_second / 1e6,
            r.frame_ms,
            r.mean_steps_per_ray
        );
        if let (Some(dir), "pyramid+tiles") = (dump, name) {
            dump_rays(dir, &terrain, &cam, &out)?;
        }
        results.push(r);
    }
    let get = |n: &str| {
        results
            .iter()
            .find(|r| r.name == n)
            .expect("configuration measured")
    };
    let (pt, p, m) = (get("pyramid+tiles"), get("pyramid"), get("march"));
    Ok(BenchReport {
        adapter: gpu.info.name.clone(),
        backend: format!("{:?}", gpu.info.backend),
        scene: scene_path.display().to_string(),
        width: w,
        height: h,
        frames,
        speedup_vs_march: pt.rays_per_second / m.rays_per_second,
        step_ratio_vs_march: m.mean_steps_per_ray / pt.mean_steps_per_ray.max(1e-9),
        tile_prepass_speedup: pt.rays_per_second / p.rays_per_second,
        pyramid_build_ms,
        configs: results,
    })
}

/// The product configuration the primary rays are timed in: pyramid traversal with the tile
/// pre-pass, no shadows (`pyramid+tiles`).
fn product_settings(scene: &Scene) -> RenderSettings {
    RenderSettings {
        mode: TraceMode::Pyramid,
        shadows: false,
        tile_prepass: true,
        max_steps: scene.desc.render.max_steps,
    }
}

/// Primary-ray timing of the product configuration alone (pyramid + tile pre-pass): what
/// `relief bench --primary-only` prints, for scripts that alternate relief with another
/// renderer (`benches/embree_compare.py`) so that this machine's slow spells fall on both.
#[derive(Clone, Debug, Serialize)]
pub struct PrimaryTiming {
    pub adapter: String,
    pub backend: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// Median milliseconds of ray table + tile pre-pass + cast (frame pairs, as `run`).
    pub primary_ms: f64,
    pub rays_per_second: f64,
}

/// Times the primary rays of `scene_path` at `size` (`frames` timed frames), nothing else.
pub fn run_primary(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<PrimaryTiming> {
    let (scene, terrain) = load_at_size(scene_path, size)?;
    let gpu = Gpu::new()?;
    let mut renderer = TerrainRenderer::new(&gpu, &terrain)?;
    let cam = scene.camera(0, &terrain);
    let s = product_settings(&scene);
    // Warm-up: shader compilation on first use, target allocation.
    renderer.capture(&gpu, &terrain, &scene.desc, &cam, &s)?;
    let primary_ms = median_frame_ms(
        &mut renderer,
        &gpu,
        &terrain,
        &scene.desc,
        &cam,
        &s,
        Stage::Cast,
        frames,
    )?;
    Ok(PrimaryTiming {
        adapter: gpu.info.name.clone(),
        backend: format!("{:?}", gpu.info.backend),
        scene: scene_path.display().to_string(),
        width: size.0,
        height: size.1,
        frames,
        primary_ms,
        rays_per_second: (size.0 * size.1) as f64 / (primary_ms * 1e-3),
    })
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

/// Prints the report as a table.
pub fn print_table(r: &BenchReport) {
    println!(
        "relief bench: {} at {}x{}, {} frames per configuration",
        r.scene, r.width, r.height, r.frames
    );
    println!("adapter: {} ({})", r.adapter, r.backend);
    println!(
        "{:<24} {:>11} {:>10} {:>10} {:>10} {:>10} {:>11} {:>10} {:>7}",
        "configuration",
        "primary ms",
        "M rays/s",
        "frame ms",
        "steps/ray",
        "patch/ray",
        "median err",
        "p99 err",
        "class≠"
    );
    for c in &r.configs {
        println!(
            "{:<24} {:>11.2} {:>10.2} {:>10.2} {:>10.1} {:>10.2} {:>11.2e} {:>10.2e} {:>7}",
            c.name,
            c.primary_ms,
            c.rays_per_second / 1e6,
            c.frame_ms,
            c.mean_steps_per_ray,
            c.mean_patch_tests_per_ray,
            c.depth_error.median_rel,
            c.depth_error.p99_rel,
            c.depth_error.class_mismatches
        );
    }
    println!(
        "pyramid+tiles vs march: {:.1}x rays/s, {:.1}x fewer steps per ray; tile pre-pass alone: {:.2}x; pyramid build {:.1} ms",
        r.speedup_vs_march, r.step_ratio_vs_march, r.tile_prepass_speedup, r.pyramid_build_ms
    );
}

/// `relief bench --freeforms`: the cost of free forms on the frame, same run, same adapter.
#[derive(Clone, Debug, Serialize)]
pub struct FreeFormReport {
    pub adapter: String,
    pub backend: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// Quadrics (base + perturbations) in the scene's free forms.
    pub quadrics: usize,
    pub objects: usize,
    /// Median full-frame milliseconds (shadows on) without and with the scene's free forms,
    /// `frames` frames of each, timed one by one and interleaved.
    pub terrain_only_ms: f64,
    pub with_free_forms_ms: f64,
    /// `with_free_forms_ms / terrain_only_ms` (target ≤ 1.5).
    pub ratio: f64,
    /// Generated free forms all in the view, 150 m to 4 km away: (count, median frame ms).
    pub scaling: Vec<(usize, f64)>,
    /// Frame ms with the most generated objects over the fewest, all in view.
    pub scaling_ratio: f64,
    /// Generated free forms spread uniformly over the whole terrain, as a database of objects
    /// is, most of them out of the view: (count, median frame ms).
    pub spread: Vec<(usize, f64)>,
    /// Frame ms with the most spread objects over the fewest (the target: ≤ 3).
    pub spread_ratio: f64,
}

/// Where [`scattered_free_forms`] puts its objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scatter {
    /// In front of the camera, within the horizontal field of view, 150 m to 4 km away.
    InView,
    /// Uniformly over the whole terrain.
    OverTerrain,
}

/// `n` perturbed free forms (domed tanks, dented balls, bumpy ellipsoids) on the terrain,
/// placed as `scatter` says, deterministic.
pub fn scattered_free_forms(
    terrain: &Terrain,
    cam: &Camera,
    n: usize,
    scatter: Scatter,
) -> Result<Vec<crate::freeform::FreeForm>> {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut rnd = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut text = String::new();
    let half = 0.5 * cam.pose.fov.to_radians();
    let (gw, gh) = (
        terrain.field.width as f64 - 1.0,
        terrain.field.height as f64 - 1.0,
    );
    for i in 0..n {
        let (x, y) = match scatter {
            Scatter::InView => {
                let dist = 150.0 + 3850.0 * rnd().powi(2);
                let ang = cam.pose.heading.to_radians() + half * (2.0 * rnd() - 1.0);
                (
                    cam.pose.position.x + dist * ang.sin(),
                    cam.pose.position.y + dist * ang.cos(),
                )
            }
            Scatter::OverTerrain => {
                let p = terrain
                    .frame
                    .grid_to_world(glam::DVec3::new(gw * rnd(), gh * rnd(), 0.0));
                (p.x, p.y)
            }
        };
        let s = 5.0 + 15.0 * rnd();
        let shape = match i % 3 {
            0 => format!(
                "shape = \"cylinder\"\nradius = {s}\nheight = {h}\nbounds = [[-{s}, -{s}, 0.0], [{s}, {s}, {h}]]\n[[objects.perturb]]\ncoefficients = [0, 0, 0, 0, 0, 0, 0, 0, {a}, {b}]\n",
                h = 2.0 * s,
                a = 1.0 / (0.4 * s),
                b = -(1.6 * s) / (0.4 * s)
            ),
            1 => format!(
                "shape = \"sphere\"\nradius = {s}\n[[objects.perturb]]\nshape = \"sphere\"\nradius = {r}\ncentre = [{s}, 0.0, {s2}]\nweight = 3.0\n",
                r = 0.6 * s,
                s2 = 0.3 * s
            ),
            _ => format!(
                "shape = \"ellipsoid\"\nradii = [{s}, {s2}, {s3}]\nheading = {h}\n[[objects.perturb]]\nshape = \"sphere\"\nradius = {r}\ncentre = [{c}, 0.0, {s3}]\nweight = -1.0\n",
                s2 = 0.6 * s,
                s3 = 0.5 * s,
                h = 360.0 * rnd(),
                r = 0.4 * s,
                c = 0.5 * s
            ),
        };
        text.push_str(&format!(
            "[[objects]]\nname = \"generated {i}\"\nposition = [{x}, {y}, 0.0]\nabove_terrain = 0.0\n{shape}\n"
        ));
    }
    let desc: crate::scene::SceneDesc = toml::from_str(&format!(
        "[terrain.procedural]\nsize = 2\n[camera]\nposition = [0.0, 0.0, 0.0]\n{text}"
    ))
    .map_err(|e| Error::invalid("generated objects", e.to_string()))?;
    desc.objects
        .iter()
        .enumerate()
        .filter_map(|(i, o)| {
            // Objects that would stand outside the terrain are skipped.
            match o.build(i, |p| {
                crate::cpu::query::terrain_point_below(terrain, p).map(|g| g.z)
            }) {
                Err(Error::Invalid { msg, .. }) if msg.contains("outside the terrain") => None,
                r => Some(r),
            }
        })
        .collect()
}

/// Runs the free-form benchmark on `scene_path` (its `[[objects]]`), then with 10, 100 and
/// 1000 generated objects.
pub fn run_freeforms(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<FreeFormReport> {
    let (scene, terrain) = load_at_size(scene_path, size)?;
    let objects = scene.free_forms(&terrain)?;
    let gpu = Gpu::new()?;
    let mut renderer = TerrainRenderer::new(&gpu, &terrain)?;
    let cam = scene.camera(0, &terrain);
    let s = RenderSettings::from_scene(&scene.desc);
    // The headline ratio: terrain only and with the scene's objects, one frame of each in
    // turn (each timed alone, submit to idle), the median of each. Interleaving keeps slow
    // spells of a shared machine from landing on one configuration only.
    let (terrain_only_ms, with_free_forms_ms) = {
        let mut with = TerrainRenderer::new(&gpu, &terrain)?;
        with.set_objects(&gpu, &objects)?;
        for r in [&mut renderer, &mut with] {
            // Warm-up: shader compilation on first use, target allocation.
            r.capture(&gpu, &terrain, &scene.desc, &cam, &s)?;
        }
        let mut times = [Vec::new(), Vec::new()];
        for round in 0..frames.max(1) as usize {
            for k in [round % 2, 1 - round % 2] {
                let r = if k == 0 { &mut renderer } else { &mut with };
                let start = Instant::now();
                r.render(&gpu, &terrain, &scene.desc, &cam, &s, Stage::Shade)?;
                gpu.wait()?;
                times[k].push(start.elapsed().as_secs_f64() * 1e3);
            }
        }
        let [a, b] = times.map(median);
        (a, b)
    };
    let mut frame_ms = |objects: &[crate::freeform::FreeForm]| -> Result<f64> {
        renderer.set_objects(&gpu, objects)?;
        // Warm-up: shader compilation on first use, target allocation.
        renderer.capture(&gpu, &terrain, &scene.desc, &cam, &s)?;
        median_frame_ms(
            &mut renderer,
            &gpu,
            &terrain,
            &scene.desc,
            &cam,
            &s,
            Stage::Shade,
            frames,
        )
    };
    let mut scaling = Vec::new();
    let mut spread = Vec::new();
    for (scatter, out) in [
        (Scatter::InView, &mut scaling),
        (Scatter::OverTerrain, &mut spread),
    ] {
        for n in [10, 100, 1000] {
            let generated = scattered_free_forms(&terrain, &cam, n, scatter)?;
            let ms = frame_ms(&generated)?;
            log::info!(
                "{} generated free forms ({scatter:?}): {ms:.1} ms",
                generated.len()
            );
            out.push((generated.len(), ms));
        }
    }
    Ok(FreeFormReport {
        adapter: gpu.info.name.clone(),
        backend: format!("{:?}", gpu.info.backend),
        scene: scene_path.display().to_string(),
        width: size.0,
        height: size.1,
        frames,
        quadrics: objects.iter().map(|o| o.nodes.len()).sum(),
        objects: objects.len(),
        terrain_only_ms,
        with_free_forms_ms,
        ratio: with_free_forms_ms / terrain_only_ms,
        scaling_ratio: scaling.last().map_or(0.0, |l| l.1) / scaling[0].1,
        scaling,
        spread_ratio: spread.last().map_or(0.0, |l| l.1) / spread[0].1,
        spread,
    })
}

/// Prints the free-form report.
pub fn print_freeforms(r: &FreeFormReport) {
    println!(
        "relief bench --freeforms: {} at {}x{}, {} frames per configuration",
        r.scene, r.width, r.height, r.frames
    );
    println!("adapter: {} ({})", r.adapter, r.backend);
    println!(
        "terrain only {:.1} ms, with {} free forms ({} quadrics) {:.1} ms (medians, interleaved): {:.2}x",
        r.terrain_only_ms, r.objects, r.quadrics, r.with_free_forms_ms, r.ratio
    );
    for (label, series, ratio) in [
        ("in the view (150 m - 4 km)", &r.scaling, r.scaling_ratio),
        ("spread over the terrain", &r.spread, r.spread_ratio),
    ] {
        for (n, ms) in series {
            println!("{n:>5} generated free forms {label}: {ms:.1} ms");
        }
        println!(
            "scaling {} -> {} objects {label}: {ratio:.2}x frame time",
            series[0].0,
            series.last().map_or(0, |l| l.0),
        );
    }
}

/// Median of a non-empty sample (mean of the middle two for an even count).
pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}
