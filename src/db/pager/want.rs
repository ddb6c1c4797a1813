//! What a view wants resident: the coarse floor everywhere, then finer tiles by screen
//! footprint, most needed first, within the pool's slots.
//!
//! A tile of a level finer than the floor is wanted when it is in view and its cells are at
//! least a pixel's footprint where the tile is nearest the eye (cell ≥ distance · pixel angle,
//! pixel angle = horizontal field of view / width), and its parent is wanted. Candidates are
//! taken greedily by that ratio (cell / footprint), largest first: at equal distance the
//! coarser, at equal level the nearer. A parent's ratio is at least twice its children's (twice
//! the cell, no farther), so the set taken is closed under parents whatever the budget cuts.

use super::super::format::{Header, IndexEntry, TileId};
use crate::terrain::heightfield::metres_per_degree;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

/// Where the eye is and where it looks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Eye longitude and latitude (degrees) and height (metres).
    pub lon: f64,
    pub lat: f64,
    pub height: f64,
    /// Degrees clockwise from north, and above the horizon.
    pub heading: f64,
    pub pitch: f64,
    /// Horizontal field of view (degrees) and the picture's size in pixels.
    pub fov: f64,
    pub width: u32,
    pub height_px: u32,
    /// The rays as a cone around the view direction where no pinhole frustum describes them
    /// (a display channel's distortion table): its half-angle and the smallest angle between
    /// neighbouring pixels' rays (radians). `None`: from `fov` and the picture's size.
    pub cone: Option<[f64; 2]>,
}

impl View {
    /// Radians a pixel subtends (the smallest, for a cone).
    pub fn pixel_angle(&self) -> f64 {
        match self.cone {
            Some([_, pixel]) => pixel,
            None => self.fov.to_radians() / self.width.max(1) as f64,
        }
    }

    /// Half-angle of a cone around the view direction holding the whole frustum.
    fn half_cone(&self) -> f64 {
        if let Some([half, _]) = self.cone {
            return half;
        }
        let tx = (0.5 * self.fov.to_radians()).tan();
        let ty = tx * self.height_px as f64 / self.width.max(1) as f64;
        tx.hypot(ty).atan()
    }

    fn direction(&self) -> [f64; 3] {
        let (h, p) = (self.heading.to_radians(), self.pitch.to_radians());
        [h.sin() * p.cos(), h.cos() * p.cos(), p.sin()]
    }
}

/// A tile's box around the eye, metres east, north and up.
struct TileBox {
    lo: [f64; 3],
    hi: [f64; 3],
}

/// Geometry of tiles seen from one view.
pub(super) struct Viewer<'a> {
    header: &'a Header,
    view: View,
    /// Metres per degree of longitude and latitude at the eye.
    m: (f64, f64),
    dir: [f64; 3],
    half_cone: f64,
    pixel: f64,
}

impl<'a> Viewer<'a> {
    pub fn new(header: &'a Header, view: View) -> Self {
        Viewer {
            header,
            view,
            // Past a pole the scale would turn negative: the pole's.
            m: metres_per_degree(view.lat.clamp(-90.0, 90.0)),
            dir: view.direction(),
            half_cone: view.half_cone(),
            pixel: view.pixel_angle(),
        }
    }

    fn tile_box(&self, e: &IndexEntry) -> TileBox {
        let lv = &self.header.levels[e.id.level as usize];
        let n = self.header.tile as i64;
        let (i0, j0) = (e.id.x as i64 * n, e.id.y as i64 * n);
        let east = |lon: f64| (lon - self.view.lon) * self.m.0;
        let north = |lat: f64| (lat - self.view.lat) * self.m.1;
        // Heights: the index's range (no-data tiles: the eye's height, a flat box).
        let (h0, h1) = if e.max > e.min && e.min > -1e29 {
            (e.min as f64, e.max as f64)
        } else {
            (self.view.height, self.view.height)
        };
        TileBox {
            lo: [east(lv.lon(i0)), north(lv.lat(j0)), h0 - self.view.height],
            hi: [
                east(lv.lon(i0 + n)),
                north(lv.lat(j0 + n)),
                h1 - self.view.height,
            ],
        }
    }

