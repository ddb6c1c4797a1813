//! `relief db build` and `relief db info`: the terrain database from the command line.

use crate::db::{self, Database};
use crate::fileio::human_bytes;
use crate::terrain::heightfield::metres_per_degree;
use crate::Result;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// `relief db ACTION`.
#[derive(Clone, Debug, clap::Subcommand)]
pub enum DbAction {
    /// Compile DEMs (SRTM .hgt tiles, GeoTIFFs in degrees; mixed resolutions, the finer wins
    /// where they overlap; voids where no source has data filled as the loaders fill them)
    /// into one tiled multi-resolution database file, written atomically.
    Build {
        /// The database file to write (e.g. alps.reliefdb).
        out: PathBuf,
        /// Source DEMs; where two of equal resolution overlap, the one given first wins.
        #[arg(required = true)]
        sources: Vec<PathBuf>,
        /// Cells per tile side: a power of two in 16..=4096.
        #[arg(long, default_value_t = db::format::DEFAULT_TILE)]
        tile: u32,
    },
    /// Write a synthetic mosaic (procedural ridged fBm, deterministic for a seed) as a
    /// database, without source files: for tests and benchmarks at any size.
    Synth {
        /// The database file to write.
        out: PathBuf,
        /// Source tiles, longitude x latitude (e.g. 16x16).
        #[arg(long, default_value = "16x16", value_parser = parse_tiles)]
        tiles: [u32; 2],
        /// Samples per source tile side (neighbours share their edges, as SRTM's 1201 or 3601).
        #[arg(long, default_value_t = 257)]
        samples: u32,
        /// Latitude of the south-west corner, degrees.
        #[arg(long, default_value_t = 46.0, allow_hyphen_values = true)]
        lat: f64,
        /// Longitude of the south-west corner, degrees.
        #[arg(long, default_value_t = 7.0, allow_hyphen_values = true)]
        lon: f64,
        /// Sample step in arc-seconds (default: one degree per source tile).
        #[arg(long)]
        arcsec: Option<f64>,
        /// Noise seed.
        #[arg(long, default_value_t = 1)]
        seed: u32,
        /// Cells per database tile side: a power of two in 16..=4096.
        #[arg(long, default_value_t = db::format::DEFAULT_TILE)]
        tile: u32,
    },
    /// Print a database's extent, levels, tile counts, size on disk and sources.
    Info {
        db: PathBuf,
        /// Also read every tile and check its checksum.
        #[arg(long)]
        verify: bool,
    },
}

/// Runs `action`; returns what to print.
pub fn run(action: &DbAction) -> Result<String> {
    match action {
        DbAction::Build { out, sources, tile } => build(out, sources, *tile),
        DbAction::Synth {
            out,
            tiles,
            samples,
            lat,
            lon,
            arcsec,
            seed,
            tile,
        } => synth(
            out,
            &db::SynthOptions {
                tiles: *tiles,
                samples: *samples,
                lat: *lat,
                lon: *lon,
                arcsec: *arcsec,
                seed: *seed,
                tile: *tile,
                ..db::SynthOptions::default()
            },
        ),
        DbAction::Info { db, verify } => {
            let d = Database::open(db)?;
            let mut text = info(&d);
            if *verify {
                let bar = progress_bar("verifying");
                d.verify(&|done, total| {
                    bar.set_length(total);
                    bar.set_position(done);
                })?;
                bar.finish_and_clear();
                let _ = writeln!(
                    text,
                    "verified: every tile's checksum and contents are sound"
                );
            }
            Ok(text)
        }
    }
}

/// A progress bar on stderr (drawn only when stderr is a terminal).
fn progress_bar(what: &str) -> indicatif::ProgressBar {
    let bar =
        indicatif::ProgressBar::with_draw_target(Some(0), indicatif::ProgressDrawTarget::stderr());
    if let Ok(style) = indicatif::ProgressStyle::with_template(&format!(
        "{what} {{wide_bar}} {{pos}}/{{len}} tiles, {{elapsed}} (eta {{eta}})"
    )) {
        bar.set_style(style);
    }
    bar
}

