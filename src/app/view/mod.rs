//! `relief view`: the renderer presented to windows (winit 0.30 + a wgpu surface) in a
//! fixed-rate frame loop, with motion (path playback, free flight, aircraft), a text overlay,
//! per-frame statistics and capture.
//!
//! The renderer is the headless one ([`crate::gpu::TerrainRenderer`]): each frame renders into
//! its own colour target, and a present pass copies that target to the swap-chain image, so a
//! window frame and a headless frame of the same pose hold the same pixels.
//!
//! The window itself needs the `window` feature (on by default); [`motion`], [`stats`] and the
//! present pass's shader and font build without it.

pub mod motion;
pub mod present;
pub mod stats;
#[cfg(feature = "window")]
mod window;
#[cfg(all(feature = "window", target_os = "linux"))]
mod x11;

use std::path::PathBuf;

pub use present::present_shader;

/// Options of `relief view`.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    pub scene: PathBuf,
    /// Window (and render) size; the scene's `[output]` when `None`.
    pub size: Option<(u32, u32)>,
    /// Display configuration: one window per channel, each through its distortion table.
    pub display: Option<PathBuf>,
    /// Only this channel of the display configuration.
    pub channel: Option<usize>,
    /// Eye point in the display frame (overrides the config's eye).
    pub eye: Option<[f64; 3]>,
    /// Eye point per frame: a file of `x,y,z` lines, or `-` for lines on stdin.
    pub eye_feed: Option<PathBuf>,
    /// Borderless fullscreen on this monitor (channel `i` on monitor `index + i`).
    pub fullscreen: Option<usize>,
    /// Exit after this many frames.
    pub frames: Option<u64>,
    /// Target frame rate (Hz); the simulation steps 1/rate per frame.
    pub rate: f64,
    /// How frames reach the screen.
    pub present: PresentChoice,
    /// Render frames back to back instead of pacing them at the target rate.
    pub unpaced: bool,
    pub stats_csv: Option<PathBuf>,
    /// Starting motion mode; path playback when there is a path, free flight otherwise.
    pub mode: Option<motion::Mode>,
    /// Path CSV to play back instead of the scene's `[path]`.
    pub path_csv: Option<PathBuf>,
    /// Write the flown path (path CSV) here.
    pub record: Option<PathBuf>,
    /// Aircraft control script CSV.
    pub script: Option<PathBuf>,
    /// Start pose x, y, z (world metres), heading (degrees) instead of the scene's camera.
    pub start: Option<[f64; 4]>,
    /// Free flight and aircraft stay this many metres above the terrain.
    pub min_agl: f64,
    /// Write every frame's capture files (as `relief render`) here.
    pub capture_frames: Option<PathBuf>,
    /// Where the screenshot key and `grab` write.
    pub screenshot_dir: PathBuf,
    /// At this frame, read the swap-chain image back (`surface_NNNN.png`) and, on X11, the
    /// window's pixels from the X server (`x11_NNNN.png`).
    pub grab: Option<u64>,
    /// After this frame, resize the window to W x H (debug, for tests).
    pub resize_at: Option<(u64, u32, u32)>,
    pub overlay: bool,
    /// Starting debug view (V cycles colour, depth, traversal steps).
    pub view_mode: present::ViewMode,
    pub shadows: Option<bool>,
    pub tile_prepass: Option<bool>,
}

impl ViewOptions {
    /// Defaults for `scene`, as the command line has them.
    pub fn new(scene: PathBuf) -> ViewOptions {
        ViewOptions {
            scene,
            size: None,
            display: None,
            channel: None,
            eye: None,
            eye_feed: None,
            fullscreen: None,
            frames: None,
            rate: 60.0,
            present: PresentChoice::Paced,
            unpaced: false,
            stats_csv: None,
            mode: None,
            path_csv: None,
            record: None,
            script: None,
            start: None,
            min_agl: 10.0,
            capture_frames: None,
            screenshot_dir: PathBuf::from("out"),
            grab: None,
            resize_at: None,
            overlay: true,
            view_mode: present::ViewMode::Colour,
            shadows: None,
            tile_prepass: None,
        }
    }
}