    /// Distance from the eye to the tile's box, metres (at least 1). An eye off the earth (a
    /// latitude past a pole, a camera flown to absurd coordinates) gets some distance, never a
    /// panic: the box's sides are taken in either order, and a NaN side counts as none.
    pub fn distance(&self, e: &IndexEntry) -> f64 {
        let b = self.tile_box(e);
        let mut d2 = 0.0;
        for k in 0..3 {
            let (lo, hi) = (b.lo[k].min(b.hi[k]), b.lo[k].max(b.hi[k]));
            let c = if lo > 0.0 {
                lo
            } else if hi < 0.0 {
                hi
            } else {
                0.0
            };
            d2 += c * c;
        }
        d2.sqrt().max(1.0)
    }

    /// Whether the tile's box may be in view (a sphere around it against a cone around the
    /// frustum: conservative).
    pub fn in_view(&self, e: &IndexEntry) -> bool {
        let b = self.tile_box(e);
        let c: Vec<f64> = (0..3).map(|k| 0.5 * (b.lo[k] + b.hi[k])).collect();
        let r = (0..3)
            .map(|k| 0.5 * (b.hi[k] - b.lo[k]))
            .map(|h| h * h)
            .sum::<f64>()
            .sqrt();
        let d = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        if d <= r {
            return true;
        }
        let cos = (c[0] * self.dir[0] + c[1] * self.dir[1] + c[2] * self.dir[2]) / d;
        cos.clamp(-1.0, 1.0).acos() - (r / d).asin() <= self.half_cone
    }

    /// Cell size over pixel footprint at the tile's nearest point.
    pub fn ratio(&self, e: &IndexEntry) -> f64 {
        let cell = self.header.levels[e.id.level as usize].spacing() * self.m.1.max(self.m.0);
        cell / (self.distance(e) * self.pixel)
    }
}

/// A candidate in the refinement heap.
struct Cand {
    ratio: f64,
    id: TileId,
}
impl PartialEq for Cand {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Cand {}
impl PartialOrd for Cand {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Cand {
    fn cmp(&self, o: &Self) -> Ordering {
        self.ratio
            .total_cmp(&o.ratio)
            .then_with(|| o.id.cmp(&self.id))
    }
}

/// The four children of `id` (those the level has).
pub(super) fn children(id: TileId) -> [TileId; 4] {
    let (x, y, level) = (2 * id.x, 2 * id.y, id.level + 1);
    [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(a, b)| TileId {
        level,
        x: x + a,
        y: y + b,
    })
}

/// The parent of `id` (none at level 0).
pub fn parent(id: TileId) -> Option<TileId> {
    (id.level > 0).then(|| TileId {
        level: id.level - 1,
        x: id.x / 2,
        y: id.y / 2,
    })
}

/// The wanted tiles, most needed first, at most `slots`: the floor tiles (nearest first),
/// then finer tiles in view whose cells are at least a pixel's footprint, by that ratio.
pub(super) fn wanted(
    viewer: &Viewer,
    index: &HashMap<TileId, IndexEntry>,
    floor: &[TileId],
    floor_level: u32,
    slots: usize,
) -> Vec<(TileId, f64)> {
    let mut out: Vec<(TileId, f64)> = floor
        .iter()
        .map(|id| (*id, viewer.distance(&index[id])))
        .collect();
    out.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    for w in &mut out {
        w.1 = f64::INFINITY;
    }
    let mut heap = BinaryHeap::new();
    let push = |heap: &mut BinaryHeap<Cand>, id: TileId| {
        for c in children(id) {
            if let Some(e) = index.get(&c) {
                let ratio = viewer.ratio(e);
                if ratio >= 1.0 && viewer.in_view(e) {
                    heap.push(Cand { ratio, id: c });
                }
            }
        }
    };
    for id in floor.iter().filter(|id| id.level == floor_level) {
        push(&mut heap, *id);
    }
    while out.len() < slots {
        let Some(c) = heap.pop() else { break };
        out.push((c.id, c.ratio));
        push(&mut heap, c.id);
    }
    out
}
