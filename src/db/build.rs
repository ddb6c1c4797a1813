//! The compiler: source DEMs → one database file, written atomically.
//!
//! Levels are planned from the sources (the finest level's spacing is the finest source's
//! latitude step; each coarser level doubles it, down to the level where one tile covers the
//! whole extent), then built tile by tile in parallel, each level row by row, a coarser row as
//! soon as the finer rows it reads are built (so host memory holds a few rows per level): each
//! tile samples the sources at its positions and takes its cell maxima from its own corners
//! and from the four finer tiles below it, so every coarse cell bounds every finer sample in
//! its footprint.

use super::format::{self, Extent, Header, IndexEntry, LevelInfo, TileId};
use super::source::{self, Source};
use super::tile::{self, Tile};
use crate::terrain::pyramid::PAD;
use crate::{fileio, Error, Result};
use rayon::prelude::*;
use std::collections::{BTreeSet, HashMap};
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Most tiles a database may have (at 256² cells, 4.4 · 10¹¹ samples).
pub const MAX_TILES: u64 = 1 << 24;

/// Options of `relief db build`.
#[derive(Clone, Copy, Debug)]
pub struct BuildOptions {
    /// Cells per tile side: a power of two in 16..=4096.
    pub tile: u32,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            tile: format::DEFAULT_TILE,
        }
    }
}

/// What a build made.
#[derive(Clone, Debug)]
pub struct BuildReport {
    pub levels: u32,
    pub tiles: u64,
    /// Samples stored, tile edges counted in each tile.
    pub samples: u64,
    /// Size of the database file.
    pub bytes: u64,
    /// Total size of the source files.
    pub source_bytes: u64,
}

/// The levels and tiles a set of sources needs.
struct Plan {
    n: u32,
    /// Coarsest first.
    levels: Vec<LevelInfo>,
    /// Per level, its tiles as (y, x), sorted.
    tiles: Vec<Vec<(u32, u32)>>,
    extent: Extent,
    /// Per source (in the sorted order), the finest level it starts tiles at.
    finest: Vec<u32>,
}

/// What a tile hands to the level above it.
struct ChildInfo {
    /// Its cell maxima reduced 2x2: one value per cell of the tile above.
    reduced: Vec<f32>,
    /// Its cell maxima along its west, east, south and north edges (n each, south to north
    /// or west to east): the bounds a missing neighbour's parent cells take from it.
    edges: [Vec<f32>; 4],
    /// Its lowest sample (and its children's); +inf where they hold none.
    min: f32,
}

/// The bound each cell of the tile above slot `(x, y)` of the finer level takes from the
/// finer level: `(n/2)²` values, or `None` where nothing finer touches the slot.
///
/// Where the finer tile exists, its cell maxima reduced 2x2 (the cells under a coarse cell
/// cover its closed footprint). Where it is missing, finer samples can still lie on the
/// border of the slot's cells: the edges of the existing neighbouring tiles, whose cells
/// touching a coarse cell's closed footprint bound them.
fn slot_bounds(
    children: &HashMap<(u32, u32), ChildInfo>,
    x: u32,
    y: u32,
    n: usize,
) -> Option<Vec<f32>> {
    if let Some(c) = children.get(&(x, y)) {
        return Some(c.reduced.clone());
    }
    let h = n / 2;
    let get = |dx: i64, dy: i64| {
        let (cx, cy) = (x as i64 + dx, y as i64 + dy);
        (cx >= 0 && cy >= 0)
            .then(|| children.get(&(cx as u32, cy as u32)))
            .flatten()
    };
    let (w, e, s, nn) = (get(-1, 0), get(1, 0), get(0, -1), get(0, 1));
    let (sw, se, nw, ne) = (get(-1, -1), get(1, -1), get(-1, 1), get(1, 1));
    if [w, e, s, nn, sw, se, nw, ne].iter().all(Option::is_none) {
        return None;
    }
    let mut out = vec![PAD; h * h];
    // Finer cells 2k-1..=2k+2 along an edge touch the closed footprint of coarse cell k.
    let run = |edge: &[f32], k: usize| {
        edge[(2 * k).saturating_sub(1)..(2 * k + 3).min(n)]
            .iter()
            .copied()
            .fold(PAD, f32::max)
    };
    for k in 0..h {
        let mut bump = |i: usize, v: f32| out[i] = out[i].max(v);
        if let Some(c) = w {
            bump(k * h, run(&c.edges[1], k));
        }
        if let Some(c) = e {
            bump(k * h + h - 1, run(&c.edges[0], k));
        }
        if let Some(c) = s {
            bump(k, run(&c.edges[3], k));
        }
        if let Some(c) = nn {
            bump((h - 1) * h + k, run(&c.edges[2], k));
        }
    }
    let corners = [
        (sw, 1, n - 1, 0),
        (se, 0, n - 1, h - 1),
        (nw, 1, 0, (h - 1) * h),
        (ne, 0, 0, h * h - 1),
    ];
    for (c, edge, at, i) in corners {
        if let Some(c) = c {
            out[i] = out[i].max(c.edges[edge][at]);
        }
    }
    Some(out)
}

