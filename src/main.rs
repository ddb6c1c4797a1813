//! `relief`: headless rendering, benchmarks and terrain queries from the command line.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use relief::app::{bench, capture};
use std::path::PathBuf;

const DEFAULT_SCENE: &str = "terrains/alps.toml";

#[derive(Parser)]
#[command(
    name = "relief",
    version,
    about = "Polygon-free terrain image generator (max-LOD pyramid ray casting on wgpu)"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Memory budget in MiB for what loading one input file may allocate (default 8192, 8 GiB):
    /// files whose declared sizes need more are refused before anything is allocated.
    #[arg(long, global = true, value_name = "MB", value_parser = clap::value_parser!(u64).range(1..=1 << 40))]
    memory_budget: Option<u64>,
}

#[derive(Subcommand)]
enum Command {
    /// Render frames headless: frame_NNNN.png, depth_NNNN.tiff, frame_NNNN.json.
    Render {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Output size WxH (overrides [output]).
        #[arg(long, value_parser = parse_size)]
        size: Option<(u32, u32)>,
        /// Number of frames (along the scene's [path] if it has one).
        #[arg(long, default_value_t = 1)]
        frames: u32,
        /// First frame number.
        #[arg(long, default_value_t = 0)]
        first: u32,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Turn sun shadows on surfaces off (terrain, free forms, voxel models, volumes casting onto them).
        #[arg(long)]
        no_shadows: bool,
        /// Turn the screen-tile pre-pass off.
        #[arg(long)]
        no_tile_prepass: bool,
        /// Render through a curved-screen distortion table (display config TOML).
        #[arg(long)]
        display: Option<PathBuf>,
        /// Channel (projector) of the display config.
        #[arg(long, default_value_t = 0)]
        channel: usize,
        /// Eye point X,Y,Z in the display frame (overrides the config's eye).
        #[arg(long, value_parser = parse_vec::<3>, allow_hyphen_values = true)]
        eye: Option<[f64; 3]>,
        /// With --display: two-pass mode (planar/cube images warped bilinearly through the
        /// table) instead of direct ray casting, for comparison.
        #[arg(long, requires = "display")]
        two_pass: bool,
        /// Render the warp test pattern (5° azimuth/elevation grid, horizon, 10° circles around
        /// the view direction) instead of the scene.
        #[arg(long)]
        pattern: bool,
        /// Render a square dome master (angular fisheye of this many degrees, 180 for a
        /// hemisphere; zenith at the centre, forward at the bottom) instead of a pinhole view.
        #[arg(long, conflicts_with = "display")]
        dome_master: Option<f64>,
    },
    /// Open a window: the same renderer in a fixed-rate frame loop, with flight and capture.
    View(Box<ViewArgs>),
    /// Benchmark the pyramid traversal against a fixed-step march on the same rays.
    Bench {
        /// Scene file (default: terrains/alps.toml).
        scene: Option<PathBuf>,
        #[arg(long, value_parser = parse_size, default_value = "1280x720")]
        size: (u32, u32),
        /// Timed frames per configuration (submitted in pairs as a frame loop does; the median
        /// over the pairs is reported; the --freeforms headline ratio alternates single frames
        /// of its two configurations instead). Default 10; 600 with --soak.
        #[arg(long)]
        frames: Option<u32>,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
        /// Also write the fixed rays and the pyramid depths (raw little-endian f32) to this directory.
        #[arg(long)]
        dump_rays: Option<PathBuf>,
        /// Time only the primary rays of the product configuration (pyramid + tile pre-pass):
        /// for scripts that alternate relief with another renderer.
        #[arg(long, conflicts_with_all = ["dump_rays", "freeforms", "voxels", "volume", "display"])]
        primary_only: bool,
        /// Measure free forms instead: the scene's objects vs terrain only, then 10/100/1000
        /// generated objects (default scene: terrains/airfield.toml).
        #[arg(long)]
        freeforms: bool,
        /// Measure voxel models instead: the scene's `[[voxels]]` one at a time vs terrain
        /// only (default scene: terrains/tree.toml).
        #[arg(long)]
        voxels: bool,
        /// Measure the density-volume pass instead (the scene's first volume): plain marching vs
        /// empty-space skipping and early termination (default scene: terrains/brain.toml).
        #[arg(long)]
        volume: bool,
        /// Measure a display config's channel instead (resized to --size, same lens):
        /// ray-table regeneration and direct-mode frame vs the pinhole frame.
        #[arg(long)]
        display: Option<PathBuf>,
        #[arg(long, default_value_t = 0)]
        channel: usize,
        /// Soak test instead: render --frames frames (default 600) as `render` does, without
        /// writing files; report RSS per frame and its slope over frames 100-500, wgpu's live
        /// objects at frames 100 and 500, and frame-time p50/p99/max.
        #[arg(long, conflicts_with_all = ["dump_rays", "primary_only", "freeforms", "voxels", "volume", "display"])]
        soak: bool,
    },
    /// Voxel model files: convert to the segment format (.rvs) and report sizes.
    Voxels {
        #[command(subcommand)]
        action: VoxelsAction,
    },
    /// Warp files: inspect PFM / Bourke warps, export a display configuration's warp.
    Warp {
        #[command(subcommand)]
        action: WarpAction,
    },
    /// Terrain queries on the CPU reference: height at (x, y), line of sight.
    Query {
        scene: PathBuf,
        /// World x,y: prints the terrain height there.
        #[arg(long, value_parser = parse_vec::<2>, allow_hyphen_values = true)]
        at: Option<[f64; 2]>,
        /// Line of sight between two world points x,y,z (give twice).
        #[arg(long, value_parser = parse_vec::<3>, num_args = 2, allow_hyphen_values = true)]
        los: Option<Vec<[f64; 3]>>,
    },
    /// Open the graphics adapter relief would render on (honours WGPU_BACKEND and
    /// WGPU_ADAPTER_NAME) and print what it is; exit 1 if there is none.
    Adapter,
}

