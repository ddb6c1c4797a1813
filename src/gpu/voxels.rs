//! Voxel-model passes: brick tables, brick pool and palettes uploaded once, instance records
//! rewritten per frame (eye in voxel units computed in f64, animation frame), and two fragment
//! passes drawn only over the pixel rectangles the models can cover (`cpu::voxel::primary_rects`
//! and `shadow_rects` for a pinhole camera, the whole image through a distortion table): the
//! cast runs the hierarchical DDA and writes the nearer voxel hit into the G-buffer, the shadow
//! pass sets flag 64 where a voxel blocks the sun. Each pass reads a copy of its rectangles of
//! the G-buffer and draws into the G-buffer itself, discarding the pixels it leaves as they
//! are, so nothing outside the rectangles is read, written or copied. Each rectangle runs the
//! models its mask names (a record per rectangle in `draws`, bound by dynamic offset), a
//! rectangle of one model by the `_one` entry points.

use super::types::{VoxDrawGpu, VoxInstanceGpu, VOX_SLABS};
use super::util::{
    buf, check_buffer_limit, fullscreen_pipeline_with, screen_texture, storage_entry, target_state,
    uint_texture_entry, uniform_entry, view,
};
use super::{shaders, Gpu, PARAM_USAGE};
use crate::cpu::voxel::InstanceRect;
use crate::voxel::{VoxelInstance, VoxelModel, BRICK_VOXELS, EMPTY_BRICK};
use crate::{Error, Result};
use std::collections::HashMap;
use std::sync::Arc;
use wgpu::util::DeviceExt;

/// What to make smaller when the voxel models do not fit the adapter.
const VOXEL_FIX: &str = "use smaller voxel models or fewer animation frames";

// Every scene's instance records fit the smallest uniform binding WebGPU guarantees (16 KiB).
/// Marks an empty brick's entry in `vox_data` (WGSL `VOX_EMPTY_BIT`); the low 16 bits hold
/// its gap in voxels towards the table's octant (`Bricks::brick_gap`), the bits from
/// [`NEAR_GAP_SHIFT`] its gap in every direction.
pub const EMPTY_BIT: u32 = 0x8000_0000;
/// Shift of an empty brick's gap in every direction in its table entry (WGSL
/// `VOX_NEAR_GAP_SHIFT`): the least of its eight octants' gaps, at most `NEAR_GAP_MAX`. The
/// union of the boxes grown towards each octant by at least that much covers the box grown by
/// it in every direction, so every voxel within `g - 1` of the brick's box is empty; the near
/// search of anti-aliased centre rays (`VoxTrace::touched`) counts a brick the ray crosses
/// where that distance is within the ray's reach.
pub const NEAR_GAP_SHIFT: u32 = 16;
/// Largest gap in every direction an entry holds (15 bits below [`EMPTY_BIT`]).
const NEAR_GAP_MAX: u16 = 0x7fff;
const _: () =
    assert!(shaders::wgsl_u32(shaders::VOXEL_DDA, "VOX_NEAR_GAP_SHIFT") == NEAR_GAP_SHIFT);

/// Words of one octant's voxel codes in a brick's block (WGSL `VOX_CODE_WORDS`).
pub const CODE_WORDS: usize = BRICK_VOXELS / 8;
/// Words of a brick's block in `vox_data`: 8 octants' codes, then the palette indices.
const BLOCK_WORDS: usize = 8 * CODE_WORDS + BRICK_VOXELS / 4;

// The codes are 4 bits (`voxel::jump_side`, 0 where occupied).
const _: () = assert!(crate::voxel::JUMP_BITS == 4);

const _: () =
    assert!(crate::voxel::desc::MAX_INSTANCES * std::mem::size_of::<VoxInstanceGpu>() <= 16384);
const _: () = assert!(shaders::wgsl_u32(shaders::VOXEL_DDA, "VOX_SLABS") as usize == VOX_SLABS);

/// Where one frame's data lies in the shared buffers.
#[derive(Clone, Copy, Debug)]
struct FrameRef {
    table: u32,
    palette: u32,
}

