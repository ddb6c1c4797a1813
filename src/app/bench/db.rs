//! `relief bench db`: the terrain database's costs. Build throughput on a synthetic mosaic;
//! the single-tile scene rendered through the database against the in-memory `.hgt`; and a
//! scripted flight over a mosaic through the pager (frame cost crossing tiles against
//! hovering, pool and host memory, frames with a wanted tile missing).
//!
//! The flight's frame cost is the pager's update, copying its uploads into the GPU pool
//! (`gpu::terrain_pool`) and the frame rendered through the pool (`TerrainRenderer::new_paged`),
//! submit to GPU idle.

use super::table::{Figures, Row, RunInfo, Table};
use super::terrain::product_settings;
use super::timing::{scene_at_size, FrameSetup};
use crate::db::{self, Database};
use crate::gpu::{Gpu, Stage, TerrainRenderer};
use crate::{Error, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
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
    /// The hover view rendered with the whole window in memory (ms, median).
    pub resident_ms: f64,
    /// The same view through the pool after the flight (ms, median, timed the same way).
    pub paged_ms: f64,
    pub pool_bytes: u64,
    pub max_staged_bytes: u64,
    pub db_cache_bytes: u64,
    pub max_rss_kib: u64,
    /// Peak resident set of the whole run (VmHWM; the window in host memory included).
    pub vm_hwm_kib: u64,
    pub frames_missing: u64,
    pub uploads: u64,
    /// The flight's window (samples, degrees).
    pub window: String,
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

/// The process's peak resident set (VmHWM), KiB.
fn hwm_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            let l = s.lines().find(|l| l.starts_with("VmHWM:"))?.to_string();
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
    let flight = fly(gpu, dir, scene_path, &mosaic, size, a)?;
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

/// The hover view `f` with the scene's window loaded whole and uploaded (median ms), where the
/// window's heights fit one storage binding (a 16385² window's 1 GiB does not on lavapipe or
/// GL: NaN, not measured).
fn hover_in_memory(f: &FrameSetup, scene: &crate::scene::Scene) -> Result<f64> {
    let (gpu, field) = (f.gpu, &f.terrain.field);
    let heights = (field.width * field.height * 4) as u64;
    if heights > gpu.limits.max_storage_buffer_binding_size {
        log::info!(
            "window of {heights} bytes of heights: over the adapter's storage binding, no in-memory comparison"
        );
        return Ok(f64::NAN);
    }
    let whole = crate::world::World::load(scene)?;
    let terrain = &whole.terrain;
    let mut full = TerrainRenderer::new(gpu, terrain)?;
    let f = FrameSetup { terrain, ..*f };
    f.capture(&mut full)?;
    f.median_ms(&mut full, Stage::Shade)
}

/// The largest window of the finest level that lies within the mosaic's extent, starts on a
/// multiple of its own side (the paged window's alignment) and has at most
/// `terrain::MAX_SIDE` samples a side: `[lat_s, lon_w, lat_n, lon_e]`.
fn aligned_window(h: &db::format::Header) -> Result<[f64; 4]> {
    let fine = h.levels[h.levels.len() - 1];
    let d = fine.per_degree;
    let e = h.extent;
    let lo = |deg: f64, base: f64| ((deg + base) * d - 1e-6).ceil() as i64;
    let hi = |deg: f64, base: f64| ((deg + base) * d + 1e-6).floor() as i64;
    let (i_lo, i_hi) = (lo(e.lon_min, 180.0), hi(e.lon_max, 180.0));
    let (j_lo, j_hi) = (lo(e.lat_min, 90.0), hi(e.lat_max, 90.0));
    for k in (4..=14).rev() {
        let side = 1i64 << k;
        // A window renders at most MAX_SIDE samples a side (side + 1 samples for side cells).
        if side + 1 > crate::terrain::MAX_SIDE as i64 {
            continue;
        }
        let (i0, j0) = (
            (i_lo + side - 1) / side * side,
            (j_lo + side - 1) / side * side,
        );
        if i0 + side <= i_hi && j0 + side <= j_hi {
            return Ok([
                fine.lat(j0),
                fine.lon(i0),
                fine.lat(j0 + side),
                fine.lon(i0 + side),
            ]);
        }
    }
    Err(Error::invalid(
        "--mosaic",
        "no aligned window of at least 16 cells fits the mosaic's finest level",
    ))
}

/// The flight's window as a scene over `mosaic` (flat base plane) and the scene `base`'s sun,
/// sky and fog.
fn flight_scene(base: &Path, mosaic: &Path, window: [f64; 4], out: &Path) -> Result<()> {
    let text = crate::fileio::read_to_string(base, 1 << 20)?;
    let mut v: toml::Table =
        toml::from_str(&text).map_err(|e| Error::format(base, e.to_string()))?;
    let mut t = toml::Table::new();
    t.insert("database".into(), mosaic.display().to_string().into());
    t.insert("curved".into(), false.into());
    let w: Vec<toml::Value> = window.iter().map(|&x| x.into()).collect();
    t.insert("window".into(), w.into());
    v.insert("terrain".into(), t.into());
    v.remove("path");
    let body = toml::to_string(&v).map_err(|e| Error::format(out, e.to_string()))?;
    std::fs::write(out, body).map_err(|e| Error::io(out, e))
}

/// The scripted flight, rendered through the paged pool (`--terrain-memory`): the largest
/// aligned window of the mosaic's finest level, `flight_frames / 2` frames crossing east at
/// `speed` (at 60 frames a second of flight time) 300 m above the window's highest point,
/// looking ahead and down, then as many hovering. A frame's cost is the pager's update, the
/// uploads into the pool and the rendered frame (full shading, the scene's settings), submit
/// to GPU idle; every frame renders what is resident then (no waiting). One frame before the
/// flight warms the pipelines up (not timed).
fn fly(
    gpu: &Gpu,
    dir: &Path,
    scene_path: &Path,
    mosaic: &Path,
    size: (u32, u32),
    a: &DbBenchArgs,
) -> Result<DbBench> {
    let mosaic = &std::fs::canonicalize(mosaic).map_err(|e| Error::io(mosaic, e))?;
    let h = Database::open(mosaic)?.header().clone();
    let window = aligned_window(&h)?;
    let flight_toml = dir.join("flight.toml");
    flight_scene(scene_path, mosaic, window, &flight_toml)?;
    let scene = scene_at_size(&flight_toml, size)?;
    // The flight holds its window hollow, as `render --terrain-memory` does (the host figures
    // are the paged run's); the in-memory comparison loads it whole afterwards.
    let world = crate::world::World::load_as(&scene, true)?;
    let terrain = &world.terrain;
    let (mut r, mut paging) = crate::app::paged::renderer(gpu, &scene, &world, a.terrain_memory)?;
    let s = product_settings(&scene);
    let geo = terrain
        .field
        .geo
        .expect("a database window is georeferenced");
    let spacing = terrain.frame.spacing;
    let mut grid = glam::DVec3::new(
        0.1 * terrain.cells()[0] as f64,
        0.5 * terrain.cells()[1] as f64,
        terrain.max_height as f64 + 300.0,
    );
    let mut pose = crate::scene::Pose {
        position: glam::DVec3::ZERO,
        heading: 90.0,
        pitch: -10.0,
        roll: 0.0,
        fov: 60.0,
    };
    let half = (a.flight_frames / 2).max(1);
    let (mut crossing, mut hover) = (Vec::new(), Vec::new());
    let (mut max_staged, mut max_rss, mut uploads, mut frames_missing) = (0u64, 0u64, 0u64, 0);
    let mut cam = crate::scene::Camera::new(pose, size.0, size.1);
    // One frame at the start, not timed: the pipelines are compiled on first use (lavapipe:
    // 0.1–0.3 s each), which no frame of a running image generator pays.
    pose.position = terrain.frame.grid_to_world(grid);
    let warm = crate::scene::Camera::new(pose, size.0, size.1);
    paging.step(gpu, &mut r, terrain, &warm)?;
    r.render(gpu, terrain, &scene.desc, &warm, &s, Stage::Shade)?;
    gpu.wait()?;
    for frame in 0..2 * half {
        if frame < half {
            grid.x += a.speed / 60.0 / spacing[0];
        }
        pose.position = terrain.frame.grid_to_world(grid);
        cam = crate::scene::Camera::new(pose, size.0, size.1);
        let t = Instant::now();
        let st = paging.step(gpu, &mut r, terrain, &cam)?;
        r.render(gpu, terrain, &scene.desc, &cam, &s, Stage::Shade)?;
        gpu.wait()?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        if frame < half {
            &mut crossing
        } else {
            &mut hover
        }
        .push(ms);
        max_staged = max_staged.max(st.staged_bytes);
        uploads += st.uploads as u64;
        frames_missing = st.frames_missing;
        max_rss = max_rss.max(rss_kib());
    }
    let pool_bytes = r.pool().map_or(0, |p| p.size().1);
    // The hover view through the pool as it stands, timed as the in-memory one is (pairs of
    // frames, median), then with the whole window in memory (tile pre-pass on in both, as a
    // scene renders).
    let f = FrameSetup {
        gpu,
        terrain,
        desc: &scene.desc,
        cam: &cam,
        settings: &s,
        frames: 20,
    };
    let paged_ms = f.median_ms(&mut r, Stage::Shade)?;
    drop(r);
    let resident_ms = hover_in_memory(&f, &scene)?;
    log::info!(
        "flight window {window:?} of {}: {}x{} samples, lon0 {:.4}",
        mosaic.display(),
        terrain.field.width,
        terrain.field.height,
        geo.lon0
    );
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
        resident_ms,
        paged_ms,
        pool_bytes,
        max_staged_bytes: max_staged,
        db_cache_bytes: 0,
        max_rss_kib: max_rss,
        vm_hwm_kib: hwm_kib(),
        frames_missing,
        uploads,
        window: format!(
            "{}x{} samples, {window:?}",
            terrain.field.width, terrain.field.height
        ),
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
                Row::new("hover, through the pool", ms(self.paged_ms)),
                Row::new("hover, window in memory", ms(self.resident_ms)),
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
                .with("vm_hwm_kib", self.vm_hwm_kib as f64)
                .with("resident_ms", self.resident_ms)
                .with("paged_ms", self.paged_ms)
                .with("paged_vs_memory", self.paged_ms / self.resident_ms)
                .with("frames_missing", self.frames_missing as f64)
                .with("uploads", self.uploads as f64),
            notes: vec![
                format!("build: {} samples in {:.2} s (synthetic mosaic)", self.build_samples, self.build_seconds),
                format!("flight over {} (window {}): frame cost = pager update + uploads into the GPU pool + the frame rendered through the pool (submit to GPU idle)", self.mosaic, self.window),
            ],
        }
    }
}
