//! Everything `relief view` loads and checks before a window exists: the scene and its world,
//! the display channels, the starting motion, the control script, the eye feed and the output
//! files. Bad input fails here, before the event loop.

use super::motion::{self, ControlScript, EyeFeed, Mode, Motion, PathRecorder};
use super::stats::StatsCsv;
use super::ViewOptions;
use crate::display::blend::ChannelBlend;
use crate::display::screen_points::ScreenPoints;
use crate::display::{DisplayConfig, ViewOffset};
use crate::gpu::RenderSettings;
use crate::scene::{Pose, Scene};
use crate::terrain::Terrain;
use crate::world::World;
use crate::{Error, Result};
use glam::DVec3;
use std::path::PathBuf;
use std::sync::mpsc;

/// One channel of a display configuration, ready for `set_display`.
pub struct ChannelSpec {
    pub index: usize,
    pub name: String,
    pub points: ScreenPoints,
    pub eye: DVec3,
    pub blend: Option<ChannelBlend>,
    pub view: Option<ViewOffset>,
    pub width: u32,
    pub height: u32,
    pub config: PathBuf,
}

/// Eye points per frame.
pub enum EyeSource {
    File(EyeFeed),
    /// Lines from stdin, read by a thread; the latest one holds.
    Stdin(
        mpsc::Receiver<std::result::Result<DVec3, String>>,
        Option<DVec3>,
    ),
}

/// Everything loaded and checked before any window exists.
pub struct Prepared {
    pub opts: ViewOptions,
    /// `--resize-at`: (frame, width, height).
    pub resize_at: Option<(u64, u32, u32)>,
    pub scene: Scene,
    /// The scene's terrain, free forms, volumes and voxel models (loaded before any window
    /// opens, so bad input fails early).
    pub world: World,
    pub channels: Vec<ChannelSpec>,
    pub settings: RenderSettings,
    pub motion: Motion,
    pub script: Option<ControlScript>,
    pub eyes: Option<EyeSource>,
    pub recorder: Option<PathRecorder>,
    pub stats_csv: Option<StatsCsv>,
    /// `--cigi`: the IG whose ownship drives the camera.
    pub cigi: Option<crate::app::cigi_ig::CigiIg>,
    /// A paged window (`--terrain-memory`) follows the eye: a CIGI host's ownship, else the
    /// motion's pose (which stays in the scene's own frame).
    pub follower: Option<crate::app::paged::Follower>,
}

/// Loads and checks everything `opts` names.
pub fn prepare(opts: &ViewOptions) -> Result<Prepared> {
    let resize_at = opts.resize_at()?;
    let mut scene = Scene::load(&opts.scene)?;
    check_options(opts)?;
    if let Some((w, h)) = opts.size {
        scene.desc.output.width = w;
        scene.desc.output.height = h;
        scene.desc.validate()?;
    }
    let channels = display_channels(opts)?;
    let paged = opts.terrain_memory.or(scene.desc.terrain.memory).is_some();
    let world = World::load_as(&scene, paged)?;
    let mut settings = RenderSettings::from_scene(&scene.desc);
    opts.toggles.apply(&mut settings);
    let motion = start_motion(opts, &scene, &world.terrain)?;
    let script = control_script(opts, motion.mode)?;
    let eyes = eye_source(opts)?;
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
    let cigi = match opts.cigi.cigi {
        Some(_) => {
            let mut ig = crate::app::cigi_ig::CigiIg::bind(&opts.cigi)?;
            ig.open_database(&scene)?;
            Some(ig)
        }
        None => None,
    };
    let follower = if paged {
        Some(crate::app::paged::Follower::new(&scene, &world.terrain)?)
    } else {
        None
    };
    Ok(Prepared {
        opts: opts.clone(),
        resize_at,
        scene,
        world,
        channels,
        settings,
        motion,
        script,
        eyes,
        recorder,
        stats_csv,
        follower,
        cigi,
    })
}

