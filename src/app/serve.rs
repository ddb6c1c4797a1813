//! `relief serve`: a headless CIGI 3.3 image generator. Each frame takes the host's datagrams
//! into the session ([`super::cigi_ig`]), renders the ownship's view through the headless
//! capture path (pinhole or a display channel), optionally writes the frame's files as
//! `relief render` does (their JSON with a `cigi` part and the geodetic camera), then answers
//! the host's queries and sends Start of Frame ([docs/cigi.md](../../docs/cigi.md)).

use super::args::{parse_size, RenderToggles};
use super::capture::{prepare, DisplayArgs, RenderJob};
use super::cigi_ig::{CigiArgs, CigiIg};
use crate::scene::Camera;
use crate::{Error, Result};
use serde_json::json;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Asynchronous mode renders at most this many frames a second.
pub const MAX_RATE_HZ: f64 = 60.0;

/// Options of `relief serve`.
#[derive(Clone, Debug, clap::Args)]
pub struct ServeOptions {
    /// Scene file (TOML): terrain, sun, fog, output size; the camera until the host places
    /// the ownship (its heading, pitch, roll and fov are the defaults).
    pub scene: PathBuf,
    #[command(flatten)]
    pub cigi: CigiArgs,
    /// Render size WxH (overrides `[output]`).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    #[command(flatten)]
    pub display: DisplayArgs,
    /// Exit after N frames (default: run until interrupted).
    #[arg(long)]
    pub frames: Option<u64>,
    /// Write every frame's files (frame_NNNN.png, depth_NNNN.tiff, frame_NNNN.json) here.
    #[arg(long)]
    pub capture_frames: Option<PathBuf>,
    /// Append one JSON line per frame here: IG frame, IG time, host frame, host time, the
    /// camera's geodetic position and heading/pitch/roll, render milliseconds.
    #[arg(long, value_name = "FILE")]
    pub pose_log: Option<PathBuf>,
    #[command(flatten)]
    pub toggles: RenderToggles,
    /// Render a database scene through a paged tile pool of this many MB (each frame pages
    /// for its view, never waiting; as `relief view --terrain-memory`).
    #[arg(long, value_name = "MB")]
    pub terrain_memory: Option<u64>,
}

/// Runs the IG until `--frames` frames are done (or the synchronous host is gone); returns
/// the session's summary line.
pub fn run(opts: &ServeOptions) -> Result<String> {
    let never = AtomicBool::new(false);
    run_with(opts, &never, |_| CigiIg::bind(&opts.cigi))
}

/// [`run`] for an IG inside another command (`relief bench cigi`): `open` binds the socket
/// once the renderer is ready (given the adapter), and the loop also ends after the frame in
/// which `stop` is set.
pub fn run_with(
    opts: &ServeOptions,
    stop: &AtomicBool,
    open: impl FnOnce(&crate::gpu::Gpu) -> Result<CigiIg>,
) -> Result<String> {
    if opts.cigi.cigi.is_none() {
        return Err(Error::invalid(
            "--cigi",
            "give the UDP port to listen on (0: any free port)",
        ));
    }
    let job = RenderJob {
        scene: opts.scene.clone(),
        size: opts.size,
        frames: 1,
        first_frame: 0,
        out_dir: opts.capture_frames.clone().unwrap_or_default(),
        toggles: opts.toggles,
        display: opts.display.clone(),
        pattern: false,
        dome_master: None,
        terrain_memory: opts.terrain_memory,
        wait_resident: false,
    };
    let (mut p, mut renderer) = prepare(&job)?;
    if let Some(dir) = &opts.capture_frames {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let base = p.scene.camera(0, &p.world.terrain);
    let mut follower = match &p.paging {
        Some(_) => Some(super::paged::Follower::new(&p.scene, &p.world.terrain)?),
        None => None,
    };
    let mut log = match &opts.pose_log {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| Error::io(p, e))?,
        )),
        None => None,
    };
    let mut ig = open(&p.gpu)?;
    ig.open_database(&p.scene)?;
    let period = Duration::from_secs_f64(1.0 / MAX_RATE_HZ);
    let mut done = 0u64;
    while opts.frames.is_none_or(|n| done < n) && !stop.load(Ordering::Relaxed) {
        let started = Instant::now();
        if ig.sync {
            ig.wait_host_frame()?;
        } else {
            ig.poll();
        }
        follow_ownship(&ig, follower.as_mut(), &mut p, &mut renderer)?;
        let (pose, own) = ig.camera_pose(&p.world.terrain, base.pose);
        let cam = Camera::new(pose, base.width, base.height);
        let terrain = &p.world.terrain;
        let frames = p.frames(&job);
        let at = own
            .map(|o| o.geodetic)
            .or_else(|| terrain.world_to_geodetic(cam.pose.position));
        let instances = ig.instances(terrain, &p.world.templates);
        renderer.set_instances(instances.drawn);
        renderer.set_voxel_instances(instances.voxels);
        let mut scene = p.scene.clone();
        ig.environment(&mut scene.desc, at);
        let frames = frames.with_scene(&scene);
        renderer.set_time(ig.now());
        let paging = frames.page(&mut renderer, &cam, false)?;
        let out = frames.render_camera(&mut renderer, &cam)?;
        let ig_frame = ig.ig_frame;
        if let (Some(w), Some(path)) = (log.as_mut(), &opts.pose_log) {
            let line = json!({
                "ig_frame": ig_frame,
                "ig_time_s": ig.frame_time,
                "host_frame": ig.session.host_frame,
                "host_time_s": own.map(|o| o.host_time),
                "geodetic": own.map(|o| o.geodetic),
                "hpr": [cam.pose.heading, cam.pose.pitch, cam.pose.roll],
                "busy_ms": started.elapsed().as_secs_f64() * 1e3,
            });
            use std::io::Write as _;
            writeln!(w, "{line}").map_err(|e| Error::io(path, e))?;
        }
        if opts.capture_frames.is_some() {
            let cigi = ig.frame_json(ig_frame);
            frames.write(&out, &cam, ig_frame, |m| {
                m["cigi"] = cigi;
                m["camera"]["geodetic"] = json!(at);
                m["camera"]["host_time_s"] = json!(own.map(|o| o.host_time));
                if let Some(p) = paging {
                    m["paging"] = p;
                }
            })?;
        }
        ig.end_frame(terrain);
        done += 1;
        if !ig.sync {
            let spent = started.elapsed();
            if spent < period {
                std::thread::sleep(period - spent);
            }
        }
    }
    // Queries kept for a frame that will not come are answered in one last datagram.
    ig.finish(&p.world.terrain);
    if let (Some(mut w), Some(path)) = (log, &opts.pose_log) {
        use std::io::Write as _;
        w.flush().map_err(|e| Error::io(path, e))?;
    }
    Ok(format!(
        "{}\ncigi-counters: {}",
        ig.summary(),
        ig.counters_json()
    ))
}

/// A paged window follows the host's ownship (also off the window), before the ownship is
/// placed in its frame.
fn follow_ownship(
    ig: &CigiIg,
    follower: Option<&mut super::paged::Follower>,
    p: &mut super::capture::Prepared,
    renderer: &mut crate::gpu::TerrainRenderer,
) -> Result<()> {
    if let (Some(lla), Some(f), Some(paging)) = (ig.eye_geodetic(), follower, &p.paging) {
        if f.follow(&mut p.world, lla)? {
            paging
                .borrow_mut()
                .sync_window(&p.gpu, renderer, &p.world, f.spec())?;
        }
    }
    Ok(())
}