/// Refuses more instances than the shaders address, and adapters with fewer than the two
/// storage buffers the passes read.
fn check_instances(gpu: &Gpu, instances: &[VoxelInstance]) -> Result<()> {
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
    if have < 2 {
        return Err(Error::Limit {
            what: "storage buffers per shader stage".into(),
            msg: format!(
                "voxel models need 2, the adapter {} allows {have}; render the scene without [[voxels]]",
                gpu.info.name
            ),
        });
    }
    Ok(())
}

/// Bytes of the brick tables of every distinct frame of the instances' models.
fn brick_table_bytes(instances: &[VoxelInstance]) -> u64 {
    let mut unique = std::collections::HashSet::new();
    instances
        .iter()
        .flat_map(|i| &i.frames)
        .filter(|f| unique.insert(Arc::as_ptr(f)))
        .map(|f| {
            f.dims
                .iter()
                .map(|&d| d.div_ceil(crate::voxel::BRICK) as u64)
                .product::<u64>()
                * 4
                * 8
        })
        .sum()
}

/// The voxel data as the passes read it, before the tables' entries point into the pool.
struct Packed {
    table: Vec<u32>,
    pool: Vec<u32>,
    palette: Vec<u32>,
    /// Per instance, where each of its frames lies.
    frames: Vec<Vec<FrameRef>>,
}

impl Packed {
    fn new(instances: &[VoxelInstance]) -> Packed {
        // Brick tables first, then the pool (`vox_data` in voxel_dda.wgsl). A frame has a table
        // per octant of ray directions; an entry is its block's word address in the same
        // buffer, or VOX_EMPTY_BIT | the brick's gap in voxels towards the octant
        // (`Bricks::brick_gap`) | its gap in every direction << NEAR_GAP_SHIFT. A block holds
        // for each octant the brick's 512 4-bit voxel codes (0 = occupied, else the octant's
        // cube side, `Bricks::pool_jump`; 8 a word), then the palette indices (4 a word).
        let mut table: Vec<u32> = Vec::new();
        let mut pool: Vec<u32> = Vec::new();
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
                let base = (pool.len() / BLOCK_WORDS) as u32;
                let r = FrameRef {
                    table: table.len() as u32,
                    palette: palette.len() as u32,
                };
                // One table per octant of ray directions, each with that octant's gaps.
                for oct in 0..8 {
                    table.extend(b.table.iter().zip(&b.brick_gap).map(|(&i, g)| {
                        if i == EMPTY_BRICK {
                            let around = g.iter().copied().min().unwrap_or(0).min(NEAR_GAP_MAX);
                            EMPTY_BIT | (around as u32) << NEAR_GAP_SHIFT | g[oct] as u32
                        } else {
                            base + i
                        }
                    }));
                }
                for (index, jump) in b
                    .pool
                    .chunks_exact(BRICK_VOXELS)
                    .zip(b.pool_jump.chunks_exact(BRICK_VOXELS))
                {
                    for oct in 0..8 {
                        pool.extend(jump.chunks_exact(8).map(|j| {
                            (0..8).fold(0, |w, k| {
                                w | (crate::voxel::jump_side(j[k], oct) as u32) << (4 * k)
                            })
                        }));
                    }
                    pool.extend(
                        index
                            .chunks_exact(4)
                            .map(|i| u32::from_le_bytes([i[0], i[1], i[2], i[3]])),
                    );
                }
                palette.extend(f.palette.iter().map(|c| u32::from_le_bytes(*c)));
                seen.insert(Arc::as_ptr(f), r);
                refs.push(r);
            }
            frames.push(refs);
        }
        Packed {
            table,
            pool,
            palette,
            frames,
        }
    }
}

/// `vox_data`: the brick tables, their entries turned into word addresses of the blocks,
/// then the pool.
fn join_tables_and_pool(table: Vec<u32>, pool: Vec<u32>) -> Vec<u32> {
    let pool_base = table.len() as u32;
    let mut data = table;
    for e in data.iter_mut().filter(|e| **e & EMPTY_BIT == 0) {
        *e = pool_base + *e * BLOCK_WORDS as u32;
    }
    data.extend(pool);
    data
}