fn build(out: &Path, sources: &[PathBuf], tile: u32) -> Result<String> {
    let t = std::time::Instant::now();
    let bar = progress_bar("building");
    let report = db::build(out, sources, &db::BuildOptions { tile }, &|done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    let r = report?;
    let secs = t.elapsed().as_secs_f64();
    Ok(format!(
        "wrote {}: {} levels, {} tiles, {} samples, {} ({:.2}x the {} of {} source file(s)) in {secs:.2} s ({:.1} M samples/s)",
        out.display(),
        r.levels,
        r.tiles,
        r.samples,
        human_bytes(r.bytes),
        r.bytes as f64 / r.source_bytes.max(1) as f64,
        human_bytes(r.source_bytes),
        sources.len(),
        r.samples as f64 / secs / 1e6
    ))
}

/// `16x16` → `[16, 16]`.
fn parse_tiles(s: &str) -> std::result::Result<[u32; 2], String> {
    let bad = || format!("`{s}`: give the tiles as WxH, e.g. 16x16");
    let (a, b) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok([
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    ])
}

fn synth(out: &Path, opts: &db::SynthOptions) -> Result<String> {
    let t = std::time::Instant::now();
    let bar = progress_bar("synthesising");
    let report = db::synth(out, opts, &|done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    let r = report?;
    let secs = t.elapsed().as_secs_f64();
    let [w, h] = opts.size();
    Ok(format!(
        "wrote {}: a {}x{} mosaic of {}² tiles ({w}x{h} samples, seed {}), {} levels, {} tiles, {} samples stored, {} in {secs:.2} s ({:.1} M samples/s)",
        out.display(),
        opts.tiles[0],
        opts.tiles[1],
        opts.samples,
        opts.seed,
        r.levels,
        r.tiles,
        r.samples,
        human_bytes(r.bytes),
        r.samples as f64 / secs / 1e6
    ))
}

/// Degrees as text with the arc-seconds of small steps.
fn degrees(v: f64) -> String {
    if v < 1.0 / 60.0 * 10.0 {
        format!("{v:.7}° ({:.3}″)", v * 3600.0)
    } else {
        format!("{v:.5}°")
    }
}

/// The report `relief db info` prints.
pub fn info(d: &Database) -> String {
    let h = d.header();
    let e = h.extent;
    let n = h.tile as u64;
    let centre = 0.5 * (e.lat_min + e.lat_max);
    let centre = if centre.abs() < 0.005 { 0.0 } else { centre };
    let (mx, my) = metres_per_degree(centre);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: relief terrain database, format version {}, {} on disk",
        d.path().display(),
        h.version,
        human_bytes(d.file_len())
    );
    let _ = writeln!(
        s,
        "extent: latitude {:.6}..{:.6}, longitude {:.6}..{:.6}; heights {}..{} m",
        e.lat_min, e.lat_max, e.lon_min, e.lon_max, h.heights[0], h.heights[1]
    );
    let samples = h.tile_count * (n + 1) * (n + 1);
    let _ = writeln!(
        s,
        "tiles: {n}x{n} cells ({}² samples each), {} tiles, {samples} samples, {} levels (0 the coarsest)",
        n + 1,
        h.tile_count,
        h.levels.len()
    );
    let _ = writeln!(
        s,
        "level  spacing                     metres at {centre:.2}° (x × y)   tiles  tile range (x, y)           samples"
    );
    for (l, lv) in h.levels.iter().enumerate() {
        let sp = lv.spacing();
        let _ = writeln!(
            s,
            "{l:>5}  {:<26}  {:>9.1} × {:<9.1}          {:>6}  {}..{}, {}..{}  {:>14}",
            degrees(sp),
            sp * mx,
            sp * my,
            lv.tiles,
            lv.x0,
            lv.x1,
            lv.y0,
            lv.y1,
            lv.tiles * (n + 1) * (n + 1)
        );
    }
    let _ = writeln!(s, "sources (finest first):");
    for src in &h.sources {
        let _ = writeln!(
            s,
            "  {}: {}x{} samples, {} x {}, longitude {:.6}..{:.6}, latitude {:.6}..{:.6}; tiles from level {}",
            src.name,
            src.width,
            src.height,
            degrees(src.dlon),
            degrees(src.dlat),
            src.lon0,
            src.lon0 + (src.width - 1) as f64 * src.dlon,
            src.lat0,
            src.lat0 + (src.height - 1) as f64 * src.dlat,
            src.finest_level
        );
    }
    s
}
