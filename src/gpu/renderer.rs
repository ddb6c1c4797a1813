//! The terrain renderer: GPU resources uploaded once per terrain, size-dependent targets,
//! per-frame uniforms, the three passes and readback.

use super::objects::{ObjectPasses, ObjectTargets};
use super::shade::{shade_pipelines, ShadeFeatures, ShadePipelines};
use super::types::{FrameUniforms, RayGenUniforms, MAX_LEVELS};
use super::voxels::{VoxelPasses, VoxelTargets};
use super::{shaders, Gpu};
use crate::cpu::voxel::InstanceRect;
use crate::scene::{Camera, SceneDesc};
use crate::terrain::Terrain;
use crate::{Error, Result};
use std::time::Instant;
use wgpu::util::DeviceExt;

/// Density volumes a scene may hold (each is a full-screen pass per frame).
pub const MAX_VOLUMES: usize = 8;

/// Screen tile side of the tile pre-pass (WGSL `TILE`).
pub const TILE: u32 = 8;

/// How primary rays find the terrain.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum TraceMode {
    /// Maximum-pyramid traversal with exact bilinear patches (the product).
    Pyramid,
    /// Fixed-step march with bisection (benchmark baseline).
    March { step_cells: f32, bisections: u32 },
}

/// Per-frame switches.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RenderSettings {
    pub mode: TraceMode,
    pub shadows: bool,
    pub tile_prepass: bool,
    pub max_steps: u32,
}

impl RenderSettings {
    /// Settings from the scene's `[render]` table.
    pub fn from_scene(desc: &SceneDesc) -> RenderSettings {
        RenderSettings {
            mode: TraceMode::Pyramid,
            shadows: desc.render.shadows,
            tile_prepass: desc.render.tile_prepass,
            max_steps: desc.render.max_steps,
        }
    }
}

/// Wall-clock milliseconds per pass (each pass submitted and waited for on its own).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PassTimes {
    pub raygen_ms: f64,
    pub tile_ms: f64,
    pub cast_ms: f64,
    /// Free-form binning and cast (0 without free forms).
    pub objects_ms: f64,
    /// Voxel-model cast (0 without voxel models).
    pub voxels_ms: f64,
    /// Voxel-model shadow rays (0 without voxel models or shadows).
    pub voxel_shadow_ms: f64,
    pub shade_ms: f64,
    /// The sun's transmittance through the volumes at the surfaces (0 without a volume that
    /// casts a shadow).
    pub volume_shadow_ms: f64,
    /// Volume integration and compositing (0 without a volume).
    pub volume_ms: f64,
    /// Edge blend (0 without one).
    pub blend_ms: f64,
    pub readback_ms: f64,
}

impl PassTimes {
    /// Time to find every primary ray's hit (ray generation, tile pre-pass, terrain and
    /// free-form cast).
    pub fn primary_ms(&self) -> f64 {
        self.raygen_ms + self.tile_ms + self.cast_ms + self.objects_ms + self.voxels_ms
    }
}

/// How far a frame is rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Ray table, tile pre-pass and cast: primary-ray hits only (the G-buffer).
    Cast,
    /// Everything: shading, shadow rays, fog, sky.
    Shade,
}

/// What a captured frame holds.
#[derive(Clone, Debug)]
pub struct FrameOutput {
    pub width: u32,
    pub height: u32,
    /// sRGB RGBA8, row 0 at the top.
    pub rgba: Vec<u8>,
    /// Ray distance in metres per pixel, `+inf` for sky.
    pub depth: Vec<f32>,
    /// Primary traversal steps per pixel.
    pub steps: Vec<u32>,
    /// Exact patch tests per pixel.
    pub patch_tests: Vec<u32>,
    /// Shadow-ray traversal steps per pixel.
    pub shadow_steps: Vec<u32>,
    /// Flags per pixel: 1 hit, 2 in shadow, 4 step limit reached, 16 free form, 32 voxel model.
    pub flags: Vec<u32>,
    /// Free-form index + 1 per pixel (0 where no free form shows).
    pub objects: Vec<u32>,
    /// Volume texture samples taken per pixel (empty without a volume).
    pub volume_samples: Vec<u32>,
    /// Volume lattice segments passed per pixel, sampled or skipped (empty without a volume).
    pub volume_segments: Vec<u32>,
    /// The sun's transmittance through the density volumes per pixel, 0..=255, for the opaque
    /// surface there (255 for sky; empty when no volume casts a shadow or shadows are off).
    pub volume_sun: Vec<u8>,
    pub times: PassTimes,
}

struct Targets {
    width: u32,
    height: u32,
    tiles: [u32; 2],
    raygen_bg: wgpu::BindGroup,
    ray_table: wgpu::Texture,
    ray_table_view: wgpu::TextureView,
    tile_bg: wgpu::BindGroup,
    cast_bg: wgpu::BindGroup,
    shade_bg: wgpu::BindGroup,
    tile_view: wgpu::TextureView,
    gbuffer: wgpu::Texture,
    gbuffer_view: wgpu::TextureView,
    colour: wgpu::Texture,
    colour_view: wgpu::TextureView,
    data: wgpu::Texture,
    data_view: wgpu::TextureView,
    colour_rb: wgpu::Buffer,
    data_rb: wgpu::Buffer,
    /// Free-form bins, G-buffer and the shade bind group that reads them.
    objects: Option<(ObjectTargets, wgpu::BindGroup)>,
    /// Per volume: its passes' bind groups.
    volumes: Vec<super::volumes::VolumeTargets>,
    /// The image under the volumes, their results and statistics (with volumes).
    composite: Option<super::volumes::CompositeTargets>,
    /// The volume-sun target (the shade pass reads it) and its readback buffer.
    volume_sun: wgpu::Texture,
    volume_sun_view: wgpu::TextureView,
    volume_sun_rb: wgpu::Buffer,
    /// The finished image before the edge blend.
    blend: Option<super::blend::BlendTargets>,
    voxels: Option<VoxelTargets>,
}

/// Which entry points run the per-pixel kernels that have both (ray generation today).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelPath {
    /// Compute dispatches: best on GPUs.
    Compute,
    /// Full-screen fragment passes: best on Mesa's CPU adapters, which run fragments on every
    /// core but hand each compute thread a fixed block of workgroups.
    Fragment,
}

impl KernelPath {
    /// Fragment on CPU adapters, compute elsewhere; `RELIEF_KERNELS=compute|fragment` overrides.
    pub fn for_adapter(info: &wgpu::AdapterInfo) -> KernelPath {
        match std::env::var("RELIEF_KERNELS").as_deref() {
            Ok("compute") => KernelPath::Compute,
            Ok("fragment") => KernelPath::Fragment,
            _ if info.device_type == wgpu::DeviceType::Cpu => KernelPath::Fragment,
            _ => KernelPath::Compute,
        }
    }
}

/// The ray-generation pass in the form that suits the adapter.
enum RayGen {
    Compute(wgpu::ComputePipeline),
    Fragment(wgpu::RenderPipeline),
}

