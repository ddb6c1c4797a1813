//! Motion of the viewpoint for the window: path playback, free flight and a simple aircraft,
//! with a terrain floor from the CPU height query. Pure CPU code stepped at a fixed rate, so a
//! run with the same inputs gives the same poses (and the same frames) every time.
//!
//! Path CSV (playback with `--path`, written by `--record`): one row per sample,
//! `time,x,y,alt,heading,pitch,roll` — seconds, world metres (alt = world z), degrees as in
//! [`crate::scene::Pose`]. A first line that does not start with a number is a header; empty
//! lines and lines starting with `#` are skipped.
//!
//! Control script CSV (`--script`): `time,throttle,pitch,roll,yaw` — from `time` on, the
//! aircraft's controls are held at these values (throttle 0..=1, sticks -1..=1; pitch +1 pulls
//! the nose up, roll +1 rolls right, yaw +1 turns right).

use crate::scene::{CameraPath, Keyframe, Pose};
use crate::terrain::Terrain;
use crate::{Error, Result};
use glam::DVec3;
use std::io::Write;
use std::path::Path;

/// Standard gravity (m/s²).
pub const GRAVITY: f64 = 9.81;

/// The aircraft model's constants.
#[derive(Clone, Copy, Debug)]
pub struct AircraftParams {
    /// Acceleration at full throttle (m/s²).
    pub max_thrust: f64,
    /// Quadratic drag (1/m): deceleration = drag · v².
    pub drag: f64,
    /// Below this speed lift falls off with (v / stall)² and gravity takes over (m/s).
    pub stall_speed: f64,
    /// Full-stick rates (degrees per second).
    pub pitch_rate: f64,
    pub roll_rate: f64,
    pub yaw_rate: f64,
    /// Throttle change per second with a throttle key held.
    pub throttle_rate: f64,
}

impl Default for AircraftParams {
    fn default() -> Self {
        AircraftParams {
            max_thrust: 6.0,
            // 6 m/s² = drag · 120² at full throttle in level flight: top speed ≈ 120 m/s.
            drag: 6.0 / (120.0 * 120.0),
            stall_speed: 35.0,
            pitch_rate: 30.0,
            roll_rate: 60.0,
            yaw_rate: 10.0,
            throttle_rate: 0.5,
        }
    }
}

/// How the viewpoint moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Playback of the scene's `[path]` or a path CSV.
    Path,
    /// Free flight: translate and look, no dynamics.
    Free,
    /// Throttle, pitch, roll, yaw and gravity.
    Aircraft,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Path => "PATH",
            Mode::Free => "FREE",
            Mode::Aircraft => "AIRCRAFT",
        }
    }

    /// `path`, `free` or `aircraft` (the command line's `--mode`).
    pub fn parse(s: &str) -> std::result::Result<Mode, String> {
        match s {
            "path" => Ok(Mode::Path),
            "free" => Ok(Mode::Free),
            "aircraft" => Ok(Mode::Aircraft),
            _ => Err(format!("`{s}`: use path, free or aircraft")),
        }
    }
}

/// Control inputs sampled for one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Controls {
    /// Free flight: -1..=1 along forward, right and world up.
    pub forward: f64,
    pub right: f64,
    pub up: f64,
    /// Sticks -1..=1 (free flight: look rates; aircraft: control surfaces).
    pub pitch: f64,
    pub roll: f64,
    pub yaw: f64,
    /// Aircraft: throttle keys, -1..=1 (rate of change).
    pub throttle_delta: f64,
    /// Aircraft: absolute throttle 0..=1 from a script (overrides the keys).
    pub throttle: Option<f64>,
    /// Free flight: mouse look this frame (degrees of heading, pitch).
    pub look: (f64, f64),
    /// Free flight: ×5 speed.
    pub fast: bool,
}

/// Aircraft state beyond the pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AircraftState {
    /// Airspeed along the nose (m/s).
    pub speed: f64,
    /// 0..=1.
    pub throttle: f64,
    /// Vertical speed from missing lift (m/s, ≤ 0).
    pub sink: f64,
}

impl Default for AircraftState {
    fn default() -> Self {
        AircraftState {
            speed: 80.0,
            throttle: 0.6,
            sink: 0.0,
        }
    }
}

