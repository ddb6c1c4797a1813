//! `relief bench cigi`: the CIGI IG under a host, in one process. The IG is `relief serve`'s
//! loop ([`crate::app::serve::run_with`], asynchronous, `--cigi-host` fixed) on this thread;
//! the host is another on a loopback socket, sending one datagram per host frame at 60 Hz
//! (IG Control with a valid timestamp and the ownship at the scene camera's geodetic
//! position). Phases of `--frames` host frames each, after 60 warm-up frames:
//!
//! * `quiet`: no queries: host-datagram-to-Start-of-Frame latency and the IG's Start of
//!   Frame period;
//! * `hat_hot`, `los`: a batch of 100 HAT/HOT requests (HOT and HAT alternating) or LOS
//!   segment requests per host frame: responses received per second; `hat_hot_1000`,
//!   `los_1000` likewise with 1,000;
//! * `flood`: as quiet, with 10,000 malformed datagrams a second from the host's own address
//!   on another thread (random bytes never starting with IG Control, IG Control of version 9:
//!   both refused whole).
//!
//! Latency of host frame F: from its send to the arrival of the first Start of Frame whose
//! `last_host_frame` is F or later, in ms and in IG frames (Start of Frames that arrived in
//! between, the reporting one included). Start of Frame period: the difference of consecutive
//! IG frames' timestamps (the IG's clock when it sent them), and its deviation from the
//! nominal 1/60 s. The CPU oracle's own rates (no network, no rendering) are the summary's
//! `oracle_*` figures ([docs/cigi.md](../../../docs/cigi.md)).

use super::table::{Figures, Row, RunInfo, Table};
use crate::app::cigi_ig::{answer, CigiArgs, CigiIg};
use crate::app::figures::percentile;
use crate::app::serve::{run_with, ServeOptions, MAX_RATE_HZ};
use crate::cigi::*;
use crate::{Error, Result};
use serde::Serialize;
use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::time::{Duration, Instant};

/// Queries per host frame in the query phases.
pub const BATCH: usize = 100;
/// Queries per host frame in the heavy query phases (a LOS batch fills a datagram: 64,072
/// bytes; the session holds at most 1,024 waiting queries).
pub const BIG_BATCH: usize = 1000;
/// Malformed datagrams a second in the flood phase.
pub const FLOOD_PER_S: f64 = 10_000.0;
/// Host frames a second.
pub const HOST_HZ: f64 = 60.0;
/// Host frames before the first measured phase.
const WARM_UP: u32 = 60;

/// One phase's figures.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Phase {
    pub name: String,
    pub host_frames: u32,
    /// Query responses received during the phase, and per second.
    pub responses: u64,
    pub responses_per_s: f64,
    pub latency_ms_p50: f64,
    pub latency_ms_p99: f64,
    pub latency_frames_p50: f64,
    pub latency_frames_p99: f64,
    /// Host frames never reported by a Start of Frame during the phase.
    pub unreported: u32,
    pub sof_period_ms_p50: f64,
    pub sof_period_ms_p99: f64,
    /// |period − 1/60 s|.
    pub sof_deviation_ms_p50: f64,
    pub sof_deviation_ms_p99: f64,
    /// Malformed datagrams sent during the phase, per second.
    pub flood_per_s: f64,
}

/// What `relief bench cigi` measures (the report's `details`).
#[derive(Clone, Debug, Serialize)]
pub struct CigiBench {
    pub host_hz: f64,
    pub batch: usize,
    pub phases: Vec<Phase>,
    /// The CPU oracle alone (`cigi_ig::answer` on a session's queue): answers a second.
    pub oracle_hat_hot_per_s: f64,
    pub oracle_los_per_s: f64,
    /// Of the oracle's answers, `valid = false` ones (points off the terrain: none expected).
    pub oracle_invalid: u64,
    /// Queries the session dropped at its cap of 1,024 waiting (two 1,000-query datagrams
    /// read in one IG frame).
    pub dropped_queries: u64,
    /// The IG's counters at the end (`relief serve`'s `cigi-counters`).
    pub summary: String,
}

/// A Start of Frame as the host saw it.
#[derive(Clone, Copy, Debug)]
struct Sof {
    arrived: f64,
    ig_frame: u32,
    timestamp: u32,
    last_host_frame: u32,
}

