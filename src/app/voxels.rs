//! `relief voxels convert|info` and `relief bench --voxels`.

use crate::gpu::{Gpu, RenderSettings, Stage, TerrainRenderer};
use crate::scene::Scene;
use crate::voxel::{desc::load_frames, segment};
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

/// Frame times of a voxel scene: terrain only, then each `[[voxels]]` model alone.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VoxelBench {
    pub adapter: String,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub terrain_only_ms: f64,
    /// (name, voxels, frame ms, voxel pass ms, voxel pixels)
    pub models: Vec<(String, usize, f64, f64, usize)>,
}

pub fn bench(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<VoxelBench> {
    let mut scene = Scene::load(scene_path)?;
    scene.desc.output.width = size.0;
    scene.desc.output.height = size.1;
    scene.desc.validate()?;
    let terrain = scene.load_terrain()?;
    let models = scene.voxel_models(&terrain)?;
    let gpu = Gpu::new()?;
    let mut r = TerrainRenderer::new(&gpu, &terrain)?;
    let cam = scene.camera(0, &terrain);
    let s = RenderSettings::from_scene(&scene.desc);
    let mut run = |m: &[crate::voxel::VoxelInstance]| -> Result<(f64, f64, usize)> {
        r.set_voxels(&gpu, m)?;
        let out = r.capture(&gpu, &terrain, &scene.desc, &cam, &s)?;
        let px = out.flags.iter().filter(|f| *f & 32 != 0).count();
        let mut pass = 0.0;
        for _ in 0..frames.min(3) {
            pass += r
                .capture(&gpu, &terrain, &scene.desc, &cam, &s)?
                .times
                .voxels_ms;
        }
        Ok((
            super::bench::median_frame_ms(
                &mut r,
                &gpu,
                &terrain,
                &scene.desc,
                &cam,
                &s,
                Stage::Shade,
                frames,
            )?,
            pass / frames.min(3) as f64,
            px,
        ))
    };
    let terrain_only_ms = run(&[])?.0;
    let mut out = Vec::new();
    for m in &models {
        // Each model alone, scaled to the first model's height so it fills the same view.
        let mut m = m.clone();
        let h0 = models[0].dims()[2] as f64 * models[0].voxel_size;
        m.voxel_size = h0 / m.dims()[2] as f64;
        m.position = models[0].position;
        let n = m.frames[0].voxels.len();
        let (ms, pass, px) = run(std::slice::from_ref(&m))?;
        out.push((m.name.clone(), n, ms, pass, px));
    }
    Ok(VoxelBench {
        adapter: gpu.describe(),
        width: size.0,
        height: size.1,
        frames,
        terrain_only_ms,
        models: out,
    })
}

pub fn print_bench(b: &VoxelBench) {
    println!(
        "relief bench --voxels: {}x{}, {} frames, {}",
        b.width, b.height, b.frames, b.adapter
    );
    println!(
        "terrain only: {:.1} ms/frame ({:.2} fps)",
        b.terrain_only_ms,
        1e3 / b.terrain_only_ms
    );
    for (name, n, ms, pass, px) in &b.models {
        println!(
            "{name}: {n} voxels, {px} voxel pixels: frame {ms:.1} ms ({:.2} fps, {:.2}x terrain only); voxel cast pass {pass:.1} ms ({:.1} fps for the voxel cast alone)",
            1e3 / ms,
            ms / b.terrain_only_ms,
            1e3 / pass
        );
    }
}
