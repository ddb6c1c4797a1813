//! The terrain's own passes: its data uploaded once (heights, square maximum pyramid and its
//! dilation, drape, the `Frame` and `RayGen` parameter blocks) and the pipelines of ray
//! generation (compute or fragment), the tile pre-pass, the cast (pyramid or march) and the
//! terrain-only shade pass.

use super::device::KernelPath;
use super::pyramid::{dilate_square_pyramid, square_pyramid, square_side};
use super::shade::{shade_pipelines, ShadePipelines};
use super::types::{FrameUniforms, RayGenUniforms, MAX_LEVELS};
use super::util::{
    check_buffer_limit, float_texture_entry, fullscreen_pipeline, pipeline_layout,
    pipeline_layout_with, render_pipeline_in, storage_entry, storage_texture_entry, target_state,
    uint_texture_entry, uniform_entry,
};
use super::{shaders, Gpu, PARAM_USAGE};
use crate::terrain::Terrain;
use crate::{Error, Result};
use wgpu::util::DeviceExt;

/// What to make smaller when the terrain does not fit the adapter.
const HEIGHT_MAP_FIX: &str = "use a smaller or cropped height map";

/// Most mip levels of a drape (`Frame.drape_size.z`): a 16384-texel side halves to one in 15.
pub const DRAPE_LEVELS: usize = 16;

/// The terrain on the GPU and the frame's parameter blocks.
pub(crate) struct TerrainData {
    pub heights: wgpu::Buffer,
    pub pyramid: wgpu::Buffer,
    pub dilated: wgpu::Buffer,
    /// Side of the square pyramid's level 0 ([`square_pyramid`]).
    pub pyramid_side: u32,
    pub drape: wgpu::Buffer,
    /// The terrain has a draped image (a shade-pipeline constant).
    pub has_drape: bool,
    /// The terrain's cells along x and y (a paged window moved keeps them).
    pub cells: [usize; 2],
    pub frame_ub: wgpu::Buffer,
    pub raygen_ub: wgpu::Buffer,
}

impl TerrainData {
    /// Checks the terrain against the shaders' and the adapter's limits and uploads it;
    /// `paged`: the heights and pyramid stay on the host (the tile pool replaces them; the
    /// bindings get 4-byte placeholders).
    pub fn upload(gpu: &Gpu, terrain: &Terrain, paged: bool) -> Result<TerrainData> {
        let dev = &gpu.device;
        if terrain.is_hollow() && !paged {
            return Err(Error::invalid(
                "terrain",
                "this database window was loaded without its samples for paged rendering: render it with --terrain-memory MB",
            ));
        }
        if terrain.pyramid.levels.len() > MAX_LEVELS {
            return Err(Error::Limit {
                what: "terrain size".into(),
                msg: format!(
                    "{}x{} samples need {} pyramid levels, the shaders address {MAX_LEVELS} (at most {} cells per side)",
                    terrain.field.width,
                    terrain.field.height,
                    terrain.pyramid.levels.len(),
                    1u32 << (MAX_LEVELS - 1)
                ),
            });
        }
        let storage = |label: &str, contents: &[u8]| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let (heights, pyramid, dilated, pyramid_side) = if paged {
            let none = || storage("paged placeholder", &[0u8; 4]);
            let side = square_side(terrain);
            (none(), none(), none(), side)
        } else {
            check_buffer_limit(
                gpu,
                "height table",
                terrain.field.heights.len() as u64 * 4,
                HEIGHT_MAP_FIX,
            )?;
            let (pyramid_data, side) = square_pyramid(terrain);
            check_buffer_limit(
                gpu,
                "maximum pyramid",
                pyramid_data.len() as u64 * 4,
                HEIGHT_MAP_FIX,
            )?;
            let heights = storage("heights", bytemuck::cast_slice(&terrain.field.heights));
            let pyramid = storage("max pyramid", bytemuck::cast_slice(&pyramid_data));
            let dilated_data = dilate_square_pyramid(&pyramid_data, side);
            let dilated = storage("dilated max pyramid", bytemuck::cast_slice(&dilated_data));
            (heights, pyramid, dilated, side)
        };
        // The drape and its mip levels, one after the other (level 0 first: frames without
        // anti-aliasing read only it; with it, footprint-filtered texturing reads the others).
        let drape_words: Vec<u32> = match &terrain.drape {
            Some((d, _)) => {
                check_buffer_limit(
                    gpu,
                    "drape image",
                    (d.rgba.len() as u64).saturating_mul(4) / 3 + 4,
                    "use a smaller drape image",
                )?;
                crate::terrain::drape_mips::mip_levels(d, DRAPE_LEVELS)
                    .iter()
                    .flat_map(|l| l.rgba.chunks_exact(4))
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            }
            None => vec![0],
        };
        let drape = storage("drape", bytemuck::cast_slice(&drape_words));
        let block = |label: &str, size: usize| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage: PARAM_USAGE,
                mapped_at_creation: false,
            })
        };
        Ok(TerrainData {
            heights,
            pyramid,
            dilated,
            pyramid_side,
            drape,
            has_drape: terrain.drape.is_some(),
            cells: terrain.cells(),
            frame_ub: block("frame uniforms", std::mem::size_of::<FrameUniforms>()),
            raygen_ub: block("raygen uniforms", std::mem::size_of::<RayGenUniforms>()),
        })
    }
}

