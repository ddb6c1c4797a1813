//! `relief`: headless rendering, benchmarks and terrain queries from the command line.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use relief::app::args::{parse_size, parse_vec};
use relief::app::bench::BenchCommand;
use relief::app::capture::RenderJob;
use relief::app::verify::VerifyOptions;
use relief::app::view::ViewOptions;
use std::path::{Path, PathBuf};

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
    /// Entry points of the kernels that have both (ray generation): `compute`, `fragment`, or
    /// `auto` (fragment on CPU adapters, whose compute runs on about one core; compute
    /// elsewhere).
    #[arg(long, global = true, value_name = "PATH", default_value = "auto")]
    kernels: relief::gpu::KernelChoice,
    /// Profiling aid: submit and wait after every sub-pass and log its time (frame times taken
    /// with it on are not comparable with those taken without).
    #[arg(long, global = true)]
    trace_passes: bool,
    /// Where an anti-aliased frame's list of marked pixels is built: `cpu` (from the edge mask
    /// read back), `gpu` (compute; only the list's length is read back), or `auto` (cpu on CPU
    /// adapters, whose compute runs on about one core; gpu elsewhere).
    #[arg(long, global = true, value_name = "WHERE", default_value = "auto")]
    aa_list: relief::gpu::ListChoice,
}

#[derive(Subcommand)]
enum Command {
    /// Render frames headless: frame_NNNN.png, depth_NNNN.tiff, frame_NNNN.json.
    Render(RenderJob),
    /// A headless CIGI 3.3 image generator: the host flies the ownship over UDP, relief
    /// renders its view and answers HAT/HOT, line-of-sight and position queries.
    Serve(Box<relief::app::serve::ServeOptions>),
    /// Open a window: the same renderer in a fixed-rate frame loop, with flight and capture.
    View(Box<ViewOptions>),
    /// Benchmarks, one mode a subcommand: terrain traversal, primary rays, free forms, volumes,
    /// voxel models, display channels, soak.
    Bench {
        #[command(subcommand)]
        mode: BenchCommand,
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
    /// Terrain databases: compile DEMs into one tiled multi-resolution file, describe one.
    Db {
        #[command(subcommand)]
        action: relief::app::db::DbAction,
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

/// `relief` without a command: `relief render` of the default scene with its defaults.
#[derive(Parser)]
struct DefaultRender {
    #[command(flatten)]
    job: RenderJob,
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
        #[command(flatten)]
        opts: VerifyOptions,
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
    relief::app::gpu_options::set(relief::gpu::GpuOptions {
        kernels: cli.kernels,
        trace_passes: cli.trace_passes,
        aa_list: cli.aa_list,
    });
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        None => render_default(),
        Some(Command::Render(job)) => {
            let files = relief::app::capture::run(&job)
                .with_context(|| format!("rendering {}", job.scene.display()))?;
            println!("wrote {} files to {}", files.len(), job.out_dir.display());
            Ok(())
        }
        Some(Command::Serve(opts)) => {
            let summary = relief::app::serve::run(&opts)
                .with_context(|| format!("serving {}", opts.scene.display()))?;
            println!("{summary}");
            Ok(())
        }
        Some(Command::View(opts)) => {
            // The window runs for hours and reads no frames back: large blocks mapped, so
            // freed ones go back to the system (`relief::app::heap`).
            relief::app::heap::map_large_blocks();
            let report = relief::app::view::run(&opts)
                .with_context(|| format!("viewing {}", opts.scene.display()))?;
            println!("{report}");
            Ok(())
        }
        Some(Command::Bench { mode }) => bench(&mode),
        Some(Command::Voxels {
            action: VoxelsAction::Convert { input, output },
        }) => {
            let r = relief::app::voxels::convert(&input, &output)
                .with_context(|| format!("converting {}", input.display()))?;
            relief::app::voxels::print_sizes(&input, &r);
            Ok(())
        }
        Some(Command::Warp { action }) => warp(action),
        Some(Command::Db { action }) => {
            let text = relief::app::db::run(&action)?;
            println!("{}", text.trim_end());
            Ok(())
        }
        Some(Command::Adapter) => adapter(),
        Some(Command::Query { scene, at, los }) => query(&scene, at, los),
    }
}

/// `relief` alone: renders the default scene (found at run time) to `out/`.
fn render_default() -> Result<()> {
    let scene = relief::app::scenes::find_shipped(relief::app::scenes::DEFAULT_SCENE)?;
    let job = DefaultRender::parse_from([std::ffi::OsString::from("relief"), scene.into()]).job;
    let files = relief::app::capture::run(&job)
        .with_context(|| format!("rendering {}", job.scene.display()))?;
    println!(
        "wrote {}",
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// `relief bench MODE`: the report as text or one JSON object.
fn bench(mode: &BenchCommand) -> Result<()> {
    let scene = mode.scene()?;
    let report = mode.run(&scene).with_context(|| mode.context(&scene))?;
    if mode.args().json {
        println!("{}", report.to_json()?);
    } else {
        print!("{report}");
    }
    Ok(())
}

fn warp(action: WarpAction) -> Result<()> {
    match action {
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
        WarpAction::Verify { config, opts, out } => {
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
    }
    Ok(())
}

fn adapter() -> Result<()> {
    let gpu = relief::app::gpu_options::open()?;
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
    Ok(())
}

/// `relief query`: terrain height at a point, line of sight between two.
fn query(scene: &Path, at: Option<[f64; 2]>, los: Option<Vec<[f64; 3]>>) -> Result<()> {
    let s = relief::scene::Scene::load(scene)?;
    let terrain = s.load_terrain()?;
    if at.is_none() && los.is_none() {
        bail!("give --at X,Y and/or --los X1,Y1,Z1 X2,Y2,Z2");
    }
    // A database scene is queried at the database's full resolution, through its tile cache.
    let full = relief::cpu::database::FullResolution::open(&s.desc.terrain, &s.base_dir)?;
    if let Some([x, y]) = at {
        let p = glam::DVec3::new(x, y, 0.0);
        let Some(q) = relief::cpu::terrain_point_below(&terrain, p) else {
            bail!("({x}, {y}) is outside the height grid");
        };
        match full.as_ref().map(|f| f.height_at(&terrain, p)).transpose()? {
            Some(Some(h)) => println!(
                "terrain at ({x}, {y}): z = {:.3} m (database level {}, {:.3}″ samples; the scene renders {:.3} m there)",
                h.height,
                h.level,
                h.spacing * 3600.0,
                q.z
            ),
            Some(None) => bail!("({x}, {y}) is off the database"),
            None => println!("terrain at ({x}, {y}): z = {:.3} m", q.z),
        }
    }
    if let Some(pts) = los {
        let (a, b) = (glam::DVec3::from(pts[0]), glam::DVec3::from(pts[1]));
        let clear = match &full {
            Some(f) => f.line_of_sight(&terrain, a, b)?.0,
            None => relief::cpu::line_of_sight(&terrain, a, b),
        };
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
    Ok(())
}
