//! Density volumes on the GPU, three passes:
//! * volume-sun (`VolumeSunPass`, before shading): per pixel, the sun's transmittance through
//!   the volumes at the opaque surface, which the shade pass scales the sun's terms by;
//! * volume (`VolumePass`, one per volume, after shading): one density volume uploaded once
//!   (RGBA8 3-D texture with mip levels, transfer table, brick occupancy, shadow grids),
//!   integrated per pixel in front of the opaque depth into its own result layer;
//! * composite (`CompositePass`): the layers sorted per pixel by the medium's depth and
//!   composited over the shaded image.

use super::specialise::SpecialisedPipelines;
use super::types::VolumeUniforms;
use super::util::{
    buf, check_buffer_limit, float_texture_entry, fullscreen_pipeline, padded_row, screen_texture,
    storage_entry, target_state, uint_texture_entry, uniform_entry, view,
};
use super::variants::VolumeSwitches;
use super::{shaders, Gpu, PARAM_USAGE};
use crate::volume::transfer::TABLE_SIZE;
use crate::volume::Volume;
use crate::{Error, Result};
use wgpu::util::DeviceExt;

/// Format of the per-pixel statistics target (samples taken, segments passed, f32 bits of the
/// medium's depth).
pub const STATS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;

/// Format of the per-pixel result target (f32 bits of `P` and `T`).
pub const RESULT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;

/// Format of the volume-sun target: per pixel, the sun's transmittance through the volumes
/// for the opaque surface there (the shade pass reads it).
pub const SUN_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Unorm;

/// The volume-sun pass (`volume_sun.wgsl`), one draw per shadow-casting volume: the first
/// writes the target, each further one multiplies into it (optical depths add, so the product
/// is exact where boxes overlap too).
pub(crate) struct VolumeSunPass {
    bgl: wgpu::BindGroupLayout,
    write: wgpu::RenderPipeline,
    multiply: wgpu::RenderPipeline,
}

impl VolumeSunPass {
    pub fn new(gpu: &Gpu) -> VolumeSunPass {
        let dev = &gpu.device;
        let fs = wgpu::ShaderStages::FRAGMENT;
        let bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volume sun"),
            entries: &[
                uniform_entry(gpu.params, 0, fs),
                uint_texture_entry(3, fs),
                uint_texture_entry(4, fs),
                uniform_entry(gpu.params, 16, fs),
                filterable_3d_entry(17),
                sampler_entry(18),
            ],
        });
        let m = super::shader_module(dev, gpu.params, "volume_sun.wgsl", &shaders::volume_sun());
        let pipeline = |label, blend| {
            fullscreen_pipeline(
                dev,
                label,
                &m,
                "fs_volume_sun",
                &bgl,
                &[Some(wgpu::ColorTargetState {
                    format: SUN_FORMAT,
                    blend,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            )
        };
        let times_target = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::Dst,
            dst_factor: wgpu::BlendFactor::Zero,
            operation: wgpu::BlendOperation::Add,
        };
        VolumeSunPass {
            write: pipeline("volume sun", None),
            multiply: pipeline(
                "volume sun (multiply)",
                Some(wgpu::BlendState {
                    color: times_target,
                    alpha: times_target,
                }),
            ),
            bgl,
        }
    }

    /// Records one render pass into `target` with a draw per bind group in `bind_groups` (one
    /// per shadow-casting volume; none records nothing).
    pub fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        bind_groups: &[&wgpu::BindGroup],
        target: &wgpu::TextureView,
    ) {
        let Some((first, rest)) = bind_groups.split_first() else {
            return;
        };
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("volume sun"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    // SAFETY: the first draw covers every pixel (full-screen triangle, no
                    // discard) and writes without blending, so nothing stale is read or stored.
                    load: wgpu::LoadOp::DontCare(unsafe { wgpu::LoadOpDontCare::enabled() }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.write);
        pass.set_bind_group(0, *first, &[]);
        pass.draw(0..3, 0..1);
        pass.set_pipeline(&self.multiply);
        for bg in rest {
            pass.set_bind_group(0, *bg, &[]);
            pass.draw(0..3, 0..1);
        }
    }
}

fn filterable_3d_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D3,
            multisampled: false,
        },
        count: None,
    }
}

fn sampler_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