/// The host: its socket, clock, frame number and what came back.
struct Host {
    socket: UdpSocket,
    ig: SocketAddr,
    t0: Instant,
    frame: u32,
    ownship: EntityControl,
    /// (host frame, send time, the highest IG frame seen before it).
    sent: Vec<(u32, f64, Option<u32>)>,
    sofs: Vec<Sof>,
    responses: u64,
    buf: Vec<u8>,
}

/// What a host frame carries besides IG Control and the ownship.
#[derive(Clone, Copy, PartialEq)]
enum Load {
    Nothing,
    HatHot,
    Los,
}

/// Query `i` of a batch around `at`: points within ±0.05° of it (a fixed pattern).
fn query(load: Load, i: usize, at: [f64; 3]) -> Option<HostPacket> {
    let f = |k: usize| ((i * k) % 101) as f64 / 100.0 - 0.5;
    let (lat, lon) = (at[0] + 0.1 * f(37), at[1] + 0.1 * f(61));
    match load {
        Load::Nothing => None,
        Load::HatHot => Some(HostPacket::HatHotRequest(HatHotRequest {
            request_id: i as u16,
            request_type: (i % 2) as u8,
            entity_frame: false,
            update_period: 0,
            entity_id: 0,
            lat,
            lon,
            alt: at[2],
        })),
        Load::Los => Some(HostPacket::LosSegmentRequest(LosSegmentRequest::between(
            i as u16,
            at,
            [lat, lon, at[2] - 1500.0],
            false,
        ))),
    }
}

fn control(frame: u32, t: f64) -> IgControl {
    IgControl {
        database: 0,
        ig_mode: 1,
        timestamp_valid: true,
        extrapolation: false,
        host_frame: frame,
        timestamp: (t / session::TICK).round() as u64 as u32,
        last_ig_frame: 0,
    }
}

impl Host {
    fn now(&self) -> f64 {
        self.t0.elapsed().as_secs_f64()
    }

    /// Takes every datagram waiting from the IG.
    fn drain(&mut self) {
        while let Ok((n, from)) = self.socket.recv_from(&mut self.buf) {
            if from != self.ig {
                continue;
            }
            let arrived = self.now();
            let Ok(m) = read_ig_message(&self.buf[..n]) else {
                continue;
            };
            for p in &m.packets {
                match p {
                    IgPacket::StartOfFrame(s) => self.sofs.push(Sof {
                        arrived,
                        ig_frame: s.ig_frame,
                        timestamp: s.timestamp,
                        last_host_frame: s.last_host_frame,
                    }),
                    _ => self.responses += 1,
                }
            }
        }
    }

    /// Flies `frames` host frames carrying `load`; returns the phase's figures.
    fn phase(
        &mut self,
        name: &str,
        frames: u32,
        load: (Load, usize),
        flood: Option<&Flood>,
    ) -> Phase {
        let (load, batch) = load;
        let (sent0, sofs0, responses0) = (self.sent.len(), self.sofs.len(), self.responses);
        let flooded0 = flood.map_or(0, |f| f.sent.load(Relaxed));
        let (start, period) = (self.now(), 1.0 / HOST_HZ);
        let at = [self.ownship.lat, self.ownship.lon, self.ownship.alt];
        for k in 0..frames {
            let t = self.now();
            let mut m = MessageBuilder::host(&control(self.frame, t), ByteOrder::Big);
            m.push_any(&HostPacket::EntityControl(self.ownship));
            for i in 0..batch {
                if let Some(q) = query(load, i, at) {
                    m.push_any(&q);
                }
            }
            let seen = self.sofs.last().map(|s| s.ig_frame);
            if self.socket.send_to(&m.finish(), self.ig).is_ok() {
                self.sent.push((self.frame, t, seen));
            }
            self.frame += 1;
            let next = start + f64::from(k + 1) * period;
            while self.now() < next {
                self.drain();
                std::thread::sleep(Duration::from_micros(300));
            }
        }
        let end = self.now();
        let mut p = figures(&self.sent[sent0..], &self.sofs[sofs0..]);
        p.name = name.into();
        p.host_frames = frames;
        p.responses = self.responses - responses0;
        p.responses_per_s = p.responses as f64 / (end - start);
        let flooded = flood.map_or(0, |f| f.sent.load(Relaxed)) - flooded0;
        p.flood_per_s = flooded as f64 / (end - start);
        p
    }
}