/// Terrain data on the GPU and the pipelines that render it.
pub struct TerrainRenderer {
    heights: wgpu::Buffer,
    pyramid: wgpu::Buffer,
    dilated: wgpu::Buffer,
    pyramid_side: u32,
    drape: wgpu::Buffer,
    frame_ub: wgpu::Buffer,
    raygen_ub: wgpu::Buffer,
    raygen_bgl: wgpu::BindGroupLayout,
    tile_bgl: wgpu::BindGroupLayout,
    cast_bgl: wgpu::BindGroupLayout,
    shade_bgl: wgpu::BindGroupLayout,
    raygen: RayGen,
    tile_pipeline: wgpu::RenderPipeline,
    cast_pipeline: wgpu::RenderPipeline,
    march_pipeline: wgpu::RenderPipeline,
    /// Terrain-only shade pipelines (with free forms, [`ObjectPasses`] has its own).
    shade: ShadePipelines,
    /// The terrain has a draped image (a shade-pipeline constant).
    has_drape: bool,
    raygen_mod: wgpu::ShaderModule,
    tile_mod: wgpu::ShaderModule,
    table: Option<TableMode>,
    objects: Option<ObjectPasses>,
    /// Lowest world z of the free forms' bounding spheres (+inf without free forms).
    objects_floor: f64,
    volumes: Vec<super::volumes::VolumePass>,
    /// The volume-sun pass (built with the first volume).
    volume_sun: Option<super::volumes::VolumeSunPass>,
    /// The composite pass for the scene's volumes (with volumes).
    volume_composite: Option<super::volumes::CompositePass>,
    /// The volumes shadow the surfaces but are not composited (see [`Self::set_volumes_hidden`]).
    volumes_hidden: bool,
    /// Edge blend of a display channel (see [`Self::set_blend`]).
    blend: Option<super::blend::BlendPass>,
    voxels: Option<VoxelPasses>,
    /// Warp test pattern instead of the scene (see [`Self::set_pattern`]).
    pattern: Option<(
        super::pattern::PatternPass,
        crate::display::pattern::PatternParams,
    )>,
    /// Scene time in seconds (animated voxel models).
    time: f64,
    /// Frames run so far (wrapping, never 0): the frame's stamp in the uniforms.
    stamp: u32,
    targets: Option<Targets>,
}

/// Ray generation from a distortion table: the cached screen points of one projector, the
/// pipelines that turn them into the ray table and tile cones, and the current eye point.
struct TableMode {
    bgl: wgpu::BindGroupLayout,
    raygen: wgpu::RenderPipeline,
    tile: wgpu::RenderPipeline,
    points_view: wgpu::TextureView,
    size: [u32; 2],
    eye: glam::DVec3,
    /// The channel's view offset (display frame rotation applied before the vehicle's).
    offset: glam::DMat3,
}