/// Presentation: vsync, or the loop's own pacing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PresentChoice {
    /// The loop paces frames at the target rate and presents without waiting (immediate where
    /// the surface has it, else mailbox, else FIFO). The default: under Xvfb, FIFO and mailbox
    /// presents through Mesa's X11 swap chain wait for Xvfb's fake refresh (measured: ~0.4 s
    /// per frame).
    Paced,
    /// FIFO (vsync): presents wait for the display's refresh.
    Vsync,
    /// Mailbox where the surface has it (no tearing, no waiting on a real display).
    Mailbox,
}

impl PresentChoice {
    /// Present modes to try, best first (FIFO always exists).
    pub fn preference(self) -> &'static [wgpu::PresentMode] {
        use wgpu::PresentMode as P;
        match self {
            PresentChoice::Paced => &[P::Immediate, P::Mailbox, P::Fifo],
            PresentChoice::Vsync => &[P::Fifo],
            PresentChoice::Mailbox => &[P::Mailbox, P::Fifo],
        }
    }
}

/// What a finished run reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ViewReport {
    pub adapter: String,
    pub windows: usize,
    /// Render size of the first window at the end.
    pub size: (u32, u32),
    pub target_hz: f64,
    pub present_mode: String,
    pub gpu_time_source: String,
    pub summary: stats::Summary,
    /// Frames the terrain floor lifted the viewpoint.
    pub floor_contacts: u64,
    /// wgpu's live objects per kind at frames 100 and 500 (those the run reached).
    pub resources: Vec<(u64, Vec<(&'static str, usize)>)>,
}

impl std::fmt::Display for ViewReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = &self.summary;
        let opt = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{v:.2} ms"));
        writeln!(
            f,
            "view: {} frames in {:.2} s on {}, {} window(s), {}x{}, target {} Hz, {}",
            s.frames,
            s.seconds,
            self.adapter,
            self.windows,
            self.size.0,
            self.size.1,
            self.target_hz,
            self.present_mode
        )?;
        writeln!(
            f,
            "fps {:.1}; frame time p50 {:.2} ms, p99 {:.2} ms; dropped frames {}",
            s.fps, s.frame_ms_p50, s.frame_ms_p99, s.dropped
        )?;
        writeln!(
            f,
            "cpu p50 {:.2} ms, p99 {:.2} ms; blocked in present p50 {:.2} ms, p99 {:.2} ms; gpu ({}) p50 {}, p99 {}",
            s.cpu_ms_p50,
            s.cpu_ms_p99,
            s.present_call_ms_p50,
            s.present_call_ms_p99,
            self.gpu_time_source,
            opt(s.gpu_ms_p50),
            opt(s.gpu_ms_p99)
        )?;
        writeln!(
            f,
            "present interval p50 {:.2} ms, p99 {:.2} ms; input-to-present latency p50 {:.2} ms, p99 {:.2} ms",
            s.present_interval_ms_p50,
            s.present_interval_ms_p99,
            s.latency_ms_p50,
            s.latency_ms_p99
        )?;
        write!(
            f,
            "memory: RSS slope {:.2} KiB/frame over frames {}..{}",
            s.rss_slope_kib_per_frame, s.rss_window[0], s.rss_window[1]
        )?;
        if let [(a, ca), (b, cb)] = &self.resources[..] {
            let total: usize = cb.iter().map(|(_, n)| n).sum();
            let changed: Vec<String> = (ca.iter().zip(cb))
                .filter(|(x, y)| x.1 != y.1)
                .map(|(x, y)| format!("{} {} -> {}", x.0, x.1, y.1))
                .collect();
            write!(
                f,
                "; wgpu objects at frames {a} and {b}: {}",
                if changed.is_empty() {
                    format!("unchanged ({total} live)")
                } else {
                    changed.join(", ")
                }
            )?;
        }
        Ok(())
    }
}

/// Opens the window(s) and runs the frame loop until the window closes, Escape, or
/// `opts.frames` frames. Every input error (scene, display config, CSV files, adapter) is
/// reported before a window opens.
#[cfg(feature = "window")]
pub fn run(opts: &ViewOptions) -> crate::Result<ViewReport> {
    window::run(opts)
}

/// Built without the `window` feature: always an error saying so.
#[cfg(not(feature = "window"))]
pub fn run(_opts: &ViewOptions) -> crate::Result<ViewReport> {
    Err(crate::Error::invalid(
        "view",
        "this relief was built without the `window` feature; rebuild with default features",
    ))
}
