//! One frame of the window loop: step the simulation, render each window's view (capturing it
//! to files when asked), present it through the present pass, and record the frame's
//! statistics; plus the text overlay and the statistics CSV.

use super::grab::{copy_surface, write_grabs};
use super::motion::Mode;
use super::prepare::Prepared;
use super::present::{pack_text, PresentUniforms, ViewMode};
use super::stats::{self, FrameStat};
use super::timer::TIMER_SLOTS;
use super::window::{App, Win};
use crate::app::capture::frame_metadata;
use crate::app::output::{frame_paths, write_frame_files};
use crate::gpu::{FrameOutput, Gpu, Stage};
use crate::scene::{Camera, Pose, SceneDesc};
use crate::{Error, Result};
use glam::DVec3;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The simulation's state for a frame.
struct Step {
    n: u64,
    /// Simulation time (s).
    t: f64,
    /// The camera's pose in the world (the frame of the window now where a paged window
    /// follows the eye).
    pose: Pose,
    /// The pose in the scene's own frame (the motion's; the camera's with `--cigi`): what
    /// `--record` and the statistics' position give.
    scene_pose: Pose,
    eye: Option<DVec3>,
    screenshot: bool,
    grab: bool,
    overlay: Option<Vec<String>>,
    /// `--cigi`: the frame's `cigi` JSON part and the ownship's geodetic position.
    cigi: Option<(serde_json::Value, Option<[f64; 3]>)>,
    /// `--cigi`: the entities drawn from the scene's templates.
    instances: Option<crate::world::Instances>,
}

/// Position `p` of the scene's own frame in `terrain`'s, the world's: through a paged window's
/// follower (`Follower::to_window`), `p` itself without one.
fn in_window(
    follower: &Option<crate::app::paged::Follower>,
    terrain: &crate::terrain::Terrain,
    p: DVec3,
) -> DVec3 {
    follower.as_ref().map_or(p, |f| f.to_window(terrain, p))
}

/// What drawing the windows took.
#[derive(Default)]
struct Drawn {
    /// Blocked acquiring swap-chain images.
    acquire: Duration,
    /// Blocked in the present pass's submit and the present calls.
    present_call: Duration,
    /// When the last window's frame was handed to present.
    last_present: Option<Instant>,
    /// Render size of the first window drawn.
    first_size: Option<(u32, u32)>,
    /// GPU milliseconds measured as wall time to completion (NaN with timestamp queries).
    gpu_ms: f64,
    /// Blocked waiting for the GPU to finish (no timestamp queries).
    gpu_wait: Duration,
    /// Anti-aliased pixels with 16, 8 and 4 samples, over the windows.
    antialias_counts: [u64; 3],
}

/// What drawing one window needs besides the window.
struct Draw<'a> {
    prep: &'a Prepared,
    desc: &'a SceneDesc,
    instance: &'a wgpu::Instance,
    step: &'a Step,
    view_mode: ViewMode,
    font: &'a [[u32; 4]; 48],
    windows: usize,
}

impl App {
    /// Renders and presents one frame in every window.
    pub(super) fn frame(&mut self) -> Result<()> {
        let start = Instant::now();
        let loop_start = *self.loop_start.get_or_insert(start);
        self.poll_gpu();
        let step = self.step()?;
        let drawn = self.draw(&step)?;
        let p = &mut self.prep;
        if let Some(ig) = &mut p.cigi {
            ig.end_frame(&p.world.terrain);
        }
        self.record(&step, &drawn, start, loop_start)
    }

    /// wgpu's live objects at frames 100 and 500 ([`super::ViewReport::resources`]), and the
    /// GPU times that have arrived.
    fn poll_gpu(&mut self) {
        let n = self.frame;
        let Some(run) = &mut self.run else { return };
        if n == 100 || n == 500 {
            let counts = run.gpu.resource_counts().unwrap_or_default();
            self.resources.push((n, counts));
        }
        self.collect_gpu_times();
    }

    /// Reads the timestamp queries that have arrived into the run's statistics.
    pub(super) fn collect_gpu_times(&mut self) {
        let Some(run) = &mut self.run else { return };
        let _ = run.gpu.device.poll(wgpu::PollType::Poll);
        if let Some(timer) = &mut run.timer {
            for (f, ms) in timer.collect() {
                self.stats.set_gpu_ms(f, ms);
            }
        }
    }

