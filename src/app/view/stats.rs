//! Per-frame statistics of the window's frame loop, the `--stats-csv` log and the summary
//! printed at exit.

use crate::app::figures::{slope, window, Percentiles, SlopeFit};
use crate::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

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
    /// Frames (from, to) of the whole run's fit: from frame 100 to the end.
    pub rss_run_frames: [u32; 2],
    /// Least-squares slope of the resident set size over `rss_run_frames`; `None` for runs
    /// of fewer than 102 frames.
    pub rss_run_slope_kib_per_frame: Option<f64>,
    /// The resident set's change (KiB) over the run's later part: from frame `[0]`, the last
    /// power of two (at least 128) no later than half the run, to its last frame (`[1]`
    /// frames in all); `None` for runs of fewer than 257 frames. Unlike a slope it ignores
    /// one-time steps early in the run (a driver's buffer made once).
    pub rss_late: Option<([u32; 2], i64)>,
}

/// The summary of `frames` (in frame order, their GPU times final): a [`RunStats`] fed them all.
pub fn summarize(frames: &[FrameStat]) -> Summary {
    let mut run = RunStats::default();
    for s in frames {
        run.push(*s);
    }
    run.settle(0, true);
    run.summary()
}

/// Frames whose resident set is kept for the RSS fit's [`window`]: up to its end, frame 500.
const RSS_EARLY: usize = 500;

/// Frames the overlay's frame rate is the mean over.
const RECENT: usize = 30;

/// The frame loop's statistics over a run of any length in bounded memory (a window left open
/// for hours, at 60 Hz 216,000 frames an hour): the frames whose GPU time may still arrive
/// (timestamp queries are read back a few frames later), the last frames' times for the
/// overlay, and what the [`Summary`] needs: percentiles ([`Percentiles`]), counts, the first
/// 500 frames' resident set (the fit window, [`window`]), a fit over the whole run from
/// frame 100 on ([`SlopeFit`]) and the resident set at frames 128, 256, 512, …
/// ([`Summary::rss_late`]). Kept whole, the frames' statistics grew the process by about
/// 0.2 KiB a frame, 40 MB an hour at 60 Hz.
#[derive(Clone, Debug, Default)]
pub struct RunStats {
    /// Frames pushed and not yet settled, in frame order.
    pending: std::collections::VecDeque<FrameStat>,
    recent: std::collections::VecDeque<f64>,
    last: Option<FrameStat>,
    /// The GPU time of the latest settled frame that had one.
    last_gpu_ms: Option<f64>,
    frames: usize,
    settled: usize,
    first_start_s: Option<f64>,
    last_start_s: f64,
    dropped: u64,
    frame_ms: Percentiles,
    cpu_ms: Percentiles,
    present_call_ms: Percentiles,
    gpu_ms: Percentiles,
    present_interval_ms: Percentiles,
    latency_ms: Percentiles,
    rss_early: Vec<f64>,
    rss_run: SlopeFit,
    /// The resident set at frames 128, 256, 512, … (for [`Summary::rss_late`]).
    rss_marks: Vec<(u32, u64)>,
}

/// The first frame [`Summary::rss_late`] may start from.
const RSS_LATE_FROM: usize = 128;

impl RunStats {
    /// Adds the next frame (its GPU time may come later: [`Self::set_gpu_ms`]).
    pub fn push(&mut self, s: FrameStat) {
        self.frames += 1;
        self.first_start_s.get_or_insert(s.start_s);
        self.last_start_s = s.start_s;
        self.dropped += u64::from(s.dropped);
        if self.recent.len() == RECENT {
            self.recent.pop_front();
        }
        self.recent.push_back(s.frame_ms);
        let n = self.frames - 1;
        if n < RSS_EARLY {
            self.rss_early.push(s.rss_kib as f64);
        }
        if n >= 100 {
            self.rss_run.add(n as f64, s.rss_kib as f64);
        }
        if n >= RSS_LATE_FROM && n.is_power_of_two() {
            self.rss_marks.push((n as u32, s.rss_kib));
        }
        self.last = Some(s);
        self.pending.push_back(s);
    }

    /// Sets frame `frame`'s GPU time where it is still pending (a time that comes after its
    /// frame settled is dropped).
    pub fn set_gpu_ms(&mut self, frame: u64, ms: f64) {
        if let Some(s) = self.pending.iter_mut().find(|s| s.frame == frame) {
            s.gpu_ms = ms;
        }
    }

