//! `relief view`: the renderer presented to windows (winit 0.30 + a wgpu surface) in a
//! fixed-rate frame loop, with motion (path playback, free flight, aircraft), a text overlay,
//! per-frame statistics and capture.
//!
//! The renderer is the headless one ([`crate::gpu::TerrainRenderer`]): each frame renders into
//! its own colour target, and a present pass copies that target to the swap-chain image, so a
//! window frame and a headless frame of the same pose hold the same pixels.
//!
//! Rooms:
//! * `mod.rs`: the options ([`ViewOptions`]), the present choice and the report;
//! * [`motion`]: path playback, free flight, aircraft; path, script and eye-feed files;
//! * [`present`]: the present pass (shader, debug views, overlay font);
//! * [`stats`]: per-frame statistics, the `--stats-csv` log, the summary;
//! * `prepare`: everything loaded and checked before a window opens;
//! * `window`: the winit application: windows, surfaces, device, events, shutdown;
//! * `frame`: one frame: step, render, present, record; the overlay text;
//! * `input`: controls from keys, mouse or script; the eye feed; quick-look keys;
//! * `timer`: GPU time per frame from timestamp queries;
//! * `grab`: `--grab`: the swap-chain image and the X server's window pixels;
//! * `x11`: reading a window back from the X server.
//!
//! The window itself needs the `window` feature (on by default); [`motion`], [`stats`] and the
//! present pass's shader and font build without it.

#[cfg(feature = "window")]
mod frame;
#[cfg(feature = "window")]
mod grab;
#[cfg(feature = "window")]
mod input;
pub mod motion;
#[cfg(feature = "window")]
mod prepare;
pub mod present;
pub mod stats;
#[cfg(feature = "window")]
mod timer;
#[cfg(feature = "window")]
mod window;
#[cfg(all(feature = "window", target_os = "linux"))]
mod x11;

use super::args::{parse_size, parse_vec, RenderToggles};
use std::path::PathBuf;

pub use present::present_shader;

/// Options of `relief view` (its command-line flags; see README: Window).
#[derive(Clone, Debug, clap::Args)]
pub struct ViewOptions {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Window and render size WxH (overrides `[output]`).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Display config: one window per channel, each through its distortion table.
    #[arg(long)]
    pub display: Option<PathBuf>,
    /// Only this channel of the display config.
    #[arg(long)]
    pub channel: Option<usize>,
    /// Eye point X,Y,Z in the display frame (overrides the config's eye).
    #[arg(long, value_parser = parse_vec::<3>, allow_hyphen_values = true)]
    pub eye: Option<[f64; 3]>,
    /// Eye point per frame for the distortion: a file of x,y,z lines, or - for stdin.
    #[arg(long)]
    pub eye_feed: Option<PathBuf>,
    /// Borderless fullscreen on monitor INDEX (default 0); channel i on INDEX + i.
    #[arg(long, num_args = 0..=1, default_missing_value = "0")]
    pub fullscreen: Option<usize>,
    /// Exit after N frames.
    #[arg(long)]
    pub frames: Option<u64>,
    /// Target frame rate in Hz; the simulation steps 1/rate per frame.
    #[arg(long, default_value_t = 60.0)]
    pub rate: f64,
    /// Wait for vsync (FIFO present) as well as pacing frames at --rate.
    #[arg(long, conflicts_with = "mailbox")]
    pub vsync: bool,
    /// Present in mailbox mode (no tearing) instead of immediate.
    #[arg(long)]
    pub mailbox: bool,
    /// Render frames back to back instead of pacing them at the target rate.
    #[arg(long)]
    pub unpaced: bool,
    /// Per-frame statistics (CPU, GPU, present interval, latency, pose) to this CSV.
    #[arg(long)]
    pub stats_csv: Option<PathBuf>,
    /// Starting motion: path, free or aircraft (default: path if there is one, else free).
    #[arg(long, value_parser = motion::Mode::parse)]
    pub mode: Option<motion::Mode>,
    /// Play back this path CSV (time,x,y,alt,heading,pitch,roll) instead of the scene's `[path]`.
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Record the flown path to this CSV (same columns as --path).
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Aircraft control script CSV (time,throttle,pitch,roll,yaw).
    #[arg(long)]
    pub script: Option<PathBuf>,
    /// Start at X,Y,Z (world metres) with HEADING (degrees) instead of the scene's camera.
    #[arg(long, value_parser = parse_vec::<4>, allow_hyphen_values = true)]
    pub start: Option<[f64; 4]>,
    /// Free flight and aircraft stay at least this many metres above the terrain.
    #[arg(long, default_value_t = 10.0)]
    pub min_agl: f64,
    /// Write every frame's capture files (as `relief render`) to this directory.
    #[arg(long)]
    pub capture_frames: Option<PathBuf>,
    /// Directory for the screenshot key (P) and --grab.
    #[arg(long, default_value = "out")]
    pub screenshot_dir: PathBuf,
    /// At frame N read back the swap-chain image and, on X11, the window from the X server.
    #[arg(long)]
    pub grab: Option<u64>,
    /// Debug: after frame FRAME resize the window to WxH (`--resize-at 30 320x240`).
    #[arg(long, num_args = 2, value_names = ["FRAME", "WxH"])]
    pub resize_at: Option<Vec<String>>,
    /// Starting view: colour, depth or steps (traversal step heat map); V cycles them.
    #[arg(long, value_parser = present::ViewMode::parse, default_value = "colour")]
    pub debug_view: present::ViewMode,
    /// Start with the text overlay hidden (H toggles it).
    #[arg(long)]
    pub no_overlay: bool,
    /// Render a database scene through a paged tile pool of this many MB on the GPU: each
    /// frame pages for its view (never waiting) and renders what is resident.
    #[arg(long, value_name = "MB")]
    pub terrain_memory: Option<u64>,
    #[command(flatten)]
    pub toggles: RenderToggles,
    /// `--cigi PORT` and its options: the camera obeys a CIGI host (as `relief serve`).
    #[command(flatten)]
    pub cigi: crate::app::cigi_ig::CigiArgs,
}

impl ViewOptions {
    /// How frames reach the screen (`--vsync`, `--mailbox`, else paced).
    pub fn present(&self) -> PresentChoice {
        if self.vsync {
            PresentChoice::Vsync
        } else if self.mailbox {
            PresentChoice::Mailbox
        } else {
            PresentChoice::Paced
        }
    }

    /// `--resize-at FRAME WxH`: (frame, width, height).
    pub fn resize_at(&self) -> crate::Result<Option<(u64, u32, u32)>> {
        let field = |msg: String| crate::Error::invalid("--resize-at", msg);
        match self.resize_at.as_deref() {
            None => Ok(None),
            Some([frame, size]) => {
                let f: u64 = frame
                    .parse()
                    .map_err(|_| field(format!("`{frame}` is not a frame number")))?;
                let (w, h) = parse_size(size).map_err(field)?;
                Ok(Some((f, w, h)))
            }
            Some(_) => Err(field("needs FRAME WxH".into())),
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
        // A run past the fit window: the whole run's slope too (hours in a window).
        if let (Some(run), [a, b]) = (s.rss_run_slope_kib_per_frame, s.rss_run_frames) {
            if b > s.rss_window[1] {
                write!(f, ", {run:.2} over frames {a}..{b}")?;
            }
        }
        // And the later part's change, which an early one-time step does not enter.
        if let Some(([a, b], kib)) = s.rss_late.filter(|([_, b], _)| *b > s.rss_window[1]) {
            write!(f, "; RSS {kib:+} KiB over frames {a}..{b}")?;
        }
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