pub(crate) fn storage_entry(
    binding: u32,
    vis: wgpu::ShaderStages,
    read_only: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind-group entry for a parameter block (`var<uniform>` in WGSL) bound in `space`.
pub(crate) fn uniform_entry(
    space: super::ParamSpace,
    binding: u32,
    vis: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Buffer {
            ty: space.binding_type(),
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind-group entry for an unsigned-integer 2-D texture.
pub(crate) fn uint_texture_entry(
    binding: u32,
    vis: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Uint,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// An unfiltered float texture binding (loaded with `textureLoad`) of `dim`.
pub(crate) fn float_texture_entry(
    binding: u32,
    vis: wgpu::ShaderStages,
    dim: wgpu::TextureViewDimension,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: dim,
            multisampled: false,
        },
        count: None,
    }
}

/// Checks that a buffer of `bytes` fits the device; the error names the data and the limit.
pub fn check_buffer_limit(gpu: &Gpu, what: &str, bytes: u64) -> Result<()> {
    let limit = gpu
        .limits
        .max_storage_buffer_binding_size
        .min(gpu.limits.max_buffer_size);
    if bytes > limit {
        return Err(Error::Limit {
            what: what.to_string(),
            msg: format!(
                "{bytes} bytes needed, the adapter {} allows {limit} bytes per storage buffer; use a smaller or cropped height map",
                gpu.info.name
            ),
        });
    }
    Ok(())
}

impl TerrainRenderer {
    /// Uploads the terrain (heights, pyramid, drape) and builds the pipelines, with the kernel
    /// path [`KernelPath::for_adapter`] picks.
    pub fn new(gpu: &Gpu, terrain: &Terrain) -> Result<TerrainRenderer> {
        Self::with_kernels(gpu, terrain, KernelPath::for_adapter(&gpu.info))
    }

    /// As [`TerrainRenderer::new`] with an explicit kernel path.
    pub fn with_kernels(
        gpu: &Gpu,
        terrain: &Terrain,
        kernels: KernelPath,
    ) -> Result<TerrainRenderer> {
        let dev = &gpu.device;
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
        check_buffer_limit(gpu, "height table", terrain.field.heights.len() as u64 * 4)?;
        let (pyramid_data, pyramid_side) = square_pyramid(terrain);
        check_buffer_limit(gpu, "maximum pyramid", pyramid_data.len() as u64 * 4)?;
        let storage = wgpu::BufferUsages::STORAGE;
        let heights = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("heights"),
            contents: bytemuck::cast_slice(&terrain.field.heights),
            usage: storage,
        });
        let pyramid = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("max pyramid"),
            contents: bytemuck::cast_slice(&pyramid_data),
            usage: storage,
        });
        let dilated_data = dilate_square_pyramid(&pyramid_data, pyramid_side);
        let dilated = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("dilated max pyramid"),
            contents: bytemuck::cast_slice(&dilated_data),
            usage: storage,
        });
        let drape_words: Vec<u32> = match &terrain.drape {
            Some((d, _)) => {
                check_buffer_limit(gpu, "drape image", d.rgba.len() as u64)?;
                d.rgba
                    .chunks_exact(4)
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            }
            None => vec![0],
        };
        let drape = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("drape"),
            contents: bytemuck::cast_slice(&drape_words),
            usage: storage,
        });
        let frame_ub = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame uniforms"),
            size: std::mem::size_of::<FrameUniforms>() as u64,
            usage: super::PARAM_USAGE,
            mapped_at_creation: false,
        });
        let raygen_ub = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("raygen uniforms"),
            size: std::mem::size_of::<RayGenUniforms>() as u64,
            usage: super::PARAM_USAGE,
            mapped_at_creation: false,
        });
        let cs = wgpu::ShaderStages::COMPUTE;
        let fs = wgpu::ShaderStages::FRAGMENT;
        let raygen_compute = kernels == KernelPath::Compute;
        let raygen_bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("raygen"),
            entries: &if raygen_compute {
                vec![
                    uniform_entry(gpu.params, 0, cs),
                    wgpu::BindGroupLayoutEntry {
                        binding: 1,
                        visibility: cs,
                        ty: wgpu::BindingType::StorageTexture {
                            access: wgpu::StorageTextureAccess::WriteOnly,
                            format: wgpu::TextureFormat::Rgba32Uint,
                            view_dimension: wgpu::TextureViewDimension::D2,
                        },
                        count: None,
                    },
                ]
            } else {
                vec![uniform_entry(gpu.params, 0, fs)]
            },
        });
        let uint_texture = |binding| uint_texture_entry(binding, fs);
        let common = [
            uniform_entry(gpu.params, 0, fs),
            storage_entry(1, fs, true),
            storage_entry(2, fs, true),
            uint_texture(3),
        ];
        let mut tile_entries = common.to_vec();
        tile_entries.push(storage_entry(4, fs, true));
        let tile_bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("tile"),
            entries: &tile_entries,
        });
        let mut cast_entries = common.to_vec();
        cast_entries.push(uint_texture(4));
        let cast_bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cast"),
            entries: &cast_entries,
        });
        let mut shade_entries = cast_entries.clone();
        shade_entries.push(storage_entry(5, fs, true));
        shade_entries.push(float_texture_entry(19, fs, wgpu::TextureViewDimension::D2));
        let shade_bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shade"),
            entries: &shade_entries,
        });

        let module = |label: &str, src: String| super::shader_module(dev, gpu.params, label, &src);
        let raygen_mod = module("raygen.wgsl", shaders::raygen());
        let tile_mod = module("tile.wgsl", shaders::tile());
        let cast_mod = module("cast.wgsl", shaders::cast());
        let layout = |bgl: &wgpu::BindGroupLayout| pipeline_layout(dev, bgl);
        let fullscreen = |label: &str,
                          m: &wgpu::ShaderModule,
                          entry: &str,
                          bgl: &wgpu::BindGroupLayout,
                          targets: &[Option<wgpu::ColorTargetState>]| {
            fullscreen_pipeline(dev, label, m, entry, bgl, targets)
        };
        let target = |format| Some(target_state(format));
        let tile_pipeline = fullscreen(
            "tile",
            &tile_mod,
            "fs_tile",
            &tile_bgl,
            &[target(wgpu::TextureFormat::Rg32Uint)],
        );
        let raygen = if raygen_compute {
            RayGen::Compute(
                dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("raygen"),
                    layout: Some(&layout(&raygen_bgl)),
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
                &raygen_bgl,
                &[target(wgpu::TextureFormat::Rgba32Uint)],
            ))
        };
        let cast_pipeline = fullscreen(
            "cast",
            &cast_mod,
            "fs_cast",
            &cast_bgl,
            &[target(wgpu::TextureFormat::Rgba32Uint)],
        );
        let march_pipeline = fullscreen(
            "march",
            &cast_mod,
            "fs_cast_march",
            &cast_bgl,
            &[target(wgpu::TextureFormat::Rgba32Uint)],
        );
        let shade = shade_pipelines(gpu.params, "shade", shaders::shade, shade_bgl.clone());
        let has_drape = terrain.drape.is_some();
        Ok(TerrainRenderer {
            heights,
            pyramid,
            dilated,
            pyramid_side,
            drape,
            frame_ub,
            raygen_ub,
            raygen_bgl,
            tile_bgl,
            cast_bgl,
            shade_bgl,
            raygen,
            tile_pipeline,
            cast_pipeline,
            march_pipeline,
            shade,
            has_drape,
            raygen_mod,
            tile_mod,
            table: None,
            objects: None,
            objects_floor: f64::INFINITY,
            volumes: Vec::new(),
            volume_sun: None,
            volume_composite: None,
            volumes_hidden: false,
            blend: None,
            voxels: None,
            pattern: None,
            time: 0.0,
            stamp: 0,
            targets: None,
        })
    }

    /// Switches ray generation to a distortion table: uploads the projector's screen points
    /// (kept while the projector does not move) and builds the table pipelines. Frames must
    /// then be rendered at the projector's resolution; the eye is set by [`Self::set_eye`].
    pub fn set_display(
        &mut self,
        gpu: &Gpu,
        points: &crate::cpu::distortion::ScreenPoints,
        eye: glam::DVec3,
    ) -> Result<()> {
        let what = format!("projector resolution {}x{}", points.width, points.height);
        gpu.scoped(&what, || self.upload_display(gpu, points, eye))
    }

    fn upload_display(
        &mut self,
        gpu: &Gpu,
        points: &crate::cpu::distortion::ScreenPoints,
        eye: glam::DVec3,
    ) -> Result<()> {
        let dev = &gpu.device;
        let max = gpu.limits.max_texture_dimension_2d;
        if points.width > max || points.height > max {
            return Err(Error::Limit {
                what: "projector resolution".into(),
                msg: format!(
                    "{}x{} is larger than the adapter's {max}x{max} texture limit",
                    points.width, points.height
                ),
            });
        }
        let texels: Vec<[f32; 4]> = points
            .points
            .iter()
            .map(|p| p.map_or([0.0; 4], |p| [p.x as f32, p.y as f32, p.z as f32, 1.0]))
            .collect();
        let texture = dev.create_texture(&wgpu::TextureDescriptor {
            label: Some("screen points"),
            size: wgpu::Extent3d {
                width: points.width,
                height: points.height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Uint,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        gpu.queue.write_texture(
            texture.as_image_copy(),
            bytemuck::cast_slice(&texels),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(points.width * 16),
                rows_per_image: Some(points.height),
            },
            wgpu::Extent3d {
                width: points.width,
                height: points.height,
                depth_or_array_layers: 1,
            },
        );
        let fs = wgpu::ShaderStages::FRAGMENT;
        let bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("raygen (table)"),
            entries: &[
                uniform_entry(gpu.params, 0, fs),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: fs,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let raygen = fullscreen_pipeline(
            dev,
            "raygen (table)",
            &self.raygen_mod,
            "fs_raygen_table",
            &bgl,
            &[Some(target_state(wgpu::TextureFormat::Rgba32Uint))],
        );
        let tile = fullscreen_pipeline(
            dev,
            "tile (table)",
            &self.tile_mod,
            "fs_tile_table",
            &self.tile_bgl,
            &[Some(target_state(wgpu::TextureFormat::Rg32Uint))],
        );
        self.table = Some(TableMode {
            bgl,
            raygen,
            tile,
            points_view: texture.create_view(&Default::default()),
            size: [points.width, points.height],
            eye,
            offset: glam::DMat3::IDENTITY,
        });
        self.targets = None;
        Ok(())
    }

    /// Sets the channel's view offset for table ray generation: world direction =
    /// vehicle attitude · `offset` · display direction (see
    /// [`crate::display::ViewOffset`]). Reset to identity by [`Self::set_display`].
    pub fn set_view_offset(&mut self, offset: glam::DMat3) {
        if let Some(t) = &mut self.table {
            t.offset = offset;
        }
    }

    /// Uploads the scene's free forms (none: the terrain-only passes). Objects are binned per
    /// 16x16-pixel screen bin every frame, so a pixel tests only its bin's objects.
    pub fn set_objects(&mut self, gpu: &Gpu, objects: &[crate::freeform::FreeForm]) -> Result<()> {
        self.upload_objects(gpu, objects, true)
    }

    /// As [`TerrainRenderer::set_objects`], with the object tables in storage buffers even
    /// where they would fit uniform buffers: the path of scenes beyond the uniform-binding
    /// size (see `gpu::objects::FfTables`), for tests and comparisons.
    pub fn set_objects_in_storage(
        &mut self,
        gpu: &Gpu,
        objects: &[crate::freeform::FreeForm],
    ) -> Result<()> {
        self.upload_objects(gpu, objects, false)
    }

    fn upload_objects(
        &mut self,
        gpu: &Gpu,
        objects: &[crate::freeform::FreeForm],
        allow_uniform: bool,
    ) -> Result<()> {
        self.objects = if objects.is_empty() {
            None
        } else {
            Some(ObjectPasses::new(gpu, objects, allow_uniform)?)
        };
        self.objects_floor = objects
            .iter()
            .map(|o| {
                let (c, r) = o.bounding_sphere();
                c.z - r
            })
            .fold(f64::INFINITY, f64::min);
        self.targets = None;
        Ok(())
    }

    /// Uploads the scene's density volumes (none: no volume pass). Each frame integrates each
    /// one cut at the opaque depth, then composites them per pixel farthest medium first (by
    /// each one's contribution-weighted depth): exact for media that do not interleave along a
    /// ray, whether or not their boxes overlap. The renderer's copies get the volumes' shadows
    /// on each other baked in (`volume::shadow::shadow_each_other`, as `Scene::volumes` does
    /// for the CPU model).
    pub fn set_volumes(&mut self, gpu: &Gpu, volumes: &[crate::volume::Volume]) -> Result<()> {
        if volumes.len() > MAX_VOLUMES {
            return Err(Error::invalid(
                "volumes",
                format!(
                    "{} [[volumes]] tables, at most {MAX_VOLUMES}: merge some into one grid",
                    volumes.len()
                ),
            ));
        }
        self.volumes = volumes
            .iter()
            .map(|v| super::volumes::VolumePass::new(gpu, v))
            .collect::<Result<_>>()?;
        self.shadow_volumes_each_other(gpu);
        if !self.volumes.is_empty() && self.volume_sun.is_none() {
            self.volume_sun = Some(super::volumes::VolumeSunPass::new(gpu));
        }
        self.volume_composite = (!self.volumes.is_empty())
            .then(|| super::volumes::CompositePass::new(gpu, self.volumes.len() as u32));
        self.targets = None;
        Ok(())
    }

    /// With `true`, the volumes still shadow the surfaces below them but are not integrated:
    /// the frame is the image the volume passes would composite over (for tests that check
    /// the volume pass against the CPU integral over that image, and for diagnostics).
    pub fn set_volumes_hidden(&mut self, hidden: bool) {
        self.volumes_hidden = hidden;
    }

    /// Uploads the scene's voxel models (none: no voxel passes). Refuses models over the
    /// adapter's storage-buffer limits with the limit in the message.
    pub fn set_voxels(&mut self, gpu: &Gpu, models: &[crate::voxel::VoxelInstance]) -> Result<()> {
        self.voxels = if models.is_empty() {
            None
        } else {
            Some(VoxelPasses::new(gpu, models)?)
        };
        self.targets = None;
        Ok(())
    }

    /// Reclassifies the volumes with a new transfer function (table and brick occupancy are
    /// recomputed and uploaded), all of them.
    pub fn set_volume_transfer(&mut self, gpu: &Gpu, tf: crate::volume::TransferFunction) {
        for v in &mut self.volumes {
            v.set_transfer(gpu, tf.clone());
        }
        self.shadow_volumes_each_other(gpu);
    }

    /// Bakes the volumes' shadows on each other into their grids again and uploads them.
    fn shadow_volumes_each_other(&mut self, gpu: &Gpu) {
        let mut vols: Vec<_> = self.volumes.iter_mut().map(|v| &mut v.volume).collect();
        crate::volume::shadow::shadow_each_other(&mut vols);
        for v in &self.volumes {
            v.upload_shadows(gpu);
        }
    }

    /// Changes the volumes' sampling switches (step, skipping, termination, jitter, mip-maps),
    /// all of them.
    pub fn set_volume_settings(&mut self, gpu: &Gpu, settings: crate::volume::VolumeSettings) {
        let mut reclassified = false;
        for v in &mut self.volumes {
            if v.volume.settings.mipmaps != settings.mipmaps {
                v.volume.settings = settings;
                let tf = v.volume.transfer.clone();
                v.set_transfer(gpu, tf);
                reclassified = true;
            }
            v.volume.settings = settings;
        }
        // Reclassifying recomputed the self-shadowing grids without the other volumes.
        if reclassified {
            self.shadow_volumes_each_other(gpu);
        }
    }

    /// Renders the warp test pattern ([`crate::display::pattern`]) from the ray table instead
    /// of the scene while `Some` (the tile, cast and shade passes are skipped); `None` renders
    /// the scene again.
    pub fn set_pattern(
        &mut self,
        gpu: &Gpu,
        params: Option<crate::display::pattern::PatternParams>,
    ) {
        self.pattern = match (params, self.pattern.take()) {
            (None, _) => None,
            (Some(p), Some((pass, _))) => Some((pass, p)),
            (Some(p), None) => Some((super::pattern::PatternPass::new(gpu), p)),
        };
    }

    /// Sets (or, with `None`, removes) the edge blend applied to the finished image, in display
    /// space after the warp ([`crate::display::blend`]).
    pub fn set_blend(
        &mut self,
        gpu: &Gpu,
        blend: Option<&crate::display::blend::ChannelBlend>,
    ) -> Result<()> {
        self.blend = blend
            .map(|b| super::blend::BlendPass::new(gpu, b))
            .transpose()?;
        self.targets = None;
        Ok(())
    }

    /// Sets the scene time (seconds) that picks animated voxel models' frames.
    pub fn set_time(&mut self, seconds: f64) {
        self.time = seconds;
    }

    /// Moves the eye (display frame) for the next frames of a distortion table.
    pub fn set_eye(&mut self, eye: glam::DVec3) {
        if let Some(t) = &mut self.table {
            t.eye = eye;
        }
    }

    /// GPU bytes per output pixel of the render targets and readback buffers, an upper
    /// estimate: ray table 16, G-buffer 16, colour 4 + readback 4, capture data 16 +
    /// readback 16, volume sun 1 + readback 1; free-form G-buffer 16; per volume result,
    /// statistics and statistics readback 48, plus the image under the volumes and the
    /// second layer GL needs 36; edge-blend copy 8; 16 of slack (tile texture, readback row
    /// padding).
    fn target_bytes_per_pixel(&self) -> u64 {
        let base = 16 + 16 + (4 + 4) + (16 + 16) + (1 + 1);
        let objects = if self.objects.is_some() { 16 } else { 0 };
        let volumes = match self.volumes.len() as u64 {
            0 => 0,
            n => n * 48 + 36,
        };
        let blend = if self.blend.is_some() { 8 } else { 0 };
        base + objects + volumes + blend + 16
    }

    /// Creates the render targets for `width` x `height` unless they exist. Refuses sizes over
    /// the adapter's limits or the memory budget before allocating, and turns wgpu's
    /// out-of-memory and validation errors during creation into an error naming the size.
    fn ensure_targets(&mut self, gpu: &Gpu, width: u32, height: u32) -> Result<()> {
        if self
            .targets
            .as_ref()
            .is_some_and(|t| t.width == width && t.height == height)
        {
            return Ok(());
        }
        let what = if self.table.is_some() {
            "projector channel resolution"
        } else {
            "output size (--size)"
        };
        let max = gpu.limits.max_texture_dimension_2d;
        if width > max || height > max {
            return Err(Error::Limit {
                what: what.into(),
                msg: format!(
                    "{width}x{height} is larger than the adapter's {max}x{max} texture limit"
                ),
            });
        }
        let readback = padded_row(width.saturating_mul(16)) as u64 * height as u64;
        if readback > gpu.limits.max_buffer_size {
            return Err(Error::Limit {
                what: what.into(),
                msg: format!(
                    "{width}x{height} needs a {} readback buffer, the adapter {} allows {}; render at a smaller size",
                    crate::fileio::human_bytes(readback),
                    gpu.info.name,
                    crate::fileio::human_bytes(gpu.limits.max_buffer_size)
                ),
            });
        }
        let bytes = width as u64 * height as u64 * self.target_bytes_per_pixel();
        let budget = crate::fileio::memory_budget();
        if bytes > budget {
            return Err(Error::Limit {
                what: what.into(),
                msg: format!(
                    "{width}x{height} needs about {} of GPU memory for its render targets, more than the memory budget of {}; render at a smaller size, or raise --memory-budget (MiB) if the adapter has the memory",
                    crate::fileio::human_bytes(bytes),
                    crate::fileio::human_bytes(budget)
                ),
            });
        }
        // Free the old targets before allocating the new ones.
        self.targets = None;
        let made = gpu.scoped(&format!("{what} {width}x{height}"), || {
            self.create_targets(gpu, width, height)
        });
        if made.is_err() {
            self.targets = None;
        }
        made
    }

    fn create_targets(&mut self, gpu: &Gpu, width: u32, height: u32) -> Result<()> {
        let dev = &gpu.device;
        let mut usage = wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::COPY_SRC;
        if matches!(self.raygen, RayGen::Compute(_)) {
            usage |= wgpu::TextureUsages::STORAGE_BINDING;
        }
        let ray_table = screen_texture(
            dev,
            "ray table",
            [width, height],
            wgpu::TextureFormat::Rgba32Uint,
            usage,
        );
        let ray_table_view = ray_table.create_view(&Default::default());
        let tiles = [width.div_ceil(TILE), height.div_ceil(TILE)];
        let tex = |label, w, h, format| {
            screen_texture(
                dev,
                label,
                [w, h],
                format,
                wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC
                    | wgpu::TextureUsages::COPY_DST,
            )
        };
        let tile_tex = tex(
            "tile start",
            tiles[0],
            tiles[1],
            wgpu::TextureFormat::Rg32Uint,
        );
        let colour = tex("colour", width, height, wgpu::TextureFormat::Rgba8Unorm);
        let data = tex("data", width, height, wgpu::TextureFormat::Rgba32Uint);
        let tile_view = tile_tex.create_view(&Default::default());
        let gbuffer = tex("g-buffer", width, height, wgpu::TextureFormat::Rgba32Uint);
        let gbuffer_view = gbuffer.create_view(&Default::default());
        let volume_sun = tex("volume sun", width, height, super::volumes::SUN_FORMAT);
        let volume_sun_view = volume_sun.create_view(&Default::default());
        let rb = |label, bpp: u32| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: padded_row(width * bpp) as u64 * height as u64,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        let raygen_bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raygen"),
            layout: self.table.as_ref().map_or(&self.raygen_bgl, |t| &t.bgl),
            entries: &if let Some(table) = &self.table {
                vec![
                    buf(0, &self.raygen_ub),
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&table.points_view),
                    },
                ]
            } else if matches!(self.raygen, RayGen::Compute(_)) {
                vec![
                    buf(0, &self.raygen_ub),
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&ray_table_view),
                    },
                ]
            } else {
                vec![buf(0, &self.raygen_ub)]
            },
        });
        let common = [
            buf(0, &self.frame_ub),
            buf(1, &self.heights),
            buf(2, &self.pyramid),
            wgpu::BindGroupEntry {
                binding: 3,
                resource: wgpu::BindingResource::TextureView(&ray_table_view),
            },
        ];
        let mut entries = common.to_vec();
        entries.push(buf(4, &self.dilated));
        let tile_bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("tile"),
            layout: &self.tile_bgl,
            entries: &entries,
        });
        let mut entries = common.to_vec();
        entries.push(wgpu::BindGroupEntry {
            binding: 4,
            resource: wgpu::BindingResource::TextureView(&tile_view),
        });
        let cast_bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cast"),
            layout: &self.cast_bgl,
            entries: &entries,
        });
        let mut entries = common.to_vec();
        entries.push(wgpu::BindGroupEntry {
            binding: 4,
            resource: wgpu::BindingResource::TextureView(&gbuffer_view),
        });
        entries.push(buf(5, &self.drape));
        entries.push(view(19, &volume_sun_view));
        let shade_bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shade"),
            layout: &self.shade_bgl,
            entries: &entries,
        });
        let objects = match &self.objects {
            Some(o) => {
                let ot = o.targets(
                    gpu,
                    width,
                    height,
                    &self.frame_ub,
                    &ray_table_view,
                    &gbuffer_view,
                )?;
                let bg = o.shade_bind_group(
                    gpu,
                    [&self.frame_ub, &self.heights, &self.pyramid, &self.drape],
                    [&ray_table_view, &volume_sun_view],
                    &ot,
                );
                Some((ot, bg))
            }
            None => None,
        };
        // The G-buffer the casts end in (see `run_passes`).
        let final_gbuffer_view = objects
            .as_ref()
            .map_or(&gbuffer_view, |(ot, _)| &ot.final_view);
        let volumes = match &self.volume_sun {
            Some(sun_pass) => self
                .volumes
                .iter()
                .map(|v| {
                    v.targets(
                        gpu,
                        &self.frame_ub,
                        &ray_table_view,
                        &data.create_view(&Default::default()),
                        sun_pass,
                        final_gbuffer_view,
                    )
                })
                .collect(),
            None => Vec::new(),
        };
        let composite = self
            .volume_composite
            .as_ref()
            .map(|c| c.targets(gpu, width, height, &self.frame_ub));
        let voxels = self
            .voxels
            .as_ref()
            .map(|v| v.targets(gpu, width, height, &self.frame_ub, &ray_table_view));
        let blend = self
            .blend
            .as_ref()
            .map(|b| b.targets(gpu, width, height))
            .transpose()?;
        self.targets = Some(Targets {
            blend,
            volumes,
            composite,
            objects,
            voxels,
            width,
            height,
            tiles,
            raygen_bg,
            ray_table,
            ray_table_view,
            tile_bg,
            cast_bg,
            shade_bg,
            tile_view,
            gbuffer,
            gbuffer_view,
            colour_view: colour.create_view(&Default::default()),
            data_view: data.create_view(&Default::default()),
            colour,
            data,
            colour_rb: rb("colour readback", 4),
            volume_sun_rb: rb("volume sun readback", 1),
            volume_sun,
            volume_sun_view,
            data_rb: rb("data readback", 16),
        });
        Ok(())
    }

    fn encode_raygen(&self, enc: &mut wgpu::CommandEncoder, t: &Targets) {
        if let Some(table) = &self.table {
            return Self::encode_fullscreen(
                enc,
                "raygen (table)",
                &table.raygen,
                &t.raygen_bg,
                &[&t.ray_table_view],
            );
        }
        match &self.raygen {
            RayGen::Compute(p) => {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("raygen"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(p);
                pass.set_bind_group(0, &t.raygen_bg, &[]);
                pass.dispatch_workgroups(t.width.div_ceil(8), t.height.div_ceil(8), 1);
            }
            RayGen::Fragment(p) => {
                Self::encode_fullscreen(enc, "raygen", p, &t.raygen_bg, &[&t.ray_table_view])
            }
        }
    }

    pub(crate) fn encode_fullscreen(
        enc: &mut wgpu::CommandEncoder,
        label: &str,
        pipeline: &wgpu::RenderPipeline,
        bg: &wgpu::BindGroup,
        views: &[&wgpu::TextureView],
    ) {
        let attachments: Vec<_> = views
            .iter()
            .map(|v| {
                Some(wgpu::RenderPassColorAttachment {
                    view: v,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        // SAFETY: the full-screen triangle covers every pixel and no full-screen
                        // pass discards (`tests/shaders.rs` checks), so every pixel is written
                        // before it is read or stored. A clear costs Mesa's CPU adapters about
                        // as much as a trivial full-screen pass of its own.
                        load: wgpu::LoadOp::DontCare(unsafe { wgpu::LoadOpDontCare::enabled() }),
                        store: wgpu::StoreOp::Store,
                    },
                })
            })
            .collect();
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &attachments,
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bg, &[]);
        pass.draw(0..3, 0..1);
    }

    /// Uploads the frame's uniforms and records the passes. With `timed`, each pass is
    /// submitted and waited for separately and its wall time returned.
    fn run_passes(
        &mut self,
        gpu: &Gpu,
        terrain: &Terrain,
        scene: &SceneDesc,
        cam: &Camera,
        s: &RenderSettings,
        stage: Stage,
        timed: bool,
    ) -> Result<PassTimes> {
        if let Some(table) = &self.table {
            if [cam.width, cam.height] != table.size {
                return Err(Error::invalid(
                    "output size",
                    format!(
                        "{}x{} does not match the projector's {}x{}: a distortion table renders at the projector's resolution",
                        cam.width, cam.height, table.size[0], table.size[1]
                    ),
                ));
            }
        }
        self.ensure_targets(gpu, cam.width, cam.height)?;
        let features = ShadeFeatures {
            shadows: s.shadows,
            drape: self.has_drape,
            voxels: self.voxels.is_some(),
            volume_shadows: s.shadows && self.volumes.iter().any(|v| v.casts_shadow()),
        };
        let shade_index = match &mut self.objects {
            Some(o) => o.shade.prepare(&gpu.device, features),
            None => self.shade.prepare(&gpu.device, features),
        };
        let t = self.targets.as_ref().expect("targets just ensured");
        let mut fu = frame_uniforms(terrain, scene, cam, s, t.tiles);
        fu.pyramid_dims = [self.pyramid_side, 0, 0, 0];
        self.stamp = self.stamp.wrapping_add(1).max(1);
        fu.stamp = [self.stamp, 0, 0, 0];
        if let (Some(o), Some((ot, _))) = (&self.objects, &t.objects) {
            fu.objects = [
                o.count,
                ot.bins[0],
                ot.bins[1],
                super::objects::BIN_CAPACITY,
            ];
        }
        gpu.queue
            .write_buffer(&self.frame_ub, 0, bytemuck::bytes_of(&fu));
        gpu.queue.write_buffer(
            &self.raygen_ub,
            0,
            bytemuck::bytes_of(&match &self.table {
                Some(t) => table_raygen_uniforms(cam, t.eye, t.offset),
                None => raygen_uniforms(cam, glam::DVec3::ZERO),
            }),
        );
        let mut times = PassTimes::default();
        let tile_on = s.tile_prepass && s.mode == TraceMode::Pyramid;
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let lap = |enc: &mut wgpu::CommandEncoder, slot: &mut f64| -> Result<()> {
            if timed {
                let start = Instant::now();
                let done =
                    std::mem::replace(enc, gpu.device.create_command_encoder(&Default::default()));
                gpu.queue.submit([done.finish()]);
                gpu.wait()?;
                *slot = start.elapsed().as_secs_f64() * 1e3;
            }
            Ok(())
        };
        self.encode_raygen(&mut enc, t);
        lap(&mut enc, &mut times.raygen_ms)?;
        if let Some((pass, params)) = &self.pattern {
            let views = (&t.ray_table_view, &t.colour_view, &t.data_view);
            pass.encode(gpu, params, &mut enc, views.0, views.1, views.2);
            lap(&mut enc, &mut times.shade_ms)?;
            self.encode_blend(&mut enc, t);
            lap(&mut enc, &mut times.blend_ms)?;
            gpu.queue.submit([enc.finish()]);
            return Ok(times);
        }
        if tile_on {
            Self::encode_fullscreen(
                &mut enc,
                "tile",
                self.table.as_ref().map_or(&self.tile_pipeline, |t| &t.tile),
                &t.tile_bg,
                &[&t.tile_view],
            );
        }
        lap(&mut enc, &mut times.tile_ms)?;
        let cast = if tile_on || s.mode == TraceMode::Pyramid {
            &self.cast_pipeline
        } else {
            &self.march_pipeline
        };
        Self::encode_fullscreen(&mut enc, "cast", cast, &t.cast_bg, &[&t.gbuffer_view]);
        lap(&mut enc, &mut times.cast_ms)?;
        let objects = self.objects.as_ref().zip(t.objects.as_ref());
        if let Some((o, (ot, _))) = objects {
            o.encode_cast(gpu, &mut enc, ot, &t.gbuffer, &t.gbuffer_view);
            lap(&mut enc, &mut times.objects_ms)?;
        }
        let voxels = self.voxels.as_ref().zip(t.voxels.as_ref());
        // The G-buffer the shade pass reads (the free-form one when there are free forms of
        // one kind only; with both kinds the casts end in the terrain's).
        let final_gbuffer = match &t.objects {
            Some((ot, _)) if !ot.final_in_terrain => (&ot.gbuffer, &ot.gbuffer_view),
            _ => (&t.gbuffer, &t.gbuffer_view),
        };
        // Pixels the voxel passes run on: rectangles from the models' occupied slabs for a
        // pinhole camera (partitioned, each with its models), every pixel through a
        // distortion table.
        let pinhole = self.table.is_none();
        let full = |n| vec![InstanceRect::full(cam.width, cam.height, n)];
        // Rectangles of the cast and (when shading with shadows) the shadow pass.
        let voxel_rects = voxels.map(|(v, _)| {
            let n = v.instances().len();
            let cast = if pinhole {
                crate::cpu::voxel::primary_rects(v.instances(), v.cover_boxes(), cam)
            } else {
                full(n)
            };
            let shadows = if stage != Stage::Shade || !s.shadows {
                Vec::new()
            } else if pinhole {
                crate::cpu::voxel::shadow_rects(
                    v.instances(),
                    v.cover_boxes(),
                    cam,
                    scene.sun.direction(),
                    // No surface lies lower: the terrain's lowest point, the free
                    // forms' and the models' own (their boxes start the sweep).
                    terrain.lowest_z().min(self.objects_floor) - 1.0,
                )
            } else {
                full(n)
            };
            (cast, shadows)
        });
        if let (Some((v, vt)), Some((cast, shadows))) = (voxels, &voxel_rects) {
            v.update(gpu, cam.pose.position, self.time, cast, shadows);
            v.encode_cast(&mut enc, vt, final_gbuffer, cast);
            lap(&mut enc, &mut times.voxels_ms)?;
        }
        if stage == Stage::Shade {
            if let (Some((v, vt)), Some((_, shadows))) = (voxels, &voxel_rects) {
                if !shadows.is_empty() {
                    v.encode_shadows(&mut enc, vt, final_gbuffer, shadows);
                    lap(&mut enc, &mut times.voxel_shadow_ms)?;
                }
            }
            let (pipeline, bg) = match objects {
                Some((o, (ot, bg))) => {
                    if s.shadows {
                        o.encode_shadows(gpu, &mut enc, ot);
                    }
                    (o.shade.get(shade_index), bg)
                }
                None => (self.shade.get(shade_index), &t.shade_bg),
            };
            for v in &self.volumes {
                v.write_uniforms(gpu, cam.pose.position);
            }
            if let (Some(sun_pass), true) = (&self.volume_sun, features.volume_shadows) {
                let casting: Vec<_> = (self.volumes.iter().zip(&t.volumes))
                    .filter(|(v, _)| v.casts_shadow())
                    .map(|(_, vt)| &vt.sun_bg)
                    .collect();
                sun_pass.encode(&mut enc, &casting, &t.volume_sun_view);
                lap(&mut enc, &mut times.volume_shadow_ms)?;
            }
            // With volumes, shade into the image under them; each volume pass writes its own
            // result layer, and the composite pass sorts them per pixel over that image into
            // the colour target.
            let volumes = self
                .volume_composite
                .as_ref()
                .zip(t.composite.as_ref())
                .filter(|_| !self.volumes_hidden);
            let shaded = volumes.map_or(&t.colour_view, |(_, ct)| &ct.under_view);
            Self::encode_fullscreen(&mut enc, "shade", pipeline, bg, &[shaded, &t.data_view]);
            lap(&mut enc, &mut times.shade_ms)?;
            if let Some((cp, ct)) = volumes {
                for (i, vt) in t.volumes.iter().enumerate() {
                    Self::encode_fullscreen(
                        &mut enc,
                        "volume",
                        self.volumes[i].pipeline(gpu),
                        &vt.bg,
                        &[&ct.result_views[i], &ct.stats_views[i]],
                    );
                }
                Self::encode_fullscreen(
                    &mut enc,
                    "volume composite",
                    &cp.pipeline,
                    &ct.bg,
                    &[&t.colour_view],
                );
                lap(&mut enc, &mut times.volume_ms)?;
            }
            self.encode_blend(&mut enc, t);
            lap(&mut enc, &mut times.blend_ms)?;
        }
        gpu.queue.submit([enc.finish()]);
        Ok(times)
    }

    /// Records the edge blend, if any: copy the finished image aside, write it back blended.
    fn encode_blend(&self, enc: &mut wgpu::CommandEncoder, t: &Targets) {
        if let (Some(b), Some(bt)) = (&self.blend, &t.blend) {
            enc.copy_texture_to_texture(
                t.colour.as_image_copy(),
                bt.src.as_image_copy(),
                wgpu::Extent3d {
                    width: t.width,
                    height: t.height,
                    depth_or_array_layers: 1,
                },
            );
            Self::encode_fullscreen(enc, "blend", &b.pipeline, &bt.bg, &[&t.colour_view]);
        }
    }

    /// Renders one frame up to `stage` without reading it back (for benchmarks and the frame
    /// loop: the caller waits or presents).
    pub fn render(
        &mut self,
        gpu: &Gpu,
        terrain: &Terrain,
        scene: &SceneDesc,
        cam: &Camera,
        s: &RenderSettings,
        stage: Stage,
    ) -> Result<()> {
        self.run_passes(gpu, terrain, scene, cam, s, stage, false)
            .map(|_| ())
    }

    /// Renders one frame, timing each pass, and reads colour and data back.
    pub fn capture(
        &mut self,
        gpu: &Gpu,
        terrain: &Terrain,
        scene: &SceneDesc,
        cam: &Camera,
        s: &RenderSettings,
    ) -> Result<FrameOutput> {
        let mut times = self.run_passes(gpu, terrain, scene, cam, s, Stage::Shade, true)?;
        let start = Instant::now();
        let t = self.targets.as_ref().expect("targets exist after a render");
        let (w, h) = (t.width, t.height);
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let volume_shadows = s.shadows && self.volumes.iter().any(|v| v.casts_shadow());
        let mut copies = vec![
            (&t.colour, &t.colour_rb, 4u32),
            (&t.data, &t.data_rb, 16u32),
        ];
        if volume_shadows {
            copies.push((&t.volume_sun, &t.volume_sun_rb, 1));
        }
        for (tex, buf, bpp) in copies {
            enc.copy_texture_to_buffer(
                tex.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: buf,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(padded_row(w * bpp)),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
        }
        let volume_stats = t.composite.as_ref().filter(|_| !self.volumes_hidden);
        if let Some(ct) = volume_stats {
            enc.copy_texture_to_buffer(
                ct.stats.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &ct.stats_rb,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(padded_row(w * 16)),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: t.volumes.len() as u32,
                },
            );
        }
        gpu.queue.submit([enc.finish()]);
        let rgba = read_buffer(gpu, &t.colour_rb, w * 4, h)?;
        let data = read_buffer(gpu, &t.data_rb, w * 16, h)?;
        let volume_sun = if volume_shadows {
            read_buffer(gpu, &t.volume_sun_rb, w, h)?
        } else {
            Vec::new()
        };
        // Volume statistics, summed over the volumes (one image per layer).
        let mut stats: Vec<[u32; 2]> = Vec::new();
        if let Some(ct) = volume_stats {
            let layers = t.volumes.len() as u32;
            let bytes = read_buffer(gpu, &ct.stats_rb, w * 16, h * layers)?;
            stats.resize((w * h) as usize, [0, 0]);
            for layer in bytes.chunks_exact((w * h * 16) as usize) {
                for (s, px) in stats.iter_mut().zip(layer.chunks_exact(16)) {
                    let word =
                        |i: usize| u32::from_le_bytes([px[i], px[i + 1], px[i + 2], px[i + 3]]);
                    s[0] += word(0);
                    s[1] += word(4);
                }
            }
        }
        times.readback_ms = start.elapsed().as_secs_f64() * 1e3;
        let words: &[u32] = bytemuck::cast_slice(&data);
        let n = (w * h) as usize;
        let mut out = FrameOutput {
            width: w,
            height: h,
            rgba,
            depth: Vec::with_capacity(n),
            steps: Vec::with_capacity(n),
            patch_tests: Vec::with_capacity(n),
            shadow_steps: Vec::with_capacity(n),
            flags: Vec::with_capacity(n),
            objects: Vec::with_capacity(n),
            volume_samples: Vec::new(),
            volume_segments: Vec::new(),
            volume_sun,
            times,
        };
        for [samples, segments] in stats {
            out.volume_samples.push(samples);
            out.volume_segments.push(segments);
        }
        for px in words.chunks_exact(4) {
            out.depth.push(f32::from_bits(px[0]));
            out.steps.push(px[1]);
            out.patch_tests.push(px[2] & 0xffff);
            out.shadow_steps.push(px[2] >> 16);
            out.flags.push(px[3] & 0xff);
            out.objects.push(px[3] >> 8);
        }
        Ok(out)
    }
}

