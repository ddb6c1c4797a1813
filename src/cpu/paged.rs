//! The paged terrain on the CPU: the twin of `terrain_paged.wgsl` (`finest_resident`,
//! `cell_max`, `patch_corners`) over the pager's page table and the pool's slots, and
//! [`intersect_paged`], the traversal with the paged stop rule: descend while the finer level
//! is resident over the cell, else intersect the finest resident level's bilinear patch.
//!
//! The traversal runs on a *window* of the database's finest level (its `Terrain` gives the
//! box, the placement and the pyramid's shape; its heights are not read): window-relative
//! cell `(i, j)` of pyramid level `L` is global cell `(origin >> L) + (i, j)` of virtual level
//! `L` (cells of `2^L` finest cells on the finest level's global grid). So the traversal
//! starts at the highest pyramid level whose cells the window's south-west sample is aligned
//! to ([`traversal_top`]: the window pyramid's top where the origin is a multiple of its top
//! cell, else the largest power of two dividing the origin, at least a tile's `n` cells:
//! [`PagedTerrain::new`] refuses a window that does not start on a tile's corner); then every
//! window cell it visits lies inside one cell of every coarser database level, and a coarse
//! patch restricted to it is exactly a bilinear patch.
//!
//! Because every cell maximum read is a bound on every finer sample in its footprint (the
//! database's cell maxima, `docs/database.md#cell-maxima`) and every patch is made of the
//! finest resident level's surface, a ray never passes below the surface it is tested
//! against: where a region's fine tiles are missing the ray meets the coarser surface, and
//! with the walls logic a step between two levels is a wall, not a crack.

use super::traverse::TraversalStats;
use super::traverse::{clip_to_box, first_root, height_slack, patch_quadratic_of, GridRay};
use crate::db::pager::residency::{MAP_NONE, SLOT_MASK};
use crate::db::pager::{PageTable, ResidencyMap};
use crate::db::{Tile, TileId};
use crate::terrain::pyramid::PAD;
use crate::terrain::Terrain;
use crate::{Error, Result};
use glam::DVec3;
use std::sync::Arc;

/// The resident tiles as a traversal reads them.
pub struct PagedTerrain<'a> {
    table: &'a PageTable,
    /// Per pool slot the tile uploaded into it (what the GPU pool holds).
    slots: &'a [Option<Arc<Tile>>],
    n: u64,
    log2n: u32,
    /// The finest database level F.
    fine: u32,
    /// Global finest-level cell of the window's sample (0, 0).
    origin: [u64; 2],
    /// The traversal's top level ([`traversal_top`]).
    top: usize,
    /// The finest resident level and slot per tile-sized cell (what the GPU reads).
    map: ResidencyMap,
}

