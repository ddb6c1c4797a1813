//! Free-form passes: object data uploaded once, the binning pass (compute, one invocation per
//! 16x16-pixel bin, primary and shadow lists, plain and perturbed objects apart), the cast and
//! shadow passes (fragment, one per object kind, drawn as quads over runs of bins that list
//! objects of that kind) and the shade pipeline that knows free forms.

use super::shade::{shade_pipelines, ShadePipelines};
use super::shaders::wgsl_u32;
use super::types::{FfNodeGpu, FfObjectGpu};
use super::util::{
    buf, check_buffer_limit, float_texture_entry, pipeline_layout, render_pipeline, screen_texture,
    storage_entry, target_state, uint_texture_entry, uniform_entry, view,
};
use super::variants::FfTables;
use super::{shaders, Gpu, PARAM_USAGE};
use crate::freeform::FreeForm;
use crate::{Error, Result};
use wgpu::util::DeviceExt;

/// What to make smaller when the free forms do not fit the adapter.
const OBJECT_FIX: &str = "use fewer or simpler free forms";

/// Bin side in pixels (WGSL `FF_BIN` in `ff_consts.wgsl`, checked at compile time).
pub const BIN: u32 = 16;
const _: () = assert!(wgsl_u32(shaders::FF_CONSTS, "FF_BIN") == BIN);
/// Margin, as a fraction of an object's half-diagonal, that the gradient bound of the
/// near-miss search holds for (`FfObjectGpu::local_from_world[1][3]`).
pub const NEAR_MARGIN: f64 = 0.25;
/// Object indices stored per bin and list; a fuller bin falls back to testing every object.
pub const BIN_CAPACITY: u32 = 255;

/// GPU records of the free forms: one [`FfObjectGpu`] per object, the nodes of all
/// perturbation trees one after the other.
pub fn pack(objects: &[FreeForm]) -> (Vec<FfObjectGpu>, Vec<FfNodeGpu>) {
    let mut recs = Vec::with_capacity(objects.len());
    let mut nodes = Vec::new();
    for ff in objects {
        recs.push(pack_record(ff, nodes.len() as u32, near_bound(ff)));
        for n in &ff.nodes {
            let c = n.q.0.map(|v| v as f32);
            nodes.push(FfNodeGpu {
                q0: [c[0], c[1], c[2], c[3]],
                q1: [c[4], c[5], c[6], c[7]],
                q2: [c[8], c[9], n.weight as f32, n.depth as f32],
            });
        }
    }
    (recs, nodes)
}

/// The near-miss search's gradient bound and the margin (m) it holds for: over the box
/// widened by a quarter of its half-diagonal (beyond, the object is a few pixels wide: see
/// `ff_intersect`). It depends on the object's own frame only, so a posed copy keeps it.
pub fn near_bound(ff: &FreeForm) -> [f32; 2] {
    let margin = NEAR_MARGIN * ff.size();
    [ff.gradient_bound(margin) as f32, margin as f32]
}

/// The record of one object whose nodes start at node `first`, with its [`near_bound`].
pub fn pack_record(ff: &FreeForm, first: u32, [bound, margin]: [f32; 2]) -> FfObjectGpu {
    let rt = ff.rotation.transpose();
    let row = |v: glam::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
    let (centre, radius) = ff.bounding_sphere();
    let [lo, hi] = ff.bounds;
    let m = &ff.material;
    let with_w = |mut r: [f32; 4], w: f32| {
        r[3] = w;
        r
    };
    FfObjectGpu {
        local_from_world: [
            with_w(row(rt.row(0)), bound),
            with_w(row(rt.row(1)), margin),
            row(rt.row(2)),
        ],
        position: [
            ff.position.x as f32,
            ff.position.y as f32,
            ff.position.z as f32,
            crate::cpu::freeform::object_shadow_offset(ff) as f32,
        ],
        box_min: [lo.x as f32, lo.y as f32, lo.z as f32, f32::from_bits(first)],
        box_max: [
            hi.x as f32,
            hi.y as f32,
            hi.z as f32,
            f32::from_bits(ff.nodes.len() as u32),
        ],
        colour: [m.colour[0], m.colour[1], m.colour[2], m.shininess],
        material: [
            m.ambient,
            m.diffuse,
            m.specular,
            if ff.is_convex() { 1.0 } else { 0.0 },
        ],
        sphere: [
            centre.x as f32,
            centre.y as f32,
            centre.z as f32,
            radius as f32,
        ],
    }
}

