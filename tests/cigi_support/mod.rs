//! A CIGI host for the IG tests (`tests/cigi_ig.rs`, `cigi_serve.rs`, `cigi_entities.rs`,
//! `cigi_los.rs`): `relief serve` processes started with
//! `--cigi 0`, the host's socket, datagrams written with relief's encoder, scenes over
//! N47E009 and WGS84 radii computed here (independently of `relief::geodesy`).
#![allow(dead_code)]

#[allow(unused_imports)]
pub use crate::common::mean_diff;
use crate::common::{relief_command, terrains};
use relief::cigi::*;
use std::io::{BufRead, BufReader, Read};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::Duration;

/// A `relief serve` process and the host's socket.
pub struct Ig {
    pub child: Child,
    pub addr: SocketAddr,
    pub host: UdpSocket,
}

impl Ig {
    /// `relief serve SCENE --cigi 0 ARGS` (give `--size` or `--display` in `args`); reads the
    /// port it prints.
    pub fn start(scene: &Path, args: &[&str], host: UdpSocket) -> Ig {
        Ig::start_command("serve", scene, args, host, &[])
    }

    /// `relief COMMAND SCENE --cigi 0 ARGS` with `envs` (`serve`, or `view` under Xvfb); reads
    /// the port it prints.
    pub fn start_command(
        command: &str,
        scene: &Path,
        args: &[&str],
        host: UdpSocket,
        envs: &[(&str, &str)],
    ) -> Ig {
        let scene = scene.to_str().unwrap();
        let mut all = vec![command, scene, "--cigi", "0"];
        all.extend_from_slice(args);
        let mut child = relief_command(&all, envs)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("relief starts");
        let mut line = String::new();
        let mut out = BufReader::new(child.stdout.take().unwrap());
        out.read_line(&mut line).unwrap();
        let addr = line
            .trim()
            .strip_prefix("cigi: listening on ")
            .unwrap_or_else(|| {
                let mut err = String::new();
                let _ = child.stderr.take().unwrap().read_to_string(&mut err);
                panic!("relief {command} printed {line:?}; stderr: {err}")
            })
            .parse()
            .unwrap();
        child.stdout = Some(out.into_inner());
        host.set_read_timeout(Some(Duration::from_secs(60)))
            .unwrap();
        Ig { child, addr, host }
    }

    pub fn send(&self, bytes: &[u8]) {
        self.host.send_to(bytes, self.addr).unwrap();
    }

    /// The IG's next datagram, decoded.
    pub fn receive(&self) -> IgMessage {
        self.receive_raw().0
    }

    /// The IG's next datagram, decoded, and its bytes.
    pub fn receive_raw(&self) -> (IgMessage, Vec<u8>) {
        let mut buf = vec![0u8; 65536];
        let (n, from) = self.host.recv_from(&mut buf).expect("the IG answers");
        assert_eq!(from, self.addr);
        buf.truncate(n);
        (read_ig_message(&buf).expect("a valid IG message"), buf)
    }

    /// Sends `bytes` and returns the IG's answer for that host frame.
    pub fn exchange(&self, bytes: &[u8], host_frame: u32) -> IgMessage {
        self.exchange_raw(bytes, host_frame).0
    }

    /// As [`Ig::exchange`], with the answer's bytes.
    pub fn exchange_raw(&self, bytes: &[u8], host_frame: u32) -> (IgMessage, Vec<u8>) {
        self.send(bytes);
        loop {
            let (m, raw) = self.receive_raw();
            if sof(&m).last_host_frame == host_frame {
                return (m, raw);
            }
        }
    }

    /// Whether the process has exited, without reaping it (`/proc` state Z or gone).
    pub fn exited(&self) -> bool {
        match std::fs::read_to_string(format!("/proc/{}/stat", self.child.id())) {
            Ok(stat) => stat
                .rsplit(')')
                .next()
                .is_some_and(|s| s.trim_start().starts_with('Z')),
            Err(_) => true,
        }
    }

    /// The process's resident set (VmRSS of `/proc/PID/status`), bytes; `None` once it is gone.
    pub fn rss(&self) -> Option<u64> {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).ok()?;
        let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb * 1024)
    }

    /// Waits for the process; its stdout, asserting success.
    pub fn finish(mut self) -> String {
        let status = self.child.wait().unwrap();
        let mut out = String::new();
        let mut err = String::new();
        self.child
            .stdout
            .take()
            .unwrap()
            .read_to_string(&mut out)
            .unwrap();
        self.child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        assert!(status.success(), "relief serve failed: {err}");
        out
    }
}