    /// Steps the simulation to this frame: controls, motion, eye point, the frame's requests.
    fn step(&mut self) -> Result<Step> {
        let n = self.frame;
        let dt = 1.0 / self.prep.opts.rate;
        let t = n as f64 * dt;
        let c = self.controls(t);
        let p = &mut self.prep;
        // The motion stays in the scene's own frame; a paged window that moved with the eye
        // gets its positions through the follower.
        let to_window = |x| in_window(&p.follower, &p.world.terrain, x);
        let dt_step = if n == 0 { 0.0 } else { dt };
        (p.motion).step_over(t, dt_step, &c, &p.world.terrain, to_window);
        let eye = self.eye_for(n)?;
        let p = &mut self.prep;
        let scene_pose = p.motion.pose;
        // A paged window follows the eye (also off the window): a CIGI host's ownship, else
        // the motion's; each window's pool takes it before its frame (`render`).
        if let Some(ig) = &mut p.cigi {
            // The same per-frame session update as `relief serve`.
            if ig.sync {
                ig.wait_host_frame()?;
            } else {
                ig.poll();
            }
            if let (Some(lla), Some(f)) = (ig.eye_geodetic(), &mut p.follower) {
                f.follow(&mut p.world, lla)?;
            }
        } else if let Some(f) = &mut p.follower {
            f.follow_scene_eye(&mut p.world, scene_pose.position)?;
        }
        let mut pose = scene_pose;
        pose.position = in_window(&p.follower, &p.world.terrain, pose.position);
        let (mut cigi, mut instances) = (None, None);
        if let Some(ig) = &mut p.cigi {
            let (cam, own) = ig.camera_pose(&p.world.terrain, pose);
            pose = cam;
            let at = own
                .map(|o| o.geodetic)
                .or_else(|| p.world.terrain.world_to_geodetic(pose.position));
            ig.environment(&mut self.desc, at);
            instances = Some(ig.instances(&p.world.terrain, &p.world.templates));
            cigi = Some((ig.frame_json(ig.ig_frame), own.map(|o| o.geodetic)));
        }
        Ok(Step {
            n,
            t,
            pose,
            scene_pose: if p.cigi.is_some() { pose } else { scene_pose },
            cigi,
            instances,
            eye,
            screenshot: std::mem::take(&mut self.screenshot),
            grab: self.prep.opts.grab == Some(n),
            overlay: self.overlay.then(|| self.overlay_text()),
        })
    }

    /// Renders and presents every window, between the frame's two GPU timestamps (or waiting
    /// for the GPU when there are none).
    fn draw(&mut self, step: &Step) -> Result<Drawn> {
        let run = self.run.as_mut().expect("running");
        let gpu = &run.gpu;
        let ctx = Draw {
            prep: &self.prep,
            desc: &self.desc,
            instance: &self.instance,
            step,
            view_mode: self.view_mode,
            font: &self.font,
            windows: run.windows.len(),
        };
        let slot = run.timer.as_ref().and_then(|tm| tm.slot(step.n));
        if let (Some(tm), Some(s)) = (&run.timer, slot) {
            let mut enc = gpu.device.create_command_encoder(&Default::default());
            tm.stamp(&mut enc, 2 * s);
            gpu.queue.submit([enc.finish()]);
        }
        let wall_done: Arc<Mutex<Option<Instant>>> = Arc::new(Mutex::new(None));
        let submit_start = Instant::now();
        let mut d = Drawn {
            gpu_ms: f64::NAN,
            ..Drawn::default()
        };
        for (wi, w) in run.windows.iter_mut().enumerate() {
            if w.hidden {
                continue;
            }
            let (size, counts) = ctx.render(gpu, w)?;
            d.first_size.get_or_insert(size);
            for (a, c) in d.antialias_counts.iter_mut().zip(counts) {
                *a += c;
            }
            ctx.present(gpu, w, wi, size, &mut d)?;
        }
        if let (Some(tm), Some(s)) = (&mut run.timer, slot) {
            let mut enc = gpu.device.create_command_encoder(&Default::default());
            tm.stamp(&mut enc, 2 * s + 1);
            tm.resolve(&mut enc, s);
            gpu.queue.submit([enc.finish()]);
            tm.start_readback(s, step.n);
        }
        if run.timer.is_none() {
            let waiting = Instant::now();
            let cell = wall_done.clone();
            gpu.queue
                .on_submitted_work_done(move || *cell.lock().unwrap() = Some(Instant::now()));
            gpu.wait()?;
            d.gpu_wait = waiting.elapsed();
            if let Some(done) = *wall_done.lock().unwrap() {
                d.gpu_ms = (done - submit_start).as_secs_f64() * 1e3;
            }
        } else {
            // Frames timed with timestamp queries are not waited for: a wgpu error no scope
            // caught (`Gpu::uncaught`) still ends the run at the frame its report came in.
            gpu.check()?;
        }
        Ok(d)
    }

