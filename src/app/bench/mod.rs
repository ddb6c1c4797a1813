//! `relief bench MODE [SCENE]`: measurements on the adapter relief renders on, one mode per
//! subcommand, every mode making the same [`BenchReport`] (one JSON schema, one printer).
//!
//! * [`terrain`]: pyramid traversal (± tile pre-pass) vs a fixed-step march, depth error vs
//!   the CPU reference, optional ray dump;
//! * [`primary`]: the primary rays of the product configuration alone;
//! * [`freeforms`]: the scene's free forms vs terrain only, then generated ones;
//! * [`volume`]: the density-volume pass, skipping and early termination vs plain marching;
//! * [`voxels`]: voxel models vs terrain only, and the paper's model sizes;
//! * [`display`]: a display channel's table regeneration and direct frame vs pinhole;
//! * [`antialias`]: edge anti-aliasing: frame time against none, extra rays, error and
//!   temporal excess against the 16-rays reference;
//! * [`clouds`]: the frame with the scene's cloud layers against the same frame without;
//! * [`cigi`]: the CIGI IG under an in-process host: query rates, latency, frame period;
//! * [`soak`]: a long run watching memory, wgpu objects and frame times;
//! * [`report`]: the report, its JSON and its printed form;
//! * [`table`]: what every report has: the run, rows of figures, summary, notes;
//! * [`timing`]: the scene at the benchmark's size, frame timing.

pub mod antialias;
pub mod cigi;
pub mod clouds;
pub mod db;
pub mod display;
pub mod freeforms;
pub mod primary;
pub mod report;
pub mod soak;
pub mod table;
pub mod terrain;
pub mod timing;
pub mod volume;
pub mod voxels;

pub use report::{BenchReport, Details};
pub use table::{Figures, Row, RunInfo, Table};

use super::args::parse_size;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// The options every mode has.
#[derive(Clone, Debug, clap::Args)]
pub struct BenchArgs {
    /// Scene file (default: the mode's demo scene in terrains/).
    pub scene: Option<PathBuf>,
    /// Render size WxH.
    #[arg(long, value_parser = parse_size, default_value = "1280x720")]
    pub size: (u32, u32),
    /// Timed frames per configuration (submitted in pairs as a frame loop does; the median
    /// over the pairs is reported; the freeforms headline ratio and the antialias ratios
    /// alternate single frames with their baseline's instead). Default 10; 600 for soak.
    #[arg(long)]
    pub frames: Option<u32>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Footprint level of detail: on, off or a scale factor (overrides the scene's
    /// `[render] lod`; `terrain` and `primary`).
    #[arg(long, value_name = "on|off|SCALE", value_parser = crate::scene::Lod::parse)]
    pub lod: Option<crate::scene::Lod>,
}

/// The benchmark modes.
#[derive(Clone, Debug, clap::Subcommand)]
pub enum BenchCommand {
    /// Pyramid traversal (with and without the tile pre-pass) against a fixed-step march on
    /// the same rays, and the frame with shadows (default scene: terrains/alps.toml).
    Terrain {
        #[command(flatten)]
        args: BenchArgs,
        /// Also write the fixed rays and the pyramid depths (raw little-endian f32) to this directory.
        #[arg(long)]
        dump_rays: Option<PathBuf>,
    },
    /// Time only the primary rays of the product configuration (pyramid + tile pre-pass):
    /// for scripts that alternate relief with another renderer (default scene:
    /// terrains/alps.toml).
    Primary {
        #[command(flatten)]
        args: BenchArgs,
    },
    /// Free forms: the scene's objects vs terrain only, then 10/100/1000 generated objects
    /// (default scene: terrains/airfield.toml).
    Freeforms {
        #[command(flatten)]
        args: BenchArgs,
    },
    /// The density-volume pass (the scene's first volume): plain marching vs empty-space
    /// skipping and early termination (default scene: terrains/brain.toml).
    Volume {
        #[command(flatten)]
        args: BenchArgs,
    },
    /// Voxel models: the scene's `[[voxels]]` one at a time vs terrain only, and the
    /// simplified-voxel paper's model sizes (default scene: terrains/tree.toml).
    Voxels {
        #[command(flatten)]
        args: BenchArgs,
    },
    /// A display config's channel (resized to --size, same lens): ray-table regeneration and
    /// direct-mode frame vs the pinhole frame (default scene: terrains/alps.toml).
    Display {
        #[command(flatten)]
        args: BenchArgs,
        /// The display config (TOML).
        #[arg(long)]
        display: PathBuf,
        /// Channel (projector) of the display config.
        #[arg(long, default_value_t = 0)]
        channel: usize,
    },
    /// Soak test: render --frames frames (default 600) as `render` does, without writing
    /// files; report RSS per frame and its slope over frames 100-500, wgpu's live objects at
    /// frames 100 and 500, and frame-time p50/p99/max (default scene: terrains/alps.toml).
    Soak {
        #[command(flatten)]
        args: BenchArgs,
        /// Edge anti-aliasing in every frame: off, edges, 4, 8, 16 or reference (overrides
        /// the scene's `[render] antialias`).
        #[arg(long, value_name = "off|edges|N|reference", value_parser = crate::scene::AntialiasOption::parse)]
        antialias: Option<crate::scene::AntialiasOption>,
    },
    /// The CIGI IG (`relief serve`'s loop) under a host on another thread of the same process over
    /// loopback: HAT/HOT and LOS responses a second (100 and 1,000 queries per host frame), the CPU
    /// oracle's own rates, host-datagram-to-Start-of-Frame latency and the Start of Frame
    /// period, quiet and under 10,000 malformed datagrams a second; --frames host frames per
    /// phase (default 240, at 60 Hz) (default scene: terrains/alps.toml).
    Cigi {
        #[command(flatten)]
        args: BenchArgs,
    },
    /// Edge anti-aliasing: frame time with 4, 8 and 16 rays per edge pixel and with `edges`
    /// (4 to 16 by contrast) against none, the extra rays, and p99 error and temporal excess
    /// against 16 rays per pixel on --frames frames in motion at 320x180 (default scene:
    /// terrains/alps.toml).
    Antialias {
        #[command(flatten)]
        args: BenchArgs,
    },
    /// Cloud layers: the frame with the scene's `[[clouds]]` against the same frame without
    /// them, frames alternated (default scene: terrains/overcast.toml).
    Clouds {
        #[command(flatten)]
        args: BenchArgs,
    },
    /// The terrain database: build throughput (synthetic mosaic), the scene through a database
    /// against its .hgt, and a scripted flight through the pager.
    Db {
        #[command(flatten)]
        args: BenchArgs,
        #[command(flatten)]
        db: db::DbBenchArgs,
    },
}

impl BenchCommand {
    /// The options every mode has.
    pub fn args(&self) -> &BenchArgs {
        match self {
            BenchCommand::Terrain { args, .. }
            | BenchCommand::Primary { args }
            | BenchCommand::Freeforms { args }
            | BenchCommand::Volume { args }
            | BenchCommand::Voxels { args }
            | BenchCommand::Display { args, .. }
            | BenchCommand::Soak { args, .. }
            | BenchCommand::Cigi { args }
            | BenchCommand::Antialias { args }
            | BenchCommand::Clouds { args }
            | BenchCommand::Db { args, .. } => args,
        }
    }

