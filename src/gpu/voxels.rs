//! Voxel-model passes: brick tables, brick pool and palettes uploaded once, instance records
//! rewritten per frame (eye in voxel units computed in f64, animation frame), and four
//! full-screen fragment passes behind a stencil mask: mark the pixels whose ray enters a model
//! box before the current hit, cast the hierarchical DDA there (nearest voxel replaces the
//! G-buffer hit), and for shadows mark the pixels whose sun ray enters a model box and set
//! flag 64 where a voxel blocks the sun. The G-buffer is copied in and back around each masked
//! pass, so the rest of the renderer sees one G-buffer.

use super::renderer::{
    buf, fullscreen_pipeline_with, screen_texture, storage_entry, target_state, uint_texture_entry,
    uniform_entry, view,
};
use super::types::VoxInstanceGpu;
use super::{shaders, Gpu};
use crate::voxel::{VoxelInstance, VoxelModel, BRICK_VOXELS, EMPTY_BRICK};
use crate::{Error, Result};
use std::collections::HashMap;
use std::sync::Arc;
use wgpu::util::DeviceExt;

// Every scene's instance records fit the smallest uniform binding WebGPU guarantees (16 KiB).
const _: () =
    assert!(crate::voxel::desc::MAX_INSTANCES * std::mem::size_of::<VoxInstanceGpu>() <= 16384);

const STENCIL_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth24PlusStencil8;

fn stencil_state(write: bool) -> wgpu::DepthStencilState {
    let face = wgpu::StencilFaceState {
        compare: if write {
            wgpu::CompareFunction::Always
        } else {
            wgpu::CompareFunction::Equal
        },
        fail_op: wgpu::StencilOperation::Keep,
        depth_fail_op: wgpu::StencilOperation::Keep,
        pass_op: if write {
            wgpu::StencilOperation::Replace
        } else {
            wgpu::StencilOperation::Keep
        },
    };
    wgpu::DepthStencilState {
        format: STENCIL_FORMAT,
        depth_write_enabled: Some(false),
        depth_compare: Some(wgpu::CompareFunction::Always),
        stencil: wgpu::StencilState {
            front: face,
            back: face,
            read_mask: 0xff,
            write_mask: 0xff,
        },
        bias: Default::default(),
    }
}

/// A full-screen pipeline behind (or, without a colour target, writing) the stencil mask.
fn masked_pipeline(
    dev: &wgpu::Device,
    label: &str,
    m: &wgpu::ShaderModule,
    entry: &str,
    bgl: &wgpu::BindGroupLayout,
    target: Option<wgpu::TextureFormat>,
) -> wgpu::RenderPipeline {
    let targets: Vec<Option<wgpu::ColorTargetState>> =
        target.map(|f| Some(target_state(f))).into_iter().collect();
    fullscreen_pipeline_with(
        dev,
        label,
        m,
        entry,
        bgl,
        &targets,
        Some(stencil_state(target.is_none())),
    )
}

/// Where one frame's data lies in the shared buffers.
#[derive(Clone, Copy, Debug)]
struct FrameRef {
    table: u32,
    palette: u32,
}

/// Uploaded voxel data and the pipelines.
pub(crate) struct VoxelPasses {
    instances: Vec<VoxelInstance>,
    frames: Vec<Vec<FrameRef>>,
    instance_buf: wgpu::Buffer,
    bricks: wgpu::Buffer,
    pool: wgpu::Buffer,
    palette: wgpu::Buffer,
    bgl: wgpu::BindGroupLayout,
    mark: wgpu::RenderPipeline,
    cast: wgpu::RenderPipeline,
    mark_shadow: wgpu::RenderPipeline,
    shadow: wgpu::RenderPipeline,
}

/// Size-dependent resources.
pub(crate) struct VoxelTargets {
    gbuffer: wgpu::Texture,
    gbuffer_view: wgpu::TextureView,
    stencil_view: wgpu::TextureView,
    bg: wgpu::BindGroup,
}