/// Latency and period figures of a phase's sends and Start of Frames.
fn figures(sent: &[(u32, f64, Option<u32>)], sofs: &[Sof]) -> Phase {
    let (mut ms, mut frames, mut unreported) = (Vec::new(), Vec::new(), 0);
    for &(f, t, seen) in sent {
        match sofs
            .iter()
            .find(|s| s.arrived >= t && s.last_host_frame >= f)
        {
            Some(s) => {
                ms.push(1e3 * (s.arrived - t));
                let before = seen.unwrap_or(s.ig_frame.saturating_sub(1));
                frames.push(f64::from(s.ig_frame.saturating_sub(before)));
            }
            None => unreported += 1,
        }
    }
    let nominal = 1e3 / MAX_RATE_HZ;
    let periods: Vec<f64> = sofs
        .windows(2)
        .filter(|w| w[1].ig_frame == w[0].ig_frame.wrapping_add(1))
        .map(|w| f64::from(w[1].timestamp.wrapping_sub(w[0].timestamp)) * session::TICK * 1e3)
        .collect();
    let dev: Vec<f64> = periods.iter().map(|p| (p - nominal).abs()).collect();
    let pc = |v: &[f64], q: f64| percentile(v, q).unwrap_or(f64::NAN);
    Phase {
        latency_ms_p50: pc(&ms, 50.0),
        latency_ms_p99: pc(&ms, 99.0),
        latency_frames_p50: pc(&frames, 50.0),
        latency_frames_p99: pc(&frames, 99.0),
        unreported,
        sof_period_ms_p50: pc(&periods, 50.0),
        sof_period_ms_p99: pc(&periods, 99.0),
        sof_deviation_ms_p50: pc(&dev, 50.0),
        sof_deviation_ms_p99: pc(&dev, 99.0),
        ..Phase::default()
    }
}

/// The malformed flood's thread state.
struct Flood {
    on: AtomicBool,
    done: AtomicBool,
    sent: std::sync::atomic::AtomicU64,
}

/// Sends [`FLOOD_PER_S`] malformed datagrams a second while `flood.on`, until `flood.done`.
fn flood_loop(socket: UdpSocket, to: SocketAddr, flood: &Flood) {
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = Instant::now();
    let step = Duration::from_secs_f64(100.0 / FLOOD_PER_S);
    while !flood.done.load(Relaxed) {
        if !flood.on.load(Relaxed) {
            std::thread::sleep(Duration::from_millis(1));
            next = Instant::now();
            continue;
        }
        for i in 0..100u64 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let d: Vec<u8> = if i % 2 == 0 {
                let n = (x % 200) as usize;
                let mut v: Vec<u8> = (0..n).map(|k| (x >> (k % 56)) as u8).collect();
                if let Some(b) = v.first_mut() {
                    *b = if *b == 1 { 77 } else { *b };
                }
                v
            } else {
                let mut v = MessageBuilder::host(&control(i as u32, 0.0), ByteOrder::Big).finish();
                v[2] = 9;
                v
            };
            if socket.send_to(&d, to).is_ok() {
                flood.sent.fetch_add(1, Relaxed);
            }
        }
        next += step;
        if let Some(w) = next.checked_duration_since(Instant::now()) {
            std::thread::sleep(w);
        }
    }
}

/// The CPU oracle's answers a second for batches of `load` (no network, no rendering), and
/// how many were answered `valid = false`.
fn oracle_rate(terrain: &crate::terrain::Terrain, at: [f64; 3], load: Load) -> (f64, u64) {
    let none = crate::cpu::bodies::Bodies::default();
    let ground = answer::Ground {
        terrain,
        full: None,
        bodies: &none,
        los: answer::LosResponses::First,
    };
    let (mut answered, mut invalid, mut spent) = (0u64, 0u64, 0.0);
    let mut frame = 0;
    while spent < 0.5 {
        let mut session = Session::new();
        let mut m = MessageBuilder::host(&control(frame, 0.0), ByteOrder::Big);
        for i in 0..1000 {
            if let Some(q) = query(load, i, at) {
                m.push_any(&q);
            }
        }
        let _ = session.receive(&m.finish(), 0.0);
        let queries = session.take_queries();
        let mut out = session.start_of_frame(frame, None);
        let t = Instant::now();
        let c = answer::answer(&ground, &session, &queries, 0.0, &mut out);
        spent += t.elapsed().as_secs_f64();
        answered += c.hat_hot + c.los;
        invalid += c.invalid;
        frame += 1;
    }
    (answered as f64 / spent, invalid)
}

