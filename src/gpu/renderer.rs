//! The terrain renderer: holds the terrain's passes and the scene's (free forms, volumes, voxel
//! models, edge blend, test pattern), makes the size-dependent targets, and orchestrates a
//! frame: parameter blocks, the passes in order, readback.

use super::blend::BlendPass;
use super::device::KernelPath;
use super::frame::{FrameOutput, PassTimes, RenderSettings, Stage, TraceMode};
use super::objects::{ObjectPasses, BIN_CAPACITY};
use super::pattern::PatternPass;
use super::readback::{self, Extras};
use super::table::TableMode;
use super::targets::{TargetPasses, Targets};
use super::terrain_passes::{RayGen, TerrainPasses};
use super::uniforms::{frame_uniforms, raygen_uniforms, table_raygen_uniforms};
use super::util::{encode_fullscreen, encode_fullscreen_with};
use super::variants::ShadeFeatures;
use super::volume_set::VolumeSet;
use super::voxels::VoxelPasses;
use super::Gpu;
use crate::cpu::voxel::InstanceRect;
use crate::display::pattern::PatternParams;
use crate::scene::{Camera, SceneDesc};

mod antialias;
mod instances;
use crate::terrain::curved::GridCurvature;
use crate::terrain::Terrain;
use crate::{Error, Result};
use std::time::Instant;

#[path = "renderer_paged.rs"]
mod paged;

// Names this file held before the gpu room was split, still reachable at their old paths.

/// Terrain data on the GPU and the pipelines that render it.
pub struct TerrainRenderer {
    base: TerrainPasses,
    table: Option<TableMode>,
    objects: Option<ObjectPasses>,
    /// Lowest world z of the free forms' bounding spheres (+inf without free forms), as
    /// placed and as this frame sees them (lowered on the curved earth).
    objects_floor: f64,
    placed_floor: f64,
    /// The scene objects' floor as this frame sees them (without the instances).
    statics_floor: f64,
    /// Entity instances to draw ([`Self::set_instances`]) and whether they changed.
    instances: Vec<(usize, crate::freeform::FreeForm)>,
    instances_dirty: bool,
    /// CIGI entities drawn from voxel templates (`(template, model posed)`), and whether
    /// they changed since placed.
    voxel_instances: Vec<(usize, crate::voxel::VoxelInstance)>,
    voxel_instances_dirty: bool,
    /// The curvature the objects were last moved for ([`Self::lower_objects`]); `None`: as
    /// placed.
    lowered_for: Option<GridCurvature>,
    volumes: VolumeSet,
    /// Edge blend of a display channel (see [`Self::set_blend`]).
    blend: Option<BlendPass>,
    voxels: Option<VoxelPasses>,
    /// Warp test pattern instead of the scene (see [`Self::set_pattern`]).
    pattern: Option<(PatternPass, PatternParams)>,
    /// Scene time in seconds (animated voxel models).
    time: f64,
    /// Frames run so far (wrapping, never 0): the frame's stamp in the uniforms.
    stamp: u32,
    targets: Option<Targets>,
    /// The paged terrain's tile pool (group 3), in paged mode ([`Self::new_paged`]).
    paged: Option<super::terrain_pool::TerrainPool>,
    /// Anti-aliasing passes and targets, made on first use (`RenderSettings::antialias`).
    antialias: Option<antialias::AntialiasState>,
}

/// One frame being recorded: what it shows, how far it goes and whether its passes are timed.
#[derive(Clone, Copy)]
struct FrameJob<'a> {
    gpu: &'a Gpu,
    terrain: &'a Terrain,
    scene: &'a SceneDesc,
    cam: &'a Camera,
    s: &'a RenderSettings,
    stage: Stage,
    timed: bool,
    /// The passes run on the anti-aliasing sample atlas (`gpu::antialias`).
    atlas: bool,
}

impl FrameJob<'_> {
    /// With timing on, submits what `enc` holds, waits for it and adds its wall time to
    /// `slot`.
    fn lap(&self, enc: &mut wgpu::CommandEncoder, slot: &mut f64) -> Result<()> {
        if self.timed {
            let gpu = self.gpu;
            let start = Instant::now();
            let done =
                std::mem::replace(enc, gpu.device.create_command_encoder(&Default::default()));
            gpu.queue.submit([done.finish()]);
            gpu.wait()?;
            *slot += start.elapsed().as_secs_f64() * 1e3;
        }
        Ok(())
    }
}

