//! The windowed frame loop: winit 0.30 `ApplicationHandler`, one window and wgpu surface per
//! display channel, a fixed simulation step per frame, paced at the target rate.
//!
//! Life cycle (as wgpu's `hello_window`): everything that can fail on bad input is loaded in
//! [`prepare`] before the event loop exists; windows, surfaces and the device are created in
//! `resumed` (windows stay hidden until the device works); frames are rendered on
//! `RedrawRequested` of the first window, requested from `about_to_wait` when the next frame is
//! due; surfaces are reconfigured on resize, `Outdated` and `Lost`; GPU objects are dropped in
//! `exiting`.

use super::motion::{ControlScript, Controls, EyeFeed, Mode, Motion, PathRecorder};
use super::present::{font_words, pack_text, PresentPass, PresentUniforms, ViewMode};
use super::stats::{self, FrameStat, GpuTimeSource, StatsCsv};
use super::{ViewOptions, ViewReport};
use crate::app::capture::{frame_metadata, write_png};
use crate::cpu::distortion::ScreenPoints;
use crate::gpu::{Gpu, RenderSettings, Stage, TerrainRenderer};
use crate::scene::{Camera, Pose, Scene, SceneDesc};
use crate::terrain::Terrain;
use crate::{Error, Result};
use glam::DVec3;
use serde_json::json;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Fullscreen, Window, WindowId};

/// One channel of a display configuration, ready for `set_display`.
struct ChannelSpec {
    index: usize,
    name: String,
    points: ScreenPoints,
    eye: DVec3,
    blend: Option<crate::display::blend::ChannelBlend>,
    view: Option<crate::display::ViewOffset>,
    width: u32,
    height: u32,
    config: PathBuf,
}

/// Eye points per frame.
enum EyeSource {
    File(EyeFeed),
    /// Lines from stdin, read by a thread; the latest one holds.
    Stdin(
        mpsc::Receiver<std::result::Result<DVec3, String>>,
        Option<DVec3>,
    ),
}

/// Everything loaded and checked before any window exists.
struct Prepared {
    opts: ViewOptions,
    scene: Scene,
    terrain: Terrain,
    /// The scene's free forms (built before any window opens, so bad objects fail early).
    objects: Vec<crate::freeform::FreeForm>,
    /// The scene's density volumes (loaded before any window opens).
    volumes: Vec<crate::volume::Volume>,
    /// The scene's voxel models (loaded before any window opens).
    voxels: Vec<crate::voxel::VoxelInstance>,
    channels: Vec<ChannelSpec>,
    settings: RenderSettings,
    motion: Motion,
    script: Option<ControlScript>,
    eyes: Option<EyeSource>,
    recorder: Option<PathRecorder>,
    stats_csv: Option<StatsCsv>,
}

fn invalid(field: &str, msg: impl Into<String>) -> Error {
    Error::Invalid {
        field: field.into(),
        msg: msg.into(),
    }
}