/// Bind-group layouts of the terrain passes.
pub(crate) struct TerrainLayouts {
    pub raygen: wgpu::BindGroupLayout,
    pub tile: wgpu::BindGroupLayout,
    pub cast: wgpu::BindGroupLayout,
    pub shade: wgpu::BindGroupLayout,
}

impl TerrainLayouts {
    /// The layouts; ray generation writes a storage texture on the compute path.
    fn new(gpu: &Gpu, raygen_compute: bool) -> TerrainLayouts {
        let dev = &gpu.device;
        let cs = wgpu::ShaderStages::COMPUTE;
        let fs = wgpu::ShaderStages::FRAGMENT;
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        };
        let raygen = layout(
            "raygen",
            &if raygen_compute {
                vec![
                    uniform_entry(gpu.params, 0, cs),
                    storage_texture_entry(1, cs, wgpu::TextureFormat::Rgba32Uint),
                ]
            } else {
                vec![uniform_entry(gpu.params, 0, fs)]
            },
        );
        let uint_texture = |binding| uint_texture_entry(binding, fs);
        let common = [
            uniform_entry(gpu.params, 0, fs),
            storage_entry(1, fs, true),
            storage_entry(2, fs, true),
            uint_texture(3),
        ];
        let mut tile_entries = common.to_vec();
        tile_entries.push(storage_entry(4, fs, true));
        let tile = layout("tile", &tile_entries);
        let mut cast_entries = common.to_vec();
        cast_entries.push(uint_texture(4));
        let cast = layout("cast", &cast_entries);
        let mut shade_entries = cast_entries.clone();
        shade_entries.push(storage_entry(5, fs, true));
        shade_entries.push(float_texture_entry(19, fs, wgpu::TextureViewDimension::D2));
        let shade = layout("shade", &shade_entries);
        TerrainLayouts {
            raygen,
            tile,
            cast,
            shade,
        }
    }
}

/// The ray-generation pass in the form that suits the adapter.
pub(crate) enum RayGen {
    Compute(wgpu::ComputePipeline),
    Fragment(wgpu::RenderPipeline),
}