/// GPU resources of one volume and the pass that integrates it.
pub(crate) struct VolumePass {
    pub volume: Volume,
    /// Rigid offset of the volume from where it was placed, this frame (the curved earth's
    /// drop at its anchor): the uniforms see the eye moved the other way.
    pub offset: glam::DVec3,
    bgl: wgpu::BindGroupLayout,
    pipelines: SpecialisedPipelines<VolumeSwitches>,
    view: wgpu::TextureView,
    /// The sun's transmittance per cell that the samples are lit with, through this volume and
    /// the others (`SunShadow::lit_data`; R8, a 1x1x1 texture without self-shadowing).
    shadow: wgpu::Texture,
    shadow_view: wgpu::TextureView,
    /// Through this volume alone (`SunShadow::data`): what the volume-sun pass reads.
    surface_shadow: wgpu::Texture,
    surface_shadow_view: wgpu::TextureView,
    linear: wgpu::Sampler,
    /// Nearest texel, nearest level: reads one texel of a chosen level (see `vol_texel`).
    nearest: wgpu::Sampler,
    table: wgpu::Buffer,
    bricks: wgpu::Buffer,
    uniforms: wgpu::Buffer,
}

/// Size-dependent bind groups of one volume's passes.
pub(crate) struct VolumeTargets {
    pub bg: wgpu::BindGroup,
    /// The volume-sun pass's bind group for this volume.
    pub sun_bg: wgpu::BindGroup,
}

/// The composite pass (`volume_composite.wgsl`) for a scene's volumes: per pixel, their
/// results sorted by the medium's depth and composited over the shaded image.
pub(crate) struct CompositePass {
    count: u32,
    bgl: wgpu::BindGroupLayout,
    pub pipeline: wgpu::RenderPipeline,
}

/// Size-dependent resources shared by the volume passes: the shaded image under the volumes,
/// and per volume (array layer) its result and statistics.
pub(crate) struct CompositeTargets {
    /// Kept with its view for the targets' lifetime.
    _under: wgpu::Texture,
    pub under_view: wgpu::TextureView,
    _results: wgpu::Texture,
    /// One render view per volume.
    pub result_views: Vec<wgpu::TextureView>,
    pub stats: wgpu::Texture,
    pub stats_views: Vec<wgpu::TextureView>,
    /// Every layer's statistics, one image after the other.
    pub stats_rb: wgpu::Buffer,
    pub bg: wgpu::BindGroup,
}

impl CompositePass {
    /// The pass for `count` volumes (1 ..= `MAX_VOLUMES`).
    pub fn new(gpu: &Gpu, count: u32) -> CompositePass {
        let dev = &gpu.device;
        let fs = wgpu::ShaderStages::FRAGMENT;
        let array = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: fs,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Uint,
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
            count: None,
        };
        let bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volume composite"),
            entries: &[
                uniform_entry(gpu.params, 0, fs),
                float_texture_entry(1, fs, wgpu::TextureViewDimension::D2),
                array(2),
                array(3),
            ],
        });
        let m = super::shader_module(
            dev,
            gpu.params,
            "volume_composite.wgsl",
            &shaders::volume_composite(count),
        );
        let pipeline = fullscreen_pipeline(
            dev,
            "volume composite",
            &m,
            "fs_composite",
            &bgl,
            &[Some(target_state(wgpu::TextureFormat::Rgba8Unorm))],
        );
        CompositePass {
            count,
            bgl,
            pipeline,
        }
    }

    pub fn targets(
        &self,
        gpu: &Gpu,
        width: u32,
        height: u32,
        frame_ub: &wgpu::Buffer,
    ) -> CompositeTargets {
        let dev = &gpu.device;
        // COPY_DST: anti-aliasing keeps the centre frame's statistics aside and puts them back.
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST;
        let under = screen_texture(
            dev,
            "colour under the volumes",
            [width, height],
            wgpu::TextureFormat::Rgba8Unorm,
            usage,
        );
        let under_view = under.create_view(&Default::default());
        // At least two layers: wgpu's GL backend fixes a texture's view dimension when it is
        // created and takes a one-layer 2-D texture for `D2`, so the composite pass's
        // `D2Array` view of a single volume's layer would read nothing (all-black frames).
        let layers = |label, format| {
            let tex = dev.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: self.count.max(2),
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            });
            let per_layer: Vec<_> = (0..self.count)
                .map(|m| {
                    tex.create_view(&wgpu::TextureViewDescriptor {
                        dimension: Some(wgpu::TextureViewDimension::D2),
                        base_array_layer: m,
                        array_layer_count: Some(1),
                        ..Default::default()
                    })
                })
                .collect();
            let all = tex.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            });
            (tex, per_layer, all)
        };
        let (results, result_views, results_all) = layers("volume results", RESULT_FORMAT);
        let (stats, stats_views, stats_all) = layers("volume statistics", STATS_FORMAT);
        let bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volume composite"),
            layout: &self.bgl,
            entries: &[
                buf(0, frame_ub),
                view(1, &under_view),
                view(2, &results_all),
                view(3, &stats_all),
            ],
        });
        let stats_rb = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("volume statistics readback"),
            size: padded_row(width * 16) as u64 * height as u64 * self.count as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        CompositeTargets {
            _under: under,
            under_view,
            _results: results,
            result_views,
            stats,
            stats_views,
            stats_rb,
            bg,
        }
    }
}