    /// The frame's statistics, the recorded path and the CSV rows that are complete.
    fn record(
        &mut self,
        step: &Step,
        d: &Drawn,
        start: Instant,
        loop_start: Instant,
    ) -> Result<()> {
        let (n, pose) = (step.n, step.pose);
        let end = Instant::now();
        let period_ms = 1e3 / self.prep.opts.rate;
        let frame_ms = self
            .last_start
            .map_or(0.0, |s| (start - s).as_secs_f64() * 1e3);
        let present_interval_ms = match (self.last_present, d.last_present) {
            (Some(a), Some(b)) => (b - a).as_secs_f64() * 1e3,
            _ => 0.0,
        };
        let (w, h) = d.first_size.unwrap_or((0, 0));
        let blocked = d.acquire + d.present_call + d.gpu_wait;
        let stat = FrameStat {
            frame: n,
            sim_time: step.t,
            start_s: (start - loop_start).as_secs_f64(),
            frame_ms,
            cpu_ms: ((end - start).saturating_sub(blocked)).as_secs_f64() * 1e3,
            acquire_ms: d.acquire.as_secs_f64() * 1e3,
            present_ms: d.present_call.as_secs_f64() * 1e3,
            gpu_ms: d.gpu_ms,
            present_interval_ms,
            latency_ms: d
                .last_present
                .map_or(f64::NAN, |p| (p - start).as_secs_f64() * 1e3),
            dropped: if n == 0 {
                0
            } else {
                stats::dropped_slots(frame_ms, period_ms)
            },
            width: w,
            height: h,
            position: step.scene_pose.position.to_array(),
            agl: (self.prep.world.terrain)
                .height_above_now(pose.position)
                .unwrap_or(f64::NAN),
            heading: pose.heading,
            pitch: pose.pitch,
            roll: pose.roll,
            rss_kib: crate::app::figures::resident_kib().unwrap_or(0),
            aa_pixels: d.antialias_counts.iter().sum(),
            aa_extra_rays: crate::gpu::antialias::sample_rays(d.antialias_counts),
        };
        self.stats.push(stat);
        if d.last_present.is_some() {
            self.last_present = d.last_present;
        }
        self.last_start = Some(start);
        if let Some(r) = &mut self.prep.recorder {
            r.record(step.t, &step.scene_pose)?;
        }
        self.settle_stats(false)?;
        self.frame += 1;
        Ok(())
    }

    /// Settles the frames whose GPU time is known (or can no longer arrive) into the run's
    /// statistics and writes their CSV rows; `all`: every frame (the run ends).
    pub(super) fn settle_stats(&mut self, all: bool) -> Result<()> {
        let timed = self.run.as_ref().is_some_and(|r| r.timer.is_some());
        // Without timestamp queries a frame's GPU time is known when it is pushed.
        let all = all || !timed;
        let late = self.frame.saturating_sub(2 * TIMER_SLOTS);
        for s in self.stats.settle(late, all) {
            if let Some(csv) = &mut self.prep.stats_csv {
                csv.write(&s)?;
            }
        }
        Ok(())
    }

