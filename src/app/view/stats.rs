//! Per-frame statistics of the window's frame loop, the `--stats-csv` log and the summary
//! printed at exit.

use crate::app::figures::percentile;
use crate::app::figures::{slope, window};
use crate::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

// The frame loop's percentiles, where they have always been found.

/// Where a frame's GPU time comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GpuTimeSource {
    /// Timestamp queries around the frame's GPU work.
    Timestamps,
    /// Wall time from the frame's last submit until the queue reports it done.
    WallToCompletion,
}

impl GpuTimeSource {
    pub fn name(self) -> &'static str {
        match self {
            GpuTimeSource::Timestamps => "timestamp queries",
            GpuTimeSource::WallToCompletion => "wall time to completion",
        }
    }
}

/// One rendered frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameStat {
    pub frame: u64,
    /// Simulation time (s).
    pub sim_time: f64,
    /// Seconds since the loop started, at frame start (input sampled).
    pub start_s: f64,
    /// Frame start to the previous frame's start (ms); 0 for the first frame.
    pub frame_ms: f64,
    /// CPU time of the frame: input, motion, encoding, submits, captures (ms); without the
    /// time blocked in acquiring swap-chain images, in present calls and waiting for the GPU.
    pub cpu_ms: f64,
    /// Blocked acquiring swap-chain images (ms).
    pub acquire_ms: f64,
    /// Blocked in the submit of the present pass and the present call (ms): a software
    /// adapter waits for the swap-chain image and finishes the frame there.
    pub present_ms: f64,
    /// GPU time (ms), `NaN` until known.
    pub gpu_ms: f64,
    /// Between this frame's present and the previous one's (ms); 0 for the first frame.
    pub present_interval_ms: f64,
    /// Input sampled → frame handed to present (ms; the last window's present).
    pub latency_ms: f64,
    /// Target slots missed before this frame.
    pub dropped: u32,
    pub width: u32,
    pub height: u32,
    pub position: [f64; 3],
    pub agl: f64,
    pub heading: f64,
    pub pitch: f64,
    pub roll: f64,
    /// Resident set size of the process after the frame (KiB; 0 where the OS does not say).
    pub rss_kib: u64,
    /// Anti-aliased pixels over the windows (0 with `antialias = "off"`).
    pub aa_pixels: u64,
    /// The sub-pixel rays they got.
    pub aa_extra_rays: u64,
}

/// Slots of `period_ms` missed by a frame that came `interval_ms` after the previous one.
pub fn dropped_slots(interval_ms: f64, period_ms: f64) -> u32 {
    if period_ms <= 0.0 || interval_ms <= 1.5 * period_ms {
        0
    } else {
        ((interval_ms / period_ms).round() as u32).saturating_sub(1)
    }
}

/// Summary of a run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Summary {
    pub frames: usize,
    pub seconds: f64,
    pub fps: f64,
    pub frame_ms_p50: f64,
    pub frame_ms_p99: f64,
    pub cpu_ms_p50: f64,
    pub cpu_ms_p99: f64,
    pub present_call_ms_p50: f64,
    pub present_call_ms_p99: f64,
    pub gpu_ms_p50: Option<f64>,
    pub gpu_ms_p99: Option<f64>,
    pub present_interval_ms_p50: f64,
    pub present_interval_ms_p99: f64,
    pub latency_ms_p50: f64,
    pub latency_ms_p99: f64,
    pub dropped: u64,
    /// Frames (from, to) the RSS slope is fitted over ([`crate::app::figures::window`]).
    pub rss_window: [u32; 2],
    /// Least-squares slope of the resident set size over `rss_window` (KiB per frame).
    pub rss_slope_kib_per_frame: f64,
}

