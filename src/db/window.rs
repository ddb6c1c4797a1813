//! A window of one level of a database as a [`Heightfield`] with its [`GeoRef`]: what a
//! scene's `[terrain] database = "…"` loads. The samples are the level's own, the metric
//! spacing comes from the same georeference conversion the `.hgt` loader uses, so a tile
//! compiled alone and windowed over its extent gives the same terrain as the tile itself.

use super::format::TileId;
use super::reader::Database;
use super::tiles::{Lookup, Tiles};
use crate::terrain::{GeoRef, Heightfield, MAX_SIDE};
use crate::{fileio, Error, Result};
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Bytes per window sample while it is assembled and turned into a height field (the
/// samples, their void flags, the field, the void filling's pyramid).
const BYTES_PER_SAMPLE: u64 = 24;

/// A rectangle of samples of one level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WindowSpec {
    pub level: u32,
    /// Sample column and row (of the whole level) of the window's south-west sample.
    pub i0: i64,
    pub j0: i64,
    /// Samples along x (east) and y (north).
    pub width: usize,
    pub height: usize,
}

fn snapped(x: f64) -> f64 {
    let r = x.round();
    if (x - r).abs() < 1e-6 {
        r
    } else {
        x
    }
}

/// The database's extent as text for errors.
fn extent_text(db: &Database) -> String {
    let e = db.header().extent;
    format!(
        "latitude {:.6}..{:.6}, longitude {:.6}..{:.6}",
        e.lat_min, e.lat_max, e.lon_min, e.lon_max
    )
}

/// The sample range `[lo, hi]` of `level` that `[a, b]` (degrees from the grid's origin)
/// covers: outward to whole samples, then inside `[in_lo, in_hi]`.
fn span(a: f64, b: f64, d: f64, in_lo: i64, in_hi: i64) -> (i64, i64) {
    let lo = (snapped(a * d).floor() as i64).max(in_lo);
    let hi = (snapped(b * d).ceil() as i64).min(in_hi);
    (lo, hi)
}

fn spec_at(db: &Database, level: u32, w: [f64; 4]) -> WindowSpec {
    let l = &db.header().levels[level as usize];
    let e = db.header().extent;
    let d = l.per_degree;
    let (xi, xa) = (
        snapped((e.lon_min + 180.0) * d).ceil() as i64,
        snapped((e.lon_max + 180.0) * d).floor() as i64,
    );
    let (yi, ya) = (
        snapped((e.lat_min + 90.0) * d).ceil() as i64,
        snapped((e.lat_max + 90.0) * d).floor() as i64,
    );
    let (i0, i1) = span(w[1] + 180.0, w[3] + 180.0, d, xi, xa);
    let (j0, j1) = span(w[0] + 90.0, w[2] + 90.0, d, yi, ya);
    WindowSpec {
        level,
        i0,
        j0,
        width: (i1 - i0 + 1).max(0) as usize,
        height: (j1 - j0 + 1).max(0) as usize,
    }
}

/// The samples a scene's `window = [lat_south, lon_west, lat_north, lon_east]` (default: the
/// whole extent) covers at `level` (default: the finest level at which it fits
/// [`MAX_SIDE`] samples a side). The window must lie within the database's extent.
pub fn resolve(db: &Database, window: Option<[f64; 4]>, level: Option<u32>) -> Result<WindowSpec> {
    let e = db.header().extent;
    let w = window.unwrap_or([e.lat_min, e.lon_min, e.lat_max, e.lon_max]);
    let tol = 1e-9;
    let ordered = w.iter().all(|v| v.is_finite()) && w[0] < w[2] && w[1] < w[3];
    if !ordered {
        return Err(Error::invalid(
            "terrain.window",
            format!("{w:?} is not [lat_south, lon_west, lat_north, lon_east] with south < north and west < east (degrees)"),
        ));
    }
    if w[0] < e.lat_min - tol
        || w[2] > e.lat_max + tol
        || w[1] < e.lon_min - tol
        || w[3] > e.lon_max + tol
    {
        return Err(Error::invalid(
            "terrain.window",
            format!(
                "{w:?} is not within the database {}, which covers {}: give a window inside it (or none for all of it)",
                db.path().display(),
                extent_text(db)
            ),
        ));
    }
    let levels = db.header().levels.len() as u32;
    let spec = match level {
        Some(l) if l >= levels => {
            return Err(Error::invalid(
                "terrain.level",
                format!(
                    "{l} is not a level of {} (levels 0..={}, 0 the coarsest)",
                    db.path().display(),
                    levels - 1
                ),
            ))
        }
        Some(l) => spec_at(db, l, w),
        None => (0..levels)
            .rev()
            .map(|l| spec_at(db, l, w))
            .find(|s| s.width <= MAX_SIDE && s.height <= MAX_SIDE)
            .unwrap_or_else(|| spec_at(db, 0, w)),
    };
    if spec.width < 2 || spec.height < 2 {
        return Err(Error::invalid(
            "terrain.window",
            format!(
                "{w:?} spans {}x{} samples at level {} of {}; a terrain needs at least 2x2: give a larger window or a finer terrain.level",
                spec.width,
                spec.height,
                spec.level,
                db.path().display()
            ),
        ));
    }
    if spec.width > MAX_SIDE || spec.height > MAX_SIDE {
        return Err(Error::invalid(
            "terrain.level",
            format!(
                "the window spans {}x{} samples at level {}, more than {MAX_SIDE} a side: give a coarser level or a smaller window",
                spec.width, spec.height, spec.level
            ),
        ));
    }
    Ok(spec)
}