/// Pipelines a frame's passes use, built before recording.
struct Prepared {
    features: ShadeFeatures,
    /// The frame's stamp (`Frame.stamp`); anti-aliasing samples take the next ones.
    stamp: u32,
    /// The frame's uniforms (the anti-aliasing atlas's are these with its size).
    uniforms: super::types::FrameUniforms,
    /// The shade pipelines of the frame's rays (with anti-aliasing, its centre rays', which
    /// search their sun rays' footprints) and of anti-aliasing's samples.
    shade_index: [usize; 2],
    /// Per volume, its pipeline for the current switches (empty when no volume is integrated).
    volume_pipelines: Vec<usize>,
}

/// Rectangles of the voxel cast and (when shading with shadows) the voxel shadow pass.
type VoxelRects = (Vec<InstanceRect>, Vec<InstanceRect>);

/// The G-buffer the shade pass reads: the free-form one when there are free forms of one kind
/// only; with both kinds the casts end in the terrain's.
fn final_gbuffer(t: &Targets) -> (&wgpu::Texture, &wgpu::TextureView) {
    match &t.objects {
        Some((ot, _)) if !ot.final_in_terrain => (&ot.gbuffer, &ot.gbuffer_view),
        _ => (&t.gbuffer, &t.gbuffer_view),
    }
}

impl TerrainRenderer {
    /// Uploads the terrain (heights, pyramid, drape) and builds the pipelines, with the kernel
    /// path `gpu.options.kernels` gives on the adapter ([`super::KernelChoice::path`]).
    pub fn new(gpu: &Gpu, terrain: &Terrain) -> Result<TerrainRenderer> {
        Self::with_kernels(gpu, terrain, gpu.options.kernels.path(&gpu.info))
    }

    /// As [`TerrainRenderer::new`] with an explicit kernel path.
    pub fn with_kernels(
        gpu: &Gpu,
        terrain: &Terrain,
        kernels: KernelPath,
    ) -> Result<TerrainRenderer> {
        Self::with_passes(TerrainPasses::new(gpu, terrain, kernels, None)?)
    }

    /// A renderer of the terrain `base` renders.
    pub(super) fn with_passes(base: TerrainPasses) -> Result<TerrainRenderer> {
        Ok(TerrainRenderer {
            base,
            table: None,
            objects: None,
            objects_floor: f64::INFINITY,
            placed_floor: f64::INFINITY,
            statics_floor: f64::INFINITY,
            instances: Vec::new(),
            instances_dirty: false,
            voxel_instances: Vec::new(),
            voxel_instances_dirty: false,
            lowered_for: None,
            volumes: VolumeSet::default(),
            blend: None,
            voxels: None,
            pattern: None,
            time: 0.0,
            stamp: 0,
            targets: None,
            paged: None,
            antialias: None,
        })
    }

    /// Switches ray generation to a distortion table: uploads the projector's screen points
    /// (kept while the projector does not move) and builds the table pipelines. Frames must
    /// then be rendered at the projector's resolution; the eye is set by [`Self::set_eye`].
    pub fn set_display(
        &mut self,
        gpu: &Gpu,
        points: &crate::display::screen_points::ScreenPoints,
        eye: glam::DVec3,
    ) -> Result<()> {
        let what = format!("projector resolution {}x{}", points.width, points.height);
        gpu.scoped(&what, || {
            self.table = Some(TableMode::new(gpu, &self.base, points, eye)?);
            self.targets = None;
            Ok(())
        })
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
        self.upload_with_templates(gpu, objects, &[], allow_uniform)
    }

    fn upload_with_templates(
        &mut self,
        gpu: &Gpu,
        objects: &[crate::freeform::FreeForm],
        templates: &[(crate::freeform::FreeForm, usize)],
        allow_uniform: bool,
    ) -> Result<()> {
        self.objects = if objects.is_empty() && templates.is_empty() {
            None
        } else {
            let t = templates;
            Some(ObjectPasses::with_templates(
                gpu,
                objects,
                t,
                allow_uniform,
                self.paged.as_ref().map(|p| &p.bgl),
            )?)
        };
        self.instances.clear();
        self.instances_dirty = false;
        self.objects_floor = objects
            .iter()
            .map(|o| {
                let (c, r) = o.bounding_sphere();
                c.z - r
            })
            .fold(f64::INFINITY, f64::min);
        self.placed_floor = self.objects_floor;
        self.statics_floor = self.objects_floor;
        self.lowered_for = None;
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
        self.volumes.set(gpu, volumes)?;
        self.lowered_for = None;
        self.targets = None;
        Ok(())
    }