fn prepare(opts: &ViewOptions) -> Result<Prepared> {
    let mut scene = Scene::load(&opts.scene)?;
    if !(opts.rate.is_finite() && (1.0..=1000.0).contains(&opts.rate)) {
        return Err(invalid(
            "--rate",
            format!("must be 1..=1000 Hz, got {}", opts.rate),
        ));
    }
    if opts.frames == Some(0) {
        return Err(invalid("--frames", "must be at least 1"));
    }
    if !(opts.min_agl.is_finite() && opts.min_agl >= 0.0) {
        return Err(invalid(
            "--min-agl",
            format!("must be ≥ 0 metres, got {}", opts.min_agl),
        ));
    }
    if let Some((w, h)) = opts.size {
        scene.desc.output.width = w;
        scene.desc.output.height = h;
        scene.desc.validate()?;
    }
    let mut channels = Vec::new();
    if let Some(cfg_path) = &opts.display {
        if opts.size.is_some() {
            return Err(invalid(
                "--size",
                "a distortion table renders at the projector's resolution; drop --size",
            ));
        }
        let cfg = crate::display::DisplayConfig::load(cfg_path)?;
        let wanted: Vec<usize> = match opts.channel {
            Some(c) if c >= cfg.channels.len() => {
                return Err(invalid(
                    "--channel",
                    format!(
                        "{} has {} channel(s), asked for index {c}",
                        cfg_path.display(),
                        cfg.channels.len()
                    ),
                ))
            }
            Some(c) => vec![c],
            None => (0..cfg.channels.len()).collect(),
        };
        let eye = DVec3::from(opts.eye.unwrap_or(cfg.eye.position));
        for index in wanted {
            let ch = &cfg.channels[index];
            let p = ch.projector;
            let points = cfg.channel_points(index)?;
            if points.points.iter().all(|p| p.is_none()) {
                return Err(invalid(
                    &format!("{} channel {index}", cfg_path.display()),
                    "no projector pixel reaches the screen",
                ));
            }
            channels.push(ChannelSpec {
                index,
                name: ch.name.clone(),
                points,
                eye,
                blend: crate::display::blend::ChannelBlend::new(&cfg, index),
                view: ch.view,
                width: p.width,
                height: p.height,
                config: cfg_path.clone(),
            });
        }
    } else if opts.channel.is_some() || opts.eye.is_some() || opts.eye_feed.is_some() {
        return Err(invalid(
            "--channel/--eye/--eye-feed",
            "need a display configuration (--display CONFIG)",
        ));
    }
    let terrain = scene.load_terrain()?;
    let objects = scene.free_forms(&terrain)?;
    let volumes = scene.volumes(&terrain)?;
    let voxels = scene.voxel_models(&terrain)?;
    let mut settings = RenderSettings::from_scene(&scene.desc);
    if let Some(s) = opts.shadows {
        settings.shadows = s;
    }
    if let Some(t) = opts.tile_prepass {
        settings.tile_prepass = t;
    }
    let start_cam = scene.camera(0, &terrain);
    let mut pose = start_cam.pose;
    let path = match &opts.path_csv {
        Some(p) => Some(super::motion::read_path_csv(p, scene.desc.camera.fov)?),
        None => scene.desc.path.clone(),
    };
    if let Some([x, y, z, heading]) = opts.start {
        pose = Pose {
            position: DVec3::new(x, y, z),
            heading,
            pitch: 0.0,
            roll: 0.0,
            fov: scene.desc.camera.fov,
        };
    }
    let mode = match opts.mode {
        Some(Mode::Path) if path.is_none() => {
            return Err(invalid(
                "--mode path",
                format!(
                    "{} has no [path]; give --path FILE.csv or another mode",
                    opts.scene.display()
                ),
            ))
        }
        Some(m) => m,
        None if path.is_some() && opts.start.is_none() => Mode::Path,
        None => Mode::Free,
    };
    if mode == Mode::Path {
        if let Some(p) = &path {
            pose = p.pose_at(0.0);
        }
    }
    let script = match &opts.script {
        Some(p) if mode != Mode::Aircraft => {
            return Err(invalid(
                "--script",
                format!(
                    "{} holds aircraft controls; add --mode aircraft",
                    p.display()
                ),
            ))
        }
        Some(p) => Some(ControlScript::load(p)?),
        None => None,
    };
    let eyes = match &opts.eye_feed {
        Some(p) if p.as_os_str() == "-" => {
            let (tx, rx) = mpsc::channel();
            std::thread::spawn(move || {
                for line in std::io::stdin().lines() {
                    let Ok(line) = line else { break };
                    match super::motion::parse_eye_line(&line) {
                        Ok(Some(e)) => {
                            if tx.send(Ok(e)).is_err() {
                                break;
                            }
                        }
                        Ok(None) => {}
                        Err(m) => {
                            let _ = tx.send(Err(m));
                            break;
                        }
                    }
                }
            });
            Some(EyeSource::Stdin(rx, None))
        }
        Some(p) => Some(EyeSource::File(EyeFeed::load(p)?)),
        None => None,
    };
    for dir in [&opts.capture_frames]
        .into_iter()
        .flatten()
        .chain((opts.grab.is_some()).then_some(&opts.screenshot_dir))
    {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let recorder = opts
        .record
        .as_deref()
        .map(PathRecorder::create)
        .transpose()?;
    let stats_csv = opts
        .stats_csv
        .as_deref()
        .map(StatsCsv::create)
        .transpose()?;
    Ok(Prepared {
        opts: opts.clone(),
        motion: Motion::new(mode, pose, path, opts.min_agl),
        scene,
        terrain,
        objects,
        volumes,
        voxels,
        channels,
        settings,
        script,
        eyes,
        recorder,
        stats_csv,
    })
}

pub fn run(opts: &ViewOptions) -> Result<ViewReport> {
    let prep = prepare(opts)?;
    // No adapter is an input error too: find out before opening a window.
    drop(Gpu::new()?);
    let event_loop = EventLoop::new().map_err(|e| {
        invalid(
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
        .map_err(|e| invalid("window", format!("event loop: {e}")))?;
    app.finish()
}

/// A window with its surface, renderer and present pass.
struct Win {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: TerrainRenderer,
    present: PresentPass,
    /// Index into `Prepared::channels`; `None` for the pinhole window.
    channel: Option<usize>,
    /// Size 0 (minimised): not drawn.
    hidden: bool,
    /// The swap-chain images can be copied from (`--grab`).
    copy_src: bool,
}

impl Win {
    fn configure(&mut self, gpu: &Gpu, size: PhysicalSize<u32>) {
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

/// GPU time per frame from timestamp queries (two per frame, a small ring of readbacks).
struct GpuTimer {
    queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    slots: Vec<TimerSlot>,
    period_ns: f64,
}

struct TimerSlot {
    buffer: wgpu::Buffer,
    /// Frame whose times the buffer holds (or will once mapped).
    frame: Option<u64>,
    mapped: Arc<Mutex<Option<std::result::Result<(), wgpu::BufferAsyncError>>>>,
}

const TIMER_SLOTS: u64 = 4;

impl GpuTimer {
    fn new(gpu: &Gpu) -> GpuTimer {
        let queries = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("frame timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 2 * TIMER_SLOTS as u32,
        });
        let resolve = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timestamp resolve"),
            size: 256 * TIMER_SLOTS,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let slots = (0..TIMER_SLOTS)
            .map(|_| TimerSlot {
                buffer: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("timestamp readback"),
                    size: 16,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                }),
                frame: None,
                mapped: Arc::new(Mutex::new(None)),
            })
            .collect();
        GpuTimer {
            queries,
            resolve,
            slots,
            period_ns: gpu.queue.get_timestamp_period() as f64,
        }
    }

    /// Query index pair for `frame`, or `None` while that slot's last readback is pending.
    fn slot(&self, frame: u64) -> Option<u32> {
        let s = (frame % TIMER_SLOTS) as usize;
        self.slots[s].frame.is_none().then_some(s as u32)
    }

    /// An empty pass that writes timestamp `index`.
    fn stamp(&self, enc: &mut wgpu::CommandEncoder, index: u32) {
        enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("timestamp"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: &self.queries,
                beginning_of_pass_write_index: Some(index),
                end_of_pass_write_index: None,
            }),
        });
    }

    fn resolve(&self, enc: &mut wgpu::CommandEncoder, slot: u32) {
        let q = 2 * slot;
        enc.resolve_query_set(&self.queries, q..q + 2, &self.resolve, 256 * slot as u64);
        enc.copy_buffer_to_buffer(
            &self.resolve,
            256 * slot as u64,
            &self.slots[slot as usize].buffer,
            0,
            16,
        );
    }

    fn start_readback(&mut self, slot: u32, frame: u64) {
        let s = &mut self.slots[slot as usize];
        s.frame = Some(frame);
        let cell = s.mapped.clone();
        s.buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            *cell.lock().unwrap() = Some(r)
        });
    }

    /// (frame, GPU milliseconds) of every readback that has arrived.
    fn collect(&mut self) -> Vec<(u64, f64)> {
        let mut out = Vec::new();
        for s in &mut self.slots {
            let Some(frame) = s.frame else { continue };
            let Some(r) = s.mapped.lock().unwrap().take() else {
                continue;
            };
            if r.is_ok() {
                if let Ok(view) = s.buffer.get_mapped_range(..) {
                    let t: &[u64] = bytemuck::cast_slice(&view[..16]);
                    if t[1] >= t[0] && t[0] != 0 {
                        out.push((frame, (t[1] - t[0]) as f64 * self.period_ns * 1e-6));
                    }
                }
                s.buffer.unmap();
            }
            s.frame = None;
        }
        out
    }
}