    /// The text overlay's lines: motion mode, frame rate, GPU time, pose, view and fog,
    /// anti-aliasing.
    fn overlay_text(&self) -> Vec<String> {
        let m = &self.prep.motion;
        let p = m.pose;
        let mean = self.stats.recent_frame_ms();
        let last = self.stats.last();
        let terrain = &self.prep.world.terrain;
        let at = in_window(&self.prep.follower, terrain, p.position);
        let agl = terrain.height_above_now(at);
        let mut lines = vec![
            format!(
                "{} {:5.1} FPS {:6.1} MS  GPU {}",
                m.mode.name(),
                if mean > 0.0 { 1e3 / mean } else { 0.0 },
                mean,
                self.stats
                    .last_gpu_ms()
                    .map_or("-".into(), |ms| format!("{ms:.1} MS"))
            ),
            format!(
                "POS {:.0} {:.0} {:.0} M  AGL {}",
                p.position.x,
                p.position.y,
                p.position.z,
                agl.map_or("-".into(), |a| format!("{a:.0} M"))
            ),
            format!(
                "HDG {:03.0}  PITCH {:+.1}  ROLL {:+.1}",
                p.heading, p.pitch, p.roll
            ),
        ];
        if m.mode == Mode::Aircraft {
            lines.push(format!(
                "SPD {:.0} M/S  THR {:.0}%",
                m.aircraft.speed,
                100.0 * m.aircraft.throttle
            ));
        }
        lines.push(format!(
            "VIEW {}  FOG {}  LAT {}  DROP {}",
            self.view_mode.name(),
            if self.desc.fog.visibility > 0.0 {
                "ON"
            } else {
                "OFF"
            },
            last.map_or("-".into(), |s| format!("{:.1} MS", s.latency_ms)),
            self.stats.dropped()
        ));
        let aa = self.prep.settings.antialias;
        lines.push(match last.filter(|_| aa.is_on()) {
            Some(s) => format!(
                "AA {}  {} PX  {} RAYS",
                aa.name(),
                s.aa_pixels,
                s.aa_extra_rays
            ),
            None => format!("AA {}", aa.name()),
        });
        lines
    }
}