/// A 2-D single-sample texture of `size` pixels, for render targets and screen-sized data.
pub(crate) fn screen_texture(
    dev: &wgpu::Device,
    label: &str,
    size: [u32; 2],
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    dev.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

pub(crate) fn pipeline_layout(
    dev: &wgpu::Device,
    bgl: &wgpu::BindGroupLayout,
) -> wgpu::PipelineLayout {
    dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &[Some(bgl)],
        immediate_size: 0,
    })
}

pub(crate) fn target_state(format: wgpu::TextureFormat) -> wgpu::ColorTargetState {
    wgpu::ColorTargetState {
        format,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    }
}

/// A full-screen-triangle pipeline running `entry` of module `m` into `targets`.
pub(crate) fn fullscreen_pipeline(
    dev: &wgpu::Device,
    label: &str,
    m: &wgpu::ShaderModule,
    entry: &str,
    bgl: &wgpu::BindGroupLayout,
    targets: &[Option<wgpu::ColorTargetState>],
) -> wgpu::RenderPipeline {
    fullscreen_pipeline_with(dev, label, m, entry, bgl, targets, None)
}

/// [`fullscreen_pipeline`] with a depth-stencil state (the voxel passes' mask).
pub(crate) fn fullscreen_pipeline_with(
    dev: &wgpu::Device,
    label: &str,
    m: &wgpu::ShaderModule,
    entry: &str,
    bgl: &wgpu::BindGroupLayout,
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: Option<wgpu::DepthStencilState>,
) -> wgpu::RenderPipeline {
    render_pipeline(
        dev,
        label,
        m,
        ["vs_fullscreen", entry],
        bgl,
        targets,
        depth_stencil,
    )
}