/// Live state once the device and windows exist.
struct Running {
    gpu: Gpu,
    windows: Vec<Win>,
    timer: Option<GpuTimer>,
    present_mode: wgpu::PresentMode,
}

struct App {
    prep: Prepared,
    instance: wgpu::Instance,
    run: Option<Running>,
    error: Option<Error>,
    /// Scene as the quick-look keys changed it.
    desc: SceneDesc,
    fog_visibility: f64,
    sun_hour: Option<f64>,
    frame: u64,
    loop_start: Option<Instant>,
    next_due: Instant,
    last_start: Option<Instant>,
    last_present: Option<Instant>,
    stats: Vec<FrameStat>,
    csv_written: usize,
    keys: HashSet<KeyCode>,
    dragging: bool,
    cursor: Option<(f64, f64)>,
    look: (f64, f64),
    overlay: bool,
    view_mode: ViewMode,
    screenshot: bool,
    /// Waiting for a requested size (debug `--resize-at`): (size, give up at).
    pending_resize: Option<(PhysicalSize<u32>, Instant)>,
    report: Option<ViewReport>,
    /// wgpu's live objects per kind at frames 100 and 500.
    resources: Vec<(u64, Vec<(&'static str, usize)>)>,
    adapter: String,
    font: [[u32; 4]; 48],
}

impl App {
    fn new(prep: Prepared, instance: wgpu::Instance) -> App {
        let desc = prep.scene.desc.clone();
        App {
            fog_visibility: desc.fog.visibility,
            overlay: prep.opts.overlay,
            view_mode: prep.opts.view_mode,
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
            stats: Vec::new(),
            csv_written: 0,
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
        let opts = &self.prep.opts;
        let specs: Vec<(Option<usize>, String, u32, u32)> = if self.prep.channels.is_empty() {
            vec![(
                None,
                format!("relief — {}", opts.scene.display()),
                self.desc.output.width,
                self.desc.output.height,
            )]
        } else {
            self.prep
                .channels
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    (
                        Some(i),
                        format!(
                            "relief — {} channel {} {}",
                            opts.scene.display(),
                            c.index,
                            c.name
                        ),
                        c.width,
                        c.height,
                    )
                })
                .collect()
        };
        let monitors: Vec<_> = el.available_monitors().collect();
        let mut windows = Vec::new();
        let mut left = 0u32;
        for (i, (_, title, w, h)) in specs.iter().enumerate() {
            let mut attrs = Window::default_attributes()
                .with_title(title.clone())
                .with_inner_size(PhysicalSize::new(*w, *h))
                .with_visible(false);
            if specs.len() > 1 {
                // Channels side by side, left to right.
                attrs = attrs.with_position(winit::dpi::PhysicalPosition::new(left, 0));
                left += w;
            }
            if let Some(first) = opts.fullscreen {
                let m = monitors.get(first + i).ok_or_else(|| {
                    invalid(
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
            let window = Arc::new(
                el.create_window(attrs)
                    .map_err(|e| invalid("window", format!("cannot create a window: {e}")))?,
            );
            let surface = self
                .instance
                .create_surface(window.clone())
                .map_err(|e| Error::Gpu(format!("cannot create a surface for the window: {e}")))?;
            windows.push((window, surface));
        }
        let gpu = Gpu::for_surface(
            &self.instance,
            &windows[0].1,
            wgpu::Features::TIMESTAMP_QUERY,
        )?;
        self.adapter = gpu.describe();
        log::info!("view adapter: {}", self.adapter);
        let mut running = Vec::new();
        let mut present_mode = wgpu::PresentMode::Fifo;
        for ((window, surface), (channel, _, w, h)) in windows.into_iter().zip(specs) {
            let adapter_caps = self.surface_caps(&gpu, &surface)?;
            let (format, usage, mode, alpha) = adapter_caps;
            present_mode = mode;
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
            let mut renderer = TerrainRenderer::new(&gpu, &self.prep.terrain)?;
            renderer.set_objects(&gpu, &self.prep.objects)?;
            renderer.set_volumes(&gpu, &self.prep.volumes)?;
            renderer.set_voxels(&gpu, &self.prep.voxels)?;
            if let Some(c) = channel {
                let c = &self.prep.channels[c];
                renderer.set_display(&gpu, &c.points, c.eye)?;
                renderer.set_blend(&gpu, c.blend.as_ref())?;
                if let Some(v) = c.view {
                    renderer.set_view_offset(v.matrix());
                }
            }
            let mut win = Win {
                present: PresentPass::new(&gpu, format),
                copy_src: usage.contains(wgpu::TextureUsages::COPY_SRC),
                window,
                surface,
                config,
                renderer,
                channel,
                hidden: false,
            };
            let size = win.window.inner_size();
            win.configure(
                &gpu,
                if size.width > 0 {
                    size
                } else {
                    PhysicalSize::new(w, h)
                },
            );
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
            .present
            .preference()
            .iter()
            .copied()
            .find(|m| caps.present_modes.contains(m))
            .unwrap_or(wgpu::PresentMode::Fifo);
        Ok((format, usage, mode, caps.alpha_modes[0]))
    }

    /// Controls from the held keys and the mouse, or the script.
    fn controls(&mut self, t: f64) -> Controls {
        let k = |c: KeyCode| f64::from(u8::from(self.keys.contains(&c)));
        let axis = |pos: KeyCode, neg: KeyCode| k(pos) - k(neg);
        let look = std::mem::take(&mut self.look);
        let mut c = match self.prep.motion.mode {
            Mode::Aircraft => Controls {
                throttle_delta: axis(KeyCode::KeyW, KeyCode::KeyS),
                pitch: axis(KeyCode::ArrowDown, KeyCode::ArrowUp),
                roll: axis(KeyCode::ArrowRight, KeyCode::ArrowLeft),
                yaw: axis(KeyCode::KeyD, KeyCode::KeyA),
                ..Controls::default()
            },
            _ => Controls {
                forward: axis(KeyCode::KeyW, KeyCode::KeyS),
                right: axis(KeyCode::KeyD, KeyCode::KeyA),
                up: axis(KeyCode::Space, KeyCode::KeyC),
                yaw: axis(KeyCode::ArrowRight, KeyCode::ArrowLeft),
                pitch: axis(KeyCode::ArrowUp, KeyCode::ArrowDown),
                look,
                fast: k(KeyCode::ShiftLeft) + k(KeyCode::ShiftRight) > 0.0,
                ..Controls::default()
            },
        };
        if let Some(s) = self.prep.script.as_ref().and_then(|s| s.at(t)) {
            c = s;
        }
        c
    }

    fn eye_for(&mut self, frame: u64) -> Result<Option<DVec3>> {
        Ok(match &mut self.prep.eyes {
            None => None,
            Some(EyeSource::File(f)) => Some(f.at(frame)),
            Some(EyeSource::Stdin(rx, last)) => {
                while let Ok(r) = rx.try_recv() {
                    *last = Some(r.map_err(|m| invalid("--eye-feed -", m))?);
                }
                *last
            }
        })
    }

    fn on_key(&mut self, el: &ActiveEventLoop, code: KeyCode, pressed: bool, repeat: bool) {
        if pressed {
            self.keys.insert(code);
        } else {
            self.keys.remove(&code);
        }
        if !pressed || repeat {
            return;
        }
        let t = self.frame as f64 / self.prep.opts.rate;
        match code {
            KeyCode::Escape => el.exit(),
            KeyCode::KeyH | KeyCode::F1 => self.overlay = !self.overlay,
            KeyCode::KeyV => self.view_mode = self.view_mode.next(),
            KeyCode::KeyF => {
                self.desc.fog.visibility = if self.desc.fog.visibility > 0.0 {
                    0.0
                } else {
                    self.fog_visibility
                };
            }
            KeyCode::KeyR => self.prep.motion.reset(t),
            KeyCode::Tab | KeyCode::KeyM => self.prep.motion.cycle_mode(),
            KeyCode::BracketLeft | KeyCode::BracketRight => {
                let h = self
                    .sun_hour
                    .unwrap_or(12.0 + (self.desc.sun.azimuth - 180.0) / 15.0);
                let h = (h + if code == KeyCode::BracketRight {
                    1.0
                } else {
                    -1.0
                })
                .rem_euclid(24.0);
                self.sun_hour = Some(h);
                self.desc.sun.azimuth = (180.0 + 15.0 * (h - 12.0)).rem_euclid(360.0);
                self.desc.sun.elevation =
                    (60.0 * (std::f64::consts::PI * (h - 6.0) / 12.0).sin()).clamp(-89.0, 89.0);
            }
            KeyCode::KeyP | KeyCode::F12 => self.screenshot = true,
            _ => {}
        }
    }

    /// Renders and presents one frame in every window.
    fn frame(&mut self) -> Result<()> {
        let start = Instant::now();
        let loop_start = *self.loop_start.get_or_insert(start);
        let opts = self.prep.opts.clone();
        let n = self.frame;
        let dt = 1.0 / opts.rate;
        let t = n as f64 * dt;
        if let Some(run) = &mut self.run {
            // wgpu's live objects at both ends of the soak window (`ViewReport::resources`).
            if n == 100 || n == 500 {
                let counts = run.gpu.resource_counts().unwrap_or_default();
                self.resources.push((n, counts));
            }
            let _ = run.gpu.device.poll(wgpu::PollType::Poll);
            if let Some(timer) = &mut run.timer {
                for (f, ms) in timer.collect() {
                    if let Some(s) = self.stats.get_mut(f as usize) {
                        s.gpu_ms = ms;
                    }
                }
            }
        }
        let c = self.controls(t);
        self.prep
            .motion
            .step(t, if n == 0 { 0.0 } else { dt }, &c, &self.prep.terrain);
        let pose = self.prep.motion.pose;
        let eye = self.eye_for(n)?;
        let capture_all = opts.capture_frames.clone();
        let screenshot = std::mem::take(&mut self.screenshot);
        let grab = opts.grab == Some(n);
        let overlay_lines = self.overlay.then(|| self.overlay_text());
        let run = self.run.as_mut().expect("running");
        let gpu = &run.gpu;
        let n_windows = run.windows.len();
        let mut acquire = Duration::ZERO;
        let mut present_call = Duration::ZERO;
        let mut last_present = None;
        let mut first_size = None;
        let slot = run.timer.as_ref().and_then(|tm| tm.slot(n));
        if let (Some(tm), Some(s)) = (&run.timer, slot) {
            let mut enc = gpu.device.create_command_encoder(&Default::default());
            tm.stamp(&mut enc, 2 * s);
            gpu.queue.submit([enc.finish()]);
        }
        let wall_done: Arc<Mutex<Option<Instant>>> = Arc::new(Mutex::new(None));
        let submit_start = Instant::now();
        for (wi, w) in run.windows.iter_mut().enumerate() {
            if w.hidden {
                continue;
            }
            let (rw, rh) = match w.channel {
                Some(c) => (self.prep.channels[c].width, self.prep.channels[c].height),
                None => (w.config.width, w.config.height),
            };
            first_size.get_or_insert((rw, rh));
            if let (Some(_), Some(e)) = (w.channel, eye) {
                w.renderer.set_eye(e);
            }
            let cam = Camera::new(pose, rw, rh);
            // Animated voxel models follow the simulation clock.
            w.renderer.set_time(t);
            let dirs: Vec<PathBuf> = capture_all
                .iter()
                .cloned()
                .chain(screenshot.then(|| opts.screenshot_dir.clone()))
                .map(|d| {
                    if n_windows > 1 {
                        d.join(format!(
                            "channel_{}",
                            w.channel.map_or(0, |c| self.prep.channels[c].index)
                        ))
                    } else {
                        d
                    }
                })
                .collect();
            if dirs.is_empty() {
                w.renderer.render(
                    gpu,
                    &self.prep.terrain,
                    &self.desc,
                    &cam,
                    &self.prep.settings,
                    Stage::Shade,
                )?;
            } else {
                let out = w.renderer.capture(
                    gpu,
                    &self.prep.terrain,
                    &self.desc,
                    &cam,
                    &self.prep.settings,
                )?;
                let mut meta = frame_metadata(
                    gpu,
                    &self.prep.scene,
                    &self.prep.terrain,
                    &cam,
                    &self.prep.settings,
                    n as u32,
                    &out,
                );
                meta["time_s"] = json!(t);
                meta["view"] = json!({
                    "mode": self.prep.motion.mode.name(),
                    "rate_hz": opts.rate,
                    "sim_time_s": t,
                });
                if let Some(c) = w.channel {
                    let c = &self.prep.channels[c];
                    meta["display"] = json!({
                        "config": c.config.display().to_string(),
                        "channel": c.index,
                        "channel_name": c.name,
                        "eye_display_frame": eye.unwrap_or(c.eye).to_array(),
                    });
                    meta["camera"]["model"] = json!(
                        "distortion-table (see display); the pinhole intrinsics do not apply"
                    );
                }
                for d in &dirs {
                    write_capture(d, n, &out, &meta)?;
                }
                log::info!("frame {n}: captured to {}", dirs[0].display());
            }
            let t_acq = Instant::now();
            let frame_tex = match w.surface.get_current_texture() {
                wgpu::CurrentSurfaceTexture::Success(t) => Some((t, false)),
                wgpu::CurrentSurfaceTexture::Suboptimal(t) => Some((t, true)),
                wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                    None
                }
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
                        .map_err(|e| {
                            Error::Gpu(format!("cannot recreate the lost surface: {e}"))
                        })?;
                    let size = w.window.inner_size();
                    w.configure(gpu, size);
                    None
                }
                wgpu::CurrentSurfaceTexture::Validation => {
                    return Err(Error::Gpu(
                        "validation error acquiring the swap-chain image".into(),
                    ))
                }
            };
            acquire += t_acq.elapsed();
            let Some((tex, suboptimal)) = frame_tex else {
                continue;
            };
            let (Some(colour), Some(data)) = (w.renderer.colour_view(), w.renderer.data_view())
            else {
                return Err(Error::Gpu(
                    "the renderer has no targets after a frame".into(),
                ));
            };
            let view = tex.texture.create_view(&Default::default());
            let (text, cols, rows) = overlay_lines
                .as_ref()
                .map_or(([[0u32; 4]; 24], 0, 0), |l| pack_text(l));
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
                font: self.font,
            };
            let mut enc = gpu.device.create_command_encoder(&Default::default());
            w.present.encode(gpu, &mut enc, colour, data, &view, &u);
            let (sw, sh) = (tex.texture.width(), tex.texture.height());
            let grab_buf = (grab && w.copy_src).then(|| {
                let row = (sw * 4).div_ceil(256) * 256;
                let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("surface readback"),
                    size: row as u64 * sh as u64,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                });
                enc.copy_texture_to_buffer(
                    tex.texture.as_image_copy(),
                    wgpu::TexelCopyBufferInfo {
                        buffer: &buf,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(row),
                            rows_per_image: Some(sh),
                        },
                    },
                    tex.texture.size(),
                );
                (buf, row)
            });
            // A software adapter blocks here (the swap-chain image's semaphore, then the
            // present's copy to the window): counted apart from the CPU time.
            let t_present = Instant::now();
            gpu.queue.submit([enc.finish()]);
            gpu.queue.present(tex);
            let presented = Instant::now();
            present_call += presented - t_present;
            last_present = Some(presented);
            if suboptimal {
                let size = w.window.inner_size();
                w.configure(gpu, size);
            }
            if grab {
                let dir = &opts.screenshot_dir;
                let suffix = if n_windows > 1 {
                    format!("_c{}", w.channel.map_or(0, |c| self.prep.channels[c].index))
                } else {
                    String::new()
                };
                match grab_buf {
                    Some((buf, row)) => {
                        let rgba = read_surface(gpu, &buf, row, sw, sh, w.config.format)?;
                        let p = dir.join(format!("surface_{n:04}{suffix}.png"));
                        write_png(&p, sw, sh, &rgba)?;
                        log::info!("frame {n}: swap-chain image read back to {}", p.display());
                    }
                    None => {
                        log::warn!("the surface does not allow COPY_SRC: no swap-chain readback")
                    }
                }
                grab_x11(&w.window, dir, n, &suffix, sw, sh);
            }
        }
        if let (Some(tm), Some(s)) = (&mut run.timer, slot) {
            let mut enc = gpu.device.create_command_encoder(&Default::default());
            tm.stamp(&mut enc, 2 * s + 1);
            tm.resolve(&mut enc, s);
            gpu.queue.submit([enc.finish()]);
            tm.start_readback(s, n);
        }
        let mut gpu_ms = f64::NAN;
        let mut gpu_wait = Duration::ZERO;
        if run.timer.is_none() {
            let waiting = Instant::now();
            let cell = wall_done.clone();
            gpu.queue
                .on_submitted_work_done(move || *cell.lock().unwrap() = Some(Instant::now()));
            gpu.wait()?;
            gpu_wait = waiting.elapsed();
            if let Some(done) = *wall_done.lock().unwrap() {
                gpu_ms = (done - submit_start).as_secs_f64() * 1e3;
            }
        }
        let end = Instant::now();
        let period_ms = 1e3 / opts.rate;
        let frame_ms = self
            .last_start
            .map_or(0.0, |s| (start - s).as_secs_f64() * 1e3);
        let present_interval_ms = match (self.last_present, last_present) {
            (Some(a), Some(b)) => (b - a).as_secs_f64() * 1e3,
            _ => 0.0,
        };
        let (w, h) = first_size.unwrap_or((0, 0));
        let stat = FrameStat {
            frame: n,
            sim_time: t,
            start_s: (start - loop_start).as_secs_f64(),
            frame_ms,
            cpu_ms: ((end - start).saturating_sub(acquire + present_call + gpu_wait)).as_secs_f64()
                * 1e3,
            acquire_ms: acquire.as_secs_f64() * 1e3,
            present_ms: present_call.as_secs_f64() * 1e3,
            gpu_ms,
            present_interval_ms,
            latency_ms: last_present.map_or(f64::NAN, |p| (p - start).as_secs_f64() * 1e3),
            dropped: if n == 0 {
                0
            } else {
                stats::dropped_slots(frame_ms, period_ms)
            },
            width: w,
            height: h,
            position: pose.position.to_array(),
            agl: crate::cpu::query::height_above_terrain(&self.prep.terrain, pose.position)
                .unwrap_or(f64::NAN),
            heading: pose.heading,
            pitch: pose.pitch,
            roll: pose.roll,
            rss_kib: crate::app::soak::resident_kib().unwrap_or(0),
        };
        self.stats.push(stat);
        if last_present.is_some() {
            self.last_present = last_present;
        }
        self.last_start = Some(start);
        if let Some(r) = &mut self.prep.recorder {
            r.record(t, &pose)?;
        }
        self.flush_csv(false)?;
        self.frame += 1;
        Ok(())
    }