/// A tile's heights: stored, or filled from a coarser level.
enum Heights {
    Stored(Arc<super::tile::Tile>),
    Filled(Vec<f32>),
}

impl Heights {
    fn get(&self) -> &[f32] {
        match self {
            Heights::Stored(t) => &t.heights,
            Heights::Filled(v) => v,
        }
    }
}

/// One tile of a row of the window: its heights (`None`: not resident) and the tiles filled
/// from a coarser level with the level used.
type RowTile = (Option<Heights>, Vec<(TileId, u32)>);

/// The heights of tile `id`: stored, or (missing from the database) bilinear from the
/// nearest coarser level that has the region, recorded in `filled` as (tile, level used).
/// `None`: a tile it needs is not resident (resident-only `tiles`, which record it).
fn heights_of(
    tiles: &dyn Tiles,
    id: TileId,
    filled: &mut Vec<(TileId, u32)>,
) -> Result<Option<Heights>> {
    match tiles.lookup(id)? {
        Lookup::Tile(t) => return Ok(Some(Heights::Stored(t))),
        Lookup::NotResident => return Ok(None),
        Lookup::NotStored => {}
    }
    let n = tiles.database().tile_cells();
    let np = n + 1;
    if id.level == 0 {
        return Ok(Some(Heights::Filled(vec![f32::NAN; np * np])));
    }
    let before = filled.len();
    let Some(parent) = heights_of(
        tiles,
        TileId {
            level: id.level - 1,
            x: id.x / 2,
            y: id.y / 2,
        },
        filled,
    )?
    else {
        return Ok(None);
    };
    let from = filled.get(before).map_or(id.level - 1, |f| f.1);
    filled.truncate(before);
    filled.push((id, from));
    let p = parent.get();
    let (ox, oy) = ((id.x % 2) as usize * n, (id.y % 2) as usize * n);
    let mut out = vec![0.0f32; np * np];
    for b in 0..np {
        let (y2, fy) = ((oy + b) / 2, (oy + b) % 2);
        for a in 0..np {
            let (x2, fx) = ((ox + a) / 2, (ox + a) % 2);
            let at = |dx: usize, dy: usize| p[(y2 + dy) * np + x2 + dx] as f64;
            // Half-way positions average their two (or four) parent samples.
            let h = match (fx, fy) {
                (0, 0) => at(0, 0),
                (1, 0) => 0.5 * (at(0, 0) + at(1, 0)),
                (0, 1) => 0.5 * (at(0, 0) + at(0, 1)),
                _ => 0.25 * (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)),
            };
            out[b * np + a] = h as f32;
        }
    }
    Ok(Some(Heights::Filled(out)))
}

/// `spec` with its south-west corner moved out to the tile corner south-west of it (a paged
/// window starts on one: `cpu::paged::check_origin`) and its north-east corner kept, unless
/// that takes a side over [`MAX_SIDE`] samples (then the far side is cut back). A window
/// already on a tile corner is returned as it is.
pub fn on_tile_corners(spec: WindowSpec, n: usize) -> WindowSpec {
    let n = n.max(1) as i64;
    let (i0, j0) = (spec.i0.div_euclid(n) * n, spec.j0.div_euclid(n) * n);
    let grow = |side: usize, by: i64| (side + by as usize).min(MAX_SIDE.max(side));
    let out = WindowSpec {
        level: spec.level,
        i0,
        j0,
        width: grow(spec.width, spec.i0 - i0),
        height: grow(spec.height, spec.j0 - j0),
    };
    if out != spec {
        log::info!(
            "paged window moved to the tile corner south-west of it: {}x{} samples from ({}, {}), was {}x{} from ({}, {})",
            out.width, out.height, out.i0, out.j0, spec.width, spec.height, spec.i0, spec.j0
        );
    }
    out
}