/// `relief view` flags (see README: Window).
#[derive(clap::Args)]
struct ViewArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Window and render size WxH (overrides [output]).
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Display config: one window per channel, each through its distortion table.
    #[arg(long)]
    display: Option<PathBuf>,
    /// Only this channel of the display config.
    #[arg(long)]
    channel: Option<usize>,
    /// Eye point X,Y,Z in the display frame (overrides the config's eye).
    #[arg(long, value_parser = parse_vec::<3>, allow_hyphen_values = true)]
    eye: Option<[f64; 3]>,
    /// Eye point per frame for the distortion: a file of x,y,z lines, or - for stdin.
    #[arg(long)]
    eye_feed: Option<PathBuf>,
    /// Borderless fullscreen on monitor INDEX (default 0); channel i on INDEX + i.
    #[arg(long, num_args = 0..=1, default_missing_value = "0")]
    fullscreen: Option<usize>,
    /// Exit after N frames.
    #[arg(long)]
    frames: Option<u64>,
    /// Target frame rate in Hz; the simulation steps 1/rate per frame.
    #[arg(long, default_value_t = 60.0)]
    rate: f64,
    /// Wait for vsync (FIFO present) as well as pacing frames at --rate.
    #[arg(long, conflicts_with = "mailbox")]
    vsync: bool,
    /// Present in mailbox mode (no tearing) instead of immediate.
    #[arg(long)]
    mailbox: bool,
    /// Render frames back to back instead of pacing them at the target rate.
    #[arg(long)]
    unpaced: bool,
    /// Per-frame statistics (CPU, GPU, present interval, latency, pose) to this CSV.
    #[arg(long)]
    stats_csv: Option<PathBuf>,
    /// Starting motion: path, free or aircraft (default: path if there is one, else free).
    #[arg(long, value_parser = parse_mode)]
    mode: Option<relief::app::view::motion::Mode>,
    /// Play back this path CSV (time,x,y,alt,heading,pitch,roll) instead of the scene's [path].
    #[arg(long)]
    path: Option<PathBuf>,
    /// Record the flown path to this CSV (same columns as --path).
    #[arg(long)]
    record: Option<PathBuf>,
    /// Aircraft control script CSV (time,throttle,pitch,roll,yaw).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Start at X,Y,Z (world metres) with HEADING (degrees) instead of the scene's camera.
    #[arg(long, value_parser = parse_vec::<4>, allow_hyphen_values = true)]
    start: Option<[f64; 4]>,
    /// Free flight and aircraft stay at least this many metres above the terrain.
    #[arg(long, default_value_t = 10.0)]
    min_agl: f64,
    /// Write every frame's capture files (as `relief render`) to this directory.
    #[arg(long)]
    capture_frames: Option<PathBuf>,
    /// Directory for the screenshot key (P) and --grab.
    #[arg(long, default_value = "out")]
    screenshot_dir: PathBuf,
    /// At frame N read back the swap-chain image and, on X11, the window from the X server.
    #[arg(long)]
    grab: Option<u64>,
    /// Debug: after frame FRAME resize the window to WxH (`--resize-at 30 320x240`).
    #[arg(long, num_args = 2, value_names = ["FRAME", "WxH"])]
    resize_at: Option<Vec<String>>,
    /// Starting view: colour, depth or steps (traversal step heat map); V cycles them.
    #[arg(long, value_parser = parse_debug_view, default_value = "colour")]
    debug_view: relief::app::view::present::ViewMode,
    /// Start with the text overlay hidden (H toggles it).
    #[arg(long)]
    no_overlay: bool,
    /// Turn sun shadows on surfaces off (terrain, free forms, voxel models, volumes casting onto them).
    #[arg(long)]
    no_shadows: bool,
    /// Turn the screen-tile pre-pass off.
    #[arg(long)]
    no_tile_prepass: bool,
}

