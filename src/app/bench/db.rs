//! `relief bench db`: the terrain database's costs. Build throughput on a synthetic mosaic;
//! the single-tile scene rendered through the database against the in-memory `.hgt`; and a
//! scripted flight over a mosaic through the pager (frame cost crossing tiles against
//! hovering, pool and host memory, frames with a wanted tile missing).
//!
//! The flight's frame cost is the pager's update plus copying its uploads into the GPU pool
//! (`gpu::terrain_pool`) and waiting for the queue: the traversal does not read the pool yet,
//! so this is the paging overhead a frame pays, not a rendered frame.

use super::table::{Figures, Row, RunInfo, Table};
use super::terrain::product_settings;
use super::timing::{scene_at_size, FrameSetup};
use crate::db::pager::{Pager, PagerOptions, View};
use crate::db::{self, Database};
use crate::gpu::terrain_pool::TerrainPool;
use crate::gpu::{Gpu, Stage, TerrainRenderer};
use crate::{Error, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Options of `relief bench db` beyond the shared ones.
#[derive(Clone, Debug, clap::Args)]
pub struct DbBenchArgs {
    /// Mosaic to fly over (a database); default: the synthetic mosaic the build figure makes.
    #[arg(long)]
    pub mosaic: Option<PathBuf>,
    /// Synthetic mosaic for the build figure: source tiles (WxH) and samples a side.
    #[arg(long, default_value = "4x4")]
    pub synth_tiles: String,
    #[arg(long, default_value_t = 257)]
    pub synth_samples: u32,
    /// The pool's size in MB (`--terrain-memory`).
    #[arg(long, default_value_t = 256)]
    pub terrain_memory: u64,
    /// Frames of the flight (half crossing, half hovering).
    #[arg(long, default_value_t = 600)]
    pub flight_frames: u32,
    /// Ground speed of the flight, metres per second (at 60 frames a second).
    #[arg(long, default_value_t = 250.0)]
    pub speed: f64,
}

/// What `relief bench db` measures.
#[derive(Clone, Debug, Serialize)]
pub struct DbBench {
    pub build_samples: u64,
    pub build_seconds: f64,
    pub build_samples_per_second: f64,
    /// Median frame of the scene through the `.hgt` and through the database (ms).
    pub hgt_ms: f64,
    pub database_ms: f64,
    pub crossing_p50_ms: f64,
    pub crossing_p99_ms: f64,
    pub hover_p50_ms: f64,
    pub hover_p99_ms: f64,
    pub pool_bytes: u64,
    pub max_staged_bytes: u64,
    pub db_cache_bytes: u64,
    pub max_rss_kib: u64,
    pub frames_missing: u64,
    pub uploads: u64,
    pub mosaic: String,
}

fn rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            let l = s.lines().find(|l| l.starts_with("VmRSS:"))?.to_string();
            l.split_whitespace().nth(1)?.parse().ok()
        })
        .unwrap_or(0)
}