pub fn summarize(frames: &[FrameStat]) -> Summary {
    let col = |f: fn(&FrameStat) -> f64, skip_first: bool| -> Vec<f64> {
        frames.iter().skip(usize::from(skip_first)).map(f).collect()
    };
    let p = |v: &[f64], q| percentile(v, q).unwrap_or(f64::NAN);
    let frame_ms = col(|s| s.frame_ms, true);
    let cpu = col(|s| s.cpu_ms, false);
    let present_call = col(|s| s.present_ms, false);
    let gpu = col(|s| s.gpu_ms, false);
    let present = col(|s| s.present_interval_ms, true);
    let lat = col(|s| s.latency_ms, false);
    let rss_window = window(frames.len() as u32);
    let rss: Vec<f64> = frames
        .get(rss_window[0] as usize..rss_window[1] as usize)
        .unwrap_or(&[])
        .iter()
        .map(|s| s.rss_kib as f64)
        .collect();
    let seconds = match (frames.first(), frames.last()) {
        (Some(a), Some(b)) if frames.len() > 1 => b.start_s - a.start_s,
        _ => 0.0,
    };
    Summary {
        frames: frames.len(),
        seconds,
        fps: if seconds > 0.0 {
            (frames.len() - 1) as f64 / seconds
        } else {
            f64::NAN
        },
        frame_ms_p50: p(&frame_ms, 50.0),
        frame_ms_p99: p(&frame_ms, 99.0),
        cpu_ms_p50: p(&cpu, 50.0),
        cpu_ms_p99: p(&cpu, 99.0),
        present_call_ms_p50: p(&present_call, 50.0),
        present_call_ms_p99: p(&present_call, 99.0),
        gpu_ms_p50: percentile(&gpu, 50.0),
        gpu_ms_p99: percentile(&gpu, 99.0),
        present_interval_ms_p50: p(&present, 50.0),
        present_interval_ms_p99: p(&present, 99.0),
        latency_ms_p50: p(&lat, 50.0),
        latency_ms_p99: p(&lat, 99.0),
        dropped: frames.iter().map(|s| s.dropped as u64).sum(),
        rss_window,
        rss_slope_kib_per_frame: slope(&rss),
    }
}

pub const CSV_HEADER: &str = "frame,sim_time_s,start_s,frame_ms,cpu_ms,acquire_ms,present_ms,gpu_ms,present_interval_ms,latency_ms,dropped,width,height,x,y,alt,agl,heading,pitch,roll,rss_kib,aa_pixels,aa_extra_rays";

/// Writes [`FrameStat`] rows to a CSV file, flushed per row (a run that stops keeps every
/// row written so far).
pub struct StatsCsv {
    out: std::io::BufWriter<std::fs::File>,
    path: PathBuf,
}

impl StatsCsv {
    pub fn create(path: &Path) -> Result<StatsCsv> {
        let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
        let mut s = StatsCsv {
            out: std::io::BufWriter::new(file),
            path: path.to_path_buf(),
        };
        writeln!(s.out, "{CSV_HEADER}").map_err(|e| Error::io(path, e))?;
        Ok(s)
    }

    pub fn write(&mut self, s: &FrameStat) -> Result<()> {
        let [x, y, z] = s.position;
        writeln!(
            self.out,
            "{},{:.6},{:.6},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{}",
            s.frame,
            s.sim_time,
            s.start_s,
            s.frame_ms,
            s.cpu_ms,
            s.acquire_ms,
            s.present_ms,
            s.gpu_ms,
            s.present_interval_ms,
            s.latency_ms,
            s.dropped,
            s.width,
            s.height,
            x,
            y,
            z,
            s.agl,
            s.heading,
            s.pitch,
            s.roll,
            s.rss_kib,
            s.aa_pixels,
            s.aa_extra_rays
        )
        .and_then(|()| self.out.flush())
        .map_err(|e| Error::io(&self.path, e))
    }

    pub fn finish(mut self) -> Result<()> {
        self.out.flush().map_err(|e| Error::io(&self.path, e))
    }
}