/// Refuses more objects than the shaders address, and adapters without storage buffers in
/// vertex shaders (the passes draw their bins from one).
fn check_objects(gpu: &Gpu, count: usize) -> Result<()> {
    if count > crate::freeform::MAX_OBJECTS {
        return Err(Error::Limit {
            what: "free forms (entity template slots included)".into(),
            msg: format!("{count} objects, at most {}", crate::freeform::MAX_OBJECTS),
        });
    }
    if !gpu.downlevel.contains(wgpu::DownlevelFlags::VERTEX_STORAGE) {
        return Err(Error::Limit {
            what: "storage buffers in vertex shaders".into(),
            msg: format!(
                "the free-form passes draw their bins from a storage buffer, which {} does \
                 not allow in vertex shaders; render the scene without [[objects]] or on \
                 another adapter (WGPU_BACKEND=vulkan)",
                gpu.info.name
            ),
        });
    }
    Ok(())
}

/// Where the object tables of `recs` and `nodes` live on this adapter (uniform buffers only if
/// `allow_uniform`), refusing tables over its storage-buffer limits.
fn choose_tables(
    gpu: &Gpu,
    recs: &[FfObjectGpu],
    nodes: &[FfNodeGpu],
    allow_uniform: bool,
) -> Result<FfTables> {
    check_buffer_limit(
        gpu,
        "free-form records",
        (recs.len() * 144) as u64,
        OBJECT_FIX,
    )?;
    check_buffer_limit(
        gpu,
        "free-form quadrics",
        (nodes.len() * 48) as u64,
        OBJECT_FIX,
    )?;
    let tables = FfTables::choose(
        recs.len(),
        nodes.len(),
        if allow_uniform {
            gpu.limits.max_uniform_buffer_binding_size
        } else {
            0
        },
    );
    log::debug!("free-form tables: {tables:?}");
    let need = tables.storage_buffers(gpu.params);
    let have = gpu.limits.max_storage_buffers_per_shader_stage;
    if have < need {
        return Err(Error::Limit {
            what: "storage buffers per shader stage".into(),
            msg: format!(
                "free forms need {need}, the adapter {} allows {have}; render the scene without [[objects]]",
                gpu.info.name
            ),
        });
    }
    Ok(tables)
}

/// Bind-group layouts of the binning pass, the cast and shadow passes, and the shade pass.
fn object_layouts(gpu: &Gpu, tables: FfTables) -> [wgpu::BindGroupLayout; 3] {
    let dev = &gpu.device;
    let cs = wgpu::ShaderStages::COMPUTE;
    let fs = wgpu::ShaderStages::FRAGMENT;
    let vfs = wgpu::ShaderStages::VERTEX_FRAGMENT;
    let bin_bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("free-form bins"),
        entries: &[
            uniform_entry(gpu.params, 0, cs),
            uint_texture_entry(3, cs),
            uint_texture_entry(4, cs),
            tables.entry(gpu.params, 6, cs),
            storage_entry(8, cs, false),
        ],
    });
    let cast_bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("free-form cast"),
        entries: &[
            uniform_entry(gpu.params, 0, vfs),
            uint_texture_entry(3, fs),
            uint_texture_entry(4, fs),
            tables.entry(gpu.params, 6, fs),
            tables.entry(gpu.params, 7, fs),
            storage_entry(8, vfs, true),
        ],
    });
    let shade_bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("shade with free forms"),
        entries: &[
            uniform_entry(gpu.params, 0, fs),
            storage_entry(1, fs, true),
            storage_entry(2, fs, true),
            uint_texture_entry(3, fs),
            uint_texture_entry(4, fs),
            storage_entry(5, fs, true),
            tables.entry(gpu.params, 6, fs),
            uint_texture_entry(9, fs),
            float_texture_entry(19, fs, wgpu::TextureViewDimension::D2),
        ],
    });
    [bin_bgl, cast_bgl, shade_bgl]
}