/// The host's flight: one datagram per host frame to the IG at `ig` with the ownship at
/// `lla`/`hpr`, the warm-up and every phase of `frames` host frames, the flood's last
/// (`flood` switched on for it, then done).
fn fly(
    socket: UdpSocket,
    ig: SocketAddr,
    lla: [f64; 3],
    hpr: [f32; 3],
    frames: u32,
    flood: &Flood,
) -> Vec<Phase> {
    let mut host = Host {
        socket,
        ig,
        t0: Instant::now(),
        frame: 1000,
        ownship: EntityControl::placed(0, 0, lla, hpr),
        sent: Vec::new(),
        sofs: Vec::new(),
        responses: 0,
        buf: vec![0; 65536],
    };
    let none = (Load::Nothing, 0);
    host.phase("warm-up", WARM_UP, none, None);
    let mut phases = vec![host.phase("quiet", frames, none, None)];
    phases.push(host.phase("hat_hot", frames, (Load::HatHot, BATCH), None));
    phases.push(host.phase("los", frames, (Load::Los, BATCH), None));
    phases.push(host.phase("hat_hot_1000", frames, (Load::HatHot, BIG_BATCH), None));
    phases.push(host.phase("los_1000", frames, (Load::Los, BIG_BATCH), None));
    flood.on.store(true, Relaxed);
    phases.push(host.phase("flood", frames, none, Some(flood)));
    flood.done.store(true, Relaxed);
    phases
}

/// Runs the host against an in-process IG on `scene_path` at `size`, `frames` host frames a
/// phase.
pub fn run(scene_path: &Path, size: (u32, u32), frames: u32) -> Result<(RunInfo, CigiBench)> {
    let scene = super::timing::scene_at_size(scene_path, size)?;
    let world = crate::world::World::load(&scene)?;
    let cam = scene.camera(0, &world.terrain);
    let p = &cam.pose;
    let lla = world.terrain.world_to_geodetic(p.position).ok_or_else(|| {
        Error::invalid(
            "bench cigi",
            "the scene's camera has no geodetic position (a georeferenced terrain is needed)",
        )
    })?;
    let io = |e: std::io::Error| Error::invalid("bench cigi", format!("UDP: {e}"));
    let socket = UdpSocket::bind("127.0.0.1:0").map_err(io)?;
    socket.set_nonblocking(true).map_err(io)?;
    let opts = ServeOptions {
        scene: scene_path.to_path_buf(),
        cigi: CigiArgs {
            cigi: Some(0),
            cigi_bind: [127, 0, 0, 1].into(),
            cigi_host: Some(socket.local_addr().map_err(io)?),
            cigi_sync: false,
            cigi_timeout: 5.0,
            cigi_los: answer::LosResponses::First,
        },
        size: Some(size),
        display: Default::default(),
        frames: None,
        capture_frames: None,
        pose_log: None,
        toggles: Default::default(),
        terrain_memory: None,
    };
    let stop = AtomicBool::new(false);
    let flood = Flood {
        on: AtomicBool::new(false),
        done: AtomicBool::new(false),
        sent: 0.into(),
    };
    let (tx, rx) = std::sync::mpsc::channel();
    // The IG, the GPU user, runs on this thread and the host on a scoped one, as `serve`
    // and `view` keep their GPU on the main thread: a GL heap corruption was seen in this
    // command once in CI and once in ~240 runs here, and wgpu issue 4285 traced one like it
    // to libglvnd freeing EGL's thread state as a thread that used EGL exits
    // (docs/robustness.md).
    std::thread::scope(|s| {
        let stop = &stop;
        let flood = &flood;
        let host = s.spawn(move || {
            // The IG stops when the host ends, a panic included.
            struct StopOnDrop<'a>(&'a AtomicBool);
            impl Drop for StopOnDrop<'_> {
                fn drop(&mut self) {
                    self.0.store(true, Relaxed);
                }
            }
            let _stop = StopOnDrop(stop);
            let hosted = rx.recv().ok().and_then(|(info, addr)| Some((info, addr?)));
            hosted.map(|(info, addr)| {
                let flood_socket = socket.try_clone().map_err(io)?;
                let flooder = s.spawn(move || flood_loop(flood_socket, addr, flood));
                let hpr = [p.heading, p.pitch, p.roll].map(|a| a as f32);
                let phases = fly(socket, addr, lla, hpr, frames, flood);
                let _ = flooder.join();
                Ok::<_, Error>((info, phases))
            })
        });
        let cigi = &opts.cigi;
        let summary = run_with(&opts, stop, move |gpu| {
            let ig = CigiIg::open(cigi)?;
            let info = (gpu.info.name.clone(), format!("{:?}", gpu.info.backend));
            let _ = tx.send((info, ig.local_addr()));
            Ok(ig)
        });
        // An IG that failed before its socket opened dropped `tx` with the closure: the
        // host's `recv` returned and it ended.
        let measured = host
            .join()
            .map_err(|_| Error::invalid("bench cigi", "the host thread panicked"))?;
        let summary = summary?;
        let ((adapter, backend), phases) =
            measured.ok_or_else(|| Error::invalid("bench cigi", "the IG did not start"))??;
        let hat_hot = oracle_rate(&world.terrain, lla, Load::HatHot);
        let los = oracle_rate(&world.terrain, lla, Load::Los);
        let counters = summary
            .lines()
            .find_map(|l| l.strip_prefix("cigi-counters: "));
        let counters: serde_json::Value =
            serde_json::from_str(counters.unwrap_or("{}")).unwrap_or_default();
        let bench = CigiBench {
            dropped_queries: counters["dropped_queries"].as_u64().unwrap_or(0),
            host_hz: HOST_HZ,
            batch: BATCH,
            phases,
            oracle_hat_hot_per_s: hat_hot.0,
            oracle_los_per_s: los.0,
            oracle_invalid: hat_hot.1 + los.1,
            summary,
        };
        let run = RunInfo {
            adapter,
            backend,
            scene: scene_path.display().to_string(),
            width: size.0,
            height: size.1,
            frames,
        };
        Ok((run, bench))
    })
}