impl VoxelPasses {
    pub fn new(gpu: &Gpu, instances: &[VoxelInstance]) -> Result<VoxelPasses> {
        let dev = &gpu.device;
        if instances.len() > crate::voxel::desc::MAX_INSTANCES {
            return Err(Error::Limit {
                what: "voxel models".into(),
                msg: format!(
                    "{} placed, at most {}",
                    instances.len(),
                    crate::voxel::desc::MAX_INSTANCES
                ),
            });
        }
        let have = gpu.limits.max_storage_buffers_per_shader_stage;
        if have < 4 {
            return Err(Error::Limit {
                what: "storage buffers per shader stage".into(),
                msg: format!(
                    "voxel models need 4, the adapter {} allows {have}; render the scene without [[voxels]]",
                    gpu.info.name
                ),
            });
        }
        let limit = gpu
            .limits
            .max_storage_buffer_binding_size
            .min(gpu.limits.max_buffer_size);
        let check = |what: &str, bytes: u64| -> Result<()> {
            if bytes > limit {
                return Err(Error::Limit {
                    what: what.to_string(),
                    msg: format!(
                        "{bytes} bytes needed, the adapter {} allows {limit} bytes per storage buffer; use smaller voxel models or fewer animation frames",
                        gpu.info.name
                    ),
                });
            }
            Ok(())
        };
        // Brick tables first, from the sizes alone (before anything large is built).
        let mut unique = std::collections::HashSet::new();
        let table_bytes: u64 = instances
            .iter()
            .flat_map(|i| &i.frames)
            .filter(|f| unique.insert(Arc::as_ptr(f)))
            .map(|f| {
                f.dims
                    .iter()
                    .map(|&d| d.div_ceil(crate::voxel::BRICK) as u64)
                    .product::<u64>()
                    * 4
            })
            .sum();
        check("voxel brick tables", table_bytes)?;
        let mut table: Vec<u32> = Vec::new();
        let mut pool: Vec<u8> = Vec::new();
        let mut palette: Vec<u32> = Vec::new();
        let mut seen: HashMap<*const VoxelModel, FrameRef> = HashMap::new();
        let mut frames = Vec::new();
        for inst in instances {
            let mut refs = Vec::new();
            for f in &inst.frames {
                if let Some(r) = seen.get(&Arc::as_ptr(f)) {
                    refs.push(*r);
                    continue;
                }
                let b = f.bricks();
                let base = (pool.len() / BRICK_VOXELS) as u32;
                let r = FrameRef {
                    table: table.len() as u32,
                    palette: palette.len() as u32,
                };
                table.extend(
                    b.table
                        .iter()
                        .map(|&i| if i == EMPTY_BRICK { i } else { base + i }),
                );
                pool.extend_from_slice(&b.pool);
                palette.extend(f.palette.iter().map(|c| u32::from_le_bytes(*c)));
                seen.insert(Arc::as_ptr(f), r);
                refs.push(r);
            }
            frames.push(refs);
        }
        check("voxel brick pool", pool.len() as u64)?;
        let bytes = table.len() as u64 * 4 + pool.len() as u64 + palette.len() as u64 * 4;
        let storage = wgpu::BufferUsages::STORAGE;
        let init = |label: &str, contents: &[u8], usage| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let bricks = init("voxel brick tables", bytemuck::cast_slice(&table), storage);
        let pool = init("voxel brick pool", &pool, storage);
        let palette = init("voxel palettes", bytemuck::cast_slice(&palette), storage);
        let instance_buf = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxel instances"),
            size: (instances.len().max(1) * std::mem::size_of::<VoxInstanceGpu>()) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let fs = wgpu::ShaderStages::FRAGMENT;
        let bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("voxels"),
            entries: &[
                uniform_entry(0, fs),
                uint_texture_entry(3, fs),
                uint_texture_entry(4, fs),
                uniform_entry(10, fs),
                storage_entry(11, fs, true),
                storage_entry(12, fs, true),
                storage_entry(13, fs, true),
            ],
        });
        let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("voxels.wgsl"),
            source: wgpu::ShaderSource::Wgsl(shaders::voxels(instances.len() as u32).into()),
        });
        let target = Some(wgpu::TextureFormat::Rgba32Uint);
        let p = |label, entry, target| masked_pipeline(dev, label, &module, entry, &bgl, target);
        log::info!(
            "voxel models: {} instance(s), {bytes} bytes of brick tables, pool and palettes",
            instances.len()
        );
        Ok(VoxelPasses {
            instances: instances.to_vec(),
            frames,
            instance_buf,
            bricks,
            pool,
            palette,
            mark: p("mark voxel boxes", "fs_vox_mark", None),
            cast: p("voxel cast", "fs_voxels", target),
            mark_shadow: p("mark voxel shadow boxes", "fs_vox_mark_shadow", None),
            shadow: p("voxel shadows", "fs_vox_shadow", target),
            bgl,
        })
    }

    /// Writes the instance records for an eye position and time (seconds).
    pub fn update(&self, gpu: &Gpu, eye: glam::DVec3, time: f64) {
        let recs: Vec<VoxInstanceGpu> = self
            .instances
            .iter()
            .zip(&self.frames)
            .map(|(inst, refs)| {
                let f = refs[inst.frame_at(time)];
                let m = inst.rotation.transpose() / inst.voxel_size;
                let row = |v: glam::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
                let e = inst.to_local(eye);
                let d = inst.dims();
                VoxInstanceGpu {
                    local_from_world: [row(m.row(0)), row(m.row(1)), row(m.row(2))],
                    eye_local: [e.x as f32, e.y as f32, e.z as f32, inst.voxel_size as f32],
                    dims: [d[0], d[1], d[2], f.table],
                    bdims: [
                        d[0].div_ceil(crate::voxel::BRICK),
                        d[1].div_ceil(crate::voxel::BRICK),
                        d[2].div_ceil(crate::voxel::BRICK),
                        f.palette,
                    ],
                }
            })
            .collect();
        gpu.queue
            .write_buffer(&self.instance_buf, 0, bytemuck::cast_slice(&recs));
    }

    /// Targets for a frame size; `gbuffer` is the G-buffer the passes read and update.
    pub fn targets(
        &self,
        gpu: &Gpu,
        width: u32,
        height: u32,
        frame_ub: &wgpu::Buffer,
        ray_table: &wgpu::TextureView,
        gbuffer: &wgpu::TextureView,
    ) -> VoxelTargets {
        let dev = &gpu.device;
        let tex = |label, format, extra| {
            screen_texture(
                dev,
                label,
                [width, height],
                format,
                wgpu::TextureUsages::RENDER_ATTACHMENT | extra,
            )
        };
        let copy = wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST;
        let g = tex("voxel g-buffer", wgpu::TextureFormat::Rgba32Uint, copy);
        let s = tex("voxel mask", STENCIL_FORMAT, wgpu::TextureUsages::empty());
        let bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxels"),
            layout: &self.bgl,
            entries: &[
                buf(0, frame_ub),
                view(3, ray_table),
                view(4, gbuffer),
                buf(10, &self.instance_buf),
                buf(11, &self.bricks),
                buf(12, &self.pool),
                buf(13, &self.palette),
            ],
        });
        VoxelTargets {
            gbuffer_view: g.create_view(&Default::default()),
            gbuffer: g,
            stencil_view: s.create_view(&Default::default()),
            bg,
        }
    }

    fn masked(
        enc: &mut wgpu::CommandEncoder,
        t: &VoxelTargets,
        pipeline: &wgpu::RenderPipeline,
        colour: bool,
    ) {
        let attachments: Vec<_> = colour
            .then_some(Some(wgpu::RenderPassColorAttachment {
                view: &t.gbuffer_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            }))
            .into_iter()
            .collect();
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("voxels (masked)"),
            color_attachments: &attachments,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &t.stencil_view,
                depth_ops: None,
                stencil_ops: Some(wgpu::Operations {
                    load: if colour {
                        wgpu::LoadOp::Load
                    } else {
                        wgpu::LoadOp::Clear(0)
                    },
                    store: wgpu::StoreOp::Store,
                }),
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &t.bg, &[]);
        pass.set_stencil_reference(1);
        pass.draw(0..3, 0..1);
    }

    /// Records mark + masked pass against `gbuffer` (the texture behind the targets' view).
    fn round(
        &self,
        enc: &mut wgpu::CommandEncoder,
        t: &VoxelTargets,
        gbuffer: &wgpu::Texture,
        mark: &wgpu::RenderPipeline,
        pass: &wgpu::RenderPipeline,
    ) {
        enc.copy_texture_to_texture(
            gbuffer.as_image_copy(),
            t.gbuffer.as_image_copy(),
            gbuffer.size(),
        );
        Self::masked(enc, t, mark, false);
        Self::masked(enc, t, pass, true);
        enc.copy_texture_to_texture(
            t.gbuffer.as_image_copy(),
            gbuffer.as_image_copy(),
            gbuffer.size(),
        );
    }

    /// Records the voxel cast (after the terrain and free-form casts).
    pub fn encode_cast(
        &self,
        enc: &mut wgpu::CommandEncoder,
        t: &VoxelTargets,
        gbuffer: &wgpu::Texture,
    ) {
        self.round(enc, t, gbuffer, &self.mark, &self.cast);
    }

    /// Records the voxel shadow rays (before shading).
    pub fn encode_shadows(
        &self,
        enc: &mut wgpu::CommandEncoder,
        t: &VoxelTargets,
        gbuffer: &wgpu::Texture,
    ) {
        self.round(enc, t, gbuffer, &self.mark_shadow, &self.shadow);
    }
}