/// Terrain data on the GPU and the pipelines that render it.
pub(crate) struct TerrainPasses {
    pub data: TerrainData,
    pub bgl: TerrainLayouts,
    pub raygen: RayGen,
    pub tile: wgpu::RenderPipeline,
    pub cast: wgpu::RenderPipeline,
    /// The cast pass with footprint level of detail (`render.lod`), built on first use.
    pub cast_lod: Option<wgpu::RenderPipeline>,
    /// The cast pass flagging near misses within the pixel cone (anti-aliasing's centre
    /// rays), built on first use.
    pub cast_near: Option<wgpu::RenderPipeline>,
    /// The terrain's curved earth (the switch the cast pipelines are built with).
    pub curved: bool,
    /// The cast pipelines' layout (group 3 the tile pool when paged).
    cast_layout: wgpu::PipelineLayout,
    /// Paged: the tile pool's storage bindings (the cast variants read the terrain from it).
    pool_bindings: Option<u32>,
    pub march: wgpu::RenderPipeline,
    /// Terrain-only shade pipelines (with free forms, `ObjectPasses` has its own).
    pub shade: ShadePipelines,
    /// Kept for the distortion-table pipelines (`TableMode`).
    pub raygen_mod: wgpu::ShaderModule,
    tile_mod: wgpu::ShaderModule,
    /// The tile pre-pass's layout: group 0, and group 3 (the tile pool) when paged.
    tile_layout: wgpu::PipelineLayout,
}

fn tile_pipeline(
    dev: &wgpu::Device,
    m: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    label: &str,
    entry: &str,
) -> wgpu::RenderPipeline {
    let targets = [Some(target_state(wgpu::TextureFormat::Rg32Uint))];
    render_pipeline_in(
        dev,
        label,
        m,
        ["vs_fullscreen", entry],
        layout,
        &targets,
        None,
    )
}