/// A render pipeline of module `m` with vertex and fragment entry points `entries`, no vertex
/// buffers (the vertex shader makes its positions).
pub(crate) fn render_pipeline(
    dev: &wgpu::Device,
    label: &str,
    m: &wgpu::ShaderModule,
    entries: [&str; 2],
    bgl: &wgpu::BindGroupLayout,
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: Option<wgpu::DepthStencilState>,
) -> wgpu::RenderPipeline {
    let [vertex, entry] = entries;
    dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout(dev, bgl)),
        vertex: wgpu::VertexState {
            module: m,
            entry_point: Some(vertex),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: m,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

pub(crate) fn buf(binding: u32, b: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: b.as_entire_binding(),
    }
}

pub(crate) fn view(binding: u32, v: &wgpu::TextureView) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::TextureView(v),
    }
}

impl TerrainRenderer {
    /// Reads back the ray table of the last frame: per pixel (direction xyz, cone half-angle;
    /// negative where the pixel shows no screen). For tests and warp tools.
    pub fn read_ray_table(&self, gpu: &Gpu) -> Result<Vec<[f32; 4]>> {
        let t = self
            .targets
            .as_ref()
            .ok_or_else(|| Error::Gpu("no frame rendered yet".into()))?;
        let (w, h) = (t.width, t.height);
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ray table readback"),
            size: padded_row(w * 16) as u64 * h as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            t.ray_table.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded_row(w * 16)),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        gpu.queue.submit([enc.finish()]);
        let bytes = read_buffer(gpu, &buffer, w * 16, h)?;
        Ok(bytemuck::cast_slice::<u8, [f32; 4]>(&bytes).to_vec())
    }
}

