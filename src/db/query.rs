//! Queries on a database at full resolution, through its tile cache: the height of the
//! surface at a geographic position on the finest level that has data there. What the CPU
//! oracle's `relief query` answers for a database scene, whatever level the scene renders.

use super::format::TileId;
use super::reader::Database;
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
    if !(lat.is_finite() && lon.is_finite()) {
        return Ok(None);
    }
    let n = db.tile_cells() as i64;
    for (level, l) in db.header().levels.iter().enumerate().rev() {
        let d = l.per_degree;
        let (gi, gj) = ((lon + 180.0) * d, (lat + 90.0) * d);
        if !(gi >= 0.0 && gj >= 0.0) {
            continue;
        }
        // The cell holding the position; on a tile border either tile has the samples.
        let (ci, cj) = (gi.floor() as i64, gj.floor() as i64);
        let (tx, ty) = (ci.div_euclid(n), cj.div_euclid(n));
        if tx > u32::MAX as i64 || ty > u32::MAX as i64 {
            continue;
        }
        let id = TileId {
            level: level as u32,
            x: tx as u32,
            y: ty as u32,
        };
        if !db.has_tile(id) {
            continue;
        }
        let Some(tile) = db.tile(id)? else {
            continue;
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
            continue;
        }
        let [h00, h10, h01, h11] = h.map(f64::from);
        return Ok(Some(SurfaceSample {
            height: h00 * (1.0 - u) * (1.0 - v)
                + h10 * u * (1.0 - v)
                + h01 * (1.0 - u) * v
                + h11 * u * v,
            level: level as u32,
            spacing: l.spacing(),
        }));
    }
    Ok(None)
}