/// The `cigi-counters: {…}` line of a `relief serve` run's stdout.
pub fn counters(out: &str) -> serde_json::Value {
    let line = out
        .lines()
        .find_map(|l| l.strip_prefix("cigi-counters: "))
        .unwrap_or_else(|| panic!("no counters line in {out:?}"));
    serde_json::from_str(line).unwrap()
}

/// The lines of a `--pose-log` file.
pub fn pose_log(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

pub fn host_socket() -> UdpSocket {
    UdpSocket::bind("127.0.0.1:0").unwrap()
}

pub fn sof(m: &IgMessage) -> StartOfFrame {
    match m.packets[0] {
        IgPacket::StartOfFrame(s) => s,
        p => panic!("first packet {p:?}"),
    }
}

/// IG Control in operate mode; `timestamp` (seconds of host time) valid when given, and the
/// global interpolation/extrapolation bit.
pub fn ig_control(frame: u32, timestamp: Option<f64>, extrapolation: bool) -> IgControl {
    IgControl {
        database: 0,
        ig_mode: 1,
        timestamp_valid: timestamp.is_some(),
        extrapolation,
        host_frame: frame,
        timestamp: timestamp.map_or(0, |t| (t / 1e-5).round() as u64 as u32),
        last_ig_frame: 0,
    }
}

pub fn ownship(lla: [f64; 3], yaw: f32, pitch: f32, roll: f32) -> EntityControl {
    EntityControl::placed(0, 0, lla, [yaw, pitch, roll])
}

pub fn message(control: IgControl, packets: &[HostPacket]) -> Vec<u8> {
    let mut m = MessageBuilder::host(&control, ByteOrder::Big);
    for p in packets {
        m.push_any(p);
    }
    m.finish()
}

/// A scene over N47E009 (`.hgt`) with the camera at geodetic `lla`, `extra` TOML appended,
/// written to `dir/NAME.toml`.
pub fn scene(dir: &Path, name: &str, lla: [f64; 3], hpr: [f64; 3], extra: &str) -> PathBuf {
    let hgt = terrains().join("N47E009.hgt");
    let [heading, pitch, roll] = hpr;
    let text = format!(
        "[terrain]\nsource = {hgt:?}\n[sun]\nazimuth = 245.0\nelevation = 24.0\n\
         [fog]\nvisibility = 90000.0\nscale_height = 3000.0\n\
         [camera]\ngeodetic = [{:?}, {:?}, {:?}]\nheading = {heading:?}\npitch = {pitch:?}\nroll = {roll:?}\nfov = 60.0\n\
         [output]\nwidth = 160\nheight = 120\n{extra}",
        lla[0], lla[1], lla[2]
    );
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

/// WGS84 radii of curvature (m) at latitude `lat` (degrees): meridional and prime vertical.
pub fn radii(lat: f64) -> (f64, f64) {
    let (a, f) = (6_378_137.0, 1.0 / 298.257_223_563);
    let e2 = f * (2.0 - f);
    let s = lat.to_radians().sin();
    let w = 1.0 - e2 * s * s;
    (a * (1.0 - e2) / w.powf(1.5), a / w.sqrt())
}

/// `p − q` of two geodetic points in metres north, east, up (local flat earth at `q`).
pub fn metres(p: [f64; 3], q: [f64; 3]) -> [f64; 3] {
    let (m, n) = radii(q[0]);
    [
        (p[0] - q[0]).to_radians() * (m + q[2]),
        (p[1] - q[1]).to_radians() * (n + q[2]) * q[0].to_radians().cos(),
        p[2] - q[2],
    ]
}

/// Percentile `q` (0..1) of `v` (sorted copy, nearest rank).
pub fn percentile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() as f64 * q).ceil() as usize).clamp(1, s.len()) - 1]
}

/// The DEM of N47E009 read here: 1201² big-endian i16, row 0 the northern edge (48°N),
/// column 0 the western (9°E), 3″ steps.
pub struct Dem(Vec<i16>);

impl Dem {
    pub fn load() -> Dem {
        let b = std::fs::read(terrains().join("N47E009.hgt")).unwrap();
        assert_eq!(b.len(), 1201 * 1201 * 2);
        Dem(b
            .chunks(2)
            .map(|c| i16::from_be_bytes([c[0], c[1]]))
            .collect())
    }

