//! Helpers every pass uses: bind-group-layout entries, bind-group entries, pipelines, screen
//! textures, full-screen draws, buffer limits and readback.

use super::{Gpu, ParamSpace};
use crate::{Error, Result};

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

/// A bind-group entry for a write-only 2-D storage texture of `format`.
pub(crate) fn storage_texture_entry(
    binding: u32,
    vis: wgpu::ShaderStages,
    format: wgpu::TextureFormat,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

/// A bind-group entry for a parameter block (`var<uniform>` in WGSL) bound in `space`.
pub(crate) fn uniform_entry(
    space: ParamSpace,
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

/// Checks that a storage buffer of `bytes` fits the device; the error names the data, the
/// limit and `fix` (what the user can make smaller).
pub fn check_buffer_limit(gpu: &Gpu, what: &str, bytes: u64, fix: &str) -> Result<()> {
    let limit = gpu
        .limits
        .max_storage_buffer_binding_size
        .min(gpu.limits.max_buffer_size);
    if bytes > limit {
        return Err(Error::Limit {
            what: what.to_string(),
            msg: format!(
                "{bytes} bytes needed, the adapter {} allows {limit} bytes per storage buffer; {fix}",
                gpu.info.name
            ),
        });
    }
    Ok(())
}

/// A 2-D single-sample texture of `size` pixels, for render targets and screen-sized data.
/// Usages of a pass's target that other passes read and copies come from and go to.
pub(crate) const TARGET_USAGE: wgpu::TextureUsages = wgpu::TextureUsages::RENDER_ATTACHMENT
    .union(wgpu::TextureUsages::TEXTURE_BINDING)
    .union(wgpu::TextureUsages::COPY_SRC)
    .union(wgpu::TextureUsages::COPY_DST);

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
    let layout = pipeline_layout(dev, bgl);
    render_pipeline_in(dev, label, m, entries, &layout, targets, depth_stencil)
}

/// The pipeline layout of group 0 `bgl` and, where given, group 3 `group3` (the paged
/// terrain's tile pool, `terrain_paged.wgsl`; groups 1 and 2 empty).
pub(crate) fn pipeline_layout_with(
    dev: &wgpu::Device,
    bgl: &wgpu::BindGroupLayout,
    group3: Option<&wgpu::BindGroupLayout>,
) -> wgpu::PipelineLayout {
    match group3 {
        None => pipeline_layout(dev, bgl),
        Some(g3) => dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: &[Some(bgl), None, None, Some(g3)],
            immediate_size: 0,
        }),
    }
}

/// [`render_pipeline`] with an explicit pipeline layout.
pub(crate) fn render_pipeline_in(
    dev: &wgpu::Device,
    label: &str,
    m: &wgpu::ShaderModule,
    entries: [&str; 2],
    layout: &wgpu::PipelineLayout,
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: Option<wgpu::DepthStencilState>,
) -> wgpu::RenderPipeline {
    let primitive = wgpu::PrimitiveState::default();
    pipeline_of(
        dev,
        label,
        (m, entries),
        layout,
        primitive,
        targets,
        depth_stencil,
    )
}

fn pipeline_of(
    dev: &wgpu::Device,
    label: &str,
    (m, [vertex, entry]): (&wgpu::ShaderModule, [&str; 2]),
    layout: &wgpu::PipelineLayout,
    primitive: wgpu::PrimitiveState,
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: Option<wgpu::DepthStencilState>,
) -> wgpu::RenderPipeline {
    dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module: m,
            entry_point: Some(vertex),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive,
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

/// Records one full-screen-triangle draw of `pipeline` into the colour targets `views`.
pub(crate) fn encode_fullscreen(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    pipeline: &wgpu::RenderPipeline,
    bg: &wgpu::BindGroup,
    views: &[&wgpu::TextureView],
) {
    encode_fullscreen_with(enc, label, pipeline, bg, None, views);
}

/// [`encode_fullscreen`] with bind group 3 `group3` (the paged terrain's tile pool) set too.
pub(crate) fn encode_fullscreen_with(
    enc: &mut wgpu::CommandEncoder,
    label: &str,
    pipeline: &wgpu::RenderPipeline,
    bg: &wgpu::BindGroup,
    group3: Option<&wgpu::BindGroup>,
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
    if let Some(g3) = group3 {
        pass.set_bind_group(3, g3, &[]);
    }
    pass.draw(0..3, 0..1);
}

pub(crate) fn padded_row(bytes: u32) -> u32 {
    bytes.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// A mappable buffer for `rows` rows of `row_bytes` each, every row padded as a copy from a
/// texture needs ([`copy_to_readback`], then [`read_buffer`]).
pub(crate) fn readback_buffer(
    dev: &wgpu::Device,
    label: &str,
    row_bytes: u32,
    rows: u32,
) -> wgpu::Buffer {
    dev.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: u64::from(padded_row(row_bytes)) * u64::from(rows),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    })
}

/// Records a copy of all of the 2-D `texture` (`row_bytes` a row) into `buffer`
/// ([`readback_buffer`]).
pub(crate) fn copy_to_readback(
    enc: &mut wgpu::CommandEncoder,
    texture: &wgpu::Texture,
    buffer: &wgpu::Buffer,
    row_bytes: u32,
) {
    let size = texture.size();
    enc.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded_row(row_bytes)),
                rows_per_image: Some(size.height),
            },
        },
        wgpu::Extent3d {
            depth_or_array_layers: 1,
            ..size
        },
    );
}

/// Maps a readback buffer and returns its rows without padding.
pub(crate) fn read_buffer(
    gpu: &Gpu,
    buf: &wgpu::Buffer,
    row_bytes: u32,
    rows: u32,
) -> Result<Vec<u8>> {
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
