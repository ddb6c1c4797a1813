//! The page table: per level, per tile of the level's tile range, the pool slot holding it.

use super::super::format::{LevelInfo, TileId};

/// No slot.
pub const NONE: u32 = u32::MAX;

/// Per level a dense grid over its tile range `x0..x1`, `y0..y1`; [`NONE`] where not resident.
#[derive(Clone, Debug)]
pub struct PageTable {
    levels: Vec<LevelInfo>,
    /// Offset of each level's grid in `slots`.
    offsets: Vec<usize>,
    slots: Vec<u32>,
}

impl PageTable {
    pub fn new(levels: &[LevelInfo]) -> Self {
        let mut offsets = Vec::with_capacity(levels.len());
        let mut total = 0usize;
        for l in levels {
            offsets.push(total);
            total += ((l.x1 - l.x0) * (l.y1 - l.y0)) as usize;
        }
        PageTable {
            levels: levels.to_vec(),
            offsets,
            slots: vec![NONE; total],
        }
    }

    fn at(&self, id: TileId) -> Option<usize> {
        let l = self.levels.get(id.level as usize)?;
        let inside = (l.x0..l.x1).contains(&id.x) && (l.y0..l.y1).contains(&id.y);
        inside.then(|| {
            self.offsets[id.level as usize] + ((id.y - l.y0) * (l.x1 - l.x0) + id.x - l.x0) as usize
        })
    }

    /// The slot holding `id`, if resident.
    pub fn slot(&self, id: TileId) -> Option<u32> {
        self.at(id).map(|k| self.slots[k]).filter(|&s| s != NONE)
    }

    pub(super) fn set(&mut self, id: TileId, slot: Option<u32>) {
        if let Some(k) = self.at(id) {
            self.slots[k] = slot.unwrap_or(NONE);
        }
    }

    /// The finest resident tile at or above `id` (its ancestors, coarser and coarser), with
    /// its slot: where a ray over `id`'s region reads the terrain.
    pub fn finest_resident(&self, id: TileId) -> Option<(TileId, u32)> {
        let mut t = Some(id);
        while let Some(c) = t {
            if let Some(s) = self.slot(c) {
                return Some((c, s));
            }
            t = super::want::parent(c);
        }
        None
    }

    /// Whether `id` and every coarser ancestor of it are resident.
    pub fn chain_resident(&self, id: TileId) -> bool {
        let mut t = Some(id);
        while let Some(c) = t {
            if self.slot(c).is_none() {
                return false;
            }
            t = super::want::parent(c);
        }
        true
    }

    /// The levels (tile ranges) it covers.
    pub fn levels(&self) -> &[LevelInfo] {
        &self.levels
    }

    /// The table as the GPU reads it: per level its offset into [`PageTable::raw`], then the
    /// entries, level by level, row by row ([`NONE`] where not resident).
    pub fn offsets(&self) -> &[usize] {
        &self.offsets
    }
    pub fn raw(&self) -> &[u32] {
        &self.slots
    }
}