/// Where a paged window moves to follow its eye at `eye` (global sample coordinates of the
/// window's level): once the eye is within a quarter of the window's side of an edge (or past
/// it) with more of the level beyond that edge, the window of the same size centred on the
/// eye (its south-west corner on the nearest tile corner, `n` cells) and kept within the level's tiles
/// `[lo, hi]` (first and last sample) where the level is wide enough; `None` while it stays.
pub fn follow(
    spec: WindowSpec,
    n: usize,
    lo: [i64; 2],
    hi: [i64; 2],
    eye: [f64; 2],
) -> Option<WindowSpec> {
    let n = n.max(1) as i64;
    let axis = |o: i64, side: usize, lo: i64, hi: i64, e: f64| -> i64 {
        let w = side as i64 - 1;
        let margin = w as f64 / 4.0;
        let rel = e - o as f64;
        let near_low = rel < margin && o > lo;
        let near_high = rel > w as f64 - margin && o + w < hi;
        if !(near_low || near_high) || !e.is_finite() {
            return o;
        }
        let centred = ((e - w as f64 / 2.0) / n as f64).round() as i64 * n;
        let last = ((hi - w).div_euclid(n) * n).max(lo);
        centred.clamp(lo, last)
    };
    let i0 = axis(spec.i0, spec.width, lo[0], hi[0], eye[0]);
    let j0 = axis(spec.j0, spec.height, lo[1], hi[1], eye[1]);
    ((i0, j0) != (spec.i0, spec.j0)).then_some(WindowSpec { i0, j0, ..spec })
}

/// Reads the window's samples into a height field (no-data samples filled, with a warning).
/// Tiles missing at the window's level are filled from the nearest coarser level that has
/// them, with a warning naming them.
pub fn read(db: &Database, spec: &WindowSpec) -> Result<Heightfield> {
    read_from(db, spec)?.ok_or_else(|| super::tiles::not_read(db))
}

/// [`read`] through `tiles`; `None` when a tile it needs is not resident (resident-only
/// `tiles`: every such tile of the window is recorded, and no height field is made).
pub fn read_from(tiles: &dyn Tiles, spec: &WindowSpec) -> Result<Option<Heightfield>> {
    let db = tiles.database();
    let (w, h) = (spec.width, spec.height);
    fileio::check_alloc(
        format!(
            "{} (a {w}x{h} window at level {})",
            db.path().display(),
            spec.level
        ),
        (w as u64 * h as u64).saturating_mul(BYTES_PER_SAMPLE),
    )?;
    let n = db.tile_cells() as i64;
    let np = n as usize + 1;
    let (i_last, j_last) = (spec.i0 + w as i64 - 1, spec.j0 + h as i64 - 1);
    let mut out = vec![f32::NAN; w * h];
    let mut filled = Vec::new();
    let mut not_resident = false;
    let xs: Vec<i64> = tiles_over(spec.i0, i_last, n).collect();
    for ty in tiles_over(spec.j0, j_last, n) {
        // One row of tiles at a time, decoded in parallel.
        let row: Vec<RowTile> = xs
            .par_iter()
            .map(|&tx| {
                let id = TileId {
                    level: spec.level,
                    x: tx as u32,
                    y: ty as u32,
                };
                let mut f = Vec::new();
                heights_of(tiles, id, &mut f).map(|t| (t, f))
            })
            .collect::<Result<_>>()?;
        for (&tx, (t, f)) in xs.iter().zip(row) {
            let Some(t) = t else {
                not_resident = true;
                continue;
            };
            filled.extend(f);
            let t = t.get();
            let (ja, jb) = ((ty * n).max(spec.j0), (ty * n + n).min(j_last));
            let (ia, ib) = ((tx * n).max(spec.i0), (tx * n + n).min(i_last));
            for j in ja..=jb {
                let src = &t[(j - ty * n) as usize * np..][..np];
                let dst = &mut out[(j - spec.j0) as usize * w..][..w];
                for i in ia..=ib {
                    dst[(i - spec.i0) as usize] = src[(i - tx * n) as usize];
                }
            }
        }
    }
    if not_resident {
        return Ok(None);
    }
    if let Some(&(first, from)) = filled.first() {
        let names: Vec<String> = filled.iter().take(3).map(|f| f.0.to_string()).collect();
        log::warn!(
            "{}: {} tile(s) of level {} under the window are not in the database ({}{}), filled bilinearly from level {from}{}",
            db.path().display(),
            filled.len(),
            first.level,
            names.join(", "),
            if filled.len() > 3 { ", …" } else { "" },
            if filled.iter().any(|f| f.1 != from) { " and coarser" } else { "" }
        );
    }
    let geo = georef(db, spec);
    let samples = out
        .into_iter()
        .map(|v| (!v.is_nan()).then_some(v))
        .collect();
    let what = format!("{} (level {} window)", db.path().display(), spec.level);
    Heightfield::from_samples_with_voids(&what, w, h, samples, geo.metric_spacing(h), Some(geo))
        .map(Some)
}

