//! Recording of an anti-aliased frame's extra passes (`gpu::antialias`): the edge mask read
//! back into the list of marked pixels, the sample atlas (its frame passes run once for every
//! sample), and the resolve into the frame's colour and data.

use super::{FrameJob, Prepared, TerrainRenderer, VoxelRects};
use crate::cpu::voxel::{InstanceRect, PixelRect};
use crate::gpu::antialias::{batches, copy_whole, AntialiasPasses, AntialiasTargets, Atlas, Batch};
use crate::gpu::frame::PassTimes;
use crate::gpu::objects::BIN_CAPACITY;
use crate::gpu::targets::Targets;
use crate::Result;
use std::cell::RefCell;
use std::time::Instant;

/// Frame stamps an anti-aliased frame reserves after its own, one per batch of samples (a
/// list that fills the atlas 16 times over, the reference's, needs 16).
pub(super) const STAMPS: u32 = 17;

/// The anti-aliasing passes and the targets of the current frame size.
pub(crate) struct AntialiasState {
    pub passes: AntialiasPasses,
    pub targets: Option<AntialiasTargets>,
    /// The sample atlas of the last anti-aliased frame (made again when its size changes).
    atlas: RefCell<Option<Atlas>>,
}

impl TerrainRenderer {
    /// Builds the passes on first use and the screen targets for the current frame size;
    /// writes the parameters. Called from `prepare` when the frame is anti-aliased; fails
    /// on an adapter that cannot store from a fragment shader (the resolve does).
    pub(super) fn prepare_antialias(&mut self, job: &FrameJob) -> Result<()> {
        let gpu = job.gpu;
        if !(gpu.downlevel).contains(wgpu::DownlevelFlags::FRAGMENT_WRITABLE_STORAGE) {
            return Err(crate::Error::Limit {
                what: "storage textures in fragment shaders".into(),
                msg: format!(
                    "anti-aliasing stores its pixels into the frame from a fragment shader, \
                     which {} does not allow; render with --antialias off or on another \
                     adapter (WGPU_BACKEND=vulkan)",
                    gpu.info.name
                ),
            });
        }
        let t = self.targets.as_ref().expect("targets just ensured");
        let size = [t.width, t.height];
        let state = self.antialias.get_or_insert_with(|| AntialiasState {
            passes: AntialiasPasses::new(gpu, &self.base),
            targets: None,
            atlas: RefCell::new(None),
        });
        if state.targets.is_none() {
            *state.atlas.borrow_mut() = None;
            let frame = [&t.colour_view, &t.data_view];
            state.targets = Some(state.passes.targets(gpu, size, &t.ray_table_view, frame));
        }
        state
            .passes
            .write_params(gpu, size, job.s.antialias, &Batch::default());
        Ok(())
    }

    /// The frame targets of a `size` atlas (no edge blend: it follows the resolve).
    fn atlas_targets(&self, job: &FrameJob, [w, h]: [u32; 2]) -> Result<Targets> {
        self.check_target_size(job.gpu, "anti-aliasing sample atlas", w, h)?;
        let passes = self.target_passes(None);
        job.gpu
            .scoped(&format!("anti-aliasing sample atlas {w}x{h}"), || {
                Targets::new(job.gpu, &passes, w, h)
            })
    }

    /// Records the samples after the centre frame `enc` holds: submits the centre frame and
    /// the edge mask, reads the mask back, submits the samples' passes on the atlas and the
    /// resolve; returns a fresh encoder (the edge blend follows).
    pub(super) fn encode_antialias(
        &self,
        job: &FrameJob,
        prepared: &Prepared,
        t: &Targets,
        times: &mut PassTimes,
        mut enc: wgpu::CommandEncoder,
    ) -> Result<wgpu::CommandEncoder> {
        let gpu = job.gpu;
        let Some(state) = &self.antialias else {
            return Ok(enc);
        };
        let (aa, at) = (&state.passes, state.targets.as_ref().expect("prepared"));
        let start = Instant::now();
        // Timed frames (`--trace-passes`) log the split: edges and list, samples, resolve.
        let mut laps = Laps::new(job.timed, gpu.options.trace_passes);
        copy_whole(&mut enc, &t.data, &at.centre_data);
        aa.encode_edges(&mut enc, at);
        gpu.queue.submit([enc.finish()]);
        let counts = at.list(gpu)?;
        laps.lap(gpu, "edges and list")?;
        let marked: u32 = counts.iter().sum();
        times.antialias_counts = counts.map(u64::from);
        if marked > 0 {
            let aa_s = job.s.antialias;
            let batches = batches(counts, at.batch_groups());
            let size = at.atlas_size(batches[0].groups);
            log::debug!(
                "anti-aliasing: {marked} pixels marked (16, 8, 4 samples: {counts:?}), atlas {size:?}"
            );
            let mut atlas = state.atlas.borrow_mut();
            if atlas.as_ref().map(|a| [a.targets.width, a.targets.height]) != Some(size) {
                *atlas = None;
                *atlas = Some(aa.atlas(gpu, at, self.atlas_targets(job, size)?));
            }
            let atlas = atlas.as_ref().expect("just made");
            for (b, batch) in batches.iter().enumerate() {
                aa.write_params(gpu, at.size, aa_s, batch);
                let mut enc = gpu.device.create_command_encoder(&Default::default());
                self.encode_samples(job, prepared, atlas, (b as u32, batch), &mut enc)?;
                laps.lap(gpu, "samples")?;
                aa.encode_resolve(&mut enc, atlas, at, batch.count);
                gpu.queue.submit([enc.finish()]);
                laps.lap(gpu, "resolve")?;
            }
            laps.log(marked);
        }
        if job.timed {
            gpu.wait()?;
            times.antialias_ms = start.elapsed().as_secs_f64() * 1e3;
        }
        Ok(gpu.device.create_command_encoder(&Default::default()))
    }

