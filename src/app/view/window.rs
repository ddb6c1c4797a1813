//! The window of `relief view`: winit 0.30 `ApplicationHandler`, one window and wgpu surface
//! per display channel, a fixed simulation step per frame, paced at the target rate.
//!
//! Life cycle (as wgpu's `hello_window`): everything that can fail on bad input is loaded in
//! [`super::prepare`] before the event loop exists; windows, surfaces and the device are
//! created in `resumed` (windows stay hidden until the device works); frames
//! ([`super::frame`]) are rendered on `RedrawRequested` of the first window, requested from
//! `about_to_wait` when the next frame is due; surfaces are reconfigured on resize, `Outdated`
//! and `Lost`; GPU objects are dropped in `exiting`.

use super::prepare::{prepare, Prepared};
use super::present::{font_words, PresentPass, ViewMode};
use super::stats::{GpuTimeSource, RunStats};
use super::timer::GpuTimer;
use super::{ViewOptions, ViewReport};
use crate::gpu::{Gpu, TerrainRenderer};
use crate::scene::SceneDesc;
use crate::{Error, Result};
use std::collections::HashSet;
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Fullscreen, Window, WindowId};

/// Opens the window(s) and runs the frame loop (see [`super::run`]).
pub fn run(opts: &ViewOptions) -> Result<ViewReport> {
    let prep = prepare(opts)?;
    // No adapter is an input error too: find out before opening a window.
    drop(crate::app::gpu_options::open()?);
    let event_loop = EventLoop::new().map_err(|e| {
        Error::invalid(
            "window",
            format!(
                "cannot connect to the window system ({e}); set DISPLAY, or run under `xvfb-run -a` for a virtual display"
            ),
        )
    })?;
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle_from_env(
        Box::new(event_loop.owned_display_handle()),
    ));
    let mut app = App::new(prep, instance);
    event_loop
        .run_app(&mut app)
        .map_err(|e| Error::invalid("window", format!("event loop: {e}")))?;
    app.finish()
}

/// A window with its surface, renderer and present pass.
pub(super) struct Win {
    pub(super) window: Arc<Window>,
    pub(super) surface: wgpu::Surface<'static>,
    pub(super) config: wgpu::SurfaceConfiguration,
    pub(super) renderer: TerrainRenderer,
    pub(super) present: PresentPass,
    /// Index into `Prepared::channels`; `None` for the pinhole window.
    pub(super) channel: Option<usize>,
    /// Size 0 (minimised): not drawn.
    pub(super) hidden: bool,
    /// The swap-chain images can be copied from (`--grab`).
    pub(super) copy_src: bool,
    /// The pager feeding a paged renderer (`--terrain-memory`).
    pub(super) paging: Option<crate::app::paged::Paging>,
}

impl Win {
    /// Configures the surface for `size`; a size of 0 hides the window from drawing.
    pub(super) fn configure(&mut self, gpu: &Gpu, size: PhysicalSize<u32>) {
        if size.width == 0 || size.height == 0 {
            self.hidden = true;
            return;
        }
        self.hidden = false;
        self.config.width = size.width;
        self.config.height = size.height;
        self.surface.configure(&gpu.device, &self.config);
    }
}

/// Live state once the device and windows exist.
pub(super) struct Running {
    pub(super) gpu: Gpu,
    pub(super) windows: Vec<Win>,
    pub(super) timer: Option<GpuTimer>,
    pub(super) present_mode: wgpu::PresentMode,
}

/// A window to open: channel (`None` for the pinhole window), title and size.
struct WindowSpec {
    channel: Option<usize>,
    title: String,
    width: u32,
    height: u32,
}