/// The viewpoint and how it moves.
#[derive(Clone, Debug)]
pub struct Motion {
    pub mode: Mode,
    pub pose: Pose,
    pub aircraft: AircraftState,
    pub params: AircraftParams,
    /// Free-flight speed (m/s).
    pub free_speed: f64,
    /// Free flight and aircraft stay at least this high above the terrain (metres along the
    /// base-plane normal); path playback is shown as recorded.
    pub min_agl: f64,
    /// Playback path (the scene's `[path]` or a CSV), if any.
    pub path: Option<CameraPath>,
    /// Frames clamped to the floor so far.
    pub floor_contacts: u64,
    start: (Mode, Pose, AircraftState),
    /// Simulation time at which path playback started (reset restarts the path).
    path_t0: f64,
}

/// Margin kept above `min_agl` when clamping, so rounding never lands a pose just below it.
const FLOOR_MARGIN: f64 = 1e-3;

impl Motion {
    pub fn new(mode: Mode, pose: Pose, path: Option<CameraPath>, min_agl: f64) -> Motion {
        let aircraft = AircraftState::default();
        Motion {
            mode,
            pose,
            aircraft,
            params: AircraftParams::default(),
            free_speed: 200.0,
            min_agl,
            path,
            floor_contacts: 0,
            start: (mode, pose, aircraft),
            path_t0: 0.0,
        }
    }

    /// Back to the starting mode, pose and aircraft state; path playback restarts at `t`.
    pub fn reset(&mut self, t: f64) {
        (self.mode, self.pose, self.aircraft) = self.start;
        self.path_t0 = t;
    }

    /// Next mode (path only when there is one); free flight and aircraft continue from the
    /// current pose.
    pub fn cycle_mode(&mut self) {
        self.mode = match self.mode {
            Mode::Path => Mode::Free,
            Mode::Free => Mode::Aircraft,
            Mode::Aircraft if self.path.is_some() => Mode::Path,
            Mode::Aircraft => Mode::Free,
        };
        if self.mode == Mode::Aircraft {
            self.pose.roll = 0.0;
            self.aircraft.sink = 0.0;
        }
    }

    /// Pose at simulation time `t` after advancing by `dt` seconds with `c`.
    pub fn step(&mut self, t: f64, dt: f64, c: &Controls, terrain: &Terrain) {
        self.step_over(t, dt, c, terrain, |p| p);
    }

    /// [`Motion::step`] over a `terrain` whose frame is not the pose's: `to_terrain` maps a
    /// position into it (a paged window that moved with the eye, `Follower::to_window`; the
    /// pose stays in the scene's own frame).
    pub fn step_over(
        &mut self,
        t: f64,
        dt: f64,
        c: &Controls,
        terrain: &Terrain,
        to_terrain: impl Fn(DVec3) -> DVec3,
    ) {
        match self.mode {
            Mode::Path => {
                if let Some(p) = &self.path {
                    self.pose = p.pose_at(t - self.path_t0);
                }
                return;
            }
            Mode::Free => self.step_free(dt, c),
            Mode::Aircraft => self.step_aircraft(dt, c),
        }
        self.apply_floor(terrain, to_terrain(self.pose.position));
    }

    fn step_free(&mut self, dt: f64, c: &Controls) {
        let p = &mut self.pose;
        p.heading = (p.heading + c.yaw * 60.0 * dt + c.look.0).rem_euclid(360.0);
        p.pitch = (p.pitch + c.pitch * 45.0 * dt + c.look.1).clamp(-89.0, 89.0);
        p.roll = 0.0;
        let (right, _, fwd) = crate::geom::attitude_basis(p.heading, p.pitch, 0.0);
        let speed = self.free_speed * if c.fast { 5.0 } else { 1.0 };
        let v = fwd * c.forward + right * c.right + DVec3::Z * c.up;
        p.position += v * speed * dt;
    }