impl Draw<'_> {
    /// The channel index naming window `w`'s files when there are several windows.
    fn channel_index(&self, w: &Win) -> usize {
        w.channel.map_or(0, |c| self.prep.channels[c].index)
    }

    /// Renders window `w`'s view (and captures it when asked); returns its render size and
    /// its anti-aliased pixels with 16, 8 and 4 samples.
    fn render(&self, gpu: &Gpu, w: &mut Win) -> Result<((u32, u32), [u64; 3])> {
        let (prep, step) = (self.prep, self.step);
        let (rw, rh) = match w.channel {
            Some(c) => (prep.channels[c].width, prep.channels[c].height),
            None => (w.config.width, w.config.height),
        };
        if let (Some(_), Some(e)) = (w.channel, step.eye) {
            w.renderer.set_eye(e);
        }
        let cam = Camera::new(step.pose, rw, rh);
        // A window moved with the ownship reaches this renderer's pool first (it uploads the
        // objects again, which drops the placed entities: they are placed below).
        if let (Some(p), Some(f)) = (&mut w.paging, &prep.follower) {
            p.sync_window(gpu, &mut w.renderer, &prep.world, f.spec())?;
        }
        // Animated voxel models follow the simulation clock.
        w.renderer.set_time(step.t);
        if let Some(i) = &step.instances {
            w.renderer.set_instances(i.drawn.clone());
            w.renderer.set_voxel_instances(i.voxels.clone());
        }
        let dirs: Vec<PathBuf> = (prep.opts.capture_frames.iter().cloned())
            .chain(step.screenshot.then(|| prep.opts.screenshot_dir.clone()))
            .map(|d| {
                if self.windows > 1 {
                    d.join(format!("channel_{}", self.channel_index(w)))
                } else {
                    d
                }
            })
            .collect();
        let terrain = &prep.world.terrain;
        if let Some(p) = &mut w.paging {
            p.step(gpu, &mut w.renderer, terrain, &cam)?;
        }
        let times = if dirs.is_empty() {
            (w.renderer).render(gpu, terrain, self.desc, &cam, &prep.settings, Stage::Shade)?
        } else {
            let out = (w.renderer).capture(gpu, terrain, self.desc, &cam, &prep.settings)?;
            self.write_capture(gpu, w, &cam, &out, &dirs)?;
            out.times
        };
        Ok(((rw, rh), times.antialias_counts))
    }

    /// Writes window `w`'s frame `out` (as `relief render` does) to each of `dirs`.
    fn write_capture(
        &self,
        gpu: &Gpu,
        w: &Win,
        cam: &Camera,
        out: &FrameOutput,
        dirs: &[PathBuf],
    ) -> Result<()> {
        let (prep, step) = (self.prep, self.step);
        let (n, t) = (step.n, step.t);
        let terrain = &prep.world.terrain;
        let mut meta = frame_metadata(
            gpu,
            &prep.scene,
            terrain,
            cam,
            &prep.settings,
            n as u32,
            out,
        );
        meta["time_s"] = json!(t);
        if let Some((c, geodetic)) = &step.cigi {
            meta["cigi"] = c.clone();
            if geodetic.is_some() {
                meta["camera"]["geodetic"] = json!(geodetic);
            }
        }
        meta["view"] = json!({
            "mode": prep.motion.mode.name(),
            "rate_hz": prep.opts.rate,
            "sim_time_s": t,
        });
        if let Some(c) = w.channel {
            let c = &prep.channels[c];
            meta["display"] = json!({
                "config": c.config.display().to_string(),
                "channel": c.index,
                "channel_name": c.name,
                "eye_display_frame": step.eye.unwrap_or(c.eye).to_array(),
            });
            meta["camera"]["model"] =
                json!("distortion-table (see display); the pinhole intrinsics do not apply");
        }
        for d in dirs {
            write_capture(d, n, out, &meta)?;
        }
        log::info!("frame {n}: captured to {}", dirs[0].display());
        Ok(())
    }

    /// The window's next swap-chain image and whether it is suboptimal; `None` when there is
    /// none this frame (the surface is then reconfigured or recreated as needed).
    fn acquire(&self, gpu: &Gpu, w: &mut Win) -> Result<Option<(wgpu::SurfaceTexture, bool)>> {
        Ok(match w.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => Some((t, false)),
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => Some((t, true)),
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => None,
            wgpu::CurrentSurfaceTexture::Outdated => {
                log::info!("surface outdated: reconfiguring");
                let size = w.window.inner_size();
                w.configure(gpu, size);
                None
            }
            wgpu::CurrentSurfaceTexture::Lost => {
                log::warn!("surface lost: recreating it");
                w.surface = self
                    .instance
                    .create_surface(w.window.clone())
                    .map_err(|e| Error::Gpu(format!("cannot recreate the lost surface: {e}")))?;
                let size = w.window.inner_size();
                w.configure(gpu, size);
                None
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(Error::Gpu(
                    "validation error acquiring the swap-chain image".into(),
                ))
            }
        })
    }

    /// Presents window `w` (index `wi`, render size `(rw, rh)`): the present pass copies the
    /// renderer's target (and draws the overlay) into the swap-chain image; `--grab` reads it
    /// back.
    fn present(
        &self,
        gpu: &Gpu,
        w: &mut Win,
        wi: usize,
        (rw, rh): (u32, u32),
        d: &mut Drawn,
    ) -> Result<()> {
        let t_acq = Instant::now();
        let frame_tex = self.acquire(gpu, w)?;
        d.acquire += t_acq.elapsed();
        let Some((tex, suboptimal)) = frame_tex else {
            return Ok(());
        };
        let (Some(colour), Some(data)) = (w.renderer.colour_view(), w.renderer.data_view()) else {
            return Err(Error::Gpu(
                "the renderer has no targets after a frame".into(),
            ));
        };
        let view = tex.texture.create_view(&Default::default());
        let (text, cols, rows) =
            (self.step.overlay.as_ref()).map_or(([[0u32; 4]; 24], 0, 0), |l| pack_text(l));
        let scale = if w.config.width >= 1200 { 2 } else { 1 };
        let u = PresentUniforms {
            sizes: [rw, rh, w.config.width, w.config.height],
            mode: [
                self.view_mode as u32,
                0,
                if wi == 0 { cols } else { 0 },
                rows,
            ],
            overlay: [scale, 4, 4, 0],
            text,
            font: *self.font,
        };
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        w.present.encode(gpu, &mut enc, colour, data, &view, &u);
        let size = (tex.texture.width(), tex.texture.height());
        let copy =
            (self.step.grab && w.copy_src).then(|| copy_surface(gpu, &mut enc, &tex.texture));
        // A software adapter blocks here (the swap-chain image's semaphore, then the
        // present's copy to the window): counted apart from the CPU time.
        let t_present = Instant::now();
        gpu.queue.submit([enc.finish()]);
        gpu.queue.present(tex);
        let presented = Instant::now();
        d.present_call += presented - t_present;
        d.last_present = Some(presented);
        if suboptimal {
            let size = w.window.inner_size();
            w.configure(gpu, size);
        }
        if self.step.grab {
            let suffix = if self.windows > 1 {
                format!("_c{}", self.channel_index(w))
            } else {
                String::new()
            };
            let dir = &self.prep.opts.screenshot_dir;
            let n = self.step.n;
            write_grabs(gpu, &w.window, copy, w.config.format, dir, n, &suffix, size)?;
        }
        Ok(())
    }
}

/// Writes frame `n`'s capture files to `dir`.
fn write_capture(dir: &Path, n: u64, out: &FrameOutput, meta: &serde_json::Value) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let [png, tif, json] = frame_paths(dir, n);
    write_frame_files(&png, &tif, &json, out, meta)
}