impl<'a> PagedTerrain<'a> {
    /// The paged view of a window whose sample (0, 0) is sample `origin` of the finest level
    /// (`WindowSpec::i0, j0`), of a terrain whose pyramid has `top + 1` levels, tiles of `n`
    /// cells. Errors where the origin is negative or not on a tile's corner
    /// ([`check_origin`]).
    pub fn new(
        table: &'a PageTable,
        slots: &'a [Option<Arc<Tile>>],
        n: usize,
        origin: [i64; 2],
        top: usize,
    ) -> Result<PagedTerrain<'a>> {
        if !n.is_power_of_two() {
            return Err(Error::invalid(
                "tile size",
                format!("tiles of {n} cells: not a power of two"),
            ));
        }
        check_origin(origin, n, top)?;
        let window_top = top;
        let top = traversal_top(origin, top);
        let origin = [origin[0] as u64, origin[1] as u64];
        let log2n = n.trailing_zeros();
        Ok(PagedTerrain {
            table,
            slots,
            n: n as u64,
            log2n,
            fine: table.levels().len() as u32 - 1,
            origin,
            top,
            map: ResidencyMap::new(table, log2n, origin, top as u32, window_top as u32),
        })
    }

    /// Global cell of window cell `(i, j)` of level `level`.
    fn global(&self, level: u32, i: usize, j: usize) -> [u64; 2] {
        [
            (self.origin[0] >> level) + i as u64,
            (self.origin[1] >> level) + j as u64,
        ]
    }

    /// Global cell `g` of virtual level `level` on database level F − `jj`'s own cell grid.
    fn cell_on(level: u32, g: [u64; 2], jj: u32) -> [u64; 2] {
        if jj <= level {
            [g[0] << (level - jj), g[1] << (level - jj)]
        } else {
            [g[0] >> (jj - level), g[1] >> (jj - level)]
        }
    }

    fn tile_at(&self, jj: u32, c: [u64; 2]) -> Option<&'a Tile> {
        let id = TileId {
            level: self.fine - jj,
            x: u32::try_from(c[0] >> self.log2n).ok()?,
            y: u32::try_from(c[1] >> self.log2n).ok()?,
        };
        let slot = self.table.slot(id)?;
        self.slots.get(slot as usize)?.as_deref()
    }

    /// The coarseness `jj` (database level F − jj) of the finest resident level over window
    /// cell `(i, j)` of `level`, and its tile; `None` where nothing is resident
    /// (`finest_resident` in WGSL): one read of the residency map.
    pub fn finest_resident(&self, level: u32, i: usize, j: usize) -> Option<(u32, &'a Tile)> {
        let e = self.map.entry(level, self.global(level, i, j));
        if e == MAP_NONE {
            return None;
        }
        let tile = self.slots.get((e & SLOT_MASK) as usize)?.as_deref()?;
        Some((e >> 24, tile))
    }

    /// [`PagedTerrain::finest_resident`] found by searching the page table from the finest
    /// level that can hold the cell upwards, a tile lookup per level (what the residency map
    /// replaces; the tests hold the two equal).
    pub fn finest_resident_searched(
        &self,
        level: u32,
        i: usize,
        j: usize,
    ) -> Option<(u32, &'a Tile)> {
        let g = self.global(level, i, j);
        (level.saturating_sub(self.log2n)..=self.fine).find_map(|jj| {
            let c = Self::cell_on(level, g, jj);
            self.tile_at(jj, c).map(|t| (jj, t))
        })
    }

    /// A bound on the terrain over window cell `(i, j)` of `level` ([`PAD`] where nothing is
    /// resident): the finest resident level's maximum (`cell_max` in WGSL).
    pub fn cell_max(&self, level: u32, i: usize, j: usize) -> f64 {
        let Some((jj, tile)) = self.finest_resident(level, i, j) else {
            return PAD as f64;
        };
        let c = Self::cell_on(level, self.global(level, i, j), jj);
        let m = level.saturating_sub(jj);
        let local = |x: u64| ((x & (self.n - 1)) >> m) as usize;
        tile.cell_max(m, local(c[0]), local(c[1])) as f64
    }

    /// Corner heights `(h00, h10, h01, h11)` of window cell `(i, j)` of `level`: the samples
    /// of database level F − level where resident, otherwise the cell's corners on the finest
    /// resident coarser level's bilinear surface (`patch_corners` in WGSL). NaN where nothing
    /// is resident.
    pub fn patch_corners(&self, level: u32, i: usize, j: usize) -> [f64; 4] {
        let Some((jr, resident)) = self.finest_resident(level, i, j) else {
            return [f64::NAN; 4];
        };
        let jj = jr.max(level);
        let g = self.global(level, i, j);
        // The map's tile where it is this level or coarser; a finer level resident under a
        // coarser patch (footprint LOD) reads that level's tile from the page table.
        let tile = if jr >= level {
            resident
        } else {
            match self.tile_at(jj, Self::cell_on(level, g, jj)) {
                Some(t) => t,
                None => return [f64::NAN; 4],
            }
        };
        let k = jj - level;
        let s = (1u64 << k) as f64;
        let base = [g[0] >> k, g[1] >> k];
        let frac = [
            (g[0] - (base[0] << k)) as f64 / s,
            (g[1] - (base[1] << k)) as f64 / s,
        ];
        let (a, b) = (
            (base[0] & (self.n - 1)) as usize,
            (base[1] & (self.n - 1)) as usize,
        );
        let h = |di: usize, dj: usize| tile.height(a + di, b + dj) as f64;
        let (h00, h10, h01, h11) = (h(0, 0), h(1, 0), h(0, 1), h(1, 1));
        let at = |u: f64, v: f64| {
            let south = h00 + (h10 - h00) * u;
            let north = h01 + (h11 - h01) * u;
            south + (north - south) * v
        };
        let inv = 1.0 / s;
        [
            at(frac[0], frac[1]),
            at(frac[0] + inv, frac[1]),
            at(frac[0], frac[1] + inv),
            at(frac[0] + inv, frac[1] + inv),
        ]
    }

    /// Whether a ray at window cell `(i, j)` of `level > 0` intersects this level's patch
    /// instead of descending: the finest resident level over the cell is this one or coarser.
    fn stops(&self, level: u32, i: usize, j: usize) -> bool {
        level == 0
            || self
                .finest_resident(level, i, j)
                .is_none_or(|(jj, _)| jj >= level)
    }
}

/// Refuses a paged window whose sample (0, 0), sample `origin` of the finest level, is
/// negative or not on a tile's corner: a multiple of `n` finest samples (or of the window
/// pyramid's top cell, `2^top`, where that is smaller).
pub fn check_origin(origin: [i64; 2], n: usize, top: usize) -> Result<()> {
    let align = (1i64 << top.min(62)).min(n as i64);
    if origin.iter().any(|&o| o < 0 || o % align != 0) {
        return Err(Error::invalid(
            "terrain.window",
            format!(
                "a paged window must start on a tile's corner, a multiple of {align} finest \
                 samples; got sample ({}, {})",
                origin[0], origin[1]
            ),
        ));
    }
    Ok(())
}