/// A built tile, ready to be written.
struct Built {
    x: u32,
    y: u32,
    blob: Vec<u8>,
    child: ChildInfo,
    max: f32,
    voids: u32,
}

fn snapped(x: f64) -> f64 {
    let r = x.round();
    if (x - r).abs() < source::SNAP {
        r
    } else {
        x
    }
}

/// Tiles `first..=last` along one axis that the interval `[lo, hi]` (degrees from the grid's
/// origin) meets with positive length, at `d` samples per degree and `n` cells per tile.
fn tile_span(lo: f64, hi: f64, d: f64, n: u32) -> (i64, i64) {
    let (a, b) = (snapped(lo * d) / n as f64, snapped(hi * d) / n as f64);
    let first = a.floor() as i64;
    (first, (b.ceil() as i64 - 1).max(first))
}

/// The finest level's samples per degree: the inverse of the finest source's latitude step,
/// made a whole number where it is one within rounding (SRTM's 1200 or 3600).
fn finest_per_degree(dlat: f64) -> f64 {
    let d = 1.0 / dlat;
    let r = d.round();
    if r >= 1.0 && (d - r).abs() <= 1e-9 * d {
        r
    } else {
        d
    }
}

fn plan(sources: &[Source], n: u32) -> Result<Plan> {
    let extent = Extent {
        lon_min: sources.iter().map(|s| s.lon0).fold(f64::INFINITY, f64::min),
        lat_min: sources.iter().map(|s| s.lat0).fold(f64::INFINITY, f64::min),
        lon_max: sources
            .iter()
            .map(|s| s.lon1())
            .fold(f64::NEG_INFINITY, f64::max),
        lat_max: sources
            .iter()
            .map(|s| s.lat1())
            .fold(f64::NEG_INFINITY, f64::max),
    };
    let d_fine = finest_per_degree(sources[0].dlat);
    let mut count = None;
    for k in 0..format::MAX_LEVELS {
        let d = d_fine / 2f64.powi(k as i32);
        let (x0, x1) = tile_span(extent.lon_min + 180.0, extent.lon_max + 180.0, d, n);
        let (y0, y1) = tile_span(extent.lat_min + 90.0, extent.lat_max + 90.0, d, n);
        if x0 == x1 && y0 == y1 {
            count = Some(k + 1);
            break;
        }
    }
    let Some(count) = count else {
        return Err(Error::invalid(
            "db build",
            format!("{} levels of {n}-cell tiles do not reach from the finest source's spacing to one tile over the extent", format::MAX_LEVELS),
        ));
    };
    let mut levels = Vec::with_capacity(count as usize);
    let mut tiles = Vec::with_capacity(count as usize);
    let mut finest = vec![0u32; sources.len()];
    let mut total = 0u64;
    for l in 0..count {
        let d = d_fine / 2f64.powi((count - 1 - l) as i32);
        let mut set = BTreeSet::new();
        for (k, s) in sources.iter().enumerate() {
            // A source starts tiles at the levels no more than half an octave finer than it.
            if l > 0 && 1.0 / d < s.dlat / std::f64::consts::SQRT_2 * (1.0 - 1e-9) {
                continue;
            }
            finest[k] = l;
            let (x0, x1) = tile_span(s.lon0 + 180.0, s.lon1() + 180.0, d, n);
            let (y0, y1) = tile_span(s.lat0 + 90.0, s.lat1() + 90.0, d, n);
            total += ((x1 - x0 + 1) * (y1 - y0 + 1)) as u64;
            if total > MAX_TILES {
                return Err(Error::invalid(
                    "db build",
                    format!("{} at level {l} needs more than {MAX_TILES} tiles of {n}x{n} cells: give a larger --tile or fewer/smaller sources", s.name),
                ));
            }
            for y in y0..=y1 {
                for x in x0..=x1 {
                    set.insert((y as u32, x as u32));
                }
            }
        }
        let list: Vec<(u32, u32)> = set.into_iter().collect();
        let xs = list.iter().map(|t| t.1);
        let (x0, x1) = (xs.clone().min().unwrap_or(0), xs.max().unwrap_or(0) + 1);
        let (y0, y1) = (list[0].0, list[list.len() - 1].0 + 1);
        levels.push(LevelInfo {
            per_degree: d,
            x0,
            y0,
            x1,
            y1,
            tiles: list.len() as u64,
        });
        tiles.push(list);
    }
    Ok(Plan {
        n,
        levels,
        tiles,
        extent,
        finest,
    })
}