    /// With `true`, the volumes still shadow the surfaces below them but are not integrated:
    /// the frame is the image the volume passes would composite over (for tests that check
    /// the volume pass against the CPU integral over that image, and for diagnostics).
    pub fn set_volumes_hidden(&mut self, hidden: bool) {
        self.volumes.hidden = hidden;
    }

    /// Reclassifies the volumes with a new transfer function (table and brick occupancy are
    /// recomputed and uploaded), all of them.
    pub fn set_volume_transfer(&mut self, gpu: &Gpu, tf: crate::volume::TransferFunction) {
        self.volumes.set_transfer(gpu, tf);
    }

    /// Changes the volumes' sampling switches (step, skipping, termination, jitter, mip-maps),
    /// all of them.
    pub fn set_volume_settings(&mut self, gpu: &Gpu, settings: crate::volume::VolumeSettings) {
        self.volumes.set_settings(gpu, settings);
    }

    /// Renders the warp test pattern ([`crate::display::pattern`]) from the ray table instead
    /// of the scene while `Some` (the tile, cast and shade passes are skipped); `None` renders
    /// the scene again.
    pub fn set_pattern(&mut self, gpu: &Gpu, params: Option<PatternParams>) {
        self.pattern = match (params, self.pattern.take()) {
            (None, _) => None,
            (Some(p), Some((pass, _))) => Some((pass, p)),
            (Some(p), None) => Some((PatternPass::new(gpu), p)),
        };
    }

    /// Sets (or, with `None`, removes) the edge blend applied to the finished image, in display
    /// space after the warp ([`crate::display::blend`]).
    pub fn set_blend(
        &mut self,
        gpu: &Gpu,
        blend: Option<&crate::display::blend::ChannelBlend>,
    ) -> Result<()> {
        self.blend = blend.map(|b| BlendPass::new(gpu, b)).transpose()?;
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
        let volumes = match self.volumes.passes.len() as u64 {
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
        self.check_target_size(gpu, what, width, height)?;
        // Free the old targets before allocating the new ones (the anti-aliasing targets
        // read the colour target: made again too).
        self.targets = None;
        if let Some(a) = &mut self.antialias {
            a.targets = None;
        }
        let made = gpu.scoped(&format!("{what} {width}x{height}"), || {
            let passes = self.target_passes(self.blend.as_ref());
            self.targets = Some(Targets::new(gpu, &passes, width, height)?);
            Ok(())
        });
        if made.is_err() {
            self.targets = None;
        }
        made
    }

    /// The passes a frame's targets are made for, with the edge blend `blend`.
    fn target_passes<'a>(&'a self, blend: Option<&'a BlendPass>) -> TargetPasses<'a> {
        TargetPasses {
            base: &self.base,
            table: self.table.as_ref(),
            objects: self.objects.as_ref(),
            volumes: &self.volumes,
            voxels: self.voxels.as_ref(),
            blend,
        }
    }

    /// Refuses a `width` x `height` frame (`what` names the size in the message) over the
    /// adapter's texture and buffer limits or the memory budget.
    fn check_target_size(&self, gpu: &Gpu, what: &str, width: u32, height: u32) -> Result<()> {
        let max = gpu.limits.max_texture_dimension_2d;
        if width > max || height > max {
            return Err(Error::Limit {
                what: what.into(),
                msg: format!(
                    "{width}x{height} is larger than the adapter's {max}x{max} texture limit"
                ),
            });
        }
        let readback = super::util::padded_row(width.saturating_mul(16)) as u64 * height as u64;
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
        Ok(())
    }

    fn encode_raygen(&self, enc: &mut wgpu::CommandEncoder, t: &Targets) {
        if let Some(table) = &self.table {
            return encode_fullscreen(
                enc,
                "raygen (table)",
                &table.raygen,
                &t.raygen_bg,
                &[&t.ray_table_view],
            );
        }
        match &self.base.raygen {
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
                encode_fullscreen(enc, "raygen", p, &t.raygen_bg, &[&t.ray_table_view])
            }
        }
    }