    fn at(&self, row: usize, col: usize) -> f64 {
        let v = self.0[row * 1201 + col];
        assert_ne!(v, -32768, "void sample at row {row}, column {col}");
        f64::from(v)
    }

    /// The bilinear surface (metres above MSL) at `lat`, `lon`.
    pub fn height(&self, lat: f64, lon: f64) -> f64 {
        let (r, c) = ((48.0 - lat) * 1200.0, (lon - 9.0) * 1200.0);
        let (r0, c0) = (r.floor() as usize, c.floor() as usize);
        let (v, u) = (r - r0 as f64, c - c0 as f64);
        self.at(r0, c0) * (1.0 - u) * (1.0 - v)
            + self.at(r0, c0 + 1) * u * (1.0 - v)
            + self.at(r0 + 1, c0) * (1.0 - u) * v
            + self.at(r0 + 1, c0 + 1) * u * v
    }

    /// The first point of a constant-longitude segment below the surface by a 40,000-step
    /// march: `(fraction along the segment, step)`, or `None` when it stays above.
    pub fn march(
        &self,
        lon: f64,
        (lat0, alt0): (f64, f64),
        (lat1, alt1): (f64, f64),
    ) -> Option<(f64, f64)> {
        let n = 40_000;
        (0..=n).map(|k| k as f64 / n as f64).find_map(|s| {
            let (lat, alt) = (lat0 + (lat1 - lat0) * s, alt0 + (alt1 - alt0) * s);
            (alt < self.height(lat, lon)).then_some((s, 1.0 / n as f64))
        })
    }
}

/// Serialises the tests of one binary that run IG processes: each renders on the same two
/// software-rasteriser cores, and the smoothing and flood tests time frames (a host-to-frame
/// lag, frame-time percentiles), which IGs of other tests running beside them would distort.
pub fn one_ig_test_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

/// `relief render SCENE --out OUT ARGS…`, which must succeed, and the frame it wrote.
pub fn render_frame(scene: &Path, out: &Path, args: &[&str]) -> image::RgbaImage {
    let mut all = vec![
        "render",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    let o = crate::common::relief_cli(&all, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    image_at(&out.join("frame_0000.png"))
}

/// An RGBA8 image file.
pub fn image_at(path: &Path) -> image::RgbaImage {
    image::open(path).unwrap().to_rgba8()
}

/// Celestial Sphere Control with the sun from the ephemeris for `date` (MMDDYYYY) at
/// `hour`:`minute` UTC, the moon and stars off.
pub fn sun_at(date: u32, hour: u8, minute: u8) -> CelestialSphereControl {
    CelestialSphereControl {
        hour,
        minute,
        ephemeris: true,
        sun: true,
        date_time_valid: true,
        date,
        ..CelestialSphereControl::default()
    }
}

/// Body → north-east-down rotation of yaw, pitch, roll (degrees; z-y-x, the aerospace
/// convention CIGI uses: body x forward, y right, z down).
pub fn dcm([yaw, pitch, roll]: [f64; 3]) -> [[f64; 3]; 3] {
    let (sy, cy) = yaw.to_radians().sin_cos();
    let (sp, cp) = pitch.to_radians().sin_cos();
    let (sr, cr) = roll.to_radians().sin_cos();
    [
        [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
        [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
        [-sp, sr * cp, cr * cp],
    ]
}

pub fn mat_mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// Yaw, pitch, roll (degrees) of a body → NED rotation.
pub fn euler(m: [[f64; 3]; 3]) -> [f64; 3] {
    [
        m[1][0].atan2(m[0][0]).to_degrees(),
        (-m[2][0]).asin().to_degrees(),
        m[2][1].atan2(m[2][2]).to_degrees(),
    ]
}

/// WGS84 geodetic → ECEF (m).
pub fn ecef(lla: [f64; 3]) -> [f64; 3] {
    let (a, f) = (6_378_137.0, 1.0 / 298.257_223_563);
    let e2 = f * (2.0 - f);
    let (la, lo) = (lla[0].to_radians(), lla[1].to_radians());
    let n = a / (1.0 - e2 * la.sin().powi(2)).sqrt();
    [
        (n + lla[2]) * la.cos() * lo.cos(),
        (n + lla[2]) * la.cos() * lo.sin(),
        (n * (1.0 - e2) + lla[2]) * la.sin(),
    ]
}