    /// Writes CSV rows whose GPU time is known (or can no longer arrive).
    fn flush_csv(&mut self, all: bool) -> Result<()> {
        let Some(csv) = &mut self.prep.stats_csv else {
            return Ok(());
        };
        let timed = self.run.as_ref().is_some_and(|r| r.timer.is_some());
        while self.csv_written < self.stats.len() {
            let s = &self.stats[self.csv_written];
            let settled =
                all || !timed || !s.gpu_ms.is_nan() || s.frame + 2 * TIMER_SLOTS < self.frame;
            if !settled {
                break;
            }
            csv.write(s)?;
            self.csv_written += 1;
        }
        Ok(())
    }

    fn overlay_text(&self) -> Vec<String> {
        let m = &self.prep.motion;
        let p = m.pose;
        let recent: Vec<f64> = self
            .stats
            .iter()
            .rev()
            .take(30)
            .map(|s| s.frame_ms)
            .filter(|v| *v > 0.0)
            .collect();
        let mean = recent.iter().sum::<f64>() / recent.len().max(1) as f64;
        let last = self.stats.last();
        let agl = crate::cpu::query::height_above_terrain(&self.prep.terrain, p.position);
        let mut lines = vec![
            format!(
                "{} {:5.1} FPS {:6.1} MS  GPU {}",
                m.mode.name(),
                if mean > 0.0 { 1e3 / mean } else { 0.0 },
                mean,
                self.stats
                    .iter()
                    .rev()
                    .take(2 * TIMER_SLOTS as usize)
                    .find(|s| !s.gpu_ms.is_nan())
                    .map_or("-".into(), |s| format!("{:.1} MS", s.gpu_ms))
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
            self.stats.iter().map(|s| s.dropped as u64).sum::<u64>()
        ));
        lines
    }