    /// Uploads the frame's uniforms and records the passes. With `job.timed`, each pass is
    /// submitted and waited for separately and its wall time returned.
    fn run_passes(&mut self, job: &FrameJob) -> Result<PassTimes> {
        let cam = job.cam;
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
        self.ensure_targets(job.gpu, cam.width, cam.height)?;
        let prepared = self.prepare(job)?;
        self.record(job, &prepared)
    }

    /// Builds the pipelines the frame needs and uploads its parameter blocks.
    fn prepare(&mut self, job: &FrameJob) -> Result<Prepared> {
        let (gpu, s) = (job.gpu, job.s);
        let features = ShadeFeatures {
            shadows: s.shadows,
            drape: self.base.data.has_drape,
            voxels: self.voxels.is_some(),
            volume_shadows: s.shadows && self.volumes.any_casts_shadow(),
            curved: job.terrain.curved,
            lod: s.lod.is_some() && s.mode == TraceMode::Pyramid && self.paged.is_none(),
            paged: self.paged.as_ref().map_or(0, |p| p.bindings()),
            drape_mips: self.base.data.has_drape && s.antialias.is_on(),
            near: false,
            clouds: !job.scene.clouds.is_empty(),
        };
        if features.lod {
            self.base.prepare_cast_lod(gpu);
        }
        if self.antialiased(job) {
            self.base.prepare_cast_near(gpu);
        }
        // Anti-aliasing's centre rays search their sun rays' footprint beams; its samples
        // need not.
        let near = self.antialiased(job) && s.shadows;
        let shade_index = [near, false].map(|near| {
            let f = ShadeFeatures { near, ..features };
            match &mut self.objects {
                Some(o) => o.shade.prepare(&gpu.device, f),
                None => self.base.shade.prepare(&gpu.device, f),
            }
        });
        self.lower_objects(job);
        let t = self.targets.as_ref().expect("targets just ensured");
        let mut fu = frame_uniforms(job.terrain, job.scene, job.cam, s, t.tiles);
        fu.pyramid_dims = [self.base.data.pyramid_side, 0, 0, 0];
        if let Some(pool) = &self.paged {
            // The paged traversal and tile pre-pass start from the level the window's origin
            // is aligned to (`grid.z` = levels used).
            fu.grid[2] = fu.grid[2].min(pool.traversal_top() + 1);
        }
        self.stamp = self.stamp.wrapping_add(1).max(1);
        let antialias = self.antialiased(job);
        // z: the centre rays of an anti-aliased frame look for free forms missed within the
        // pixel cone (`ff_plain_near`); the sample atlas sets its own (`[stamp, 1, 0, 0]`).
        fu.stamp = [self.stamp, 0, (antialias && !job.atlas) as u32, 0];
        let stamp = self.stamp;
        if antialias {
            self.stamp = self.stamp.wrapping_add(antialias::STAMPS);
        }
        if let (Some(o), Some((ot, _))) = (&self.objects, &t.objects) {
            fu.objects = [o.active, ot.bins[0], ot.bins[1], BIN_CAPACITY];
        }
        let data = &self.base.data;
        gpu.queue
            .write_buffer(&data.frame_ub, 0, bytemuck::bytes_of(&fu));
        gpu.queue.write_buffer(
            &data.raygen_ub,
            0,
            bytemuck::bytes_of(&match &self.table {
                Some(t) => table_raygen_uniforms(job.cam, t.eye, t.offset),
                None => raygen_uniforms(job.cam, glam::DVec3::ZERO),
            }),
        );
        let integrated = job.stage == Stage::Shade
            && self.pattern.is_none()
            && self.volumes.composite.is_some()
            && !self.volumes.hidden;
        if antialias {
            self.prepare_antialias(job)?;
        }
        Ok(Prepared {
            features,
            stamp,
            uniforms: fu,
            shade_index,
            volume_pipelines: if integrated {
                self.volumes.prepare(gpu)
            } else {
                Vec::new()
            },
        })
    }