fn parse_mode(s: &str) -> std::result::Result<relief::app::view::motion::Mode, String> {
    use relief::app::view::motion::Mode;
    match s {
        "path" => Ok(Mode::Path),
        "free" => Ok(Mode::Free),
        "aircraft" => Ok(Mode::Aircraft),
        _ => Err(format!("`{s}`: use path, free or aircraft")),
    }
}

fn parse_debug_view(s: &str) -> std::result::Result<relief::app::view::present::ViewMode, String> {
    use relief::app::view::present::ViewMode;
    match s {
        "colour" | "color" => Ok(ViewMode::Colour),
        "depth" => Ok(ViewMode::Depth),
        "steps" => Ok(ViewMode::Steps),
        _ => Err(format!("`{s}`: use colour, depth or steps")),
    }
}

fn view_options(a: ViewArgs) -> Result<relief::app::view::ViewOptions> {
    let resize_at = match a.resize_at.as_deref() {
        None => None,
        Some([frame, size]) => {
            let f: u64 = frame
                .parse()
                .map_err(|_| anyhow::anyhow!("--resize-at: `{frame}` is not a frame number"))?;
            let (w, h) = parse_size(size).map_err(|e| anyhow::anyhow!("--resize-at: {e}"))?;
            Some((f, w, h))
        }
        Some(_) => bail!("--resize-at needs FRAME WxH"),
    };
    let mut o = relief::app::view::ViewOptions::new(a.scene);
    o.size = a.size;
    o.display = a.display;
    o.channel = a.channel;
    o.eye = a.eye;
    o.eye_feed = a.eye_feed;
    o.fullscreen = a.fullscreen;
    o.frames = a.frames;
    o.rate = a.rate;
    o.present = if a.vsync {
        relief::app::view::PresentChoice::Vsync
    } else if a.mailbox {
        relief::app::view::PresentChoice::Mailbox
    } else {
        relief::app::view::PresentChoice::Paced
    };
    o.unpaced = a.unpaced;
    o.stats_csv = a.stats_csv;
    o.mode = a.mode;
    o.path_csv = a.path;
    o.record = a.record;
    o.script = a.script;
    o.start = a.start;
    o.min_agl = a.min_agl;
    o.capture_frames = a.capture_frames;
    o.screenshot_dir = a.screenshot_dir;
    o.grab = a.grab;
    o.resize_at = resize_at;
    o.overlay = !a.no_overlay;
    o.view_mode = a.debug_view;
    o.shadows = a.no_shadows.then_some(false);
    o.tile_prepass = a.no_tile_prepass.then_some(false);
    Ok(o)
}

#[derive(Subcommand)]
enum VoxelsAction {
    /// Convert a .vox (composed scene graph, frame 0) or .rvs to a segment file and print
    /// the voxel count, the sizes and the ratios vs a dense grid and vs the source file.
    Convert { input: PathBuf, output: PathBuf },
}