/// `--rate`, `--frames` and `--min-agl` within their ranges.
fn check_options(opts: &ViewOptions) -> Result<()> {
    if !(opts.rate.is_finite() && (1.0..=1000.0).contains(&opts.rate)) {
        return Err(Error::invalid(
            "--rate",
            format!("must be 1..=1000 Hz, got {}", opts.rate),
        ));
    }
    if opts.frames == Some(0) {
        return Err(Error::invalid("--frames", "must be at least 1"));
    }
    if !(opts.min_agl.is_finite() && opts.min_agl >= 0.0) {
        return Err(Error::invalid(
            "--min-agl",
            format!("must be ≥ 0 metres, got {}", opts.min_agl),
        ));
    }
    Ok(())
}

/// The channels of `--display` (all, or `--channel`), each with its table; none without a
/// display configuration.
fn display_channels(opts: &ViewOptions) -> Result<Vec<ChannelSpec>> {
    let Some(cfg_path) = &opts.display else {
        if opts.channel.is_some() || opts.eye.is_some() || opts.eye_feed.is_some() {
            return Err(Error::invalid(
                "--channel/--eye/--eye-feed",
                "need a display configuration (--display CONFIG)",
            ));
        }
        return Ok(Vec::new());
    };
    if opts.size.is_some() {
        return Err(Error::invalid(
            "--size",
            "a distortion table renders at the projector's resolution; drop --size",
        ));
    }
    let cfg = DisplayConfig::load(cfg_path)?;
    let wanted: Vec<usize> = match opts.channel {
        Some(c) => {
            crate::app::channel::channel(&cfg, &cfg_path.display().to_string(), c)?;
            vec![c]
        }
        None => (0..cfg.channels.len()).collect(),
    };
    let eye = DVec3::from(opts.eye.unwrap_or(cfg.eye.position));
    let mut channels = Vec::new();
    for index in wanted {
        let ch = &cfg.channels[index];
        let p = ch.projector;
        let points = cfg.channel_points(index)?;
        if points.points.iter().all(|p| p.is_none()) {
            return Err(Error::invalid(
                format!("{} channel {index}", cfg_path.display()),
                "no projector pixel reaches the screen",
            ));
        }
        channels.push(ChannelSpec {
            index,
            name: ch.name.clone(),
            points,
            eye,
            blend: ChannelBlend::new(&cfg, index),
            view: ch.view,
            width: p.width,
            height: p.height,
            config: cfg_path.clone(),
        });
    }
    Ok(channels)
}

/// The starting pose and motion mode: the scene's camera, `--start`, or the start of the path
/// played back (`--path`, else the scene's `[path]`).
fn start_motion(opts: &ViewOptions, scene: &Scene, terrain: &Terrain) -> Result<Motion> {
    let mut pose = scene.camera(0, terrain).pose;
    let path = match &opts.path {
        Some(p) => Some(motion::read_path_csv(p, scene.desc.camera.fov)?),
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
            return Err(Error::invalid(
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
    Ok(Motion::new(mode, pose, path, opts.min_agl))
}

/// `--script`, which needs aircraft mode.
fn control_script(opts: &ViewOptions, mode: Mode) -> Result<Option<ControlScript>> {
    match &opts.script {
        Some(p) if mode != Mode::Aircraft => Err(Error::invalid(
            "--script",
            format!(
                "{} holds aircraft controls; add --mode aircraft",
                p.display()
            ),
        )),
        Some(p) => Ok(Some(ControlScript::load(p)?)),
        None => Ok(None),
    }
}

/// `--eye-feed`: a file, or `-` for lines on stdin read by a thread.
fn eye_source(opts: &ViewOptions) -> Result<Option<EyeSource>> {
    Ok(match &opts.eye_feed {
        Some(p) if p.as_os_str() == "-" => {
            let (tx, rx) = mpsc::channel();
            std::thread::spawn(move || {
                for line in std::io::stdin().lines() {
                    let Ok(line) = line else { break };
                    match motion::parse_eye_line(&line) {
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
    })
}