/// Samples tile `(x, y)` of `level` from the sources (finest first: the first with data at
/// a position wins) and makes its cell maxima and their pyramid.
fn build_tile(
    sources: &[Source],
    level: &LevelInfo,
    n: usize,
    x: u32,
    y: u32,
    below: [Option<Vec<f32>>; 4],
    child_min: f32,
) -> Built {
    let np = n + 1;
    let (i0, j0) = (x as i64 * n as i64, y as i64 * n as i64);
    let (lon_a, lon_b) = (level.lon(i0), level.lon(i0 + n as i64));
    let (lat_a, lat_b) = (level.lat(j0), level.lat(j0 + n as i64));
    let cands: Vec<&Source> = sources
        .iter()
        .filter(|s| s.touches(lon_a, lat_a, lon_b, lat_b))
        .collect();
    let mut heights = vec![f32::NAN; np * np];
    for b in 0..np {
        let lat = level.lat(j0 + b as i64);
        let row: Vec<&&Source> = cands
            .iter()
            .filter(|s| s.touches(lon_a, lat, lon_b, lat))
            .collect();
        for a in 0..np {
            let lon = level.lon(i0 + a as i64);
            // Where every source covering the position is void there, the finest of them
            // answers with its voids filled: a function of the position alone, as every
            // sample is (tiles sharing an edge hold the same samples).
            heights[b * np + a] = row
                .iter()
                .find_map(|s| s.sample(lon, lat))
                .or_else(|| row.iter().find_map(|s| s.sample_filled(lon, lat)))
                .unwrap_or(f32::NAN);
        }
    }
    let half = n / 2;
    let mut cells = vec![PAD; n * n];
    for b in 0..n {
        for a in 0..n {
            let k = b * np + a;
            let corners = heights[k]
                .max(heights[k + 1])
                .max(heights[k + np])
                .max(heights[k + np + 1]);
            let mut m = PAD.max(corners);
            if let Some(c) = &below[(b / half) * 2 + a / half] {
                m = m.max(c[(b % half) * half + a % half]);
            }
            cells[b * n + a] = m;
        }
    }
    let maxima = tile::max_pyramid(n, &cells);
    let reduced = maxima[n * n..n * n + half * half].to_vec();
    let own_min = heights
        .iter()
        .copied()
        .filter(|h| !h.is_nan())
        .fold(f32::INFINITY, f32::min);
    // +inf where neither the tile nor a finer one below it has data.
    let min = own_min.min(child_min);
    let max = *maxima.last().expect("a pyramid has a top");
    let voids = heights.iter().filter(|h| h.is_nan()).count() as u32;
    let tile = Tile { n, heights, maxima };
    Built {
        x,
        y,
        blob: tile::encode_tile(&tile),
        child: ChildInfo {
            reduced,
            edges: [
                (0..n).map(|j| cells[j * n]).collect(),
                (0..n).map(|j| cells[j * n + n - 1]).collect(),
                cells[..n].to_vec(),
                cells[(n - 1) * n..].to_vec(),
            ],
            min,
        },
        max,
        voids,
    }
}