/// The transfer table as the uniform array `vol_table` (`VOL_TABLE` = [`TABLE_SIZE`] vec4s;
/// a uniform binding must hold the whole declared array). In a uniform buffer, not a storage
/// buffer: two table entries per sample are loaded at a per-pixel index (see
/// `gpu::objects::FfTables` for why that matters on Mesa's CPU adapters).
fn table_bytes(v: &Volume) -> Vec<u8> {
    let mut entries = v.table.entries.clone();
    entries.resize(TABLE_SIZE, [0.0; 4]);
    bytemuck::cast_slice(&entries).to_vec()
}

impl VolumePass {
    /// Uploads `volume` (texture with its mip levels, shadow grids, transfer table, brick
    /// occupancy) and makes its pass; the pipelines are built on first use.
    pub fn new(gpu: &Gpu, volume: &Volume) -> Result<VolumePass> {
        check_volume_limits(gpu, volume)?;
        let dev = &gpu.device;
        let view = upload_texture(gpu, volume).create_view(&Default::default());
        let shadow = shadow_texture(gpu, volume, |sh| sh.lit_data());
        let shadow_view = shadow.create_view(&Default::default());
        let surface_shadow = shadow_texture(gpu, volume, |sh| &sh.data);
        let surface_shadow_view = surface_shadow.create_view(&Default::default());
        // The transmittance is smooth: the sampler's 8-bit filter weights stay within a
        // fraction of a level of the CPU reference's exact trilinear weights.
        let linear = dev.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("volume shadow"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let nearest = dev.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("volume texel"),
            ..Default::default()
        });
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let table = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("transfer table"),
            contents: &table_bytes(volume),
            usage: PARAM_USAGE,
        });
        let bricks = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("volume bricks"),
            contents: bytemuck::cast_slice(&volume.occupancy),
            usage: storage,
        });
        let uniforms = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("volume uniforms"),
            size: std::mem::size_of::<VolumeUniforms>() as u64,
            usage: PARAM_USAGE,
            mapped_at_creation: false,
        });
        let bgl = volume_layout(gpu);
        let pipelines = SpecialisedPipelines::new(
            gpu.params,
            "volume",
            shaders::volume,
            "fs_volume",
            bgl.clone(),
            vec![
                Some(target_state(RESULT_FORMAT)),
                Some(target_state(STATS_FORMAT)),
            ],
        );
        Ok(VolumePass {
            volume: volume.clone(),
            offset: glam::DVec3::ZERO,
            bgl,
            pipelines,
            view,
            shadow,
            shadow_view,
            surface_shadow,
            surface_shadow_view,
            linear,
            nearest,
            table,
            bricks,
            uniforms,
        })
    }

    /// Reclassifies the volume with a new transfer function (table, brick occupancy and
    /// self-shadowing).
    pub fn set_transfer(&mut self, gpu: &Gpu, tf: crate::volume::TransferFunction) {
        self.volume.set_transfer(tf);
        self.upload_shadows(gpu);
        gpu.queue
            .write_buffer(&self.table, 0, &table_bytes(&self.volume));
        gpu.queue.write_buffer(
            &self.bricks,
            0,
            bytemuck::cast_slice(&self.volume.occupancy),
        );
    }

    /// Builds the pipeline for the volume's current sampling switches unless it exists;
    /// returns its index for [`VolumePass::pipeline`].
    pub fn prepare(&mut self, gpu: &Gpu) -> usize {
        self.pipelines
            .prepare(&gpu.device, VolumeSwitches::on(&self.volume, &gpu.info))
    }

    /// A pipeline [`VolumePass::prepare`] returned the index of.
    pub fn pipeline(&self, index: usize) -> &wgpu::RenderPipeline {
        self.pipelines.get(index)
    }

    /// Uploads the per-frame uniforms for an eye at world position `eye`.
    pub fn write_uniforms(&self, gpu: &Gpu, eye: glam::DVec3) {
        gpu.queue.write_buffer(
            &self.uniforms,
            0,
            bytemuck::bytes_of(&uniforms(&self.volume, eye - self.offset)),
        );
    }

    /// Uploads the shadow grids again (after reclassification, or after
    /// [`crate::volume::desc::shadow_each_other`] changed what the samples are lit with).
    pub fn upload_shadows(&self, gpu: &Gpu) {
        if let Some(sh) = &self.volume.sun_shadow {
            write_shadow(gpu, &self.shadow, sh.dims, sh.lit_data());
            write_shadow(gpu, &self.surface_shadow, sh.dims, &sh.data);
        }
    }

    /// Whether the volume shadows what lies below it (it has a self-shadowing grid).
    pub fn casts_shadow(&self) -> bool {
        self.volume.sun_shadow.is_some()
    }

    /// Bind groups for a frame's targets: `data` is the capture data the volume pass reads
    /// (opaque depth), `gbuffer` the final G-buffer the volume-sun pass reads.
    pub fn targets(
        &self,
        gpu: &Gpu,
        frame_ub: &wgpu::Buffer,
        ray_table: &wgpu::TextureView,
        data: &wgpu::TextureView,
        sun_pass: &VolumeSunPass,
        gbuffer: &wgpu::TextureView,
    ) -> VolumeTargets {
        let dev = &gpu.device;
        let bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volume"),
            layout: &self.bgl,
            entries: &[
                buf(0, frame_ub),
                view(3, ray_table),
                view(11, data),
                view(12, &self.view),
                buf(14, &self.table),
                buf(15, &self.bricks),
                buf(16, &self.uniforms),
                view(17, &self.shadow_view),
                wgpu::BindGroupEntry {
                    binding: 18,
                    resource: wgpu::BindingResource::Sampler(&self.linear),
                },
                wgpu::BindGroupEntry {
                    binding: 20,
                    resource: wgpu::BindingResource::Sampler(&self.nearest),
                },
            ],
        });
        let sampler = wgpu::BindingResource::Sampler(&self.linear);
        let sun_bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volume sun"),
            layout: &sun_pass.bgl,
            entries: &[
                buf(0, frame_ub),
                view(3, ray_table),
                view(4, gbuffer),
                buf(16, &self.uniforms),
                view(17, &self.surface_shadow_view),
                wgpu::BindGroupEntry {
                    binding: 18,
                    resource: sampler,
                },
            ],
        });
        VolumeTargets { bg, sun_bg }
    }
}