pub(crate) fn padded_row(bytes: u32) -> u32 {
    bytes.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// Maps a readback buffer and returns its rows without padding.
fn read_buffer(gpu: &Gpu, buf: &wgpu::Buffer, row_bytes: u32, rows: u32) -> Result<Vec<u8>> {
    let (tx, rx) = std::sync::mpsc::channel();
    buf.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.wait()?;
    rx.recv()
        .map_err(|_| Error::Gpu("readback callback never ran".into()))?
        .map_err(|e| Error::Gpu(format!("mapping the readback buffer: {e}")))?;
    let out = {
        let view = buf
            .get_mapped_range(..)
            .map_err(|e| Error::Gpu(format!("readback range: {e}")))?;
        let stride = padded_row(row_bytes) as usize;
        let mut out = Vec::with_capacity(row_bytes as usize * rows as usize);
        for r in 0..rows as usize {
            out.extend_from_slice(&view[r * stride..r * stride + row_bytes as usize]);
        }
        out
    };
    buf.unmap();
    Ok(out)
}

fn v4(v: glam::DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
}

/// Pinhole ray-generation uniforms for a camera.
pub fn raygen_uniforms(cam: &Camera, display_eye: glam::DVec3) -> RayGenUniforms {
    let (r, d, f) = cam.basis();
    let (fx, fy, cx, cy) = cam.intrinsics();
    RayGenUniforms {
        right: v4(r, 0.0),
        down: v4(d, 0.0),
        forward: v4(f, 0.0),
        intrinsics: [fx as f32, fy as f32, cx as f32, cy as f32],
        size: [cam.width, cam.height, 0, 0],
        eye: v4(display_eye, 1.0),
    }
}

/// [`raygen_uniforms`] for table ray generation with a channel view offset: the basis
/// becomes the columns of `world_from_display · offset`.
pub fn table_raygen_uniforms(
    cam: &Camera,
    display_eye: glam::DVec3,
    offset: glam::DMat3,
) -> RayGenUniforms {
    let (r, d, f) = cam.basis();
    let m = glam::DMat3::from_cols(r, f, -d) * offset;
    RayGenUniforms {
        right: v4(m.col(0), 0.0),
        down: v4(-m.col(2), 0.0),
        forward: v4(m.col(1), 0.0),
        ..raygen_uniforms(cam, display_eye)
    }
}

/// The frame uniform block for a terrain, scene, camera and settings.
pub fn frame_uniforms(
    terrain: &Terrain,
    scene: &SceneDesc,
    cam: &Camera,
    s: &RenderSettings,
    tiles: [u32; 2],
) -> FrameUniforms {
    let fr = &terrain.frame;
    let [sx, sy] = fr.spacing;
    let eye = fr.world_to_grid(cam.pose.position);
    let sun = scene.sun.direction();
    let local =
        |v: glam::DVec3| glam::DVec3::new(v.dot(fr.axis_x), v.dot(fr.axis_y), v.dot(fr.normal));
    let fog_colour = scene.fog.colour.unwrap_or(scene.sky.horizon);
    let sigma = if scene.fog.visibility > 0.0 {
        3.912 / scene.fog.visibility
    } else {
        0.0
    };
    let mut levels = [[0u32; 4]; MAX_LEVELS];
    for (dst, l) in levels.iter_mut().zip(&terrain.pyramid.levels) {
        *dst = [l.cells[0], l.cells[1], l.stored[0], l.offset];
    }
    let (drape_map, drape_size) = match &terrain.drape {
        Some((d, m)) => (
            [
                m.offset[0] as f32,
                m.offset[1] as f32,
                m.scale[0] as f32,
                m.scale[1] as f32,
            ],
            [d.width as u32, d.height as u32, 0, 0],
        ),
        None => ([0.0; 4], [1, 1, 0, 0]),
    };
    let (mode, march) = match s.mode {
        TraceMode::Pyramid => (0, [0.0; 4]),
        TraceMode::March {
            step_cells,
            bisections,
        } => (1, [step_cells, bisections as f32, 0.0, 0.0]),
    };
    let c = |v: [f32; 3], w: f32| [v[0], v[1], v[2], w];
    FrameUniforms {
        eye: v4(eye, 1.0),
        grid_from_world: [
            v4(fr.axis_x / sx, 0.0),
            v4(fr.axis_y / sy, 0.0),
            v4(fr.normal, 0.0),
        ],
        local_from_world: [v4(fr.axis_x, 0.0), v4(fr.axis_y, 0.0), v4(fr.normal, 0.0)],
        sun_local: v4(local(sun), scene.sun.intensity as f64),
        sun_grid: v4(fr.world_dir_to_grid(sun), 0.0),
        sun_colour: c(scene.sun.colour, (0.27f64).to_radians().cos() as f32),
        up_local: v4(local(glam::DVec3::Z), 0.0),
        sky_zenith: c(scene.sky.zenith, scene.sky.ambient),
        sky_horizon: c(scene.sky.horizon, 0.0),
        fog_colour: c(fog_colour, sigma as f32),
        fog: [scene.fog.scale_height as f32, 0.0, 0.0, 0.0],
        spacing: [sx as f32, sy as f32, (1.0 / sx) as f32, (1.0 / sy) as f32],
        heights_range: [
            terrain.min_height,
            terrain.max_height,
            crate::cpu::query::shadow_offset(terrain) as f32,
            (4.0 * crate::cpu::traverse::height_slack(terrain)).max(1e-3) as f32,
        ],
        drape_map,
        size: [cam.width, cam.height, tiles[0], tiles[1]],
        grid: [
            terrain.field.width as u32,
            terrain.field.height as u32,
            terrain.pyramid.levels.len() as u32,
            0,
        ],
        mode: [
            mode,
            s.max_steps,
            (!terrain.walls) as u32,
            s.tile_prepass as u32,
        ],
        drape_size,
        march,
        pyramid_dims: [0; 4],
        eye_world: v4(cam.pose.position, 1.0),
        sun_world: v4(sun, 0.0),
        objects: [0; 4],
        stamp: [0; 4],
        levels,
    }
}

/// Each cell of every level of a [`square_pyramid`] replaced by the maximum of its 3x3
/// neighbourhood (cells outside the square count as PAD): the tile pre-pass's cone test.
pub fn dilate_square_pyramid(data: &[f32], n: u32) -> Vec<f32> {
    use rayon::prelude::*;
    let pad = crate::terrain::pyramid::PAD;
    let mut out = vec![pad; data.len()];
    let mut side = n as usize;
    let mut offset = 0usize;
    loop {
        let src = &data[offset..offset + side * side];
        // Separable: 3-wide row maxima, then 3-tall column maxima of those.
        let mut rows = vec![pad; side * side];
        rows.par_chunks_mut(side).enumerate().for_each(|(j, row)| {
            let s = &src[j * side..][..side];
            for (i, out) in row.iter_mut().enumerate() {
                *out = s[i.saturating_sub(1)..=(i + 1).min(side - 1)]
                    .iter()
                    .copied()
                    .fold(pad, f32::max);
            }
        });
        out[offset..offset + side * side]
            .par_chunks_mut(side)
            .enumerate()
            .for_each(|(j, dst)| {
                let (lo, hi) = (j.saturating_sub(1), (j + 1).min(side - 1));
                for (i, out) in dst.iter_mut().enumerate() {
                    *out = (lo..=hi).map(|jj| rows[jj * side + i]).fold(pad, f32::max);
                }
            });
        offset += side * side;
        if side == 1 {
            break;
        }
        side /= 2;
    }
    out
}

/// The maximum pyramid re-laid for the GPU as a square power-of-two mip chain: level L has side
/// `N >> L` (N = the next power of two of the larger cell count), starts at
/// `4 (N² − (N >> L)²) / 3` and is padded with [`crate::terrain::pyramid::PAD`]. Returns the data and N.
pub fn square_pyramid(terrain: &Terrain) -> (Vec<f32>, u32) {
    let pyr = &terrain.pyramid;
    let cells = pyr.levels[0].cells;
    let n = cells[0].max(cells[1]).next_power_of_two();
    debug_assert_eq!(pyr.levels.len() as u32, 32 - n.leading_zeros());
    let total = (4 * (n as u64 * n as u64) - 1) / 3 + 1;
    let mut data = vec![crate::terrain::pyramid::PAD; total as usize];
    for (l, level) in pyr.levels.iter().enumerate() {
        let side = (n >> l) as u64;
        let offset = (n as u64 * n as u64 - side * side) / 3 * 4;
        for j in 0..level.cells[1] as u64 {
            let src = &pyr.data[(level.offset as u64 + j * level.stored[0] as u64) as usize..]
                [..level.cells[0] as usize];
            data[(offset + j * side) as usize..][..src.len()].copy_from_slice(src);
        }
    }
    (data, n)
}

/// Access to the last frame's targets, for callers that present them (the window).
impl TerrainRenderer {
    /// Size of the current targets, once a frame has been rendered.
    pub fn target_size(&self) -> Option<(u32, u32)> {
        self.targets.as_ref().map(|t| (t.width, t.height))
    }

    /// The colour target (Rgba8Unorm holding sRGB-encoded values, row 0 at the top).
    pub fn colour_view(&self) -> Option<&wgpu::TextureView> {
        self.targets.as_ref().map(|t| &t.colour_view)
    }

    /// The data target (Rgba32Uint: depth bits, steps, patch tests | shadow steps << 16, flags).
    pub fn data_view(&self) -> Option<&wgpu::TextureView> {
        self.targets.as_ref().map(|t| &t.data_view)
    }
}