/// The frame loop's state.
pub(super) struct App {
    pub(super) prep: Prepared,
    pub(super) instance: wgpu::Instance,
    pub(super) run: Option<Running>,
    pub(super) error: Option<Error>,
    /// Scene as the quick-look keys changed it.
    pub(super) desc: SceneDesc,
    pub(super) fog_visibility: f64,
    /// What the anti-aliasing key (E) turns on: the scene's or the command line's choice,
    /// `"edges"` where that is off.
    pub(super) antialias_on: crate::gpu::Antialias,
    pub(super) sun_hour: Option<f64>,
    pub(super) frame: u64,
    pub(super) loop_start: Option<Instant>,
    pub(super) next_due: Instant,
    pub(super) last_start: Option<Instant>,
    pub(super) last_present: Option<Instant>,
    /// The run's frame statistics (bounded: [`RunStats`]).
    pub(super) stats: RunStats,
    pub(super) keys: HashSet<KeyCode>,
    pub(super) dragging: bool,
    pub(super) cursor: Option<(f64, f64)>,
    pub(super) look: (f64, f64),
    pub(super) overlay: bool,
    pub(super) view_mode: ViewMode,
    pub(super) screenshot: bool,
    /// Waiting for a requested size (debug `--resize-at`): (size, give up at).
    pub(super) pending_resize: Option<(PhysicalSize<u32>, Instant)>,
    pub(super) report: Option<ViewReport>,
    /// wgpu's live objects per kind at frames 100 and 500.
    pub(super) resources: Vec<(u64, Vec<(&'static str, usize)>)>,
    pub(super) adapter: String,
    pub(super) font: [[u32; 4]; 48],
}

impl App {
    fn new(prep: Prepared, instance: wgpu::Instance) -> App {
        let desc = prep.scene.desc.clone();
        App {
            fog_visibility: desc.fog.visibility,
            antialias_on: Some(prep.settings.antialias)
                .filter(|a| a.is_on())
                .unwrap_or(crate::gpu::Antialias::EDGES),
            overlay: !prep.opts.no_overlay,
            view_mode: prep.opts.debug_view,
            desc,
            prep,
            instance,
            run: None,
            error: None,
            sun_hour: None,
            frame: 0,
            loop_start: None,
            next_due: Instant::now(),
            last_start: None,
            last_present: None,
            stats: RunStats::default(),
            keys: HashSet::new(),
            dragging: false,
            cursor: None,
            look: (0.0, 0.0),
            screenshot: false,
            pending_resize: None,
            resources: Vec::new(),
            report: None,
            adapter: String::new(),
            font: font_words(),
        }
    }

    fn fail(&mut self, el: &ActiveEventLoop, e: Error) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        el.exit();
    }

    fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.prep.opts.rate)
    }

    /// Creates the windows (hidden), surfaces, device, renderers; then shows the windows.
    fn start(&mut self, el: &ActiveEventLoop) -> Result<()> {
        let specs = self.window_specs();
        let windows = self.create_windows(el, &specs)?;
        let mut gpu = Gpu::for_surface(
            &self.instance,
            &windows[0].1,
            wgpu::Features::TIMESTAMP_QUERY,
        )?;
        gpu.options = crate::app::gpu_options::get();
        self.adapter = gpu.describe();
        log::info!("view adapter: {}", self.adapter);
        let mut running = Vec::new();
        let mut present_mode = wgpu::PresentMode::Fifo;
        for ((window, surface), spec) in windows.into_iter().zip(specs) {
            let win = self.open_window(&gpu, window, surface, &spec)?;
            present_mode = win.config.present_mode;
            running.push(win);
        }
        let timer = gpu
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            .then(|| GpuTimer::new(&gpu));
        log::info!(
            "GPU time per frame from {}",
            if timer.is_some() {
                GpuTimeSource::Timestamps.name()
            } else {
                GpuTimeSource::WallToCompletion.name()
            }
        );
        for w in &running {
            w.window.set_visible(true);
            log::info!(
                "opened window {}x{} ({:?}, {:?})",
                w.config.width,
                w.config.height,
                w.config.format,
                w.config.present_mode
            );
        }
        self.run = Some(Running {
            gpu,
            windows: running,
            timer,
            present_mode,
        });
        let now = Instant::now();
        self.next_due = now;
        Ok(())
    }

    /// The windows to open: the pinhole view, or one per display channel.
    fn window_specs(&self) -> Vec<WindowSpec> {
        let scene = self.prep.opts.scene.display();
        if self.prep.channels.is_empty() {
            return vec![WindowSpec {
                channel: None,
                title: format!("relief — {scene}"),
                width: self.desc.output.width,
                height: self.desc.output.height,
            }];
        }
        (self.prep.channels.iter().enumerate())
            .map(|(i, c)| WindowSpec {
                channel: Some(i),
                title: format!("relief — {scene} channel {} {}", c.index, c.name),
                width: c.width,
                height: c.height,
            })
            .collect()
    }

    /// Creates the windows (hidden; side by side, or fullscreen on consecutive monitors) and
    /// their surfaces.
    fn create_windows(
        &self,
        el: &ActiveEventLoop,
        specs: &[WindowSpec],
    ) -> Result<Vec<(Arc<Window>, wgpu::Surface<'static>)>> {
        let monitors: Vec<_> = el.available_monitors().collect();
        let mut windows = Vec::new();
        let mut left = 0u32;
        for (i, spec) in specs.iter().enumerate() {
            let (w, h) = (spec.width, spec.height);
            let mut attrs = Window::default_attributes()
                .with_title(spec.title.clone())
                .with_inner_size(PhysicalSize::new(w, h))
                .with_visible(false);
            if specs.len() > 1 {
                // Channels side by side, left to right.
                attrs = attrs.with_position(winit::dpi::PhysicalPosition::new(left, 0));
                left += w;
            }
            if let Some(first) = self.prep.opts.fullscreen {
                let m = monitors.get(first + i).ok_or_else(|| {
                    Error::invalid(
                        "--fullscreen",
                        format!(
                            "window {i} wants monitor {}, there are {} monitor(s) (0..{})",
                            first + i,
                            monitors.len(),
                            monitors.len()
                        ),
                    )
                })?;
                // Position and size too: without a window manager (Xvfb, kiosk setups) the
                // fullscreen hint alone changes nothing.
                attrs = attrs
                    .with_position(m.position())
                    .with_inner_size(m.size())
                    .with_fullscreen(Some(Fullscreen::Borderless(Some(m.clone()))));
            }
            let window =
                Arc::new(el.create_window(attrs).map_err(|e| {
                    Error::invalid("window", format!("cannot create a window: {e}"))
                })?);
            let surface = self
                .instance
                .create_surface(window.clone())
                .map_err(|e| Error::Gpu(format!("cannot create a surface for the window: {e}")))?;
            windows.push((window, surface));
        }
        Ok(windows)
    }

    /// Configures `surface` for `window` and gives it a renderer holding the world (through
    /// the channel's table when `spec` names one) and a present pass.
    fn open_window(
        &self,
        gpu: &Gpu,
        window: Arc<Window>,
        surface: wgpu::Surface<'static>,
        spec: &WindowSpec,
    ) -> Result<Win> {
        let (w, h) = (spec.width, spec.height);
        let (format, usage, mode, alpha) = self.surface_caps(gpu, &surface)?;
        let config = wgpu::SurfaceConfiguration {
            usage,
            format,
            color_space: Default::default(),
            width: w.max(1),
            height: h.max(1),
            present_mode: mode,
            desired_maximum_frame_latency: 2,
            alpha_mode: alpha,
            view_formats: vec![],
        };
        let (prep, mut paging) = (&self.prep, None);
        let memory = prep.opts.terrain_memory.or(prep.scene.desc.terrain.memory);
        let mut renderer = match memory {
            Some(mb) => {
                let (r, p) = crate::app::paged::renderer(gpu, &prep.scene, &prep.world, mb)?;
                paging = Some(p);
                r
            }
            None => crate::app::upload::renderer(gpu, &prep.world)?,
        };
        if let Some(c) = spec.channel {
            let c = &self.prep.channels[c];
            renderer.set_display(gpu, &c.points, c.eye)?;
            renderer.set_blend(gpu, c.blend.as_ref())?;
            if let Some(v) = c.view {
                renderer.set_view_offset(v.matrix());
            }
            // A paged terrain pages for the channel's rays (from the configured eye: an eye
            // feed moves them a little), not the scene camera's frustum.
            if let Some(p) = &mut paging {
                if let Some(bundle) = c.points.ray_bundle(c.eye) {
                    p.set_channel(crate::app::paged::ChannelRays {
                        bundle,
                        offset: c.view.map_or(glam::DMat3::IDENTITY, |v| v.matrix()),
                    });
                }
            }
        }
        let mut win = Win {
            present: PresentPass::new(gpu, format),
            copy_src: usage.contains(wgpu::TextureUsages::COPY_SRC),
            window,
            surface,
            config,
            renderer,
            channel: spec.channel,
            hidden: false,
            paging,
        };
        let size = win.window.inner_size();
        win.configure(
            gpu,
            if size.width > 0 {
                size
            } else {
                PhysicalSize::new(w, h)
            },
        );
        Ok(win)
    }

    /// Format (non-sRGB when offered, so the encoded bytes pass through), usage (COPY_SRC when
    /// offered, for `--grab`), present mode and alpha mode for a surface.
    fn surface_caps(
        &self,
        gpu: &Gpu,
        surface: &wgpu::Surface<'_>,
    ) -> Result<(
        wgpu::TextureFormat,
        wgpu::TextureUsages,
        wgpu::PresentMode,
        wgpu::CompositeAlphaMode,
    )> {
        // The device's adapter: a surface's capabilities depend on it. Gpu keeps no adapter, so
        // ask the instance for the one with this name and backend.
        let caps = pollster::block_on(self.instance.enumerate_adapters(gpu.info.backend.into()))
            .into_iter()
            .find(|a| a.get_info() == gpu.info)
            .map(|a| surface.get_capabilities(&a))
            .ok_or_else(|| Error::Gpu(format!("adapter {} vanished", gpu.info.name)))?;
        if caps.formats.is_empty() {
            return Err(Error::Gpu(format!(
                "{} cannot present to this window",
                gpu.info.name
            )));
        }
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| {
                matches!(
                    f,
                    wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm
                )
            })
            .unwrap_or(caps.formats[0]);
        let mut usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
        if caps.usages.contains(wgpu::TextureUsages::COPY_SRC) {
            usage |= wgpu::TextureUsages::COPY_SRC;
        }
        log::debug!(
            "surface: formats {:?}, present modes {:?}, usages {:?}",
            caps.formats,
            caps.present_modes,
            caps.usages
        );
        let mode = self
            .prep
            .opts
            .present()
            .preference()
            .iter()
            .copied()
            .find(|m| caps.present_modes.contains(m))
            .unwrap_or(wgpu::PresentMode::Fifo);
        Ok((format, usage, mode, caps.alpha_modes[0]))
    }

    /// The first window's redraw: the frame when it is due, then the debug resize and the exit
    /// after `--frames`.
    fn redraw(&mut self, el: &ActiveEventLoop) {
        if self.pending_resize.is_some() {
            return;
        }
        if Instant::now() < self.next_due && !self.prep.opts.unpaced {
            return;
        }
        if let Err(e) = self.frame() {
            return self.fail(el, e);
        }
        let now = Instant::now();
        let period = self.period();
        self.next_due += period;
        if self.next_due + period < now {
            // More than a frame behind: pace from now (the missed slots count as dropped).
            self.next_due = now;
        }
        let done = self.frame;
        if let Some((at, w, h)) = self.prep.resize_at {
            if done == at + 1 {
                let size = PhysicalSize::new(w, h);
                let run = self.run.as_mut().expect("running");
                match run.windows[0].window.request_inner_size(size) {
                    Some(now_size) => {
                        let gpu = &run.gpu;
                        run.windows[0].configure(gpu, now_size);
                    }
                    None => {
                        self.pending_resize = Some((size, Instant::now() + Duration::from_secs(3)));
                    }
                }
            }
        }
        if self.prep.opts.frames.is_some_and(|f| done >= f) {
            el.exit();
        }
    }

    fn finish(mut self) -> Result<ViewReport> {
        if let Some(ig) = &mut self.prep.cigi {
            ig.finish(&self.prep.world.terrain);
            log::info!("{}", ig.summary());
        }
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.report.take().ok_or_else(|| {
            Error::invalid(
                "window",
                "the event loop ended before a window opened (no display?)",
            )
        })
    }

    /// Final GPU times, CSV and recorder flush, the report; drops the GPU objects.
    fn shut_down(&mut self) -> Result<()> {
        if let Some(run) = &self.run {
            let _ = run.gpu.wait();
        }
        self.collect_gpu_times();
        self.settle_stats(true)?;
        if let Some(csv) = self.prep.stats_csv.take() {
            csv.finish()?;
        }
        if let Some(r) = self.prep.recorder.take() {
            r.finish()?;
        }
        if let Some(run) = self.run.take() {
            let size = run.windows.first().map_or((0, 0), |w| match w.channel {
                Some(c) => (self.prep.channels[c].width, self.prep.channels[c].height),
                None => (w.config.width, w.config.height),
            });
            self.report = Some(ViewReport {
                adapter: self.adapter.clone(),
                windows: run.windows.len(),
                size,
                target_hz: self.prep.opts.rate,
                present_mode: format!(
                    "{:?}{}",
                    run.present_mode,
                    if self.prep.opts.unpaced {
                        ", unpaced"
                    } else {
                        ""
                    }
                ),
                gpu_time_source: if run.timer.is_some() {
                    GpuTimeSource::Timestamps
                } else {
                    GpuTimeSource::WallToCompletion
                }
                .name()
                .into(),
                summary: self.stats.summary(),
                floor_contacts: self.prep.motion.floor_contacts,
                resources: std::mem::take(&mut self.resources),
            });
            // Surfaces before the windows they draw to, everything before the device.
            for w in run.windows {
                drop(w.surface);
                drop(w.renderer);
                drop(w.window);
            }
            drop(run.timer);
            drop(run.gpu);
        }
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.run.is_some() || self.error.is_some() {
            return;
        }
        if let Err(e) = self.start(el) {
            self.fail(el, e);
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, id: WindowId, event: WindowEvent) {
        let Some(run) = &mut self.run else { return };
        let Some(wi) = run.windows.iter().position(|w| w.window.id() == id) else {
            return;
        };
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(size) => {
                let w = &mut run.windows[wi];
                w.configure(&run.gpu, size);
                log::info!("window {wi} resized to {}x{}", size.width, size.height);
                if wi == 0 && self.pending_resize.is_some_and(|(s, _)| s == size) {
                    self.pending_resize = None;
                }
            }
            WindowEvent::KeyboardInput { event, .. } => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    self.on_key(el, code, event.state == ElementState::Pressed, event.repeat);
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                self.dragging = state == ElementState::Pressed;
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let (true, Some((x, y))) = (self.dragging, self.cursor) {
                    self.look.0 += (position.x - x) * 0.2;
                    self.look.1 -= (position.y - y) * 0.2;
                }
                self.cursor = Some((position.x, position.y));
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y as f64,
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                let m = &mut self.prep.motion;
                m.free_speed = (m.free_speed * 1.25f64.powf(lines)).clamp(1.0, 20_000.0);
            }
            WindowEvent::RedrawRequested if wi == 0 => self.redraw(el),
            _ => {}
        }
    }

    fn about_to_wait(&mut self, el: &ActiveEventLoop) {
        let Some(run) = &self.run else { return };
        let now = Instant::now();
        if let Some((size, give_up)) = self.pending_resize {
            if now < give_up {
                el.set_control_flow(ControlFlow::WaitUntil(give_up));
                return;
            }
            log::warn!(
                "the window system did not apply the size {}x{} within 3 s; going on",
                size.width,
                size.height
            );
            self.pending_resize = None;
        }
        if self.prep.opts.unpaced || now >= self.next_due {
            run.windows[0].window.request_redraw();
            el.set_control_flow(ControlFlow::Poll);
        } else {
            el.set_control_flow(ControlFlow::WaitUntil(self.next_due));
        }
    }

    fn exiting(&mut self, _el: &ActiveEventLoop) {
        if let Err(e) = self.shut_down() {
            if self.error.is_none() {
                self.error = Some(e);
            }
        }
    }
}
