//! The IG side of CIGI for the frame loops (`relief serve`, `relief view --cigi`): the UDP
//! socket, the [`Session`] fed from it, the ownship as the camera, and the IG→host datagram
//! of each frame (Start of Frame and the answers of [`answer`]). The loops call, per frame:
//! [`CigiIg::poll`] (or [`CigiIg::wait_host_frame`] when synchronous), [`CigiIg::camera_pose`],
//! render, then [`CigiIg::end_frame`] ([docs/cigi.md](../../../docs/cigi.md)).

pub mod answer;
pub mod weather;

use crate::cigi::{MessageBuilder, Session};
use crate::scene::solar::{self, UtcTime};
use crate::scene::Pose as CameraPose;
use crate::scene::SceneDesc;
use crate::terrain::Terrain;
use crate::{Error, Result};
use std::net::{IpAddr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

/// The CIGI options of `relief serve` and `relief view`.
#[derive(Clone, Debug, clap::Args)]
pub struct CigiArgs {
    /// Be a CIGI 3.3 IG on this UDP port (0: a free port, printed as `cigi: listening on ADDR`).
    #[arg(long, value_name = "PORT")]
    pub cigi: Option<u16>,
    /// Address to bind the CIGI port on (0.0.0.0 for every interface).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1")]
    pub cigi_bind: IpAddr,
    /// Accept CIGI datagrams only from this host (others are counted and dropped) and send
    /// the IG's datagrams there; default: answer the sender of the last accepted datagram.
    #[arg(long, value_name = "ADDR:PORT")]
    pub cigi_host: Option<SocketAddr>,
    /// Synchronous mode: one IG frame per host frame (each host datagram with a new host
    /// frame number starts one frame); default asynchronous (free-running, at most 60 Hz).
    #[arg(long)]
    pub cigi_sync: bool,
    /// Synchronous mode: give up when no host frame came for this many seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 5.0)]
    pub cigi_timeout: f64,
    /// Lines of sight: answer each request with its nearest intersection only (`first`), or
    /// with one response for every surface the line meets, nearest first (`every`: each
    /// entity, and the terrain, where the line meets it first).
    #[arg(long, value_name = "WHICH", value_enum, default_value_t = answer::LosResponses::First)]
    pub cigi_los: answer::LosResponses,
}

/// What [`CigiIg::camera_pose`] made of the session.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ownship {
    /// The ownship's geodetic `[lat, lon, alt]` at the frame's host time.
    pub geodetic: [f64; 3],
    /// The host time (s) the pose is for.
    pub host_time: f64,
}

/// The receive buffer asked for: a frame's worth of datagrams at flood rates (the kernel caps
/// it at `net.core.rmem_max`).
pub const RECEIVE_BUFFER: usize = 4 << 20;