    /// Records the frame's passes (submitting between them when timed) and submits.
    fn record(&self, job: &FrameJob, prepared: &Prepared) -> Result<PassTimes> {
        let gpu = job.gpu;
        let t = self.targets.as_ref().expect("targets just ensured");
        let mut times = PassTimes::default();
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        self.encode_raygen(&mut enc, t);
        job.lap(&mut enc, &mut times.raygen_ms)?;
        if let Some((pass, params)) = &self.pattern {
            let views = (&t.ray_table_view, &t.colour_view, &t.data_view);
            pass.encode(gpu, params, &mut enc, views.0, views.1, views.2);
            job.lap(&mut enc, &mut times.shade_ms)?;
            self.encode_blend(&mut enc, t);
            job.lap(&mut enc, &mut times.blend_ms)?;
            gpu.queue.submit([enc.finish()]);
            return Ok(times);
        }
        let voxel_rects = self.voxel_rects(job);
        self.encode_primary(job, &mut enc, &mut times, t, voxel_rects.as_ref())?;
        if job.stage == Stage::Shade {
            let rects = voxel_rects.as_ref();
            self.encode_shading(job, &mut enc, &mut times, t, prepared, rects)?;
            if self.antialiased(job) {
                enc = self.encode_antialias(job, prepared, t, &mut times, enc)?;
            }
            self.encode_blend(&mut enc, t);
            job.lap(&mut enc, &mut times.blend_ms)?;
        }
        gpu.queue.submit([enc.finish()]);
        Ok(times)
    }

    /// Records the primary-ray passes: tile pre-pass, terrain cast, free-form binning and
    /// cast, voxel cast (over `voxel_rects`).
    fn encode_primary(
        &self,
        job: &FrameJob,
        enc: &mut wgpu::CommandEncoder,
        times: &mut PassTimes,
        t: &Targets,
        voxel_rects: Option<&VoxelRects>,
    ) -> Result<()> {
        let s = job.s;
        let tile_on = s.tile_prepass && s.mode == TraceMode::Pyramid;
        let pool = self.paged.as_ref().map(|p| &p.bind_group);
        if tile_on {
            encode_fullscreen_with(
                enc,
                "tile",
                match (&self.antialias, &self.table) {
                    (Some(aa), _) if job.atlas => &aa.passes.tile,
                    (_, Some(t)) => &t.tile,
                    (_, None) => &self.base.tile,
                },
                &t.tile_bg,
                pool,
                &[&t.tile_view],
            );
        }
        job.lap(enc, &mut times.tile_ms)?;
        // Anti-aliasing's centre rays flag near misses (the atlas's samples need not).
        let centre_rays = self.antialiased(job) && !job.atlas;
        let cast = if tile_on || s.mode == TraceMode::Pyramid {
            self.base.cast_pipeline(s.lod.is_some(), centre_rays)
        } else {
            &self.base.march
        };
        let g = &[&t.gbuffer_view];
        encode_fullscreen_with(enc, "cast", cast, &t.cast_bg, pool, g);
        job.lap(enc, &mut times.cast_ms)?;
        if let Some((o, (ot, _))) = self.objects.as_ref().zip(t.objects.as_ref()) {
            let terrain = (&t.gbuffer, &t.gbuffer_view);
            times.objects_ms = o.encode_cast(job.gpu, enc, ot, terrain, centre_rays);
            job.lap(enc, &mut times.objects_ms)?;
        }
        let voxels = self.voxels.as_ref().zip(t.voxels.as_ref());
        if let (Some((v, vt)), Some((cast, shadows))) = (voxels, voxel_rects) {
            v.update(job.gpu, job.cam.pose.position, self.time, cast, shadows);
            v.encode_cast(enc, vt, final_gbuffer(t), cast, centre_rays);
            job.lap(enc, &mut times.voxels_ms)?;
        }
        Ok(())
    }