/// Refuses a volume over the adapter's 3-D texture or storage-buffer limits or 2 GiB of texture.
fn check_volume_limits(gpu: &Gpu, volume: &Volume) -> Result<()> {
    let max3 = gpu.limits.max_texture_dimension_3d;
    let dims = volume.grid.dims;
    if dims.iter().any(|&d| d > max3) {
        return Err(Error::Limit {
            what: format!("volume {:?}", volume.name),
            msg: format!(
                "{}x{}x{} voxels; the adapter {} allows {max3} per side of a 3-D texture: \
                 downsample the volume",
                dims[0], dims[1], dims[2], gpu.info.name
            ),
        });
    }
    let bytes: u64 = volume
        .texture
        .levels
        .iter()
        .map(|l| l.texels.len() as u64 * 4)
        .sum();
    if bytes > 2 << 30 {
        return Err(Error::Limit {
            what: format!("volume {:?}", volume.name),
            msg: format!("{bytes} bytes of texture; at most 2 GiB"),
        });
    }
    check_buffer_limit(
        gpu,
        "volume brick grid",
        volume.occupancy.len() as u64 * 4,
        "use a smaller or downsampled volume",
    )?;
    Ok(())
}

/// The volume's RGBA8 3-D texture with every mip level written.
fn upload_texture(gpu: &Gpu, volume: &Volume) -> wgpu::Texture {
    let dims = volume.grid.dims;
    let tex = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("volume"),
        size: wgpu::Extent3d {
            width: dims[0],
            height: dims[1],
            depth_or_array_layers: dims[2],
        },
        mip_level_count: volume.texture.levels.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D3,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (i, l) in volume.texture.levels.iter().enumerate() {
        gpu.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &tex,
                mip_level: i as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(&l.texels),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(l.dims[0] * 4),
                rows_per_image: Some(l.dims[1]),
            },
            wgpu::Extent3d {
                width: l.dims[0],
                height: l.dims[1],
                depth_or_array_layers: l.dims[2],
            },
        );
    }
    tex
}