impl TerrainPasses {
    /// Uploads the terrain (heights, pyramid, drape) and builds the pipelines, ray generation
    /// on the `kernels` path. `paged`: group 3's layout of the tile pool; the cast (and march)
    /// and shade pipelines read the terrain from it (`shaders::cast_paged`, `PAGED`) and the
    /// heights and pyramid are not uploaded.
    pub fn new(
        gpu: &Gpu,
        terrain: &Terrain,
        kernels: KernelPath,
        pool: Option<(&wgpu::BindGroupLayout, u32)>,
    ) -> Result<TerrainPasses> {
        let paged = pool.map(|(bgl, _)| bgl);
        let bindings = pool.map_or(1, |(_, n)| n);
        let data = TerrainData::upload(gpu, terrain, paged.is_some())?;
        let raygen_compute = kernels == KernelPath::Compute;
        let bgl = TerrainLayouts::new(gpu, raygen_compute);
        let dev = &gpu.device;
        let module = |label: &str, src: String| super::shader_module(dev, gpu.params, label, &src);
        let raygen_mod = module("raygen.wgsl", shaders::raygen());
        let tile_mod = match paged {
            Some(_) => module(
                "tile.wgsl (paged)",
                shaders::tile_paged(terrain.curved, bindings),
            ),
            None => module("tile.wgsl", shaders::tile(terrain.curved)),
        };
        let tile_layout = pipeline_layout_with(dev, &bgl.tile, paged);
        let cast_mod = match paged {
            Some(_) => module(
                "cast.wgsl (paged)",
                shaders::cast_paged(terrain.curved, bindings, false),
            ),
            None => module("cast.wgsl", shaders::cast(terrain.curved, false, false)),
        };
        let fullscreen = |label: &str,
                          m: &wgpu::ShaderModule,
                          entry: &str,
                          bgl: &wgpu::BindGroupLayout,
                          format| {
            fullscreen_pipeline(dev, label, m, entry, bgl, &[Some(target_state(format))])
        };
        let tile = tile_pipeline(dev, &tile_mod, &tile_layout, "tile", "fs_tile");
        let raygen = if raygen_compute {
            RayGen::Compute(
                dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("raygen"),
                    layout: Some(&pipeline_layout(dev, &bgl.raygen)),
                    module: &raygen_mod,
                    entry_point: Some("cs_raygen"),
                    compilation_options: Default::default(),
                    cache: None,
                }),
            )
        } else {
            RayGen::Fragment(fullscreen(
                "raygen",
                &raygen_mod,
                "fs_raygen",
                &bgl.raygen,
                wgpu::TextureFormat::Rgba32Uint,
            ))
        };
        let g = [Some(target_state(wgpu::TextureFormat::Rgba32Uint))];
        let cast_layout = pipeline_layout_with(dev, &bgl.cast, paged);
        let cast_pipeline = |label: &str, entry: &str| {
            let entries = ["vs_fullscreen", entry];
            render_pipeline_in(dev, label, &cast_mod, entries, &cast_layout, &g, None)
        };
        let cast = cast_pipeline("cast", "fs_cast");
        let march = cast_pipeline("march", "fs_cast_march");
        let mut shade = shade_pipelines(gpu.params, "shade", shaders::shade, bgl.shade.clone());
        if let Some(p) = paged {
            shade = shade.with_group3(p.clone());
        }
        Ok(TerrainPasses {
            data,
            bgl,
            raygen,
            tile,
            cast,
            cast_lod: None,
            cast_near: None,
            curved: terrain.curved,
            cast_layout,
            pool_bindings: pool.map(|(_, n)| n),
            march,
            shade,
            raygen_mod,
            tile_mod,
            tile_layout,
        })
    }

    /// A tile pre-pass pipeline of entry point `entry` (`fs_tile`, `fs_tile_table`), on the
    /// paged or in-memory terrain as the passes were built.
    pub fn tile_pipeline(&self, gpu: &Gpu, label: &str, entry: &str) -> wgpu::RenderPipeline {
        tile_pipeline(&gpu.device, &self.tile_mod, &self.tile_layout, label, entry)
    }

    /// Builds the footprint-LOD cast pipeline unless it exists (0.1–0.3 s on Mesa: only
    /// frames that ask for LOD pay for it).
    pub fn prepare_cast_lod(&mut self, gpu: &Gpu) {
        if self.cast_lod.is_none() {
            self.cast_lod = Some(self.cast_variant(gpu, true, false, "cast (lod)"));
        }
    }

    /// Builds the near-miss cast pipeline unless it exists (anti-aliased frames only; on the
    /// paged terrain too).
    pub fn prepare_cast_near(&mut self, gpu: &Gpu) {
        if self.cast_near.is_none() {
            self.cast_near = Some(self.cast_variant(gpu, false, true, "cast (near)"));
        }
    }

    fn cast_variant(&self, gpu: &Gpu, lod: bool, near: bool, label: &str) -> wgpu::RenderPipeline {
        let src = match self.pool_bindings {
            Some(n) => shaders::cast_paged(self.curved, n, near),
            None => shaders::cast(self.curved, lod, near),
        };
        let m = super::shader_module(&gpu.device, gpu.params, label, &src);
        let target = [Some(target_state(wgpu::TextureFormat::Rgba32Uint))];
        let entries = ["vs_fullscreen", "fs_cast"];
        render_pipeline_in(
            &gpu.device,
            label,
            &m,
            entries,
            &self.cast_layout,
            &target,
            None,
        )
    }

    /// The cast pipeline for a frame with (`lod`) or without footprint level of detail, and
    /// (`near`, without `lod`) flagging near misses.
    pub fn cast_pipeline(&self, lod: bool, near: bool) -> &wgpu::RenderPipeline {
        match (&self.cast_lod, &self.cast_near, lod, near) {
            (Some(p), _, true, _) => p,
            (_, Some(p), false, true) => p,
            _ => &self.cast,
        }
    }

    /// Ray generation is a compute dispatch (it writes the ray table as a storage texture).
    pub fn raygen_is_compute(&self) -> bool {
        matches!(self.raygen, RayGen::Compute(_))
    }
}