/// The voxel passes' bind-group layout.
fn voxel_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let fs = wgpu::ShaderStages::FRAGMENT;
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("voxels"),
            entries: &[
                uniform_entry(gpu.params, 0, fs),
                uint_texture_entry(3, fs),
                uint_texture_entry(4, fs),
                uniform_entry(gpu.params, 10, fs),
                storage_entry(11, fs, true),
                storage_entry(13, fs, true),
                wgpu::BindGroupLayoutEntry {
                    binding: 16,
                    visibility: fs,
                    ty: wgpu::BindingType::Buffer {
                        ty: gpu.params.binding_type(),
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<VoxDrawGpu>() as u64
                        ),
                    },
                    count: None,
                },
            ],
        })
}

/// Uploaded voxel data and the pipelines.
pub(crate) struct VoxelPasses {
    /// The models as placed (on the flat base plane).
    placed: Vec<VoxelInstance>,
    /// The models as this frame sees them ([`VoxelPasses::set_offsets`]).
    instances: Vec<VoxelInstance>,
    /// Boxes the screen rectangles come from (`cpu::voxel::cover_boxes`), once per upload.
    cover: Vec<Vec<[glam::DVec3; 2]>>,
    /// Per instance, whether it is drawn: the scene's models always, the entity templates'
    /// slots when placed ([`VoxelPasses::set_slots`]).
    active: Vec<bool>,
    /// The instances of each entity template (after the scene's models).
    slots: Vec<std::ops::Range<usize>>,
    frames: Vec<Vec<FrameRef>>,
    instance_buf: wgpu::Buffer,
    /// One `VoxDrawGpu` per drawn rectangle, `draw_stride` bytes apart: the cast's first,
    /// then the shadow pass's (`slots` each).
    draws: wgpu::Buffer,
    draw_stride: u64,
    /// Brick tables, then the brick pool (`vox_data`).
    data: wgpu::Buffer,
    palette: wgpu::Buffer,
    bgl: wgpu::BindGroupLayout,
    /// Per pass (cast, shadows), for frames without and with anti-aliasing's near-miss
    /// search (`_near`), the entry points for rectangles of several instances and of one
    /// (`_one`).
    pipelines: [[[wgpu::RenderPipeline; 2]; 2]; 2],
}

/// Size-dependent resources.
pub(crate) struct VoxelTargets {
    /// The copy of the G-buffer's rectangles the passes read.
    gbuffer_copy: wgpu::Texture,
    bg: wgpu::BindGroup,
}

