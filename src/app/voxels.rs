//! `relief voxels convert|info` and `relief bench --voxels`.

use crate::gpu::{Gpu, RenderSettings, Stage, TerrainRenderer};
use crate::scene::Scene;
use crate::voxel::{desc::load_frames, segment, VoxelInstance};
use crate::{Error, Result};
use std::path::Path;

/// Sizes of a model in the formats compared.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SizeReport {
    pub voxels: usize,
    pub dims: [u32; 3],
    /// Dense grid, 1 byte (palette index) per voxel.
    pub dense_bytes: u64,
    /// Dense grid, 4 bytes (RGBA) per voxel.
    pub dense_rgba_bytes: u64,
    pub source_bytes: u64,
    pub segment_bytes: u64,
}

/// Converts `input` (.vox or .rvs; frame 0) to a segment file `output` and reports sizes.
pub fn convert(input: &Path, output: &Path) -> Result<SizeReport> {
    if output.extension().and_then(|e| e.to_str()) != Some("rvs") {
        return Err(Error::invalid(
            "output",
            format!(
                "{}: the segment format's extension is .rvs",
                output.display()
            ),
        ));
    }
    let m = load_frames(input)?.remove(0);
    let source_bytes = std::fs::metadata(input)
        .map_err(|e| Error::io(input, e))?
        .len();
    let segment_bytes = segment::write(&m, output)?;
    Ok(SizeReport {
        voxels: m.voxels.len(),
        dims: m.dims,
        dense_bytes: m.dense_bytes(),
        dense_rgba_bytes: m.dense_bytes() * 4,
        source_bytes,
        segment_bytes,
    })
}

pub fn print_sizes(input: &Path, r: &SizeReport) {
    let [x, y, z] = r.dims;
    println!("{}: {x}x{y}x{z}, {} voxels", input.display(), r.voxels);
    println!(
        "segment {} B; dense 1 B/voxel {} B ({:.1}x), dense RGBA {} B ({:.1}x); source file {} B ({:.2}x)",
        r.segment_bytes,
        r.dense_bytes,
        r.dense_bytes as f64 / r.segment_bytes as f64,
        r.dense_rgba_bytes,
        r.dense_rgba_bytes as f64 / r.segment_bytes as f64,
        r.source_bytes,
        r.source_bytes as f64 / r.segment_bytes as f64
    );
}

/// Voxel counts of the simplified-voxel paper's two models (seed 000: 355 fps and 63 fps).
pub const PAPER_SMALL: usize = 49_152;
pub const PAPER_LARGE: usize = 1_548_288;

/// Timings of one set of placed models.
#[derive(Clone, Debug, serde::Serialize)]
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

/// `relief bench --voxels`: terrain only, each `[[voxels]]` model alone filling the view, and
/// the paper's two model sizes at one voxel per pixel.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VoxelBench {
    pub adapter: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub terrain_only_ms: f64,
    pub fill: Vec<VoxelRun>,
    pub paper: Vec<VoxelRun>,
}

/// Models of the paper's sizes at one voxel per pixel, `distance` metres ahead of `cam` in a
/// row across the view: the smallest scene model upsampled to at least [`PAPER_SMALL`] voxels;
/// and copies of the largest (then the upsampled small one) until at least [`PAPER_LARGE`].
fn paper_sets(
    models: &[VoxelInstance],
    cam: &crate::scene::Camera,
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

pub fn bench(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<VoxelBench> {
    let mut scene = Scene::load(scene_path)?;
    scene.desc.output.width = size.0;
    scene.desc.output.height = size.1;
    scene.desc.validate()?;
    let terrain = scene.load_terrain()?;
    let models = scene.voxel_models(&terrain)?;
    if models.is_empty() {
        return Err(Error::invalid(
            "voxels",
            format!(
                "{} places no [[voxels]] model to measure",
                scene_path.display()
            ),
        ));
    }
    let gpu = Gpu::new()?;
    let mut r = TerrainRenderer::new(&gpu, &terrain)?;
    let cam = scene.camera(0, &terrain);
    let s = RenderSettings::from_scene(&scene.desc);
    let frames = frames.max(1);
    let mut run = |name: String, m: &[VoxelInstance]| -> Result<VoxelRun> {
        r.set_voxels(&gpu, m)?;
        let out = r.capture(&gpu, &terrain, &scene.desc, &cam, &s)?;
        let hits: Vec<usize> = (0..out.flags.len())
            .filter(|&k| out.flags[k] & 32 != 0)
            .collect();
        let steps: u64 = hits.iter().map(|&k| out.steps[k] as u64).sum();
        let (mut cast, mut shadow) = (Vec::new(), Vec::new());
        for _ in 0..frames {
            let t = r.capture(&gpu, &terrain, &scene.desc, &cam, &s)?.times;
            cast.push(t.voxels_ms);
            shadow.push(t.voxel_shadow_ms);
        }
        let frame_ms = super::bench::median_frame_ms(
            &mut r,
            &gpu,
            &terrain,
            &scene.desc,
            &cam,
            &s,
            Stage::Shade,
            frames,
        )?;
        Ok(VoxelRun {
            name,
            instances: m.len(),
            voxels: m.iter().map(|i| i.frames[0].voxels.len()).sum(),
            voxel_pixels: hits.len(),
            mean_steps: steps as f64 / hits.len().max(1) as f64,
            cast_ms: super::bench::median(cast),
            shadow_ms: super::bench::median(shadow),
            frame_ms,
        })
    };
    let terrain_only_ms = run("terrain only".into(), &[])?.frame_ms;
    let mut fill = Vec::new();
    for m in &models {
        // Each model alone, scaled to the first model's height so it fills the same view.
        let mut m = m.clone();
        let h0 = models[0].dims()[2] as f64 * models[0].voxel_size;
        m.voxel_size = h0 / m.dims()[2] as f64;
        m.position = models[0].position;
        fill.push(run(m.name.clone(), std::slice::from_ref(&m))?);
    }
    let mut paper = Vec::new();
    for (name, set) in paper_sets(&models, &cam, 60.0)? {
        paper.push(run(name, &set)?);
    }
    Ok(VoxelBench {
        adapter: gpu.describe(),
        width: size.0,
        height: size.1,
        frames,
        terrain_only_ms,
        fill,
        paper,
    })
}

pub fn print_bench(b: &VoxelBench) {
    println!(
        "relief bench --voxels: {}x{}, {} frames, {}",
        b.width, b.height, b.frames, b.adapter
    );
    println!(
        "terrain only: frame {:.1} ms ({:.2} fps)",
        b.terrain_only_ms,
        1e3 / b.terrain_only_ms
    );
    let line = |r: &VoxelRun| {
        println!(
            "  {}: {} instance(s), {} voxels, {} voxel pixels, {:.1} DDA steps/pixel: voxel cast {:.2} ms ({:.0} fps), voxel shadows {:.2} ms; frame {:.1} ms ({:.2} fps, {:.2}x terrain only)",
            r.name,
            r.instances,
            r.voxels,
            r.voxel_pixels,
            r.mean_steps,
            r.cast_ms,
            1e3 / r.cast_ms,
            r.shadow_ms,
            r.frame_ms,
            1e3 / r.frame_ms,
            r.frame_ms / b.terrain_only_ms
        )
    };
    println!("each model alone, scaled to fill the view:");
    b.fill.iter().for_each(line);
    println!("the simplified-voxel paper's sizes (seed 000: {PAPER_SMALL} voxels at 355 fps, {PAPER_LARGE} at 63 fps), one voxel per pixel 60 m ahead:");
    b.paper.iter().for_each(line);
}