/// The binning pass's pipelines: primary and shadow lists.
fn bin_pipelines(
    gpu: &Gpu,
    tables: FfTables,
    bin_bgl: &wgpu::BindGroupLayout,
) -> [wgpu::ComputePipeline; 2] {
    let dev = &gpu.device;
    let bin_mod = super::shader_module(dev, gpu.params, "ff_bin.wgsl", &shaders::ff_bin(tables));
    let compute = |entry: &str| {
        dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&pipeline_layout(dev, bin_bgl)),
            module: &bin_mod,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    };
    let bin_primary = compute("cs_bin_primary");
    let bin_shadow = compute("cs_bin_shadow");
    [bin_primary, bin_shadow]
}

/// Pipelines drawn over the bins, [plain, perturbed] each: the casts, their pass-through
/// draws and the shadow passes; `small`: see [`shaders::freeform`].
#[allow(clippy::type_complexity)]
fn binned_pipelines(
    gpu: &Gpu,
    tables: FfTables,
    small: bool,
    cast_bgl: &wgpu::BindGroupLayout,
) -> (
    [wgpu::RenderPipeline; 3],
    [wgpu::RenderPipeline; 2],
    [wgpu::RenderPipeline; 4],
) {
    let dev = &gpu.device;
    let module = |label: &str, src: String| super::shader_module(dev, gpu.params, label, &src);
    let cast_mod = module("objects.wgsl", shaders::objects(small, tables));
    let shadow_mod = module("ff_shadow.wgsl", shaders::ff_shadow(small, tables));
    // One pass per list and object kind, drawn as a quad per bin with such objects.
    let binned_masked = |m: &wgpu::ShaderModule, entries: [&str; 2], format, write_mask| {
        let target = wgpu::ColorTargetState {
            write_mask,
            ..target_state(format)
        };
        render_pipeline(dev, entries[1], m, entries, cast_bgl, &[Some(target)], None)
    };
    let binned = |m: &wgpu::ShaderModule, entries: [&str; 2], format| {
        binned_masked(m, entries, format, wgpu::ColorWrites::ALL)
    };
    let g = wgpu::TextureFormat::Rgba32Uint;
    let cast = [
        binned(&cast_mod, ["vs_bins_primary_plain", "fs_objects_plain"], g),
        binned(
            &cast_mod,
            ["vs_bins_primary_general", "fs_objects_general"],
            g,
        ),
        binned(
            &cast_mod,
            ["vs_bins_primary_general", "fs_objects_general_near"],
            g,
        ),
    ];
    // With both kinds, each cast pass also copies its input through over the bins only the
    // other kind lists (see `encode_cast`).
    let copy_through = [
        binned(
            &cast_mod,
            ["vs_bins_primary_general_only", "fs_copy_gbuffer"],
            g,
        ),
        binned(
            &cast_mod,
            ["vs_bins_primary_plain_only", "fs_copy_gbuffer"],
            g,
        ),
    ];
    // The shadow target: blocked (first channel), the near-miss passes' flag (second).
    let rg = wgpu::TextureFormat::Rg32Uint;
    let shadow = |kind: &str, near: bool| {
        let entries = [
            format!("vs_bins_shadow_{kind}"),
            format!("fs_ff_shadow_{kind}{}", if near { "_near" } else { "" }),
        ];
        let mask = if near {
            wgpu::ColorWrites::GREEN
        } else {
            wgpu::ColorWrites::RED
        };
        binned_masked(&shadow_mod, [&entries[0], &entries[1]], rg, mask)
    };
    let shadow = [
        shadow("plain", false),
        shadow("general", false),
        shadow("plain", true),
        shadow("general", true),
    ];
    (cast, copy_through, shadow)
}