impl VoxelPasses {
    /// Uploads the brick tables, pool and palettes of the `instances`' models (each frame of
    /// a model once) and builds the pipelines.
    pub fn new(gpu: &Gpu, instances: &[VoxelInstance]) -> Result<VoxelPasses> {
        check_instances(gpu, instances)?;
        // Brick tables first, from the sizes alone (before anything large is built).
        check_buffer_limit(
            gpu,
            "voxel brick tables",
            brick_table_bytes(instances),
            VOXEL_FIX,
        )?;
        let built = std::time::Instant::now();
        let packed = Packed::new(instances);
        let data_bytes = (packed.table.len() + packed.pool.len()) as u64 * 4;
        check_buffer_limit(gpu, "voxel brick tables and pool", data_bytes, VOXEL_FIX)?;
        let bytes = data_bytes + packed.palette.len() as u64 * 4;
        let Packed {
            table,
            pool,
            palette,
            frames,
        } = packed;
        let data = join_tables_and_pool(table, pool);
        let dev = &gpu.device;
        let storage = wgpu::BufferUsages::STORAGE;
        let init = |label: &str, contents: &[u8], usage| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let data = init("voxel bricks", bytemuck::cast_slice(&data), storage);
        let palette = init("voxel palettes", bytemuck::cast_slice(&palette), storage);
        let instance_buf = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxel instances"),
            size: (instances.len().max(1) * std::mem::size_of::<VoxInstanceGpu>()) as u64,
            usage: PARAM_USAGE,
            mapped_at_creation: false,
        });
        let draw_stride = (std::mem::size_of::<VoxDrawGpu>() as u64)
            .next_multiple_of(gpu.params.offset_alignment(&gpu.limits) as u64);
        let draws = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxel draws"),
            size: draw_stride * 2 * crate::cpu::voxel::max_rects(instances.len()) as u64,
            usage: PARAM_USAGE,
            mapped_at_creation: false,
        });
        let bgl = voxel_layout(gpu);
        let module = super::shader_module(
            dev,
            gpu.params,
            "voxels.wgsl",
            &shaders::voxels(instances.len() as u32),
        );
        let target = [Some(target_state(wgpu::TextureFormat::Rgba32Uint))];
        let p = |label, entry| {
            fullscreen_pipeline_with(dev, label, &module, entry, &bgl, &target, None)
        };
        log::info!(
            "voxel models: {} instance(s), {bytes} bytes of brick tables, pool and palettes, built in {:.0} ms",
            instances.len(),
            built.elapsed().as_secs_f64() * 1e3
        );
        Ok(VoxelPasses {
            placed: instances.to_vec(),
            instances: instances.to_vec(),
            cover: crate::cpu::voxel::cover_boxes(instances),
            active: vec![true; instances.len()],
            slots: Vec::new(),
            frames,
            instance_buf,
            draws,
            draw_stride,
            data,
            palette,
            pipelines: [
                [
                    [
                        p("voxel cast", "fs_voxels"),
                        p("voxel cast, one instance", "fs_voxels_one"),
                    ],
                    [
                        p("voxel cast, near misses", "fs_voxels_near"),
                        p(
                            "voxel cast, one instance, near misses",
                            "fs_voxels_one_near",
                        ),
                    ],
                ],
                [
                    [
                        p("voxel shadows", "fs_vox_shadow"),
                        p("voxel shadows, one instance", "fs_vox_shadow_one"),
                    ],
                    [
                        p("voxel shadows, near misses", "fs_vox_shadow_near"),
                        p(
                            "voxel shadows, one instance, near misses",
                            "fs_vox_shadow_one_near",
                        ),
                    ],
                ],
            ],
            bgl,
        })
    }

    /// Writes the instance records for an eye position and time (seconds), and the records of
    /// the rectangles this frame's cast and shadow pass will draw (`encode_cast`,
    /// `encode_shadows`).
    pub fn update(
        &self,
        gpu: &Gpu,
        eye: glam::DVec3,
        time: f64,
        cast: &[InstanceRect],
        shadows: &[InstanceRect],
    ) {
        let recs: Vec<VoxInstanceGpu> = self
            .instances
            .iter()
            .zip(&self.frames)
            .zip(&self.cover)
            .map(|((inst, refs), cover)| {
                let f = refs[inst.frame_at(time)];
                let mut slab_lo = [[0.0; 4]; VOX_SLABS];
                let mut slab_hi = [[0.0; 4]; VOX_SLABS];
                for (k, b) in cover.iter().take(VOX_SLABS).enumerate() {
                    let corner = |p: glam::DVec3| [p.x as f32, p.y as f32, p.z as f32, 1.0];
                    (slab_lo[k], slab_hi[k]) = (corner(b[0]), corner(b[1]));
                }
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
                    slab_lo,
                    slab_hi,
                }
            })
            .collect();
        gpu.queue
            .write_buffer(&self.instance_buf, 0, bytemuck::cast_slice(&recs));
        let stride = self.draw_stride as usize;
        let slots = self.slots();
        let mut bytes = vec![0u8; 2 * slots * stride];
        for (pass, rects) in [cast, shadows].into_iter().enumerate() {
            for (i, r) in self.drawn(rects).iter().enumerate() {
                bytes[(pass * slots + i) * stride..][..std::mem::size_of::<VoxDrawGpu>()]
                    .copy_from_slice(bytemuck::bytes_of(&VoxDrawGpu::new(r.instances, &recs)));
            }
        }
        gpu.queue.write_buffer(&self.draws, 0, &bytes);
    }

    /// Records per pass in `draws` (`cpu::voxel::max_rects`).
    fn slots(&self) -> usize {
        crate::cpu::voxel::max_rects(self.instances.len())
    }

    /// The rectangles a pass draws: none empty, at most `slots` (`cpu::voxel` never gives
    /// more).
    fn drawn<'a>(&self, rects: &'a [InstanceRect]) -> Vec<&'a InstanceRect> {
        let drawn: Vec<_> = rects
            .iter()
            .filter(|r| r.rect.area() > 0 && r.instances != 0)
            .collect();
        debug_assert!(
            drawn.len() <= self.slots(),
            "more rectangles than draw records"
        );
        drawn.into_iter().take(self.slots()).collect()
    }

    /// The models as this frame sees them (as uploaded, moved by [`Self::set_offsets`]).
    pub fn instances(&self) -> &[VoxelInstance] {
        &self.instances
    }

    /// The scene's `models`, then `max` slots for each entity template `(model, max)`: the
    /// slots are not drawn until [`Self::set_slots`] places them.
    pub fn with_templates(
        gpu: &Gpu,
        models: &[VoxelInstance],
        templates: &[(VoxelInstance, usize)],
    ) -> Result<VoxelPasses> {
        let mut all = models.to_vec();
        let mut slots = Vec::new();
        for (model, max) in templates {
            slots.push(all.len()..all.len() + max);
            all.extend(std::iter::repeat_n(model.clone(), *max));
        }
        let mut passes = VoxelPasses::new(gpu, &all)?;
        for r in &slots {
            passes.active[r.clone()].fill(false);
        }
        passes.slots = slots;
        Ok(passes)
    }

    /// Places entity instances `(template, model at its pose)` in their templates' slots (the
    /// rest are not drawn), each moved by `offset(position)` (the curved earth's drop).
    pub fn set_slots(
        &mut self,
        placed: &[(usize, VoxelInstance)],
        offset: impl Fn(glam::DVec3) -> glam::DVec3,
    ) {
        let mut next: Vec<usize> = self.slots.iter().map(|r| r.start).collect();
        for r in &self.slots {
            self.active[r.clone()].fill(false);
        }
        for (k, m) in placed {
            let Some(range) = self.slots.get(*k) else {
                continue;
            };
            let i = next[*k];
            if i >= range.end {
                continue;
            }
            next[*k] += 1;
            self.placed[i].position = m.position;
            self.placed[i].rotation = m.rotation;
            self.instances[i].rotation = m.rotation;
            self.instances[i].position = m.position + offset(m.position);
            self.active[i] = true;
        }
    }

    /// Per instance, the boxes its screen rectangles come from (`cpu::voxel::cover_boxes`);
    /// none for the instances not drawn.
    pub fn active_boxes(&self) -> Vec<Vec<[glam::DVec3; 2]>> {
        (self.cover.iter().zip(&self.active))
            .map(|(b, &on)| if on { b.clone() } else { Vec::new() })
            .collect()
    }

    /// The mask of the instances drawn.
    pub fn active_mask(&self) -> u64 {
        (self.active.iter().enumerate())
            .filter(|(_, &on)| on)
            .fold(0, |m, (i, _)| m | 1 << i)
    }

    /// The models as placed (before [`Self::set_offsets`]).
    pub fn placed(&self) -> &[VoxelInstance] {
        &self.placed
    }

    /// Moves each model rigidly by its offset from where it was placed (the curved earth's
    /// drop at its anchor); the next [`Self::update`] writes the records.
    pub fn set_offsets(&mut self, offsets: &[glam::DVec3]) {
        for ((m, p), o) in self.instances.iter_mut().zip(&self.placed).zip(offsets) {
            m.position = p.position + *o;
        }
    }

    /// Targets for a frame size; the passes update the G-buffer the shade pass reads.
    pub fn targets(
        &self,
        gpu: &Gpu,
        width: u32,
        height: u32,
        frame_ub: &wgpu::Buffer,
        ray_table: &wgpu::TextureView,
    ) -> VoxelTargets {
        let dev = &gpu.device;
        let copy = screen_texture(
            dev,
            "voxel g-buffer copy",
            [width, height],
            wgpu::TextureFormat::Rgba32Uint,
            wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxels"),
            layout: &self.bgl,
            entries: &[
                buf(0, frame_ub),
                view(3, ray_table),
                view(4, &copy.create_view(&Default::default())),
                buf(10, &self.instance_buf),
                buf(11, &self.data),
                buf(13, &self.palette),
                wgpu::BindGroupEntry {
                    binding: 16,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &self.draws,
                        offset: 0,
                        size: wgpu::BufferSize::new(std::mem::size_of::<VoxDrawGpu>() as u64),
                    }),
                },
            ],
        });
        VoxelTargets {
            gbuffer_copy: copy,
            bg,
        }
    }

    /// Records the cast (`pass` 0) or shadow pass (1), with the near-miss search (`near` 1) or
    /// without (0), over `rects` of `gbuffer`, each
    /// rectangle running its own instances (records written by `update`): copy the rectangles
    /// aside, then draw them into the G-buffer, each pixel reading its copy (pixels a pass
    /// leaves as they are discard).
    fn over_rects(
        &self,
        enc: &mut wgpu::CommandEncoder,
        t: &VoxelTargets,
        gbuffer: (&wgpu::Texture, &wgpu::TextureView),
        [pass, near]: [usize; 2],
        rects: &[InstanceRect],
    ) {
        let rects = self.drawn(rects);
        let slots = self.slots();
        if rects.is_empty() {
            return;
        }
        for r in &rects {
            let r = r.rect;
            let origin = wgpu::Origin3d {
                x: r.x0,
                y: r.y0,
                z: 0,
            };
            enc.copy_texture_to_texture(
                wgpu::TexelCopyTextureInfo {
                    origin,
                    ..gbuffer.0.as_image_copy()
                },
                wgpu::TexelCopyTextureInfo {
                    origin,
                    ..t.gbuffer_copy.as_image_copy()
                },
                wgpu::Extent3d {
                    width: r.width(),
                    height: r.height(),
                    depth_or_array_layers: 1,
                },
            );
        }
        let pipelines = &self.pipelines[pass][near];
        let mut rp = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("voxels"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: gbuffer.1,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        for (i, r) in rects.iter().enumerate() {
            // A rectangle of one instance runs the `_one` entry point.
            rp.set_pipeline(&pipelines[(r.instances.count_ones() == 1) as usize]);
            let offset = (pass * slots + i) as u64 * self.draw_stride;
            rp.set_bind_group(0, &t.bg, &[offset as u32]);
            let r = r.rect;
            rp.set_scissor_rect(r.x0, r.y0, r.width(), r.height());
            rp.draw(0..3, 0..1);
        }
    }

    /// Records the voxel cast over `rects` (after the terrain and free-form casts; the same
    /// rectangles as given to `update`); `near`: anti-aliasing's centre rays, flagging near
    /// misses.
    pub fn encode_cast(
        &self,
        enc: &mut wgpu::CommandEncoder,
        t: &VoxelTargets,
        gbuffer: (&wgpu::Texture, &wgpu::TextureView),
        rects: &[InstanceRect],
        near: bool,
    ) {
        self.over_rects(enc, t, gbuffer, [0, near as usize], rects);
    }

    /// Records the voxel shadow rays over `rects` (before shading; the same rectangles as
    /// given to `update`); `near` as for [`Self::encode_cast`].
    pub fn encode_shadows(
        &self,
        enc: &mut wgpu::CommandEncoder,
        t: &VoxelTargets,
        gbuffer: (&wgpu::Texture, &wgpu::TextureView),
        rects: &[InstanceRect],
        near: bool,
    ) {
        self.over_rects(enc, t, gbuffer, [1, near as usize], rects);
    }
}