    /// Records every sample's passes of batch number `batch` (its share of the list:
    /// `marked`) on `atlas`: its frame uniforms (its
    /// size, tiles and bins, a stamp of its own, bins over every ray; the tile pre-pass over
    /// every ray of a tile), the sample rays, the primary and shading passes.
    fn encode_samples(
        &self,
        job: &FrameJob,
        prepared: &Prepared,
        atlas: &Atlas,
        (batch, marked): (u32, &Batch),
        enc: &mut wgpu::CommandEncoder,
    ) -> Result<()> {
        let gpu = job.gpu;
        let state = self.antialias.as_ref().expect("prepared");
        let (aa, screen) = (&state.passes, state.targets.as_ref().expect("prepared"));
        let at = &atlas.targets;
        let mut fu = prepared.uniforms;
        fu.size = [at.width, at.height, at.tiles[0], at.tiles[1]];
        if let (Some(o), Some((ot, _))) = (&self.objects, &at.objects) {
            fu.objects = [o.active, ot.bins[0], ot.bins[1], BIN_CAPACITY];
        }
        // A stamp of its own per batch (the free-form shadow marks of an earlier one must not
        // count): the frame reserved `STAMPS` after its own.
        let stamp = prepared
            .stamp
            .wrapping_add(1 + batch.min(STAMPS - 1))
            .max(1);
        fu.stamp = [stamp, 1, 0, 0];
        gpu.queue
            .write_buffer(&self.base.data.frame_ub, 0, bytemuck::bytes_of(&fu));
        // The voxel passes over the whole atlas (screen rectangles do not apply to it).
        let rects: Option<VoxelRects> = self.voxels.as_ref().map(|v| {
            let full = vec![InstanceRect {
                rect: PixelRect::full(at.width, at.height),
                instances: v.active_mask(),
            }];
            let shadows = if job.s.shadows {
                full.clone()
            } else {
                Vec::new()
            };
            (full, shadows)
        });
        // Timed frames (captures): every pass on the atlas is waited for; its split is logged
        // per batch, at `info` with `--trace-passes` (a profile) and at `debug` otherwise (a
        // capture of thousands of frames logs one line a frame, not one a batch).
        let atlas_job = FrameJob {
            atlas: true,
            ..*job
        };
        let mut times = PassTimes::default();
        aa.encode_rays(enc, atlas, screen, marked.count);
        self.encode_primary(&atlas_job, enc, &mut times, at, rects.as_ref())?;
        self.encode_shading(&atlas_job, enc, &mut times, at, prepared, rects.as_ref())?;
        if job.timed {
            let level = if job.gpu.options.trace_passes {
                log::Level::Info
            } else {
                log::Level::Debug
            };
            log::log!(
                level,
                "anti-aliasing atlas {}x{} batch {batch}: sample rays and tile {:.1} ms, cast {:.1} ms, free forms {:.1} ms, voxels {:.1} ms, voxel shadows {:.1} ms, free-form shadows {:.1} ms, shade {:.1} ms, volumes {:.1} ms",
                at.width,
                at.height,
                times.tile_ms,
                times.cast_ms,
                times.objects_ms,
                times.voxels_ms,
                times.voxel_shadow_ms,
                times.object_shadow_ms,
                times.shade_ms,
                times.volume_shadow_ms + times.volume_ms
            );
        }
        Ok(())
    }
}

/// Wall time of the anti-aliasing stages of a timed frame, each waited for; logged at `info`
/// with `--trace-passes` (a profile), else at `debug` (`relief serve` times every frame: one
/// line a frame at 60 Hz).
struct Laps {
    on: bool,
    level: log::Level,
    last: Instant,
    laps: Vec<(&'static str, f64)>,
}

impl Laps {
    fn new(on: bool, trace_passes: bool) -> Laps {
        Laps {
            on,
            level: if trace_passes {
                log::Level::Info
            } else {
                log::Level::Debug
            },
            last: Instant::now(),
            laps: Vec::new(),
        }
    }

    /// Waits for what was submitted and adds the time since the last lap to `stage`'s.
    fn lap(&mut self, gpu: &crate::gpu::Gpu, stage: &'static str) -> Result<()> {
        if self.on {
            gpu.wait()?;
            let ms = self.last.elapsed().as_secs_f64() * 1e3;
            match self.laps.iter_mut().find(|(s, _)| *s == stage) {
                Some((_, t)) => *t += ms,
                None => self.laps.push((stage, ms)),
            }
            self.last = Instant::now();
        }
        Ok(())
    }

    fn log(&self, marked: u32) {
        if self.on {
            let laps: Vec<String> = (self.laps.iter())
                .map(|(s, ms)| format!("{s} {ms:.1} ms"))
                .collect();
            log::log!(
                self.level,
                "anti-aliasing, {marked} pixels: {}",
                laps.join(", ")
            );
        }
    }
}