#[derive(Subcommand)]
enum WarpAction {
    /// Warp a dome master (square angular fisheye, zenith at the centre, front at the bottom)
    /// into one channel's projector image through its table, with its edge blend.
    Apply {
        /// Display config (or give --mesh and --size instead).
        #[arg(required_unless_present = "mesh")]
        config: Option<PathBuf>,
        /// A Bourke type-2 warp mesh instead of a display config.
        #[arg(long, conflicts_with = "config", requires = "size")]
        mesh: Option<PathBuf>,
        /// Projector image size WxH (with --mesh).
        #[arg(long, value_parser = parse_size)]
        size: Option<(u32, u32)>,
        #[arg(long, default_value_t = 0)]
        channel: usize,
        #[arg(long, value_parser = parse_vec::<3>, allow_hyphen_values = true)]
        eye: Option<[f64; 3]>,
        /// The dome-master PNG.
        #[arg(long)]
        dome_master: PathBuf,
        /// Its field of view in degrees.
        #[arg(long, default_value_t = 180.0)]
        fov: f64,
        #[arg(long)]
        out: PathBuf,
    },
    /// Describe a warp file (.pfm, or a Bourke mesh).
    Inspect {
        file: PathBuf,
        /// PFM rows are stored top to bottom (default: bottom to top, as netpbm).
        #[arg(long)]
        top_to_bottom: bool,
    },
    /// Closed-loop check: render the test pattern through the channels, throw it onto the
    /// screen, view it from the eye; print the angular error (arc-min) and the sharpness of
    /// direct vs two-pass warping; write the "as seen from the eye" images and verify.json.
    Verify {
        config: PathBuf,
        /// Only this channel (default: all).
        #[arg(long)]
        channel: Option<usize>,
        #[arg(long, value_parser = parse_vec::<3>, allow_hyphen_values = true)]
        eye: Option<[f64; 3]>,
        /// Eye-view (fisheye) image size.
        #[arg(long, value_parser = parse_size, default_value = "480x480")]
        size: (u32, u32),
        /// Skip the two-pass comparison.
        #[arg(long)]
        no_two_pass: bool,
        /// Generate the tables for this eye instead (display frame): the error a stale
        /// head-tracked table leaves.
        #[arg(long, value_parser = parse_vec::<3>, allow_hyphen_values = true)]
        table_eye: Option<[f64; 3]>,
        #[arg(long, default_value = "out/verify")]
        out: PathBuf,
    },
    /// Write a channel's warp: FILE.pfm = 3-D screen geometry, otherwise a Bourke mesh.
    Export {
        config: PathBuf,
        #[arg(long, default_value_t = 0)]
        channel: usize,
        #[arg(long, value_parser = parse_vec::<3>, allow_hyphen_values = true)]
        eye: Option<[f64; 3]>,
        /// Bourke meshes: one node every STEP projector pixels.
        #[arg(long, default_value_t = 8)]
        step: u32,
        #[arg(long)]
        out: PathBuf,
    },
}

fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}` is not WIDTHxHEIGHT"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in `{s}`"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in `{s}`"))?;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(format!("size {w}x{h} must be within 1..=16384 per side"));
    }
    Ok((w, h))
}

fn parse_vec<const N: usize>(s: &str) -> std::result::Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| format!("`{s}`: {e}"))?;
    let arr: [f64; N] = v
        .try_into()
        .map_err(|_| format!("`{s}` needs {N} comma-separated numbers"))?;
    if arr.iter().any(|x| !x.is_finite()) {
        return Err(format!("`{s}` has a non-finite number"));
    }
    Ok(arr)
}

fn default_scene() -> PathBuf {
    let local = PathBuf::from(DEFAULT_SCENE);
    if local.exists() {
        local
    } else {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_SCENE)
    }
}

fn main() {
    env_logger::Builder::from_env(
        env_logger::Env::default().default_filter_or("info,wgpu_core=warn,wgpu_hal=warn,naga=warn"),
    )
    .format_timestamp(None)
    .init();
    relief::fileio::install_signal_cleanup();
    let cli = Cli::parse();
    if let Some(mb) = cli.memory_budget {
        relief::fileio::set_memory_budget(mb << 20);
    }
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        None => {
            let job = capture::RenderJob {
                scene: default_scene(),
                size: None,
                frames: 1,
                first_frame: 0,
                out_dir: "out".into(),
                shadows: None,
                tile_prepass: None,
                display: None,
                pattern: false,
                dome_master: None,
            };
            let files =
                capture::run(&job).with_context(|| format!("rendering {}", job.scene.display()))?;
            println!(
                "wrote {}",
                files
                    .iter()
                    .map(|f| f.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        Some(Command::Render {
            scene,
            size,
            frames,
            first,
            out,
            no_shadows,
            no_tile_prepass,
            display,
            channel,
            eye,
            two_pass,
            pattern,
            dome_master,
        }) => {
            let job = capture::RenderJob {
                scene,
                size,
                frames,
                first_frame: first,
                out_dir: out,
                shadows: no_shadows.then_some(false),
                tile_prepass: no_tile_prepass.then_some(false),
                display: display.map(|config| capture::DisplayJob {
                    config,
                    channel,
                    eye,
                    two_pass,
                }),
                pattern,
                dome_master,
            };
            let files =
                capture::run(&job).with_context(|| format!("rendering {}", job.scene.display()))?;
            println!("wrote {} files to {}", files.len(), job.out_dir.display());
        }
        Some(Command::View(args)) => {
            let opts = view_options(*args)?;
            let report = relief::app::view::run(&opts)
                .with_context(|| format!("viewing {}", opts.scene.display()))?;
            println!("{report}");
        }
        Some(Command::Bench {
            scene,
            size,
            frames,
            json,
            dump_rays,
            primary_only,
            freeforms,
            voxels,
            volume,
            display,
            channel,
            soak,
        }) => {
            let frames = frames.unwrap_or(if soak { 600 } else { 10 });
            if frames == 0 {
                bail!("--frames must be at least 1");
            }
            if soak {
                let scene = scene.unwrap_or_else(default_scene);
                let report = relief::app::soak::run(&scene, size, frames)
                    .with_context(|| format!("soak test of {}", scene.display()))?;
                if json {
                    println!("{}", serde_json::to_string_pretty(&report)?);
                } else {
                    relief::app::soak::print(&report);
                }
                return Ok(());
            }
            if let Some(config) = display {
                let scene = scene.unwrap_or_else(default_scene);
                let r = relief::app::verify::bench_display(&scene, &config, channel, size, frames)
                    .with_context(|| format!("benchmarking {}", config.display()))?;
                if json {
                    println!("{}", serde_json::to_string_pretty(&r)?);
                } else {
                    println!(
                        "relief bench --display {} (channel {}) on {} at {}x{}, {} frames, {} ({})\n  table regeneration {:.1} ms; direct frame {:.1} ms vs pinhole {:.1} ms: {:.2}x",
                        r.config, r.channel, r.scene, r.width, r.height, r.frames, r.adapter,
                        r.backend, r.table_ms, r.direct_frame_ms, r.pinhole_frame_ms,
                        r.direct_over_pinhole
                    );
                }
                return Ok(());
            }
            if volume {
                let scene = scene.unwrap_or_else(|| PathBuf::from("terrains/brain.toml"));
                let report = relief::app::volumes::bench(&scene, size, frames)
                    .with_context(|| format!("benchmarking {}", scene.display()))?;
                if json {
                    println!("{}", serde_json::to_string_pretty(&report)?);
                } else {
                    relief::app::volumes::print(&report);
                }
                return Ok(());
            }
            if voxels {
                let scene = scene.unwrap_or_else(|| PathBuf::from("terrains/tree.toml"));
                let report = relief::app::voxels::bench(&scene, size, frames)
                    .with_context(|| format!("benchmarking {}", scene.display()))?;
                if json {
                    println!("{}", serde_json::to_string_pretty(&report)?);
                } else {
                    relief::app::voxels::print_bench(&report);
                }
                return Ok(());
            }
            if freeforms {
                let scene = scene.unwrap_or_else(|| PathBuf::from("terrains/airfield.toml"));
                let report = bench::run_freeforms(&scene, size, frames)
                    .with_context(|| format!("benchmarking {}", scene.display()))?;
                if json {
                    println!("{}", serde_json::to_string_pretty(&report)?);
                } else {
                    bench::print_freeforms(&report);
                }
                return Ok(());
            }
            let scene = scene.unwrap_or_else(default_scene);
            if primary_only {
                let r = bench::run_primary(&scene, size, frames)
                    .with_context(|| format!("benchmarking {}", scene.display()))?;
                if json {
                    println!("{}", serde_json::to_string_pretty(&r)?);
                } else {
                    println!(
                        "relief bench --primary-only: {} at {}x{}, {} frames, {} ({}): primary {:.2} ms, {:.2} M rays/s",
                        r.scene, r.width, r.height, r.frames, r.adapter, r.backend, r.primary_ms,
                        r.rays_per_second / 1e6
                    );
                }
                return Ok(());
            }
            let report = bench::run(&scene, size, frames, dump_rays.as_deref())
                .with_context(|| format!("benchmarking {}", scene.display()))?;
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                bench::print_table(&report);
            }
        }
        Some(Command::Voxels {
            action: VoxelsAction::Convert { input, output },
        }) => {
            let r = relief::app::voxels::convert(&input, &output)
                .with_context(|| format!("converting {}", input.display()))?;
            relief::app::voxels::print_sizes(&input, &r);
        }
        Some(Command::Warp { action }) => match action {
            WarpAction::Inspect {
                file,
                top_to_bottom,
            } => {
                let order = if top_to_bottom {
                    relief::display::warp::RowOrder::TopToBottom
                } else {
                    relief::display::warp::RowOrder::BottomToTop
                };
                println!("{}", relief::app::warp::inspect(&file, order)?);
            }
            WarpAction::Verify {
                config,
                channel,
                eye,
                size,
                no_two_pass,
                table_eye,
                out,
            } => {
                let opts = relief::app::verify::VerifyOptions {
                    channels: channel.into_iter().collect(),
                    eye: eye.map(glam::DVec3::from),
                    size,
                    two_pass: !no_two_pass,
                    table_eye: table_eye.map(glam::DVec3::from),
                };
                let (report, files) = relief::app::verify::run(&config, &opts, &out)
                    .with_context(|| format!("verifying {}", config.display()))?;
                println!("{}", relief::app::verify::summary(&report));
                println!("wrote {} files to {}", files.len(), out.display());
            }
            WarpAction::Apply {
                config,
                mesh,
                size,
                channel,
                eye,
                dome_master,
                fov,
                out,
            } => {
                let msg = match (config, mesh, size) {
                    (Some(config), None, _) => relief::app::warp::apply_dome_master(
                        &config,
                        channel,
                        eye,
                        &dome_master,
                        fov,
                        &out,
                    )?,
                    (None, Some(mesh), Some(size)) => {
                        relief::app::warp::apply_mesh(&mesh, &dome_master, size, &out)?
                    }
                    _ => bail!("give a display CONFIG, or --mesh MESH --size WxH"),
                };
                println!("{msg}");
            }
            WarpAction::Export {
                config,
                channel,
                eye,
                step,
                out,
            } => {
                println!(
                    "{}",
                    relief::app::warp::export(&config, channel, eye, &out, step)?
                );
            }
        },
        Some(Command::Adapter) => {
            let gpu = relief::gpu::Gpu::new()?;
            let l = &gpu.limits;
            println!(
                "{} ({:?}, {:?}, driver {} {})\n  parameter blocks: {:?}; 2-D textures up to {}, 3-D up to {}, storage buffers up to {} bytes",
                gpu.info.name,
                gpu.info.backend,
                gpu.info.device_type,
                gpu.info.driver,
                gpu.info.driver_info,
                gpu.params,
                l.max_texture_dimension_2d,
                l.max_texture_dimension_3d,
                l.max_storage_buffer_binding_size
            );
        }
        Some(Command::Query { scene, at, los }) => {
            let s = relief::scene::Scene::load(&scene)?;
            let terrain = s.load_terrain()?;
            if at.is_none() && los.is_none() {
                bail!("give --at X,Y and/or --los X1,Y1,Z1 X2,Y2,Z2");
            }
            if let Some([x, y]) = at {
                let p = glam::DVec3::new(x, y, 0.0);
                match relief::cpu::terrain_point_below(&terrain, p) {
                    Some(q) => println!("terrain at ({x}, {y}): z = {:.3} m", q.z),
                    None => bail!("({x}, {y}) is outside the height grid"),
                }
            }
            if let Some(pts) = los {
                let (a, b) = (glam::DVec3::from(pts[0]), glam::DVec3::from(pts[1]));
                let clear = relief::cpu::line_of_sight(&terrain, a, b);
                let below: Vec<_> = [("first", a), ("second", b)]
                    .iter()
                    .filter(|(_, p)| relief::cpu::query::is_underground(&terrain, *p))
                    .map(|(n, _)| *n)
                    .collect();
                let why = if below.is_empty() {
                    String::new()
                } else {
                    format!(" ({} point below the terrain surface)", below.join(" and "))
                };
                println!(
                    "line of sight {a} -> {b}: {}{why}",
                    if clear { "clear" } else { "blocked" }
                );
            }
        }
    }
    Ok(())
}