/// Object buffers and the pipelines that use them.
pub(crate) struct ObjectPasses {
    /// Records allocated: the scene's objects, then the entity templates' slots.
    pub count: u32,
    /// Records drawn: the scene's objects and the instances of [`ObjectPasses::set_instances`].
    pub active: u32,
    /// Per entity template, the first of its nodes (after the scene objects' nodes) and its
    /// [`near_bound`].
    template_nodes: Vec<(u32, [f32; 2])>,
    /// The object records as placed, and per object its origin and bounding-sphere centre
    /// (world, f64): what [`ObjectPasses::set_offsets`] moves.
    placed: Vec<FfObjectGpu>,
    placed_points: Vec<[glam::DVec3; 2]>,
    objects: wgpu::Buffer,
    nodes: wgpu::Buffer,
    bin_bgl: wgpu::BindGroupLayout,
    cast_bgl: wgpu::BindGroupLayout,
    pub shade_bgl: wgpu::BindGroupLayout,
    bin_primary: wgpu::ComputePipeline,
    bin_shadow: wgpu::ComputePipeline,
    /// Objects of each kind: [plain (one quadric), perturbed].
    kinds: [u32; 2],
    /// Cast passes, [plain, perturbed, perturbed with the near-miss search (anti-aliasing's
    /// centre rays)].
    cast: [wgpu::RenderPipeline; 3],
    /// Pass-through draws for `cast[k]`'s pass over the bins only the other kind lists.
    copy_through: [wgpu::RenderPipeline; 2],
    /// Shadow passes, [plain, perturbed], then their near-miss twins (anti-aliasing's centre
    /// rays: the sun rays of a pixel's footprint).
    shadow: [wgpu::RenderPipeline; 4],
    pub shade: ShadePipelines,
}

/// Size-dependent resources of the free-form passes.
pub(crate) struct ObjectTargets {
    pub bins: [u32; 2],
    bin_primary_bg: wgpu::BindGroup,
    bin_shadow_bg: wgpu::BindGroup,
    cast_bg: wgpu::BindGroup,
    /// The cast bind group reading the free-form G-buffer (the perturbed pass's input when
    /// both kinds exist).
    cast_plain_bg: wgpu::BindGroup,
    shadow_bg: wgpu::BindGroup,
    pub gbuffer: wgpu::Texture,
    pub gbuffer_view: wgpu::TextureView,
    shadow_view: wgpu::TextureView,
    /// The casts' result is in the terrain's G-buffer (both kinds of object), not `gbuffer`.
    pub final_in_terrain: bool,
    /// View of the G-buffer holding the casts' result.
    pub final_view: wgpu::TextureView,
}

