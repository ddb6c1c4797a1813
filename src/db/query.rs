//! Queries on a database at full resolution, through its tile cache: the height of the
//! surface at a geographic position on the finest level that has data there. What the CPU
//! oracle's `relief query` answers for a database scene, whatever level the scene renders.
//! [`height_in`] does the same through any [`Tiles`] (resident only: see `db::tiles`).

use super::format::TileId;
use super::reader::Database;
use super::tiles::{Lookup, Tiles};
use crate::Result;

/// The surface height at a position and where it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    /// Metres above mean sea level: bilinear between the four samples around the position.
    pub height: f64,
    /// The level read (0 the coarsest).
    pub level: u32,
    /// Degrees between samples there.
    pub spacing: f64,
}

/// Height of the bilinear surface at (`lat`, `lon`) on the finest level whose tile around the
/// position exists and has data at its four samples (a void or a missing tile lets the next
/// coarser level answer). `Ok(None)`: no level has data there (off the database). Errors: a
/// tile that fails its checks (a damaged file).
pub fn height_at(db: &Database, lat: f64, lon: f64) -> Result<Option<SurfaceSample>> {
    height_in(db, lat, lon)
}

/// [`height_at`] through `tiles`. A tile that is not resident (resident-only `tiles`, which
/// record it) ends the search: `Ok(None)`, to be told from "off the database" by the tiles'
/// missing list.
pub fn height_in(tiles: &dyn Tiles, lat: f64, lon: f64) -> Result<Option<SurfaceSample>> {
    surface(tiles, lat, lon, false)
}

/// The height at (`lat`, `lon`) that `tiles` hold now: [`height_in`], but a tile that is not
/// resident lets the next coarser level answer (its level in the sample says which did). What
/// a caller that must not wait for the disk takes in the meantime; the tiles' missing list
/// says whether a finer answer exists (an empty list: the answer is [`height_at`]'s).
pub fn height_resident(tiles: &dyn Tiles, lat: f64, lon: f64) -> Result<Option<SurfaceSample>> {
    surface(tiles, lat, lon, true)
}

/// [`height_in`]; `coarser_when_missing`: a tile not resident lets the next coarser level
/// answer instead of ending the search.
fn surface(
    tiles: &dyn Tiles,
    lat: f64,
    lon: f64,
    coarser_when_missing: bool,
) -> Result<Option<SurfaceSample>> {
    if !(lat.is_finite() && lon.is_finite()) {
        return Ok(None);
    }
    let db = tiles.database();
    let n = db.tile_cells() as i64;
    for (level, l) in db.header().levels.iter().enumerate().rev() {
        let d = l.per_degree;
        let (gi, gj) = ((lon + 180.0) * d, (lat + 90.0) * d);
        if !(gi >= 0.0 && gj >= 0.0) {
            continue;
        }
        // The cell holding the position. On a sample line the cell before it has the same
        // samples there: it answers where the cell after has no data (the data's east and
        // north edges) or no tile.
        let (fi, fj) = (gi.floor() as i64, gj.floor() as i64);
        let on_x = gi == fi as f64 && fi > 0;
        let on_y = gj == fj as f64 && fj > 0;
        for (a, b) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            if (a == 1 && !on_x) || (b == 1 && !on_y) {
                continue;
            }
            let (ci, cj) = (fi - a, fj - b);
            match cell_height(tiles, level as u32, n, ci, cj, gi, gj)? {
                Cell::Height(height) => {
                    return Ok(Some(SurfaceSample {
                        height,
                        level: level as u32,
                        spacing: l.spacing(),
                    }))
                }
                Cell::NoData => {}
                Cell::NotResident if coarser_when_missing => {}
                Cell::NotResident => return Ok(None),
            }
        }
    }
    Ok(None)
}

/// What one cell says at a position.
enum Cell {
    Height(f64),
    /// Its tile is not stored, or a corner has no data.
    NoData,
    /// Its tile is stored but not resident (resident-only lookups).
    NotResident,
}

/// The bilinear height at level position (`gi`, `gj`) from the samples of cell (`ci`, `cj`) of
/// `level`.
fn cell_height(
    tiles: &dyn Tiles,
    level: u32,
    n: i64,
    ci: i64,
    cj: i64,
    gi: f64,
    gj: f64,
) -> Result<Cell> {
    let (tx, ty) = (ci.div_euclid(n), cj.div_euclid(n));
    if tx > u32::MAX as i64 || ty > u32::MAX as i64 {
        return Ok(Cell::NoData);
    }
    let id = TileId {
        level,
        x: tx as u32,
        y: ty as u32,
    };
    let tile = match tiles.lookup(id)? {
        Lookup::Tile(t) => t,
        Lookup::NotStored => return Ok(Cell::NoData),
        Lookup::NotResident => return Ok(Cell::NotResident),
    };
    let (i, j) = ((ci - tx * n) as usize, (cj - ty * n) as usize);
    let (u, v) = (gi - ci as f64, gj - cj as f64);
    let h = [
        tile.height(i, j),
        tile.height(i + 1, j),
        tile.height(i, j + 1),
        tile.height(i + 1, j + 1),
    ];
    if h.iter().any(|x| x.is_nan()) {
        return Ok(Cell::NoData);
    }
    let [h00, h10, h01, h11] = h.map(f64::from);
    Ok(Cell::Height(
        h00 * (1.0 - u) * (1.0 - v) + h10 * u * (1.0 - v) + h01 * (1.0 - u) * v + h11 * u * v,
    ))
}