impl CigiBench {
    /// A row per phase; the query rates and the oracle's as the summary.
    pub fn table(&self) -> Table {
        let rows = self
            .phases
            .iter()
            .map(|p| {
                let f = Figures::default()
                    .with("responses_per_s", p.responses_per_s)
                    .with("latency_ms_p50", p.latency_ms_p50)
                    .with("latency_ms_p99", p.latency_ms_p99)
                    .with("latency_frames_p50", p.latency_frames_p50)
                    .with("latency_frames_p99", p.latency_frames_p99)
                    .with("sof_ms_p50", p.sof_period_ms_p50)
                    .with("sof_ms_p99", p.sof_period_ms_p99)
                    .with("sof_dev_ms_p50", p.sof_deviation_ms_p50)
                    .with("sof_dev_ms_p99", p.sof_deviation_ms_p99)
                    .with("flood_per_s", p.flood_per_s);
                Row::new(p.name.clone(), f)
            })
            .collect();
        let rate = |n: &str| {
            (self.phases.iter())
                .find(|p| p.name == n)
                .map_or(f64::NAN, |p| p.responses_per_s)
        };
        let summary = Figures::default()
            .with("hat_hot_per_s", rate("hat_hot"))
            .with("los_per_s", rate("los"))
            .with("hat_hot_1000_per_s", rate("hat_hot_1000"))
            .with("los_1000_per_s", rate("los_1000"))
            .with("dropped_queries", self.dropped_queries as f64)
            .with("oracle_hat_hot_per_s", self.oracle_hat_hot_per_s)
            .with("oracle_los_per_s", self.oracle_los_per_s);
        let unreported: u32 = self.phases.iter().map(|p| p.unreported).sum();
        let notes = vec![
            format!(
                "host at {} Hz, {} queries per host frame in hat_hot and los, {BIG_BATCH} in the _1000 phases; the IG asynchronous (at most {} Hz)",
                self.host_hz, self.batch, MAX_RATE_HZ
            ),
            format!(
                "{unreported} host frames never reported by a Start of Frame; {} oracle answers valid = false",
                self.oracle_invalid
            ),
            self.summary.lines().next().unwrap_or("").to_string(),
        ];
        Table {
            rows,
            summary,
            notes,
        }
    }
}