fn pct(mut v: Vec<f64>, p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(((v.len() as f64 - 1.0) * p).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

fn parse_tiles(s: &str) -> Result<[u32; 2]> {
    let bad = || Error::invalid("--synth-tiles", format!("`{s}`: give WxH, e.g. 4x4"));
    let (a, b) = s.split_once('x').ok_or_else(bad)?;
    Ok([a.parse().map_err(|_| bad())?, b.parse().map_err(|_| bad())?])
}

/// Median frame (full shading) of `scene_path` at `size`.
fn frame_ms(gpu: &Gpu, scene_path: &Path, size: (u32, u32), frames: u32) -> Result<f64> {
    let scene = scene_at_size(scene_path, size)?;
    let terrain = scene.load_terrain()?;
    let mut renderer = TerrainRenderer::new(gpu, &terrain)?;
    let cam = scene.camera(0, &terrain);
    let s = product_settings(&scene);
    let f = FrameSetup {
        gpu,
        terrain: &terrain,
        desc: &scene.desc,
        cam: &cam,
        settings: &s,
        frames,
    };
    f.capture(&mut renderer)?;
    f.median_ms(&mut renderer, Stage::Shade)
}

/// The scene with its `.hgt` replaced by `database` on the flat base plane.
fn database_scene(scene_path: &Path, database: &Path, out: &Path) -> Result<()> {
    let text = crate::fileio::read_to_string(scene_path, 1 << 20)?;
    let mut v: toml::Table =
        toml::from_str(&text).map_err(|e| Error::format(scene_path, e.to_string()))?;
    let mut t = toml::Table::new();
    t.insert("database".into(), database.display().to_string().into());
    t.insert("curved".into(), false.into());
    v.insert("terrain".into(), t.into());
    let body = toml::to_string(&v).map_err(|e| Error::format(out, e.to_string()))?;
    std::fs::write(out, body).map_err(|e| Error::io(out, e))
}

/// Runs the three measurements.
pub fn run(
    scene_path: &Path,
    size: (u32, u32),
    frames: u32,
    a: &DbBenchArgs,
) -> Result<(RunInfo, DbBench)> {
    let gpu = crate::app::gpu_options::open()?;
    let dir = std::env::temp_dir().join(format!("relief-bench-db-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let result = measure(&gpu, &dir, scene_path, size, frames, a);
    let _ = std::fs::remove_dir_all(&dir);
    Ok((RunInfo::new(&gpu, scene_path, size, frames), result?))
}

fn measure(
    gpu: &Gpu,
    dir: &Path,
    scene_path: &Path,
    size: (u32, u32),
    frames: u32,
    a: &DbBenchArgs,
) -> Result<DbBench> {
    // Build throughput.
    let synth = dir.join("synth.reliefdb");
    let opts = db::SynthOptions {
        tiles: parse_tiles(&a.synth_tiles)?,
        samples: a.synth_samples,
        ..db::SynthOptions::default()
    };
    let t = Instant::now();
    let built = db::synth(&synth, &opts, &|_, _| {})?;
    let build_seconds = t.elapsed().as_secs_f64();
    // The scene through the database against the .hgt.
    let scene = crate::scene::Scene::load(scene_path)?;
    let hgt = scene
        .desc
        .terrain
        .source
        .as_ref()
        .map(|s| scene_path.parent().unwrap_or(Path::new(".")).join(s))
        .ok_or_else(|| {
            Error::invalid(
                "bench db",
                "the scene's terrain must be a height file (`source`)",
            )
        })?;
    let alps_db = dir.join("scene.reliefdb");
    db::build(&alps_db, &[hgt], &db::BuildOptions::default(), &|_, _| {})?;
    let db_scene = dir.join("scene.toml");
    database_scene(scene_path, &alps_db, &db_scene)?;
    let hgt_ms = frame_ms(gpu, scene_path, size, frames)?;
    let database_ms = frame_ms(gpu, &db_scene, size, frames)?;
    // The flight.
    let mosaic = a.mosaic.clone().unwrap_or(synth);
    let flight = fly(gpu, &mosaic, size, a)?;
    Ok(DbBench {
        build_samples: built.samples,
        build_seconds,
        build_samples_per_second: built.samples as f64 / build_seconds,
        hgt_ms,
        database_ms,
        mosaic: mosaic.display().to_string(),
        ..flight
    })
}

/// The scripted flight: `flight_frames / 2` frames crossing east at `speed` (60 frames a
/// second) 300 m above the mosaic's highest point, looking ahead and down, then as many
/// hovering, paced at 60 frames a second (the frame cost excludes the wait).
fn fly(gpu: &Gpu, mosaic: &Path, size: (u32, u32), a: &DbBenchArgs) -> Result<DbBench> {
    let mut database = Database::open(mosaic)?;
    database.set_cache_bytes(64 << 20);
    let store = Arc::new(database);
    let h = store.header().clone();
    let opts = PagerOptions {
        pool_bytes: a.terrain_memory << 20,
        ..PagerOptions::default()
    };
    let (mut pager, first) = Pager::new(store.clone(), opts)?;
    let (slots, slot_bytes) = pager.slots();
    let n = store.tile_cells();
    let pool = TerrainPool::new(gpu, pager.page_table(), n, slots)?;
    pool.apply(gpu, &first, pager.page_table());
    gpu.wait()?;
    let e = h.extent;
    let lat = 0.5 * (e.lat_min + e.lat_max);
    let (mx, _) = crate::terrain::heightfield::metres_per_degree(lat);
    let mut view = View {
        lon: e.lon_min + 0.1 * (e.lon_max - e.lon_min),
        lat,
        height: h.heights[1] as f64 + 300.0,
        heading: 90.0,
        pitch: -10.0,
        fov: 60.0,
        width: size.0,
        height_px: size.1,
    };
    let half = (a.flight_frames / 2).max(1);
    let (mut crossing, mut hover) = (Vec::new(), Vec::new());
    let (mut max_staged, mut max_rss, mut uploads) = (0u64, 0u64, 0u64);
    let mut frames_missing = 0;
    for frame in 0..2 * half {
        let t = Instant::now();
        if frame < half {
            view.lon += a.speed / 60.0 / mx;
        }
        let (up, st) = pager.update(&view)?;
        pool.apply(gpu, &up, pager.page_table());
        gpu.wait()?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        if frame < half {
            &mut crossing
        } else {
            &mut hover
        }
        .push(ms);
        max_staged = max_staged.max(st.staged_bytes);
        uploads += up.len() as u64;
        frames_missing = st.frames_missing;
        max_rss = max_rss.max(rss_kib());
        // Frames paced at 60 a second, as a frame loop's present would.
        if let Some(rest) = std::time::Duration::from_secs_f64(1.0 / 60.0).checked_sub(t.elapsed())
        {
            std::thread::sleep(rest);
        }
    }
    Ok(DbBench {
        build_samples: 0,
        build_seconds: 0.0,
        build_samples_per_second: 0.0,
        hgt_ms: 0.0,
        database_ms: 0.0,
        crossing_p50_ms: pct(crossing.clone(), 0.5),
        crossing_p99_ms: pct(crossing, 0.99),
        hover_p50_ms: pct(hover.clone(), 0.5),
        hover_p99_ms: pct(hover, 0.99),
        pool_bytes: slots as u64 * slot_bytes,
        max_staged_bytes: max_staged,
        db_cache_bytes: store.cached_bytes(),
        max_rss_kib: max_rss,
        frames_missing,
        uploads,
        mosaic: String::new(),
    })
}

impl DbBench {
    /// Rows: the scene through `.hgt` and database; the flight crossing and hovering.
    pub fn table(&self) -> Table {
        let ms = |v: f64| Figures::default().with("frame_ms", v);
        Table {
            rows: vec![
                Row::new("scene .hgt", ms(self.hgt_ms)),
                Row::new("scene database", ms(self.database_ms)),
                Row::new("flight crossing p50", ms(self.crossing_p50_ms)),
                Row::new("flight crossing p99", ms(self.crossing_p99_ms)),
                Row::new("flight hover p50", ms(self.hover_p50_ms)),
                Row::new("flight hover p99", ms(self.hover_p99_ms)),
            ],
            summary: Figures::default()
                .with("build_samples_per_second", self.build_samples_per_second)
                .with("database_vs_hgt", self.database_ms / self.hgt_ms)
                .with("crossing_vs_hover_p50", self.crossing_p50_ms / self.hover_p50_ms)
                .with("crossing_vs_hover_p99", self.crossing_p99_ms / self.hover_p99_ms)
                .with("pool_bytes", self.pool_bytes as f64)
                .with("max_staged_bytes", self.max_staged_bytes as f64)
                .with("db_cache_bytes", self.db_cache_bytes as f64)
                .with("max_rss_kib", self.max_rss_kib as f64)
                .with("frames_missing", self.frames_missing as f64)
                .with("uploads", self.uploads as f64),
            notes: vec![
                format!("build: {} samples in {:.2} s (synthetic mosaic)", self.build_samples, self.build_seconds),
                format!("flight over {}: frame cost = pager update + uploads into the GPU pool + queue wait; the traversal does not read the pool yet", self.mosaic),
            ],
        }
    }
}