/// The top level of a paged traversal over a window whose sample (0, 0) is finest sample
/// `origin` and whose pyramid's top is `top`: the highest level `≤ top` whose cells the
/// origin is aligned to (the largest power of two dividing both coordinates; 0 divides all),
/// so that every window cell the traversal visits lies inside one database cell. A window
/// aligned to its top cell starts from that one cell; one aligned to tiles only starts from
/// a grid of tile-sized cells (more steps for rays that cross much of the window).
pub fn traversal_top(origin: [i64; 2], top: usize) -> usize {
    let twos = |o: i64| o.trailing_zeros() as usize;
    top.min(twos(origin[0])).min(twos(origin[1]))
}

/// The paged traversal of `r` over `terrain`'s box (a terrain with walls; `terrain` gives the
/// box and the pyramid's shape, the data comes from `paged`): the first hit `(t, finest
/// cell)`. `stats.hit_level` is the level of the patch hit (0: full resolution there).
pub fn intersect_paged(
    terrain: &Terrain,
    paged: &PagedTerrain,
    r: &GridRay,
    [t_min, t_max]: [f64; 2],
    max_steps: u32,
    stats: &mut TraversalStats,
) -> Option<(f64, [usize; 2])> {
    let (t0, t1) = clip_to_box(terrain, r, t_min, t_max)?;
    let pyr = &terrain.pyramid;
    let top = paged.top;
    let slack = height_slack(terrain);
    let (mut level, mut t) = (top, t0);
    let cells = |level: usize| pyr.levels[level].cells;
    let (mut ix, mut iy) = r.cell_at(t, level, cells(level));
    let (sx, sy) = r.cell_steps();
    while stats.steps < max_steps {
        stats.steps += 1;
        let s = (1u64 << level) as f64;
        let (tx, ty) = r.cell_exits(level, (ix, iy), (sx, sy));
        let t_exit = tx.min(ty).min(t1).max(t);
        let (lv, ci, cj) = (level as u32, ix as usize, iy as usize);
        let cell_max = paged.cell_max(lv, ci, cj);
        if r.lowest(t, t_exit) <= cell_max + slack && cell_max > PAD as f64 {
            if !paged.stops(lv, ci, cj) {
                let p = r.at(t);
                let half = s * 0.5;
                let (mx, my) = ((2 * ix + 1) as f64 * half, (2 * iy + 1) as f64 * half);
                level -= 1;
                let c = cells(level);
                ix = (2 * ix + (p.x > mx || (p.x == mx && sx > 0)) as i64).min(c[0] as i64 - 1);
                iy = (2 * iy + (p.y > my || (p.y == my && sy > 0)) as i64).min(c[1] as i64 - 1);
                continue;
            }
            stats.patch_tests += 1;
            stats.lod_patches += (level > 0) as u32;
            let corners = paged.patch_corners(lv, ci, cj);
            let (qa, qb, qc) = patch_quadratic_of(corners, r, (level, ci, cj), t);
            let hit = if qc <= 0.0 {
                Some(t)
            } else {
                first_root(qa, qb, qc, t_exit - t).map(|s| t + s)
            };
            if let Some(th) = hit {
                stats.hit_level = lv;
                return Some((th, finest_cell(terrain, level, ix, iy, r.at(th))));
            }
        }
        if t_exit >= t1 {
            return None;
        }
        let (mut ox, mut oy) = (ix, iy);
        if tx <= ty {
            ix += sx;
        }
        if ty <= tx {
            iy += sy;
        }
        t = t_exit;
        while level < top && ((ix >> 1) != (ox >> 1) || (iy >> 1) != (oy >> 1)) {
            level += 1;
            (ix, iy, ox, oy) = (ix >> 1, iy >> 1, ox >> 1, oy >> 1);
        }
        let c = cells(level);
        if ix < 0 || iy < 0 || ix >= c[0] as i64 || iy >= c[1] as i64 {
            return None;
        }
    }
    stats.exhausted = true;
    None
}

/// The level-0 cell under `p` within cell `(ix, iy)` of `level`.
fn finest_cell(terrain: &Terrain, level: usize, ix: i64, iy: i64, p: DVec3) -> [usize; 2] {
    let [cw, ch] = terrain.cells();
    let s = 1i64 << level;
    let pick = |x: f64, i: i64, n: usize| -> usize {
        ((x.floor() as i64).clamp(i * s, (i + 1) * s - 1) as usize).min(n - 1)
    };
    [pick(p.x, ix, cw), pick(p.y, iy, ch)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_traversal_starts_at_the_level_the_origin_is_aligned_to() {
        // Aligned to the top cell (2^11): from the top.
        assert_eq!(traversal_top([49152, 34816], 11), 11);
        assert_eq!(traversal_top([0, 0], 11), 11);
        // Aligned to tiles of 256 only.
        assert_eq!(traversal_top([49408, 35072], 11), 8);
        assert_eq!(traversal_top([49152, 35072], 11), 8);
        // Tiles' corners are what a paged window needs; else one-line errors.
        assert!(check_origin([49408, 35072], 256, 11).is_ok());
        let e = check_origin([49408, 35073], 256, 11)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tile's corner") && e.contains("256"), "{e}");
        assert!(check_origin([-256, 0], 256, 11).is_err());
        // A window smaller than a tile: its own top cell.
        assert!(check_origin([64, 128], 256, 6).is_ok());
    }
}