    fn step_aircraft(&mut self, dt: f64, c: &Controls) {
        let k = self.params;
        let a = &mut self.aircraft;
        a.throttle = match c.throttle {
            Some(t) => t.clamp(0.0, 1.0),
            None => (a.throttle + c.throttle_delta * k.throttle_rate * dt).clamp(0.0, 1.0),
        };
        let p = &mut self.pose;
        p.pitch = (p.pitch + c.pitch.clamp(-1.0, 1.0) * k.pitch_rate * dt).clamp(-80.0, 80.0);
        p.roll = (p.roll + c.roll.clamp(-1.0, 1.0) * k.roll_rate * dt).clamp(-80.0, 80.0);
        // Coordinated turn from the bank, plus rudder.
        let turn = GRAVITY * p.roll.to_radians().tan() / a.speed.max(10.0);
        p.heading = (p.heading + turn.to_degrees() * dt + c.yaw.clamp(-1.0, 1.0) * k.yaw_rate * dt)
            .rem_euclid(360.0);
        let pitch = p.pitch.to_radians();
        let accel = a.throttle * k.max_thrust - k.drag * a.speed * a.speed - GRAVITY * pitch.sin();
        a.speed = (a.speed + accel * dt).max(0.0);
        let lift = (a.speed / k.stall_speed).powi(2).min(1.0);
        a.sink = if lift < 1.0 {
            a.sink - GRAVITY * (1.0 - lift) * dt
        } else {
            a.sink * (-2.0 * dt).exp()
        };
        let (_, _, fwd) = crate::geom::attitude_basis(p.heading, p.pitch, 0.0);
        p.position += (fwd * a.speed + DVec3::Z * a.sink) * dt;
    }

    /// Lifts the pose to `min_agl` above the terrain where it is lower (on the grid only; on
    /// a paged window once the ground under it is in memory at full resolution);
    /// `at`: the pose's position in the terrain's frame (the two frames share their vertical).
    fn apply_floor(&mut self, terrain: &Terrain, at: DVec3) {
        if let Some(agl) = terrain.height_above_now(at) {
            if agl < self.min_agl {
                self.pose.position += terrain.frame.normal * (self.min_agl + FLOOR_MARGIN - agl);
                self.aircraft.sink = 0.0;
                self.floor_contacts += 1;
            }
        }
    }
}

fn csv_fields(path: &Path, text: &str, columns: &[&str]) -> Result<Vec<(usize, Vec<f64>)>> {
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        let n = i + 1;
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if rows.is_empty()
            && fields[0]
                .chars()
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic())
        {
            continue; // header
        }
        if fields.len() < columns.len() {
            return Err(Error::format(
                path,
                format!(
                    "line {n}: {} field(s), need {} ({})",
                    fields.len(),
                    columns.len(),
                    columns.join(",")
                ),
            ));
        }
        let mut v = Vec::with_capacity(columns.len());
        for (f, name) in fields.iter().zip(columns) {
            match f.parse::<f64>() {
                Ok(x) if x.is_finite() => v.push(x),
                _ => {
                    return Err(Error::format(
                        path,
                        format!("line {n}: `{name}` = `{f}` is not a finite number"),
                    ))
                }
            }
        }
        if let Some((pn, prev)) = rows.last() {
            let prev: &Vec<f64> = prev;
            if v[0] <= prev[0] {
                return Err(Error::format(
                    path,
                    format!(
                        "line {n}: time {} does not increase (line {pn} has {})",
                        v[0], prev[0]
                    ),
                ));
            }
        }
        rows.push((n, v));
    }
    if rows.is_empty() {
        return Err(Error::format(
            path,
            format!("no data rows ({} expected)", columns.join(",")),
        ));
    }
    Ok(rows)
}

const PATH_COLUMNS: [&str; 7] = ["time", "x", "y", "alt", "heading", "pitch", "roll"];

/// Reads a path CSV into a camera path (Catmull-Rom through the samples, as scene paths) with
/// field of view `fov`. Times are relative to the first row.
pub fn read_path_csv(path: &Path, fov: f64) -> Result<CameraPath> {
    // Parsed rows take several times their text: an eighth of the memory budget at most.
    let text = crate::fileio::read_to_string(path, crate::fileio::memory_budget() / 8)?;
    let rows = csv_fields(path, &text, &PATH_COLUMNS)?;
    let t0 = rows[0].1[0];
    let keyframes = rows
        .iter()
        .map(|(_, v)| Keyframe {
            time: v[0] - t0,
            position: [v[1], v[2], v[3]],
            heading: v[4],
            pitch: v[5],
            roll: v[6],
            fov,
        })
        .collect();
    Ok(CameraPath {
        fps: 30.0,
        keyframes,
    })
}

/// Writes the flown path as a path CSV, one row per frame.
pub struct PathRecorder {
    out: std::io::BufWriter<std::fs::File>,
    path: std::path::PathBuf,
}