    /// Records the shading passes: voxel and free-form shadows, volume sun, shade, volumes and
    /// their composite (the edge blend follows anti-aliasing, in `record`).
    fn encode_shading(
        &self,
        job: &FrameJob,
        enc: &mut wgpu::CommandEncoder,
        times: &mut PassTimes,
        t: &Targets,
        prepared: &Prepared,
        voxel_rects: Option<&VoxelRects>,
    ) -> Result<()> {
        let gpu = job.gpu;
        // Anti-aliasing's centre rays flag their sun rays' near misses too.
        let centre_rays = self.antialiased(job) && !job.atlas;
        let voxels = self.voxels.as_ref().zip(t.voxels.as_ref());
        if let (Some((v, vt)), Some((_, shadows))) = (voxels, voxel_rects) {
            if !shadows.is_empty() {
                v.encode_shadows(enc, vt, final_gbuffer(t), shadows, centre_rays);
                job.lap(enc, &mut times.voxel_shadow_ms)?;
            }
        }
        let index = prepared.shade_index[job.atlas as usize];
        let (pipeline, bg) = match self.objects.as_ref().zip(t.objects.as_ref()) {
            Some((o, (ot, bg))) => {
                if job.s.shadows {
                    times.object_shadow_ms = o.encode_shadows(gpu, enc, ot, centre_rays);
                    job.lap(enc, &mut times.object_shadow_ms)?;
                }
                (o.shade.get(index), bg)
            }
            None => (self.base.shade.get(index), &t.shade_bg),
        };
        self.volumes.write_uniforms(gpu, job.cam.pose.position);
        if prepared.features.volume_shadows
            && self.volumes.encode_sun(enc, &t.volumes, &t.volume_sun_view)
        {
            job.lap(enc, &mut times.volume_shadow_ms)?;
        }
        // With volumes, shade into the image under them; each volume pass writes its own
        // result layer, and the composite pass sorts them per pixel over that image into
        // the colour target.
        let volumes = (self.volumes.composite.as_ref())
            .zip(t.composite.as_ref())
            .filter(|_| !self.volumes.hidden);
        let shaded = volumes.map_or(&t.colour_view, |(_, ct)| &ct.under_view);
        let pool = self.paged.as_ref().map(|p| &p.bind_group);
        let views = &[shaded, &t.data_view];
        encode_fullscreen_with(enc, "shade", pipeline, bg, pool, views);
        job.lap(enc, &mut times.shade_ms)?;
        if let Some(composite) = volumes {
            let pipelines = &prepared.volume_pipelines;
            (self.volumes).encode(enc, pipelines, &t.volumes, composite, &t.colour_view);
            job.lap(enc, &mut times.volume_ms)?;
        }
        Ok(())
    }

    /// Whether the frame gets anti-aliasing samples: asked for, shaded, not the test pattern.
    fn antialiased(&self, job: &FrameJob) -> bool {
        job.s.antialias.is_on() && job.stage == Stage::Shade && self.pattern.is_none()
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
            encode_fullscreen(enc, "blend", &b.pipeline, &bt.bg, &[&t.colour_view]);
        }
    }

    /// Renders one frame up to `stage` without reading it back (for benchmarks and the frame
    /// loop: the caller waits or presents). The times are not taken (zero); the
    /// anti-aliased pixels' counts are (`PassTimes::antialias_counts`).
    pub fn render(
        &mut self,
        gpu: &Gpu,
        terrain: &Terrain,
        scene: &SceneDesc,
        cam: &Camera,
        s: &RenderSettings,
        stage: Stage,
    ) -> Result<PassTimes> {
        let job = FrameJob {
            gpu,
            terrain,
            scene,
            cam,
            s,
            stage,
            timed: false,
            atlas: false,
        };
        self.run_passes(&job)
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
        let job = FrameJob {
            gpu,
            terrain,
            scene,
            cam,
            s,
            stage: Stage::Shade,
            timed: true,
            atlas: false,
        };
        let times = self.run_passes(&job)?;
        let t = self.targets.as_ref().expect("targets exist after a render");
        let extras = Extras {
            volume_sun: s.shadows && self.volumes.any_casts_shadow(),
            volume_stats: !self.volumes.hidden,
        };
        readback::capture(gpu, t, extras, times)
    }

    /// Reads back the ray table of the last frame: per pixel (direction xyz, cone half-angle;
    /// negative where the pixel shows no screen). For tests and warp tools.
    pub fn read_ray_table(&self, gpu: &Gpu) -> Result<Vec<[f32; 4]>> {
        let t = self
            .targets
            .as_ref()
            .ok_or_else(|| Error::Gpu("no frame rendered yet".into()))?;
        readback::ray_table(gpu, t)
    }
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