impl ObjectPasses {
    /// Uploads `statics` (drawn) with room for `max` instances of each entity template
    /// (`(object, max)`; drawn only as [`ObjectPasses::set_instances`] places them) and
    /// builds their pipelines; `allow_uniform`: tables in uniform buffers where they fit (else
    /// always storage buffers); `pool`: the tile pool's layout (group 3) of a paged terrain,
    /// which the shade pass reads the terrain from.
    pub fn with_templates(
        gpu: &Gpu,
        statics: &[FreeForm],
        templates: &[(FreeForm, usize)],
        allow_uniform: bool,
        pool: Option<&wgpu::BindGroupLayout>,
    ) -> Result<ObjectPasses> {
        let slots: usize = templates.iter().map(|(_, m)| m).sum();
        check_objects(gpu, statics.len() + slots)?;
        let objects: Vec<FreeForm> = (statics.iter().cloned())
            .chain(templates.iter().map(|(o, _)| o.clone()))
            .collect();
        let objects = &objects[..];
        let (packed, nodes) = pack(objects);
        let template_nodes: Vec<(u32, [f32; 2])> = packed[statics.len()..]
            .iter()
            .map(|r| {
                let near = [r.local_from_world[0][3], r.local_from_world[1][3]];
                (r.box_min[3].to_bits(), near)
            })
            .collect();
        // The slots start as copies of their template (not drawn: `active` leaves them out).
        let mut recs = packed[..statics.len()].to_vec();
        for ((_, max), rec) in templates.iter().zip(&packed[statics.len()..]) {
            recs.extend(std::iter::repeat_n(*rec, *max));
        }
        let tables = choose_tables(gpu, &recs, &nodes, allow_uniform)?;
        let dev = &gpu.device;
        let usage = if tables.uniform() {
            PARAM_USAGE
        } else {
            // Written again per frame on the curved earth (`set_offsets`).
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST
        };
        let objects_buf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("free forms"),
            contents: bytemuck::cast_slice(&recs),
            usage,
        });
        let nodes_buf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("free-form quadrics"),
            contents: bytemuck::cast_slice(&nodes),
            usage,
        });
        let [bin_bgl, cast_bgl, shade_bgl] = object_layouts(gpu, tables);
        // Perturbed objects of at most FF_RAY_NODES nodes (every one in the demo) keep their
        // node data per ray in the interval search.
        let small = objects
            .iter()
            .all(|o| o.nodes.len() <= shaders::FF_RAY_NODES);
        let [bin_primary, bin_shadow] = bin_pipelines(gpu, tables, &bin_bgl);
        let (cast, copy_through, shadow) = binned_pipelines(gpu, tables, small, &cast_bgl);
        let plain = objects.iter().filter(|o| o.nodes.len() == 1).count() as u32;
        let mut shade = shade_pipelines(
            gpu.params,
            "shade (free forms)",
            move |f| shaders::shade_objects(f, tables),
            shade_bgl.clone(),
        );
        if let Some(p) = pool {
            shade = shade.with_group3(p.clone());
        }
        Ok(ObjectPasses {
            count: recs.len() as u32,
            active: statics.len() as u32,
            template_nodes,
            placed: recs[..statics.len()].to_vec(),
            placed_points: statics
                .iter()
                .map(|o| [o.position, o.bounding_sphere().0])
                .collect(),
            objects: objects_buf,
            nodes: nodes_buf,
            bin_bgl,
            cast_bgl,
            shade_bgl,
            bin_primary,
            bin_shadow,
            kinds: [plain, objects.len() as u32 - plain],
            cast,
            copy_through,
            shadow,
            shade,
        })
    }

    /// World origins of the objects as placed.
    pub fn placed_origins(&self) -> impl Iterator<Item = glam::DVec3> + '_ {
        self.placed_points.iter().map(|[p, _]| *p)
    }

    /// Moves each object rigidly by its offset from where it was placed (the curved earth's
    /// drop at its origin, `Terrain::curved_offset`) and uploads the records: the passes read
    /// positions and bounding spheres from them only.
    pub fn set_offsets(&self, gpu: &Gpu, offsets: &[glam::DVec3]) {
        let f = |v: glam::DVec3| [v.x as f32, v.y as f32, v.z as f32];
        let recs: Vec<FfObjectGpu> = (self.placed.iter().zip(&self.placed_points))
            .zip(offsets)
            .map(|((rec, [p, c]), o)| {
                let mut rec = *rec;
                rec.position[..3].copy_from_slice(&f(*p + *o));
                rec.sphere[..3].copy_from_slice(&f(*c + *o));
                rec
            })
            .collect();
        gpu.queue
            .write_buffer(&self.objects, 0, bytemuck::cast_slice(&recs));
    }

    /// Draws `instances` (`(template index, the template's object posed)`, at most the
    /// template slots in all) after the scene's objects until the next call; returns how many
    /// are drawn.
    pub fn set_instances(&mut self, gpu: &Gpu, instances: &[(usize, FreeForm)]) -> usize {
        let statics = self.placed.len();
        let room = self.count as usize - statics;
        let recs: Vec<FfObjectGpu> = instances
            .iter()
            .filter_map(|(k, ff)| {
                let &(first, near) = self.template_nodes.get(*k)?;
                Some(pack_record(ff, first, near))
            })
            .take(room)
            .collect();
        if !recs.is_empty() {
            let at = (statics * std::mem::size_of::<FfObjectGpu>()) as u64;
            gpu.queue
                .write_buffer(&self.objects, at, bytemuck::cast_slice(&recs));
        }
        self.active = (statics + recs.len()) as u32;
        recs.len()
    }

    /// Bins, the free-form G-buffer and bind groups for a `width` x `height` frame.
    #[allow(clippy::too_many_arguments)]
    pub fn targets(
        &self,
        gpu: &Gpu,
        width: u32,
        height: u32,
        frame_ub: &wgpu::Buffer,
        ray_table: &wgpu::TextureView,
        terrain_gbuffer: &wgpu::TextureView,
    ) -> Result<ObjectTargets> {
        let dev = &gpu.device;
        let bins = [width.div_ceil(BIN), height.div_ceil(BIN)];
        let bytes = 2 * bins[0] as u64 * bins[1] as u64 * (BIN_CAPACITY as u64 + 1) * 4;
        check_buffer_limit(gpu, "free-form bins", bytes, "render a smaller image")?;
        let bins_buf = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("free-form bins"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let target = |label, format| {
            let tex = screen_texture(
                dev,
                label,
                [width, height],
                format,
                wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_DST
                    | wgpu::TextureUsages::COPY_SRC,
            );
            let view = tex.create_view(&Default::default());
            (tex, view)
        };
        let (gbuffer, gbuffer_view) =
            target("g-buffer with free forms", wgpu::TextureFormat::Rgba32Uint);
        let (_, shadow_view) = target("free-form shadows", wgpu::TextureFormat::Rg32Uint);
        let bin_bg = |label, depth: &wgpu::TextureView| {
            dev.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &self.bin_bgl,
                entries: &[
                    buf(0, frame_ub),
                    view(3, ray_table),
                    view(4, depth),
                    buf(6, &self.objects),
                    buf(8, &bins_buf),
                ],
            })
        };
        let bin_primary_bg = bin_bg("free-form bins (primary)", terrain_gbuffer);
        // The G-buffer the casts leave their result in: with both kinds the terrain's (see
        // `encode_cast`), else this one.
        let both = self.kinds[0] > 0 && self.kinds[1] > 0;
        let final_view = if both {
            terrain_gbuffer.clone()
        } else {
            gbuffer_view.clone()
        };
        let bin_shadow_bg = bin_bg("free-form bins (shadow)", &final_view);
        let cast_bg = |label, depth: &wgpu::TextureView| {
            dev.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &self.cast_bgl,
                entries: &[
                    buf(0, frame_ub),
                    view(3, ray_table),
                    view(4, depth),
                    buf(6, &self.objects),
                    buf(7, &self.nodes),
                    buf(8, &bins_buf),
                ],
            })
        };
        Ok(ObjectTargets {
            bins,
            bin_primary_bg,
            bin_shadow_bg,
            cast_bg: cast_bg("free-form cast", terrain_gbuffer),
            cast_plain_bg: cast_bg("free-form cast (plain result)", &gbuffer_view),
            shadow_bg: cast_bg("free-form shadows", &final_view),
            gbuffer,
            gbuffer_view,
            final_in_terrain: both,
            final_view,
            shadow_view,
        })
    }

    /// The shade pass's bind group: terrain data, the free-form G-buffer and object data.
    pub fn shade_bind_group(
        &self,
        gpu: &Gpu,
        terrain: [&wgpu::Buffer; 4],
        views: [&wgpu::TextureView; 2],
        t: &ObjectTargets,
    ) -> wgpu::BindGroup {
        let [frame_ub, heights, pyramid, drape] = terrain;
        // The ray table and the volume-sun target.
        let [ray_table, volume_sun] = views;
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shade (free forms)"),
            layout: &self.shade_bgl,
            entries: &[
                buf(0, frame_ub),
                buf(1, heights),
                buf(2, pyramid),
                view(3, ray_table),
                view(4, &t.final_view),
                buf(5, drape),
                buf(6, &self.objects),
                view(9, &t.shadow_view),
                view(19, volume_sun),
            ],
        })
    }

    fn bin(&self, enc: &mut wgpu::CommandEncoder, t: &ObjectTargets, shadow: bool) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(if shadow {
                "bin free forms (shadow)"
            } else {
                "bin free forms (primary)"
            }),
            timestamp_writes: None,
        });
        pass.set_pipeline(if shadow {
            &self.bin_shadow
        } else {
            &self.bin_primary
        });
        pass.set_bind_group(
            0,
            if shadow {
                &t.bin_shadow_bg
            } else {
                &t.bin_primary_bg
            },
            &[],
        );
        pass.dispatch_workgroups((t.bins[0] * t.bins[1]).div_ceil(64), 1, 1);
    }

    /// One render pass into `target` drawing, for each pipeline, the bins listing objects of
    /// its kind.
    fn binned(
        &self,
        enc: &mut wgpu::CommandEncoder,
        t: &ObjectTargets,
        draws: &[(&wgpu::RenderPipeline, &wgpu::BindGroup)],
        target: &wgpu::TextureView,
        load: wgpu::LoadOp<wgpu::Color>,
    ) {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("free forms (binned)"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        for (pipeline, bg) in draws {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, *bg, &[]);
            pass.draw(0..6 * t.bins[0] * t.bins[1], 0..1);
        }
    }

    /// Records the primary binning and the free-form cast (after the terrain cast). With one
    /// kind of object: the free-form G-buffer starts as a copy of the terrain's and that
    /// kind's pass writes its nearer hits into it. With both kinds, no copies: the plain pass
    /// reads the terrain's G-buffer and writes the free-form one over the bins either kind
    /// lists (passing its input through where only perturbed objects are listed); the
    /// perturbed pass reads that and writes the terrain's G-buffer over the same bins
    /// (passing through where only plain objects are listed), which then holds the result
    /// (`ObjectTargets::final_view`; elsewhere it is the terrain's hit, as it should be).
    ///
    /// `near`: anti-aliasing's centre rays, whose perturbed pass also flags near misses.
    /// Returns the time of the sub-passes `Gpu::trace_lap` waited for (0 without tracing).
    pub fn encode_cast(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        t: &ObjectTargets,
        terrain: (&wgpu::Texture, &wgpu::TextureView),
        near: bool,
    ) -> f64 {
        let (terrain_gbuffer, terrain_view) = terrain;
        let general = &self.cast[if near { 2 } else { 1 }];
        self.bin(enc, t, false);
        let mut traced = gpu.trace_lap(enc, "bin primary");
        let load = wgpu::LoadOp::Load;
        if t.final_in_terrain {
            let plain = [
                (&self.cast[0], &t.cast_bg),
                (&self.copy_through[0], &t.cast_bg),
            ];
            self.binned(enc, t, &plain, &t.gbuffer_view, load);
            traced += gpu.trace_lap(enc, "cast plain");
            let general = [
                (general, &t.cast_plain_bg),
                (&self.copy_through[1], &t.cast_plain_bg),
            ];
            self.binned(enc, t, &general, terrain_view, load);
            return traced + gpu.trace_lap(enc, "cast general");
        }
        enc.copy_texture_to_texture(
            terrain_gbuffer.as_image_copy(),
            t.gbuffer.as_image_copy(),
            terrain_gbuffer.size(),
        );
        traced += gpu.trace_lap(enc, "copy");
        let kind = if self.kinds[0] > 0 { 0 } else { 1 };
        let pass = if kind == 0 { &self.cast[0] } else { general };
        self.binned(enc, t, &[(pass, &t.cast_bg)], &t.gbuffer_view, load);
        let name = if kind == 0 {
            "cast plain"
        } else {
            "cast general"
        };
        traced + gpu.trace_lap(enc, name)
    }

    /// Records the shadow binning and the free-form shadow passes (after the free-form cast,
    /// before shading). `near`: anti-aliasing's centre rays, whose near-miss twins follow.
    /// Returns the time of the sub-passes `Gpu::trace_lap` waited for (0 without tracing).
    pub fn encode_shadows(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        t: &ObjectTargets,
        near: bool,
    ) -> f64 {
        self.bin(enc, t, true);
        let traced = gpu.trace_lap(enc, "bin shadow");
        // Both kinds in one render pass (they only mark blocked pixels, in any order, and the
        // near-miss twins write the other channel): one pass's fixed cost less on Mesa's CPU
        // adapters.
        let passes = if near { 4 } else { 2 };
        let draws: Vec<_> = (0..passes)
            .filter(|&k| self.kinds[k % 2] > 0)
            .map(|k| (&self.shadow[k], &t.shadow_bg))
            .collect();
        // No clear (on lavapipe a clear costs about what a pass does): blocked pixels carry
        // this frame's stamp, anything else in the target is from earlier frames.
        self.binned(enc, t, &draws, &t.shadow_view, wgpu::LoadOp::Load);
        traced + gpu.trace_lap(enc, "shadows")
    }
}