/// Asks for [`RECEIVE_BUFFER`] bytes of socket receive buffer, so datagrams arriving between
/// two frames' reads are not dropped by the default one (~200 KiB, a few hundred datagrams).
fn grow_receive_buffer(socket: &UdpSocket) {
    #[cfg(unix)]
    {
        use std::os::fd::AsRawFd;
        let size = RECEIVE_BUFFER as libc::c_int;
        // SAFETY: a valid socket descriptor, a pointer to a c_int and its size.
        let r = unsafe {
            libc::setsockopt(
                socket.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_RCVBUF,
                (&size as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if r != 0 {
            log::debug!("CIGI: SO_RCVBUF: {}", std::io::Error::last_os_error());
        }
    }
    #[cfg(not(unix))]
    let _ = socket;
}

/// Moves `pose` (the ownship's) by a View Control offset: `xyz` metres along its forward,
/// right and down axes, then turns it by `ypr` (yaw, pitch, roll in degrees) in its own frame.
pub fn offset_view(pose: &mut CameraPose, xyz: [f64; 3], ypr: [f64; 3]) {
    use crate::geom::{attitude_angles, attitude_basis, attitude_matrix};
    let (right, down, fwd) = attitude_basis(pose.heading, pose.pitch, pose.roll);
    pose.position += fwd * xyz[0] + right * xyz[1] + down * xyz[2];
    let m = attitude_matrix(pose.heading, pose.pitch, pose.roll)
        * attitude_matrix(ypr[0], ypr[1], ypr[2]);
    (pose.heading, pose.pitch, pose.roll) = attitude_angles(m);
}

/// A view's offsets from the entity it rides: `[x, y, z]` metres along its body axes
/// (forward, right, down) and `[yaw, pitch, roll]` degrees relative to its attitude.
pub type ViewOffsets = ([f64; 3], [f64; 3]);

/// A CIGI IG: socket, session, frame counter.
pub struct CigiIg {
    socket: UdpSocket,
    pub session: Session,
    /// The host fixed by `--cigi-host`.
    fixed_host: Option<SocketAddr>,
    /// Where the IG's datagrams go: the fixed host, else the last accepted sender.
    reply_to: Option<SocketAddr>,
    start: Instant,
    /// IG frames ended so far (the next Start of Frame's number).
    pub ig_frame: u32,
    /// The host frame the last frame was started for (synchronous mode).
    last_started: Option<u32>,
    pub sync: bool,
    /// How many intersections a line of sight is answered with (`--cigi-los`).
    pub los: answer::LosResponses,
    timeout: Duration,
    /// Datagrams sent and send failures.
    pub sent: u64,
    pub send_errors: u64,
    /// Queries answered, by kind, since the start.
    pub answers: answer::AnswerCounts,
    /// The most entities besides the ownship not drawn in one frame (no template,
    /// off the terrain, beyond the template's `max`).
    pub other_entities: usize,
    /// This frame's entity instances: drawn, not drawn, hidden (inactive).
    pub entities_frame: (usize, usize, usize),
    /// The entities drawn this frame, for lines of sight (`cpu::bodies`).
    bodies: crate::cpu::bodies::Bodies,
    /// The voxel templates' brick tables for lines of sight, made on the first frame.
    bricks: std::sync::Arc<crate::cpu::bodies::BrickCache>,
    /// The ownship pose was off the terrain (the camera kept its last pose), frames.
    pub off_terrain: u64,
    /// Local time (s since the IG started) the current frame's camera is for.
    pub frame_time: f64,
    /// On a database scene, the database the queries are answered from at full resolution
    /// ([`CigiIg::open_database`]).
    pub full: Option<crate::cpu::database::FullResolution>,
    /// With `full`: the queries kept for the next frame and the prefetcher reading their tiles.
    pub deferral: Option<answer::Deferral>,
    /// The frame's sun `(azimuth, elevation)` from Celestial Sphere Control, and fog
    /// visibility (m) from Atmosphere/Weather Control, when the host gave them.
    pub sun: Option<(f64, f64)>,
    /// The frame's moon from Celestial Sphere Control's date, time and moon-enable bit.
    pub moon: Option<crate::scene::Moon>,
    pub visibility: Option<f64>,
    /// The frame's cloud layers from Weather Control ([`weather::host_clouds`]).
    pub clouds: Option<Vec<crate::scene::clouds::CloudLayer>>,
    /// Host cloud layers not drawn (bad values, overlaps), frames times layers.
    pub clouds_dropped: u64,
    /// Celestial Sphere Control with a date or time that does not exist, frames.
    pub bad_dates: u64,
    buf: Vec<u8>,
}

impl CigiIg {
    /// Binds the socket of `args` (`args.cigi` must be set) and prints the address it listens
    /// on as one line on stdout.
    pub fn bind(args: &CigiArgs) -> Result<CigiIg> {
        let ig = CigiIg::open(args)?;
        if let Some(local) = ig.local_addr() {
            println!("cigi: listening on {local}");
            use std::io::Write as _;
            let _ = std::io::stdout().flush();
        }
        Ok(ig)
    }

    /// [`CigiIg::bind`] without the line on stdout (an IG inside another command).
    pub fn open(args: &CigiArgs) -> Result<CigiIg> {
        let port = args
            .cigi
            .ok_or_else(|| Error::invalid("--cigi", "give the UDP port to listen on"))?;
        if !(args.cigi_timeout.is_finite()
            && args.cigi_timeout > 0.0
            && args.cigi_timeout <= 3600.0)
        {
            return Err(Error::invalid(
                "--cigi-timeout",
                format!("must be in (0, 3600] seconds, got {}", args.cigi_timeout),
            ));
        }
        let at = SocketAddr::new(args.cigi_bind, port);
        let io = |e: std::io::Error| Error::invalid("--cigi", format!("UDP {at}: {e}"));
        let socket = UdpSocket::bind(at).map_err(io)?;
        socket.set_nonblocking(true).map_err(io)?;
        grow_receive_buffer(&socket);
        let session = match args.cigi_host {
            Some(h) => Session::with_host(h),
            None => Session::new(),
        };
        Ok(CigiIg {
            socket,
            session,
            fixed_host: args.cigi_host,
            reply_to: args.cigi_host,
            start: Instant::now(),
            ig_frame: 0,
            last_started: None,
            sync: args.cigi_sync,
            los: args.cigi_los,
            timeout: Duration::from_secs_f64(args.cigi_timeout),
            sent: 0,
            send_errors: 0,
            answers: Default::default(),
            other_entities: 0,
            entities_frame: (0, 0, 0),
            bodies: Default::default(),
            bricks: Default::default(),
            off_terrain: 0,
            frame_time: 0.0,
            full: None,
            deferral: None,
            sun: None,
            moon: None,
            visibility: None,
            clouds: None,
            clouds_dropped: 0,
            bad_dates: 0,
            buf: vec![0; 65536],
        })
    }

    /// Answers queries from the database of `scene` at full resolution when its terrain is a
    /// database (else from the scene's terrain).
    pub fn open_database(&mut self, scene: &crate::scene::Scene) -> Result<()> {
        let full =
            crate::cpu::database::FullResolution::open(&scene.desc.terrain, &scene.base_dir)?;
        self.deferral = full.as_ref().map(answer::Deferral::new).transpose()?;
        self.full = full;
        Ok(())
    }

    /// The socket's address.
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.socket.local_addr().ok()
    }

    /// Seconds since the IG started (the session's local clock).
    pub fn now(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Takes one waiting datagram into the session; `false` when none is waiting.
    fn receive_one(&mut self) -> bool {
        match self.socket.recv_from(&mut self.buf) {
            Ok((n, from)) => {
                let now = self.now();
                let accepted = match self.fixed_host {
                    Some(_) => self.session.receive_from(from, &self.buf[..n], now),
                    None => Some(self.session.receive(&self.buf[..n], now)),
                };
                if matches!(accepted, Some(Ok(_))) && self.fixed_host.is_none() {
                    self.reply_to = Some(from);
                }
                true
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => false,
            Err(e) => {
                // ICMP port unreachable from an earlier send and the like: not fatal.
                log::debug!("CIGI receive: {e}");
                true
            }
        }
    }

    /// Takes every waiting datagram into the session (asynchronous mode); returns how many.
    pub fn poll(&mut self) -> usize {
        let mut n = 0;
        // Bounded so a flood cannot keep a frame from ever starting.
        while n < 100_000 && self.receive_one() {
            n += 1;
        }
        n
    }

    /// Synchronous mode: waits until a datagram with a host frame other than the last one
    /// started has been accepted (datagrams already waiting count). `Err` after the timeout.
    pub fn wait_host_frame(&mut self) -> Result<()> {
        let deadline = Instant::now() + self.timeout;
        loop {
            while self.receive_one() {
                if self.session.host_frame.is_some() && self.session.host_frame != self.last_started
                {
                    self.last_started = self.session.host_frame;
                    return Ok(());
                }
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(Error::invalid(
                    "--cigi-sync",
                    format!(
                        "no new host frame for {:.1} s (last host frame {:?}): the host is gone",
                        self.timeout.as_secs_f64(),
                        self.last_started
                    ),
                ));
            }
            self.wait_readable(left.min(Duration::from_millis(50)));
        }
    }

    /// Blocks until a datagram is waiting or `d` passed.
    fn wait_readable(&self, d: Duration) {
        let mut probe = [0u8; 1];
        if self.socket.set_nonblocking(false).is_ok() {
            let _ = self
                .socket
                .set_read_timeout(Some(d.max(Duration::from_millis(1))));
            let _ = self.socket.peek_from(&mut probe);
            let _ = self.socket.set_nonblocking(true);
        } else {
            std::thread::sleep(d);
        }
    }

    /// Where the view's entity ([`CigiIg::view_control`]: the ownship unless the lowest view
    /// rides another) is now, as the host placed it (latitude, longitude, altitude; an
    /// attached entity's top-level ancestor's), on the terrain or not: a paged window follows
    /// it there. `None` before the host has placed it.
    pub fn eye_geodetic(&self) -> Option<[f64; 3]> {
        let t = self.session.host_time_at(self.now());
        let mut id = self.view_control().0;
        for _ in 0..32 {
            match self.session.entity(id)?.parent {
                Some(parent) => id = parent,
                None => break,
            }
        }
        self.session.pose_at(id, t).map(|p| [p.lat, p.lon, p.alt])
    }

    /// The camera for this frame: `base` (the scene's camera) with the position and attitude
    /// at the frame's host time (interpolated by [`Session::pose_at`]) of the entity the view
    /// rides ([`CigiIg::view_control`]: the ownship unless the lowest view's View Control
    /// names another), moved by the view's offsets, and the fov of a View Definition with both
    /// left and right given. `None` for the position part while the host has not placed that
    /// entity (or placed it off the terrain: `base` kept).
    pub fn camera_pose(
        &mut self,
        terrain: &Terrain,
        base: CameraPose,
    ) -> (CameraPose, Option<Ownship>) {
        let mut pose = base;
        if let Some(fov) = self.view_fov() {
            pose.fov = fov;
        }
        self.frame_time = self.now();
        let t = self.session.host_time_at(self.frame_time);
        let (id, offsets) = self.view_control();
        let Some(e) = self.session.entity(id) else {
            return (pose, None);
        };
        let Some(p) = self.session.pose_at(id, t) else {
            return (pose, None);
        };
        let mut lla = [p.lat, p.lon, p.alt];
        // A top-level ownship that is not clamped: its pose as sent. Otherwise where the IG
        // puts the entity (`world::entity_placement`): clamped to the ground or the sea (a
        // ground vehicle's or a ship's eye), carried by its parents when attached, or the
        // entity another than the ownship that the view rides.
        let placed = if id == 0 && e.parent.is_none() && e.ground_clamp == 0 {
            terrain
                .geodetic_to_world("CIGI ownship", lla)
                .ok()
                .map(|w| (w, (p.yaw, p.pitch, p.roll)))
        } else {
            crate::world::entity_placement(&self.session, terrain, id, t).map(|pl| {
                lla = pl.geodetic;
                (pl.position, crate::geom::attitude_angles(pl.attitude))
            })
        };
        match placed {
            Some((w, (heading, pitch, roll))) => {
                pose.position = w;
                (pose.heading, pose.pitch, pose.roll) = (heading, pitch, roll);
                if let Some((xyz, ypr)) = offsets {
                    offset_view(&mut pose, xyz, ypr);
                }
                (
                    pose,
                    Some(Ownship {
                        geodetic: lla,
                        host_time: t,
                    }),
                )
            }
            None => {
                self.off_terrain += 1;
                if self.off_terrain == 1 {
                    log::warn!(
                        "CIGI entity {id}, which the view rides, at {lla:?} is off the terrain: camera kept"
                    );
                }
                (pose, None)
            }
        }
    }

    /// The host's environment into the frame's scene: the sun of Celestial Sphere Control
    /// (date and time of day, read as UTC; its date/time-valid bit set) seen from `at` (the
    /// ownship's geodetic position), the session's visibility as the fog's (Koschmieder
    /// extinction 3.912 / visibility in the frame uniforms) and its cloud layers (Weather
    /// Control's layers 1–3) as the scene's `[[clouds]]`. What the host has not sent stays
    /// the scene's.
    pub fn environment(&mut self, desc: &mut SceneDesc, at: Option<[f64; 3]>) {
        self.sun = None;
        self.moon = None;
        if let (Some(c), Some([lat, lon, _])) = (self.session.celestial, at) {
            let t = UtcTime::new(
                (c.date % 10_000) as i32,
                c.date / 1_000_000,
                c.date / 10_000 % 100,
                f64::from(c.hour) * 3600.0 + f64::from(c.minute) * 60.0,
            );
            match t.filter(|_| c.date_time_valid) {
                Some(t) => {
                    let (azimuth, elevation) = solar::sun_position(t, lat, lon);
                    desc.sun.azimuth = azimuth;
                    desc.sun.elevation = elevation;
                    self.sun = Some((azimuth, elevation));
                    // The moon where the host enables it (else none).
                    desc.moon = c.moon.then(|| {
                        let m = crate::scene::lunar::moon_position(t, lat, lon);
                        crate::scene::Moon {
                            azimuth: m.azimuth,
                            elevation: m.elevation,
                            illuminated: m.illuminated,
                        }
                    });
                    self.moon = desc.moon;
                }
                None if c.date_time_valid => {
                    self.bad_dates += 1;
                    if self.bad_dates == 1 {
                        log::warn!(
                            "CIGI Celestial Sphere Control: no such date/time (date {}, {}:{}); the scene's sun kept",
                            c.date,
                            c.hour,
                            c.minute
                        );
                    }
                }
                None => {}
            }
        }
        self.visibility = self
            .session
            .visibility()
            .map(f64::from)
            .filter(|v| v.is_finite() && *v > 0.0);
        if let Some(v) = self.visibility {
            desc.fog.visibility = v;
        }
        self.clouds = weather::host_clouds(&self.session, &mut self.clouds_dropped);
        if let Some(c) = &self.clouds {
            desc.clouds = c.clone();
        }
    }

    /// The entities drawn from `templates` this frame, at the frame's host time (call after
    /// [`CigiIg::camera_pose`]); the counts go to the frame's JSON and the summary.
    pub fn instances(
        &mut self,
        terrain: &Terrain,
        templates: &crate::world::Templates,
    ) -> crate::world::Instances {
        let t = self.session.host_time_at(self.frame_time);
        let i = crate::world::entity_instances(&self.session, terrain, templates, t);
        self.entities_frame = (i.drawn.len() + i.voxels.len(), i.not_drawn, i.hidden);
        if self.bricks.is_empty() {
            // Every voxel template's tables, once, before any line needs them mid-run.
            for m in templates.voxels.iter().flat_map(|v| &v.model.frames) {
                self.bricks.get(m);
            }
        }
        self.bodies = crate::cpu::bodies::Bodies::of(&i, t, &self.bricks);
        if i.not_drawn > self.other_entities {
            if self.other_entities == 0 {
                log::warn!(
                    "CIGI: {} entities not drawn (no [[cigi.entity]] template for their type, off the terrain or beyond the template's max)",
                    i.not_drawn
                );
            }
            self.other_entities = i.not_drawn;
        }
        i
    }

    /// The entity the view rides and the eye's offset from it: the lowest view ID's View
    /// Control names the entity (the ownship, 0, when no view has one), with `[x, y, z]`
    /// metres in its body frame (forward, right, down) and `[yaw, pitch, roll]` degrees
    /// relative to it; offsets never enabled are 0.
    pub fn view_control(&self) -> (u16, Option<ViewOffsets>) {
        let found = self.session.views.values().find_map(|v| {
            let c = v.control?;
            let on = |e: bool, x: f32| if e { f64::from(x) } else { 0.0 };
            Some((
                c.entity_id,
                [
                    on(c.x_enable, c.x),
                    on(c.y_enable, c.y),
                    on(c.z_enable, c.z),
                ],
                [
                    on(c.yaw_enable, c.yaw),
                    on(c.pitch_enable, c.pitch),
                    on(c.roll_enable, c.roll),
                ],
            ))
        });
        match found {
            Some((id, xyz, ypr)) => (id, Some((xyz, ypr))),
            None => (0, None),
        }
    }

    /// Horizontal fov (degrees) of the lowest view ID whose View Definition gives both the
    /// left and right half-angles, when it is a usable pinhole fov.
    fn view_fov(&self) -> Option<f64> {
        self.session.views.values().find_map(|v| {
            let d = v.definition?;
            let fov = f64::from(d.right) - f64::from(d.left);
            (d.left_enable && d.right_enable && fov.is_finite() && fov > 0.0 && fov <= 179.0)
                .then_some(fov)
        })
    }

    /// Ends IG frame `self.ig_frame`: answers the waiting queries from the CPU reference and
    /// sends Start of Frame with the answers to the host (none known yet: nothing is sent).
    /// On a database scene the queries kept from the last frame are answered first, and a
    /// query whose tiles are not in memory is kept for the next ([`answer::Deferral`]).
    /// Returns the IG frame number just ended.
    pub fn end_frame(&mut self, terrain: &Terrain) -> u32 {
        self.answer_and_send(terrain, false)
    }

    /// The end of a run: on a database scene with queries kept from the last frame, answers
    /// them (reading what is not in memory) in one more IG datagram, a Start of Frame numbered
    /// as the next IG frame (no picture goes with it); else nothing. Returns whether it sent.
    pub fn finish(&mut self, terrain: &Terrain) -> bool {
        if self.deferral.as_ref().is_none_or(|d| d.kept() == 0) {
            return false;
        }
        self.answer_and_send(terrain, true);
        true
    }

    /// This frame's Collision Detection Segment and Volume Notifications onto `msg`
    /// ([`answer::segment_collisions`], [`answer::volume_collisions`]); on a database scene the
    /// segments from resident tiles only, the tiles a segment misses handed to the prefetcher
    /// (that segment is tested again next frame).
    fn collide(
        &self,
        terrain: &Terrain,
        host_t: f64,
        msg: &mut MessageBuilder,
    ) -> answer::Notified {
        match (&self.full, &self.deferral) {
            (Some(full), Some(d)) => {
                let tiles = crate::db::ResidentOnly::new(full.database());
                let g = answer::Ground {
                    terrain,
                    full: Some((full, &tiles)),
                    bodies: &self.bodies,
                    los: self.los,
                };
                let n = answer::segment_collisions(&g, &self.session, host_t, msg)
                    .and(answer::volume_collisions(&g, &self.session, host_t, msg));
                d.prefetcher().request(tiles.missing());
                n
            }
            _ => {
                let g = answer::Ground {
                    terrain,
                    full: None,
                    bodies: &self.bodies,
                    los: self.los,
                };
                answer::segment_collisions(&g, &self.session, host_t, msg)
                    .and(answer::volume_collisions(&g, &self.session, host_t, msg))
            }
        }
    }

    /// Start of Frame for IG frame `self.ig_frame` and the answers (`kept_only`: only the
    /// queries kept from the last frame), sent; the frame counter advances.
    fn answer_and_send(&mut self, terrain: &Terrain, kept_only: bool) -> u32 {
        let frame = self.ig_frame;
        let now = self.now();
        let ticks = ((now / crate::cigi::session::TICK) as u64 & u64::from(u32::MAX)) as u32;
        let mut msg = self.session.start_of_frame(frame, Some(ticks));
        let queries = if kept_only {
            Vec::new()
        } else {
            self.session.take_queries()
        };
        let host_t = self.session.host_time_at(now);
        let mut c = match (&self.full, &mut self.deferral) {
            (Some(full), Some(d)) => {
                // The host frame this IG frame answers for (the last IG Control received).
                let answering = self.session.host_frame.unwrap_or(0);
                let on = answer::OnDatabase {
                    terrain,
                    full,
                    session: &self.session,
                    now_host: host_t,
                    bodies: &self.bodies,
                    los: self.los,
                };
                d.answer_frame(&on, &queries, answering, &mut msg)
            }
            _ => {
                let ground = answer::Ground {
                    terrain,
                    full: None,
                    bodies: &self.bodies,
                    los: self.los,
                };
                answer::answer(&ground, &self.session, &queries, host_t, &mut msg)
            }
        };
        if !kept_only {
            let n = self.collide(terrain, host_t, &mut msg);
            (c.collisions, c.collisions_dropped) = (n.sent, n.dropped);
        }
        self.answers.add(&c);
        let bytes = msg.finish();
        if let Some(to) = self.reply_to {
            match self.socket.send_to(&bytes, to) {
                Ok(_) => self.sent += 1,
                Err(e) => {
                    self.send_errors += 1;
                    log::debug!("CIGI send to {to}: {e}");
                }
            }
        }
        self.ig_frame = self.ig_frame.wrapping_add(1);
        frame
    }

    /// The frame's JSON part: `{"host_frame", "ig_frame", counters}`.
    pub fn frame_json(&self, ig_frame: u32) -> serde_json::Value {
        let c = &self.session.counters;
        serde_json::json!({
            "host_frame": self.session.host_frame,
            "ig_frame": ig_frame,
            "ig_time_s": self.frame_time,
            "sun": self.sun.map(|(a, e)| [a, e]),
            "moon": self.moon.map(|m| [m.azimuth, m.elevation, m.illuminated]),
            "visibility": self.visibility,
            "clouds": self.clouds,
            "clouds_dropped": self.clouds_dropped,
            "sync": self.sync,
            "datagrams": c.datagrams,
            "accepted": c.accepted,
            "refused": c.datagrams - c.accepted,
            "malformed": c.malformed(),
            "entities": self.session.entity_count(),
            "drawn": self.entities_frame.0,
            "not_drawn": self.entities_frame.1,
            "hidden": self.entities_frame.2,
        })
    }

    /// Every session counter and the IG's own, as one JSON object (the end of a run).
    pub fn counters_json(&self) -> serde_json::Value {
        let c = &self.session.counters;
        let by_kind: serde_json::Map<String, serde_json::Value> = crate::cigi::Kind::ALL
            .iter()
            .filter(|k| c.of_kind(**k) > 0)
            .map(|k| (format!("{k:?}"), c.of_kind(*k).into()))
            .collect();
        serde_json::json!({
            "ig_frames": self.ig_frame,
            "datagrams": c.datagrams,
            "accepted": c.accepted,
            "short": c.short,
            "no_header": c.no_header,
            "refused_version": c.refused_version,
            "bad_magic": c.bad_magic,
            "ignored_sender": c.ignored_sender,
            "packets": c.packets,
            "by_kind": by_kind,
            "unknown": c.unknown,
            "short_packets": c.short_packets,
            "misplaced_header": c.misplaced_header,
            "size_below_two": c.size_below_two,
            "past_end": c.past_end,
            "trailing": c.trailing,
            "invalid_values": c.invalid_values,
            "refused_capacity": c.refused_capacity,
            "dropped_queries": c.dropped_queries,
            "destroyed": c.destroyed,
            "malformed": c.malformed(),
            "entities": self.session.entity_count(),
            "sent": self.sent,
            "send_errors": self.send_errors,
            "deferred": self.answers.deferred,
            "no_room": self.answers.no_room,
            "blocking_reads": self.answers.blocking_reads,
            "collisions": self.answers.collisions,
            "collisions_dropped": self.answers.collisions_dropped,
        })
    }

    /// One line of what the session did, for the end of a run.
    pub fn summary(&self) -> String {
        let c = &self.session.counters;
        format!(
            "cigi: {} IG frames, {} datagrams in ({} accepted, {} refused, {} from other senders, {} malformed), {} sent ({} failed); answered {} HAT/HOT, {} LOS, {} position ({} invalid, {} unanswered; {} deferred a frame, {} blocking reads); {} collision notifications ({} dropped: no room in the datagram); {} other entities not drawn",
            self.ig_frame,
            c.datagrams,
            c.accepted,
            c.datagrams - c.accepted,
            c.ignored_sender,
            c.malformed(),
            self.sent,
            self.send_errors,
            self.answers.hat_hot,
            self.answers.los,
            self.answers.position,
            self.answers.invalid,
            self.answers.unanswered,
            self.answers.deferred,
            self.answers.blocking_reads,
            self.answers.collisions,
            self.answers.collisions_dropped,
            self.other_entities,
        )
    }
}