/// Checks `--tile`: a power of two in 16..=4096.
pub fn check_tile(n: u32) -> Result<()> {
    if !n.is_power_of_two() || !(format::MIN_TILE..=format::MAX_TILE).contains(&n) {
        return Err(Error::invalid(
            "--tile",
            format!(
                "{n} cells is not a power of two in {}..={}",
                format::MIN_TILE,
                format::MAX_TILE
            ),
        ));
    }
    Ok(())
}

/// Compiles `sources` into the database `out` (written atomically: a temporary file renamed
/// when complete, removed on any error or interruption). `progress(done, total)` is called
/// after each tile. Sources are `.hgt` tiles or GeoTIFFs in degrees; where they overlap the
/// finer wins (equal resolutions: the one given first, with a warning).
pub fn build(
    out: &Path,
    sources: &[PathBuf],
    opts: &BuildOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<BuildReport> {
    check_tile(opts.tile)?;
    if sources.is_empty() {
        return Err(Error::invalid(
            "db build",
            "give at least one source DEM (.hgt or GeoTIFF)",
        ));
    }
    fileio::check_writable_target(out)?;
    let mut srcs = sources
        .iter()
        .enumerate()
        .map(|(k, p)| Source::load(p, k))
        .collect::<Result<Vec<_>>>()?;
    source::order_and_check_overlaps(&mut srcs);
    build_sources(out, &srcs, opts, progress)
}

/// Compiles loaded (or procedural) sources, ordered finest first, into `out`.
pub(crate) fn build_sources(
    out: &Path,
    srcs: &[Source],
    opts: &BuildOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<BuildReport> {
    check_tile(opts.tile)?;
    let n = opts.tile;
    let plan = plan(srcs, n)?;
    let tile_count: u64 = plan.levels.iter().map(|l| l.tiles).sum();
    let mut header = Header {
        version: format::VERSION,
        tile: n,
        tile_count,
        index_offset: 0,
        data_offset: 0,
        extent: plan.extent,
        heights: [0.0, 0.0],
        levels: plan.levels.clone(),
        sources: srcs
            .iter()
            .zip(&plan.finest)
            .map(|(s, &finest_level)| format::SourceInfo {
                name: s.name.clone(),
                lon0: s.lon0,
                lat0: s.lat0,
                dlon: s.dlon,
                dlat: s.dlat,
                width: s.width as u32,
                height: s.height as u32,
                finest_level,
            })
            .collect(),
    };
    header.index_offset = format::header_len(&header) as u64;
    header.data_offset = header.index_offset + tile_count * format::INDEX_ENTRY as u64 + 4;
    let entries = fileio::write_atomic(out, |f| {
        write_tiles(f, out, srcs, &plan, &mut header, progress)
    })?;
    let bytes = fileio::file_len(out)?;
    Ok(BuildReport {
        levels: plan.levels.len() as u32,
        tiles: entries,
        samples: entries * (n as u64 + 1).pow(2),
        bytes,
        source_bytes: srcs.iter().map(|s| s.file_len).sum(),
    })
}

/// Writes the tiles after a placeholder for the header and the index, then the header and
/// the index over it. Returns the number of tiles.
///
/// Tiles are built in the order of a [`Schedule`]: a row of a coarser level as soon as the
/// rows of the finer level it reads are built, so that host memory holds a few rows of
/// [`ChildInfo`] per level, not a whole level (4.7 GB for a 16x16 mosaic of 3601² tiles).
fn write_tiles(
    f: &mut fileio::AtomicFile,
    out: &Path,
    srcs: &[Source],
    plan: &Plan,
    header: &mut Header,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<u64> {
    let io = |e| Error::io(out, e);
    f.write_all(&vec![0u8; header.data_offset as usize])
        .map_err(io)?;
    let total = header.tile_count;
    let mut entries: Vec<IndexEntry> = Vec::with_capacity(total as usize);
    let mut offset = header.data_offset;
    let mut schedule = Schedule::new(plan);
    while let Some((l, batch)) = schedule.next_batch(16) {
        for b in schedule.build(srcs, plan, l, &batch) {
            f.write_all(&b.blob).map_err(io)?;
            entries.push(IndexEntry {
                id: TileId {
                    level: l as u32,
                    x: b.x,
                    y: b.y,
                },
                voids: b.voids,
                offset,
                length: b.blob.len() as u32,
                crc: crc32fast::hash(&b.blob),
                min: if b.child.min.is_finite() {
                    b.child.min
                } else {
                    PAD
                },
                max: b.max,
            });
            offset += b.blob.len() as u64;
            schedule.built(l, b);
            progress(entries.len() as u64, total);
        }
        schedule.release(l);
    }
    entries.sort_by_key(|e| (e.id.level, e.id.y, e.id.x));
    let valid = entries.iter().filter(|e| e.max > PAD);
    let lo = valid.clone().map(|e| e.min).fold(f32::INFINITY, f32::min);
    let hi = valid.map(|e| e.max).fold(f32::NEG_INFINITY, f32::max);
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(Error::invalid(
            "db build",
            "the sources hold no valid height sample (every sample is void or no-data)",
        ));
    }
    header.heights = [lo, hi];
    f.seek(SeekFrom::Start(0)).map_err(io)?;
    f.write_all(&format::write_header(header)).map_err(io)?;
    f.write_all(&format::write_index(&entries)).map_err(io)?;
    Ok(entries.len() as u64)
}

/// The build order: levels in rows (tiles sorted by row, then column), a coarser row as soon
/// as the finer level has built every row it reads (its children's rows `2y, 2y + 1` and the
/// neighbours' `2y − 1, 2y + 2`, see [`slot_bounds`]), coarsest ready level first so that
/// finer rows are released early. What a level holds is dropped as soon as no row left above
/// it reads it.
struct Schedule {
    /// Per level (coarsest first), the index in `plan.tiles` of its next tile to build.
    next: Vec<usize>,
    /// Per level, its built tiles that the level above still reads.
    done: Vec<HashMap<(u32, u32), ChildInfo>>,
    /// Per level, its tiles in build order, as (y, x).
    tiles: Vec<Vec<(u32, u32)>>,
    /// Most `ChildInfo`s held at once (for the tests and the docs).
    peak_held: usize,
}

impl Schedule {
    fn new(plan: &Plan) -> Schedule {
        let count = plan.levels.len();
        Schedule {
            next: vec![0; count],
            done: (0..count).map(|_| HashMap::new()).collect(),
            tiles: plan.tiles.clone(),
            peak_held: 0,
        }
    }

    fn complete(&self, l: usize) -> bool {
        self.next[l] == self.tiles[l].len()
    }

    /// Whether row `y` of level `l` may be built: the finer level has built its rows up to
    /// `2y + 2`.
    fn row_ready(&self, l: usize, y: u32) -> bool {
        let finer = l + 1;
        finer == self.tiles.len()
            || self.complete(finer)
            || self.tiles[finer][self.next[finer]].0 as u64 > 2 * y as u64 + 2
    }

    /// The coarsest level with a ready tile and up to `max` of its next tiles that are ready,
    /// in order; `None` when every tile is built.
    fn next_batch(&self, max: usize) -> Option<(usize, Vec<(u32, u32)>)> {
        (0..self.tiles.len()).find_map(|l| {
            let batch: Vec<(u32, u32)> = self.tiles[l][self.next[l]..]
                .iter()
                .take(max)
                .take_while(|&&(y, _)| self.row_ready(l, y))
                .copied()
                .collect();
            (!batch.is_empty()).then_some((l, batch))
        })
    }

    /// Builds `batch` of level `l` in parallel from the sources and the finer level's infos.
    fn build(&self, srcs: &[Source], plan: &Plan, l: usize, batch: &[(u32, u32)]) -> Vec<Built> {
        let n = plan.n as usize;
        let empty = HashMap::new();
        let children = self.done.get(l + 1).unwrap_or(&empty);
        batch
            .par_iter()
            .map(|&(y, x)| {
                let slot = |cx: u32, cy: u32| slot_bounds(children, 2 * x + cx, 2 * y + cy, n);
                let min = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .filter_map(|&(cx, cy)| children.get(&(2 * x + cx, 2 * y + cy)))
                    .fold(f32::INFINITY, |m, c| m.min(c.min));
                let below = [slot(0, 0), slot(1, 0), slot(0, 1), slot(1, 1)];
                build_tile(srcs, &plan.levels[l], n, x, y, below, min)
            })
            .collect()
    }

    /// Records a built tile of level `l` (its info kept while the level above reads it).
    fn built(&mut self, l: usize, b: Built) {
        self.next[l] += 1;
        if l > 0 {
            self.done[l].insert((b.x, b.y), b.child);
        }
        let held = self.done.iter().map(HashMap::len).sum();
        self.peak_held = self.peak_held.max(held);
    }

    /// Drops the infos of level `l + 1` that no row left of level `l` reads.
    fn release(&mut self, l: usize) {
        let Some(finer) = self.done.get_mut(l + 1) else {
            return;
        };
        match self.tiles[l].get(self.next[l]) {
            None => finer.clear(),
            Some(&(y, _)) => finer.retain(|&(_, cy), _| cy as u64 + 1 >= 2 * y as u64),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::source::{SourceData, Synth};

    /// A coarse grid with voids (30″ over 1° x 1°; filled where the inset has no data) and a
    /// fine procedural inset (3″) placed off the tile grid, so that levels are sparse and
    /// slots miss their finer tile.
    fn mixed_sources() -> Vec<Source> {
        let grid: Vec<f32> = (0..121 * 121)
            .map(|k| match k % 97 {
                0 => f32::NAN,
                r => 200.0 + 10.0 * r as f32 + (k / 121) as f32,
            })
            .collect();
        let voids: Vec<Option<f32>> = grid.iter().map(|h| (!h.is_nan()).then_some(*h)).collect();
        let coarse = Source {
            path: PathBuf::from("coarse"),
            name: "coarse".into(),
            order: 1,
            lon0: 7.0,
            lat0: 46.0,
            dlon: 1.0 / 120.0,
            dlat: 1.0 / 120.0,
            width: 121,
            height: 121,
            data: SourceData::Grid(grid),
            // Its voids filled where the inset does not cover them.
            filled: Some(crate::terrain::heightfield::fill_voids(121, 121, &voids)),
            file_len: 0,
        };
        let fine = Source {
            path: PathBuf::from("fine"),
            name: "fine".into(),
            order: 0,
            lon0: 7.0 + 37.0 / 1200.0,
            lat0: 46.0 + 91.0 / 1200.0,
            dlon: 1.0 / 1200.0,
            dlat: 1.0 / 1200.0,
            width: 301,
            height: 241,
            data: SourceData::Synth(Synth {
                seed: 3,
                wavelength: 40.0,
                octaves: 5,
                height: 2500.0,
            }),
            filled: None,
            file_len: 0,
        };
        let mut srcs = vec![coarse, fine];
        source::order_and_check_overlaps(&mut srcs);
        srcs
    }

    type Tiles = HashMap<(usize, u32, u32), (Vec<u8>, f32, f32, u32)>;

    /// The order the compiler had before the schedule: level by level, finest first, every
    /// tile's info kept until the level above is built.
    fn level_by_level(srcs: &[Source], plan: &Plan) -> Tiles {
        let n = plan.n as usize;
        let mut out = Tiles::new();
        let mut children: HashMap<(u32, u32), ChildInfo> = HashMap::new();
        for l in (0..plan.levels.len()).rev() {
            let mut next = HashMap::new();
            for &(y, x) in &plan.tiles[l] {
                let slot = |cx: u32, cy: u32| slot_bounds(&children, 2 * x + cx, 2 * y + cy, n);
                let min = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .filter_map(|&(cx, cy)| children.get(&(2 * x + cx, 2 * y + cy)))
                    .fold(f32::INFINITY, |m, c| m.min(c.min));
                let below = [slot(0, 0), slot(1, 0), slot(0, 1), slot(1, 1)];
                let b = build_tile(srcs, &plan.levels[l], n, x, y, below, min);
                out.insert((l, x, y), (b.blob, b.max, b.child.min, b.voids));
                next.insert((x, y), b.child);
            }
            children = next;
        }
        out
    }

    #[test]
    fn the_schedule_builds_the_same_tiles_as_level_by_level_holding_a_few_rows() {
        let srcs = mixed_sources();
        let plan = plan(&srcs, 16).expect("plan");
        let expected = level_by_level(&srcs, &plan);
        let total: usize = plan.tiles.iter().map(Vec::len).sum();
        assert!(
            plan.levels.len() >= 5 && total > 500,
            "{} levels, {total} tiles",
            plan.levels.len()
        );
        let mut schedule = Schedule::new(&plan);
        let mut got = Tiles::new();
        while let Some((l, batch)) = schedule.next_batch(16) {
            for b in schedule.build(&srcs, &plan, l, &batch) {
                let key = (l, b.x, b.y);
                assert!(!got.contains_key(&key), "{key:?} built twice");
                got.insert(key, (b.blob.clone(), b.max, b.child.min, b.voids));
                schedule.built(l, b);
            }
            schedule.release(l);
        }
        assert_eq!(got.len(), expected.len());
        for (key, want) in &expected {
            let have = got.get(key).unwrap_or_else(|| panic!("{key:?} not built"));
            assert!(have.0 == want.0, "tile {key:?}: blobs differ");
            assert_eq!(
                (have.1.to_bits(), have.2.to_bits(), have.3),
                (want.1.to_bits(), want.2.to_bits(), want.3),
                "tile {key:?}: max, min, voids"
            );
        }
        // A level holds at most the rows one row above reads (4) and the row being built,
        // each level half as wide as the one below: under 10 of the finest level's widest
        // rows, plus a batch. Holding a whole level would be more than the finest's 300.
        let finest = plan.tiles.last().expect("levels");
        let widest = finest
            .chunk_by(|a, b| a.0 == b.0)
            .map(<[_]>::len)
            .max()
            .unwrap_or(0);
        assert!(
            schedule.peak_held <= 10 * widest + 16 && finest.len() > 10 * widest + 16,
            "held {} infos at once ({total} tiles, rows of {widest})",
            schedule.peak_held
        );
    }
}