    /// The demo scene the mode measures when none is given.
    pub fn default_scene(&self) -> &'static str {
        match self {
            BenchCommand::Freeforms { .. } => "terrains/airfield.toml",
            BenchCommand::Volume { .. } => "terrains/brain.toml",
            BenchCommand::Voxels { .. } => "terrains/tree.toml",
            BenchCommand::Clouds { .. } => "terrains/overcast.toml",
            _ => super::scenes::DEFAULT_SCENE,
        }
    }

    /// The scene to measure: the one given, else the mode's demo scene.
    pub fn scene(&self) -> Result<PathBuf> {
        match &self.args().scene {
            Some(s) => Ok(s.clone()),
            None => super::scenes::find_shipped(self.default_scene()),
        }
    }

    /// Timed frames: as given, else 10 (600 for soak, 240 host frames a phase for cigi).
    pub fn frames(&self) -> Result<u32> {
        let default = match self {
            BenchCommand::Soak { .. } => 600,
            BenchCommand::Cigi { .. } => 240,
            _ => 10,
        };
        match self.args().frames.unwrap_or(default) {
            0 => Err(Error::invalid("--frames", "must be at least 1")),
            n => Ok(n),
        }
    }

    /// What an error of the run is about, e.g. "benchmarking terrains/alps.toml".
    pub fn context(&self, scene: &Path) -> String {
        match self {
            BenchCommand::Soak { .. } => format!("soak test of {}", scene.display()),
            BenchCommand::Display { display, .. } => format!("benchmarking {}", display.display()),
            _ => format!("benchmarking {}", scene.display()),
        }
    }

    /// Runs the mode on `scene`.
    pub fn run(&self, scene: &Path) -> Result<BenchReport> {
        let (size, frames) = (self.args().size, self.frames()?);
        let (run, details) = match self {
            BenchCommand::Terrain { dump_rays, .. } => {
                let (run, d) =
                    terrain::run(scene, size, frames, self.args().lod, dump_rays.as_deref())?;
                (run, Details::Terrain(d))
            }
            BenchCommand::Primary { .. } => {
                let (run, d) = primary::run(scene, size, frames, self.args().lod)?;
                (run, Details::Primary(d))
            }
            BenchCommand::Freeforms { .. } => {
                let (run, d) = freeforms::run(scene, size, frames)?;
                (run, Details::FreeForms(d))
            }
            BenchCommand::Volume { .. } => {
                let (run, d) = volume::run(scene, size, frames)?;
                (run, Details::Volume(d))
            }
            BenchCommand::Voxels { .. } => {
                let (run, d) = voxels::run(scene, size, frames)?;
                (run, Details::Voxels(d))
            }
            BenchCommand::Display {
                display, channel, ..
            } => {
                let (run, d) = display::run(scene, display, *channel, size, frames)?;
                (run, Details::Display(d))
            }
            BenchCommand::Soak { antialias, .. } => {
                let (run, d) = soak::run(scene, size, frames, *antialias)?;
                (run, Details::Soak(d))
            }
            BenchCommand::Cigi { .. } => {
                let (run, d) = cigi::run(scene, size, frames)?;
                (run, Details::Cigi(d))
            }
            BenchCommand::Antialias { .. } => {
                let (run, d) = antialias::run(scene, size, frames)?;
                (run, Details::Antialias(d))
            }
            BenchCommand::Clouds { .. } => {
                let (run, d) = clouds::run(scene, size, frames)?;
                (run, Details::Clouds(d))
            }
            BenchCommand::Db { db: a, .. } => {
                let (run, d) = db::run(scene, size, frames, a)?;
                (run, Details::Db(d))
            }
        };
        Ok(BenchReport::new(run, details))
    }
}