/// The tile columns (or rows) of `n` cells that samples `lo..=hi` lie in (a sample on a tile
/// edge in the tile before it, except the first).
fn tiles_over(lo: i64, hi: i64, n: i64) -> std::ops::RangeInclusive<i64> {
    lo.div_euclid(n)..=((hi - 1).div_euclid(n)).max(lo.div_euclid(n))
}

/// The georeference of window `spec`: its south-west sample and its level's step.
pub fn georef(db: &Database, spec: &WindowSpec) -> GeoRef {
    let level = &db.header().levels[spec.level as usize];
    GeoRef {
        lon0: level.lon(spec.i0),
        lat0: level.lat(spec.j0),
        dlon: level.spacing(),
        dlat: level.spacing(),
    }
}

/// The lowest and highest sample of window `spec` as the index tells them, reading no tile:
/// the union of the height ranges of the tiles under the window (a tile the level does not
/// have answers with its nearest stored ancestor, whose range bounds it). Exact where the
/// window's edges lie on tile edges; otherwise it may be wider than the window's own samples.
/// `None` where no tile under the window has data.
pub fn height_bounds(db: &Database, spec: &WindowSpec) -> Option<(f32, f32)> {
    let n = db.tile_cells() as i64;
    let (i_last, j_last) = (
        spec.i0 + spec.width as i64 - 1,
        spec.j0 + spec.height as i64 - 1,
    );
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for ty in tiles_over(spec.j0, j_last, n) {
        for tx in tiles_over(spec.i0, i_last, n) {
            let mut id = Some(TileId {
                level: spec.level,
                x: tx as u32,
                y: ty as u32,
            });
            while let Some(t) = id {
                if let Some(e) = db.entry(t) {
                    (lo, hi) = (lo.min(e.min), hi.max(e.max));
                    break;
                }
                id = super::pager::parent(t);
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// Opens the database at `path` and reads a window of it (see [`resolve`] and [`read`]).
pub fn load(path: &Path, window: Option<[f64; 4]>, level: Option<u32>) -> Result<Heightfield> {
    let db = Database::open(path)?;
    let spec = resolve(&db, window, level)?;
    let l = &db.header().levels[spec.level as usize];
    log::info!(
        "{}: level {} ({:.3}″ spacing), window of {}x{} samples from lon {:.6}, lat {:.6}",
        path.display(),
        spec.level,
        l.spacing() * 3600.0,
        spec.width,
        spec.height,
        l.lon(spec.i0),
        l.lat(spec.j0)
    );
    read(&db, &spec)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(i0: i64, j0: i64, width: usize, height: usize) -> WindowSpec {
        WindowSpec {
            level: 3,
            i0,
            j0,
            width,
            height,
        }
    }

    #[test]
    fn paged_windows_move_out_to_the_tile_corner_keeping_their_far_corner() {
        // On a corner already: unchanged.
        assert_eq!(
            on_tile_corners(spec(512, 768, 300, 40), 256),
            spec(512, 768, 300, 40)
        );
        // Out to (256, 512), the north-east corner kept.
        assert_eq!(
            on_tile_corners(spec(300, 700, 100, 50), 256),
            spec(256, 512, 144, 238)
        );
        // Grown past the largest side: the far side cut back.
        let big = on_tile_corners(spec(1000, 0, MAX_SIDE, 10), 256);
        assert_eq!((big.i0, big.width), (768, MAX_SIDE));
    }

    #[test]
    fn a_followed_window_recentres_on_tile_corners_within_the_level() {
        let w = spec(2048, 2048, 513, 513);
        let (lo, hi) = ([0, 0], [8192, 8192]);
        // The middle half: stays.
        assert_eq!(
            follow(w, 256, lo, hi, [2048.0 + 200.0, 2048.0 + 300.0]),
            None
        );
        // Near the east edge: centred on the eye, on a tile corner.
        let e = follow(w, 256, lo, hi, [2048.0 + 450.0, 2048.0 + 256.0]).unwrap();
        assert_eq!(
            (e.i0, e.j0, e.width, e.height),
            (2048 + 256, 2048, 513, 513)
        );
        // Far past the north-west corner.
        let f = follow(w, 256, lo, hi, [100.0, 7900.0]).unwrap();
        assert_eq!((f.i0, f.j0), (0, 7680));
        // At the level's west edge it cannot move further west.
        let edge = spec(0, 2048, 513, 513);
        assert_eq!(follow(edge, 256, lo, hi, [10.0, 2300.0]), None);
    }
}
