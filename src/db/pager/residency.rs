//! The residency map of a paged window: for every tile-sized cell of the window, at every
//! virtual level from a finest tile's up to the window's top cell, the finest resident
//! database level over it and the pool slot holding that tile, in one `u32`.
//!
//! The paged traversal asks "which is the finest resident level over this cell, and where is
//! its tile?" at every step. Searching the page table from the finest level up costs a tile
//! lookup per level tried (a range check and a table read each); the map answers with one read.
//! It is rebuilt on the host whenever the page table changes (a few thousand entries even for a
//! 16384² window), and read the same way by `terrain_paged.wgsl` (`paged_map_entry`) and by the
//! CPU twin (`cpu::paged::PagedTerrain`).
//!
//! **Why one entry per tile is enough.** Virtual level `L` cells are `2^L` finest cells on the
//! finest level's global grid; database level `F − j` holds cells of `2^j`. For `L ≤ log2 N`
//! a cell lies inside one finest-level tile, and every database tile containing that tile
//! contains the cell, so the finest resident level over the cell is that of its finest tile.
//! For `L = log2 N + k` (`k > 0`) the search starts at database level `F − k`, the level whose
//! tiles are exactly the cell; the map's level `k` holds that answer per cell. Residency is
//! hierarchical (a resident tile's ancestors are resident: the pager's invariant), but the map
//! does not rely on it: each entry is the page table's own answer.
//!
//! **Layout.** Map level `k` (`0 ..= levels − 1`) is a square of `side >> k` entries a side,
//! cell `(x, y)` relative to the window's first cell at that level (`origin >> (log2 N + k)`),
//! row by row; levels are stored finest first, level `k` starting at entry
//! `4 (side² − side_k²) / 3` — the layout of the square maximum pyramid (`pyramid_index`).

use super::super::format::TileId;
use super::table::PageTable;

/// No resident level (also the entry of a map cell off the database).
pub const MAP_NONE: u32 = u32::MAX;
/// Slot bits of an entry; the coarseness `j` sits in the top 8 bits.
pub const SLOT_MASK: u32 = 0x00ff_ffff;

/// See the module documentation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResidencyMap {
    /// Entries a side at map level 0 (a power of two).
    side: u32,
    /// Map levels: virtual levels `log2 N ..= log2 N + levels − 1`.
    levels: u32,
    log2n: u32,
    /// The finest database level F.
    fine: u32,
    /// The window's sample (0, 0) on the finest level's global grid.
    origin: [u64; 2],
    entries: Vec<u32>,
}

/// An entry: coarseness `j` and slot.
pub fn pack(j: u32, slot: u32) -> u32 {
    (j.min(254) << 24) | (slot & SLOT_MASK)
}

impl ResidencyMap {
    /// The map of a window whose sample (0, 0) is sample `origin` of the finest level, read by
    /// a traversal whose top level is `top` (cells of `2^top` finest cells, `origin` a
    /// multiple of it: `cpu::paged::traversal_top`), of a window whose own pyramid's top cell
    /// is `2^window_top` finest cells (the map's side), tiles of `2^log2n` cells, from `table`.
    /// Slots must fit 24 bits (a pool of 16 M tiles).
    pub fn new(
        table: &PageTable,
        log2n: u32,
        origin: [u64; 2],
        top: u32,
        window_top: u32,
    ) -> ResidencyMap {
        let levels = top.saturating_sub(log2n) + 1;
        let side = 1u32 << window_top.max(top).saturating_sub(log2n);
        let mut m = ResidencyMap {
            side,
            levels,
            log2n,
            fine: table.levels().len() as u32 - 1,
            origin,
            entries: vec![MAP_NONE; entry_count(side, levels)],
        };
        m.update(table);
        m
    }

    /// Rewrites every entry from `table` (the same window).
    pub fn update(&mut self, table: &PageTable) {
        for k in 0..self.levels {
            let s = self.side >> k;
            let base = Self::level_offset(self.side, k);
            let first = [
                self.origin[0] >> (self.log2n + k),
                self.origin[1] >> (self.log2n + k),
            ];
            for y in 0..s {
                for x in 0..s {
                    let g = [first[0] + x as u64, first[1] + y as u64];
                    let e = self.searched(k, g, table);
                    self.entries[base + (y * s + x) as usize] = e;
                }
            }
        }
    }

    /// The page table's answer for cell `g` of map level `k` (virtual level `log2 N + k`,
    /// global index): the finest resident tile at database level `F − k` or coarser.
    fn searched(&self, k: u32, g: [u64; 2], table: &PageTable) -> u32 {
        if k > self.fine {
            return MAP_NONE;
        }
        let (Ok(x), Ok(y)) = (u32::try_from(g[0]), u32::try_from(g[1])) else {
            return MAP_NONE;
        };
        let id = TileId {
            level: self.fine - k,
            x,
            y,
        };
        match table.finest_resident(id) {
            Some((t, slot)) => pack(self.fine - t.level, slot),
            None => MAP_NONE,
        }
    }

    fn level_offset(side: u32, k: u32) -> usize {
        let s = (side >> k) as usize;
        4 * ((side as usize).pow(2) - s * s) / 3
    }

    /// The entry over global cell `cell` of virtual level `level` ([`MAP_NONE`] off the map):
    /// `paged_map_entry` in `terrain_paged.wgsl`, operation for operation.
    pub fn entry(&self, level: u32, cell: [u64; 2]) -> u32 {
        let k = level.saturating_sub(self.log2n);
        if k >= self.levels {
            return MAP_NONE;
        }
        let shift = self.log2n + k - level;
        let s = (self.side >> k) as u64;
        let first = |o: u64| o >> (self.log2n + k);
        let t = [
            (cell[0] >> shift).wrapping_sub(first(self.origin[0])),
            (cell[1] >> shift).wrapping_sub(first(self.origin[1])),
        ];
        if t[0] >= s || t[1] >= s {
            return MAP_NONE;
        }
        self.entries[Self::level_offset(self.side, k) + (t[1] * s + t[0]) as usize]
    }

    /// The entries as the GPU reads them (`paged_map`).
    pub fn raw(&self) -> &[u32] {
        &self.entries
    }

    /// Entries a side at map level 0, and the map's levels (`PagedParams.map_side`,
    /// `map_levels`).
    pub fn shape(&self) -> (u32, u32) {
        (self.side, self.levels)
    }
}

fn entry_count(side: u32, levels: u32) -> usize {
    (0..levels).map(|k| ((side >> k) as usize).pow(2)).sum()
}