    fn finish(mut self) -> Result<ViewReport> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.report.take().ok_or_else(|| {
            invalid(
                "window",
                "the event loop ended before a window opened (no display?)",
            )
        })
    }

    /// Final GPU times, CSV and recorder flush, the report; drops the GPU objects.
    fn shut_down(&mut self) -> Result<()> {
        if let Some(run) = &mut self.run {
            let _ = run.gpu.wait();
            let _ = run.gpu.device.poll(wgpu::PollType::Poll);
            if let Some(timer) = &mut run.timer {
                for (f, ms) in timer.collect() {
                    if let Some(s) = self.stats.get_mut(f as usize) {
                        s.gpu_ms = ms;
                    }
                }
            }
        }
        self.flush_csv(true)?;
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
                summary: stats::summarize(&self.stats),
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

fn write_capture(
    dir: &Path,
    n: u64,
    out: &crate::gpu::FrameOutput,
    meta: &serde_json::Value,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    crate::app::capture::write_frame_files(
        &dir.join(format!("frame_{n:04}.png")),
        &dir.join(format!("depth_{n:04}.tiff")),
        &dir.join(format!("frame_{n:04}.json")),
        out,
        meta,
    )
}

/// Maps a swap-chain readback and returns RGBA8 rows (BGRA formats swizzled).
fn read_surface(
    gpu: &Gpu,
    buf: &wgpu::Buffer,
    row: u32,
    w: u32,
    h: u32,
    format: wgpu::TextureFormat,
) -> Result<Vec<u8>> {
    let (tx, rx) = mpsc::channel();
    buf.slice(..)
        .map_async(wgpu::MapMode::Read, move |r| drop(tx.send(r)));
    gpu.wait()?;
    rx.recv()
        .map_err(|_| Error::Gpu("surface readback callback never ran".into()))?
        .map_err(|e| Error::Gpu(format!("mapping the surface readback: {e}")))?;
    let bgra = matches!(
        format,
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    );
    let mut out = Vec::with_capacity((w * h * 4) as usize);
    {
        let view = buf
            .get_mapped_range(..)
            .map_err(|e| Error::Gpu(format!("surface readback range: {e}")))?;
        for r in 0..h as usize {
            for px in view[r * row as usize..][..w as usize * 4].chunks_exact(4) {
                if bgra {
                    out.extend_from_slice(&[px[2], px[1], px[0], px[3]]);
                } else {
                    out.extend_from_slice(px);
                }
            }
        }
    }
    buf.unmap();
    Ok(out)
}

/// Reads the window back from the X server once the presented image has settled (two equal
/// reads in a row); writes `x11_NNNN.png`. Logs why when it cannot.
#[allow(unused_variables)]
fn grab_x11(window: &Window, dir: &Path, n: u64, suffix: &str, w: u32, h: u32) {
    #[cfg(target_os = "linux")]
    {
        use winit::raw_window_handle::{HasWindowHandle, RawWindowHandle};
        let id = match window.window_handle().map(|h| h.as_raw()) {
            Ok(RawWindowHandle::Xlib(x)) => x.window,
            Ok(RawWindowHandle::Xcb(x)) => x.window.get() as u64,
            _ => {
                log::warn!("not an X11 window: no X server readback");
                return;
            }
        };
        let mut last: Option<Vec<u8>> = None;
        for _ in 0..40 {
            std::thread::sleep(Duration::from_millis(50));
            match super::x11::grab_window(id, w, h) {
                Ok(px) => {
                    if last.as_ref() == Some(&px) {
                        break;
                    }
                    last = Some(px);
                }
                Err(e) => {
                    log::warn!("{e}");
                    return;
                }
            }
        }
        if let Some(px) = last {
            let p = dir.join(format!("x11_{n:04}{suffix}.png"));
            match write_png(&p, w, h, &px) {
                Ok(()) => log::info!("frame {n}: X server's window pixels to {}", p.display()),
                Err(e) => log::warn!("{e}"),
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    log::warn!("X server readback exists on Linux only");
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
            WindowEvent::RedrawRequested if wi == 0 => {
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
                if let Some((at, w, h)) = self.prep.opts.resize_at {
                    if done == at + 1 {
                        let size = PhysicalSize::new(w, h);
                        let run = self.run.as_mut().expect("running");
                        match run.windows[0].window.request_inner_size(size) {
                            Some(now_size) => {
                                let gpu = &run.gpu;
                                run.windows[0].configure(gpu, now_size);
                            }
                            None => {
                                self.pending_resize =
                                    Some((size, Instant::now() + Duration::from_secs(3)));
                            }
                        }
                    }
                }
                if self.prep.opts.frames.is_some_and(|f| done >= f) {
                    el.exit();
                }
            }
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