impl PathRecorder {
    pub fn create(path: &Path) -> Result<PathRecorder> {
        let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
        let mut r = PathRecorder {
            out: std::io::BufWriter::new(file),
            path: path.to_path_buf(),
        };
        r.line(format_args!("{}", PATH_COLUMNS.join(",")))?;
        Ok(r)
    }

    fn line(&mut self, args: std::fmt::Arguments) -> Result<()> {
        // Flushed per line: a run that stops keeps every pose recorded so far.
        writeln!(self.out, "{args}")
            .and_then(|()| self.out.flush())
            .map_err(|e| Error::io(&self.path, e))
    }

    /// Appends the pose at time `t` (full precision: playback reproduces it exactly).
    pub fn record(&mut self, t: f64, p: &Pose) -> Result<()> {
        let q = p.position;
        self.line(format_args!(
            "{t},{},{},{},{},{},{}",
            q.x, q.y, q.z, p.heading, p.pitch, p.roll
        ))
    }

    pub fn finish(mut self) -> Result<()> {
        self.out.flush().map_err(|e| Error::io(&self.path, e))
    }
}

/// Aircraft controls over time, read from a control script CSV.
#[derive(Clone, Debug)]
pub struct ControlScript {
    /// (time, throttle, pitch, roll, yaw), times increasing.
    rows: Vec<[f64; 5]>,
}

impl ControlScript {
    pub fn load(path: &Path) -> Result<ControlScript> {
        // Parsed rows take several times their text: an eighth of the memory budget at most.
        let text = crate::fileio::read_to_string(path, crate::fileio::memory_budget() / 8)?;
        let cols = ["time", "throttle", "pitch", "roll", "yaw"];
        let rows = csv_fields(path, &text, &cols)?;
        let mut out = Vec::with_capacity(rows.len());
        for (n, v) in rows {
            if !(0.0..=1.0).contains(&v[1]) || v[2..5].iter().any(|s| !(-1.0..=1.0).contains(s)) {
                return Err(Error::format(
                    path,
                    format!("line {n}: throttle must be in 0..=1 and pitch, roll, yaw in -1..=1"),
                ));
            }
            out.push([v[0], v[1], v[2], v[3], v[4]]);
        }
        Ok(ControlScript { rows: out })
    }

    /// The controls held at time `t` (before the first row: none).
    pub fn at(&self, t: f64) -> Option<Controls> {
        let i = self.rows.partition_point(|r| r[0] <= t);
        let r = self.rows.get(i.checked_sub(1)?)?;
        Some(Controls {
            throttle: Some(r[1]),
            pitch: r[2],
            roll: r[3],
            yaw: r[4],
            ..Controls::default()
        })
    }
}

/// Eye points for a distortion table, one `x,y,z` line (display frame, metres) per frame; the
/// last line holds after the file ends.
#[derive(Clone, Debug)]
pub struct EyeFeed {
    eyes: Vec<DVec3>,
}

impl EyeFeed {
    pub fn load(path: &Path) -> Result<EyeFeed> {
        // Parsed rows take several times their text: an eighth of the memory budget at most.
        let text = crate::fileio::read_to_string(path, crate::fileio::memory_budget() / 8)?;
        Self::parse(path, &text)
    }

    pub fn parse(path: &Path, text: &str) -> Result<EyeFeed> {
        let mut eyes = Vec::new();
        for (i, line) in text.lines().enumerate() {
            if let Some(e) = parse_eye_line(line)
                .map_err(|m| Error::format(path, format!("line {}: {m}", i + 1)))?
            {
                eyes.push(e);
            }
        }
        if eyes.is_empty() {
            return Err(Error::format(path, "no eye points (x,y,z per line)"));
        }
        Ok(EyeFeed { eyes })
    }

    /// The eye for frame `n`.
    pub fn at(&self, n: u64) -> DVec3 {
        self.eyes[(n as usize).min(self.eyes.len() - 1)]
    }
}

/// One eye-feed line: `Ok(None)` for blank and `#` lines.
pub fn parse_eye_line(line: &str) -> std::result::Result<Option<DVec3>, String> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') || line.starts_with(|c: char| c.is_alphabetic()) {
        return Ok(None);
    }
    let v: Vec<f64> = line
        .split(',')
        .map(|f| f.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| format!("`{line}`: {e}"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Some(DVec3::new(x, y, z))),
        _ => Err(format!("`{line}` is not three finite numbers x,y,z")),
    }
}