/// The volume pass's bind-group layout.
fn volume_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let fs = wgpu::ShaderStages::FRAGMENT;
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volume"),
            entries: &[
                uniform_entry(gpu.params, 0, fs),
                uint_texture_entry(3, fs),
                uint_texture_entry(11, fs),
                float_texture_entry(12, fs, wgpu::TextureViewDimension::D3),
                uniform_entry(gpu.params, 14, fs),
                storage_entry(15, fs, true),
                uniform_entry(gpu.params, 16, fs),
                filterable_3d_entry(17),
                sampler_entry(18),
                wgpu::BindGroupLayoutEntry {
                    binding: 20,
                    visibility: fs,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::NonFiltering),
                    count: None,
                },
            ],
        })
}

/// A shadow texture of `volume`: the transmittance bytes `grid` picks, or one fully lit texel.
fn shadow_texture(
    gpu: &Gpu,
    volume: &Volume,
    grid: impl Fn(&crate::volume::shadow::SunShadow) -> &[u8],
) -> wgpu::Texture {
    let one = [255u8];
    let (dims, data): ([u32; 3], &[u8]) = match &volume.sun_shadow {
        Some(sh) => (sh.dims, grid(sh)),
        None => ([1, 1, 1], &one),
    };
    let tex = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("volume sun transmittance"),
        size: wgpu::Extent3d {
            width: dims[0],
            height: dims[1],
            depth_or_array_layers: dims[2],
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D3,
        format: wgpu::TextureFormat::R8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    write_shadow(gpu, &tex, dims, data);
    tex
}

fn write_shadow(gpu: &Gpu, tex: &wgpu::Texture, dims: [u32; 3], data: &[u8]) {
    let size = tex.size();
    if [size.width, size.height, size.depth_or_array_layers] != dims {
        // A volume built without a grid keeps its 1x1x1 texture (fully lit).
        return;
    }
    gpu.queue.write_texture(
        tex.as_image_copy(),
        data,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(dims[0]),
            rows_per_image: Some(dims[1]),
        },
        wgpu::Extent3d {
            width: dims[0],
            height: dims[1],
            depth_or_array_layers: dims[2],
        },
    );
}

/// The uniform block for `v` seen from world position `eye`.
pub fn uniforms(v: &Volume, eye: glam::DVec3) -> VolumeUniforms {
    let f = |x: f64| x as f32;
    let row = |r: glam::DVec3, w: f64| [f(r.x), f(r.y), f(r.z), f(w)];
    let lw = v.rotation.transpose();
    let ext = v.extent();
    let sp = v.grid.spacing;
    let s = &v.settings;
    let m = &v.material;
    let (sc, sr) = v.shell.unwrap_or((glam::DVec3::ZERO, glam::DVec3::ONE));
    VolumeUniforms {
        eye_local: row(v.to_local(eye), s.step * v.voxel()),
        local_from_world: [
            row(lw.row(0), 0.0),
            row(lw.row(1), 0.0),
            row(lw.row(2), 0.0),
        ],
        // WGSL sums these weighted by the local vector's components: the rotation's columns.
        world_from_local: [
            row(v.rotation.col(0), 0.0),
            row(v.rotation.col(1), 0.0),
            row(v.rotation.col(2), 0.0),
        ],
        extent: row(ext, v.voxel()),
        spacing: [f(sp[0]), f(sp[1]), f(sp[2]), f(s.epsilon)],
        dims: [
            v.grid.dims[0],
            v.grid.dims[1],
            v.grid.dims[2],
            v.texture.levels.len() as u32,
        ],
        bricks: [
            v.bricks.dims[0],
            v.bricks.dims[1],
            v.bricks.dims[2],
            // Unused: the pass is built with its switches (`VolumeSwitches`).
            0,
        ],
        material: [f(m.ambient), f(m.diffuse), f(m.specular), f(m.shininess)],
        shell_centre: row(sc, 0.0),
        shell_radii: row(sr, 0.0),
    }
}