    /// Settles the pending frames whose GPU time is known or can no longer arrive (`all`: every
    /// pending frame; `late`: frames before this one), in order, into the summary; returns
    /// them (the CSV rows to write).
    pub fn settle(&mut self, late: u64, all: bool) -> Vec<FrameStat> {
        let mut done = Vec::new();
        while let Some(s) = self.pending.front() {
            if !(all || !s.gpu_ms.is_nan() || s.frame < late) {
                break;
            }
            let s = self.pending.pop_front().expect("front exists");
            // The first frame has no frame time or present interval (0).
            if self.settled > 0 {
                self.frame_ms.add(s.frame_ms);
                self.present_interval_ms.add(s.present_interval_ms);
            }
            self.settled += 1;
            self.cpu_ms.add(s.cpu_ms);
            self.present_call_ms.add(s.present_ms);
            self.gpu_ms.add(s.gpu_ms);
            self.latency_ms.add(s.latency_ms);
            if !s.gpu_ms.is_nan() {
                self.last_gpu_ms = Some(s.gpu_ms);
            }
            done.push(s);
        }
        done
    }

    /// The mean frame time of the last 30 frames, without first frames (0).
    pub fn recent_frame_ms(&self) -> f64 {
        let v: Vec<f64> = self.recent.iter().copied().filter(|v| *v > 0.0).collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    }

    /// The latest frame.
    pub fn last(&self) -> Option<&FrameStat> {
        self.last.as_ref()
    }

    /// The latest GPU time known.
    pub fn last_gpu_ms(&self) -> Option<f64> {
        let pending = self.pending.iter().rev().find(|s| !s.gpu_ms.is_nan());
        pending.map(|s| s.gpu_ms).or(self.last_gpu_ms)
    }

    /// Frames pushed and not yet settled.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// Target slots missed so far.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// The run's summary (of the frames settled; settle them all first).
    pub fn summary(&self) -> Summary {
        let p = |v: &Percentiles, q| v.get(q).unwrap_or(f64::NAN);
        let n = self.frames;
        let rss_window = window(n as u32);
        let rss = (self.rss_early)
            .get(rss_window[0] as usize..(rss_window[1] as usize).min(self.rss_early.len()))
            .unwrap_or(&[]);
        let seconds = match self.first_start_s {
            Some(a) if n > 1 => self.last_start_s - a,
            _ => 0.0,
        };
        Summary {
            frames: n,
            seconds,
            fps: if seconds > 0.0 {
                (n - 1) as f64 / seconds
            } else {
                f64::NAN
            },
            frame_ms_p50: p(&self.frame_ms, 50.0),
            frame_ms_p99: p(&self.frame_ms, 99.0),
            cpu_ms_p50: p(&self.cpu_ms, 50.0),
            cpu_ms_p99: p(&self.cpu_ms, 99.0),
            present_call_ms_p50: p(&self.present_call_ms, 50.0),
            present_call_ms_p99: p(&self.present_call_ms, 99.0),
            gpu_ms_p50: self.gpu_ms.get(50.0),
            gpu_ms_p99: self.gpu_ms.get(99.0),
            present_interval_ms_p50: p(&self.present_interval_ms, 50.0),
            present_interval_ms_p99: p(&self.present_interval_ms, 99.0),
            latency_ms_p50: p(&self.latency_ms, 50.0),
            latency_ms_p99: p(&self.latency_ms, 99.0),
            dropped: self.dropped,
            rss_window,
            rss_slope_kib_per_frame: slope(rss),
            rss_run_frames: [100, n as u32],
            rss_run_slope_kib_per_frame: (self.rss_run.points() >= 2).then(|| self.rss_run.slope()),
            rss_late: self.rss_late(),
        }
    }

    /// [`Summary::rss_late`].
    fn rss_late(&self) -> Option<([u32; 2], i64)> {
        let last = self.last.as_ref()?;
        let half = self.frames.saturating_sub(1) / 2;
        let &(from, rss) = self
            .rss_marks
            .iter()
            .rev()
            .find(|(f, _)| *f as usize <= half)?;
        Some(([from, self.frames as u32], last.rss_kib as i64 - rss as i64))
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
