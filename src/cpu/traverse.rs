//! Top-down maximum-pyramid traversal with exact bilinear-patch intersection.
//!
//! Per ray, in the grid frame: clip to the terrain's box; start at the top level; at each cell
//! compute the ray's exit; skip the cell when the lower end of the ray segment over it is above
//! the cell's maximum; otherwise descend to the child containing the entry point; at level 0
//! intersect the bilinear patch exactly (a quadratic in t, re-centred on the entry point).
//! After a crossing climb while the new cell's parent differs from the old one's.
//!
//! Walls: a ray already below the surface where it enters the box (through a side of the
//! grid, its floor, or from an origin underground) meets the patch test's `C ≤ 0` at once,
//! i.e. the terrain renders as a solid block with vertical side walls down to the lowest
//! sample and a floor there. With `terrain.walls = false` such a ray instead passes under the
//! surface until it comes up through it ([`patch_hit_from_below`]).
//!
//! Curved earth (`terrain.curved`): the ray carries the picture's [`GridCurvature`] (the
//! eye's paraboloid); its height above the curved datum is `z(t) + drop(x(t), y(t))`, a convex
//! quadratic in `t`, which the box clip, the cell bound test and the patch quadratic use in
//! place of `z(t)` (see `docs/database.md#curved-earth`). Flat: `drop = 0`, the same
//! arithmetic as before.

use crate::terrain::curved::GridCurvature;
use crate::terrain::pyramid::PAD;
use crate::terrain::Terrain;
use glam::DVec3;

/// A ray in the grid frame: `p(t) = o + d t`, with `t` in world metres, and the curvature of
/// the picture it belongs to ([`GridCurvature::FLAT`] on a flat terrain).
#[derive(Clone, Copy, Debug)]
pub struct GridRay {
    pub o: DVec3,
    pub d: DVec3,
    pub curv: GridCurvature,
}

impl GridRay {
    /// The grid-frame ray of a world ray (`dir` must be unit length for `t` in metres), seen
    /// from its own origin: on a curved terrain the world frame is the origin's tangent frame.
    pub fn from_world(terrain: &Terrain, origin: DVec3, dir: DVec3) -> GridRay {
        Self::seen_from(terrain, origin, dir, terrain.curvature(origin))
    }
    /// As [`GridRay::from_world`] in the tangent frame of another eye (`curv`, from
    /// [`Terrain::curvature`] of the camera): shadow rays of a picture.
    ///
    /// The direction is measured in the eye's metric ([`GridCurvature::metric`]): a metre
    /// along the ray is a metre of the ground at the eye's latitude.
    pub fn seen_from(terrain: &Terrain, origin: DVec3, dir: DVec3, curv: GridCurvature) -> GridRay {
        let d = terrain.frame.world_dir_to_grid(dir);
        GridRay {
            o: terrain.frame.world_to_grid(origin),
            d: DVec3::new(d.x / curv.metric.x, d.y / curv.metric.y, d.z),
            curv,
        }
    }
    #[inline]
    pub fn at(&self, t: f64) -> DVec3 {
        self.o + self.d * t
    }
    /// The cell of `level` (2^level grid units a side, `cells` across and down) holding the
    /// ray's point at `t`, clamped into the grid.
    pub fn cell_at(&self, t: f64, level: usize, cells: [u32; 2]) -> (i64, i64) {
        let (p, s) = (self.at(t), (1u64 << level) as f64);
        (
            ((p.x / s).floor() as i64).clamp(0, i64::from(cells[0]) - 1),
            ((p.y / s).floor() as i64).clamp(0, i64::from(cells[1]) - 1),
        )
    }
    /// The cell steps along x and y: +1 or -1.
    pub fn cell_steps(&self) -> (i64, i64) {
        (
            if self.d.x >= 0.0 { 1 } else { -1 },
            if self.d.y >= 0.0 { 1 } else { -1 },
        )
    }
    /// Where the ray leaves cell (`ix`, `iy`) of `level` across x and across y, stepping
    /// [`GridRay::cell_steps`] `(sx, sy)` (infinite along an axis it does not move on).
    pub fn cell_exits(
        &self,
        level: usize,
        (ix, iy): (i64, i64),
        (sx, sy): (i64, i64),
    ) -> (f64, f64) {
        let s = (1u64 << level) as f64;
        let exit = |i: i64, step: i64, o: f64, d: f64| {
            if d.abs() < 1e-300 {
                f64::INFINITY
            } else {
                (((i + (step > 0) as i64) as f64) * s - o) / d
            }
        };
        (
            exit(ix, sx, self.o.x, self.d.x),
            exit(iy, sy, self.o.y, self.d.y),
        )
    }
    /// Height of the ray at `t` above the curved datum: `z(t) + drop(x(t), y(t))`.
    #[inline]
    pub fn lifted(&self, t: f64) -> f64 {
        let p = self.at(t);
        p.z + self.curv.drop(p.x, p.y)
    }
    /// `lifted(t) = A t² + B t + C` (A ≥ 0): the coefficients, `x − eye` taken before squaring.
    pub fn lifted_quadratic(&self) -> (f64, f64, f64) {
        let k = self.curv.k;
        let (ex, ey) = (self.o.x - self.curv.eye.x, self.o.y - self.curv.eye.y);
        (
            k.x * self.d.x * self.d.x + k.y * self.d.y * self.d.y,
            self.d.z + 2.0 * (k.x * ex * self.d.x + k.y * ey * self.d.y),
            self.o.z + self.curv.drop(self.o.x, self.o.y),
        )
    }
    /// Lowest height above the curved datum over `[ta, tb]` (the lower end of the segment on
    /// a flat terrain; else also the vertex of the convex quadratic where it lies inside).
    pub fn lowest(&self, ta: f64, tb: f64) -> f64 {
        if self.curv.is_flat() {
            return (self.o.z + self.d.z * ta).min(self.o.z + self.d.z * tb);
        }
        let (a, b, _) = self.lifted_quadratic();
        let mut low = self.lifted(ta).min(self.lifted(tb));
        if a > 0.0 {
            let tv = -b / (2.0 * a);
            if tv > ta && tv < tb {
                low = low.min(self.lifted(tv));
            }
        }
        low
    }
}

/// A ray–terrain hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit, world) ray in metres.
    pub t: f64,
    /// World position.
    pub point: DVec3,
    /// World unit normal of the bilinear patch.
    pub normal: DVec3,
    /// Grid cell hit.
    pub cell: [usize; 2],
}

/// Work done by one traversal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalStats {
    /// Loop iterations (cells visited at any level).
    pub steps: u32,
    /// Exact bilinear-patch tests.
    pub patch_tests: u32,
    /// True when the step limit ended the walk.
    pub exhausted: bool,
    /// Patch tests at a level above 0 (footprint level of detail).
    pub lod_patches: u32,
    /// Pyramid level of the patch that was hit (0: the finest; above 0 only with LOD).
    pub hit_level: u32,
}

/// Footprint level of detail of one ray: a cell of level L may stand in for its samples where
/// `2^L ≤ k · t` (t: its entry distance in metres), `k = lod · 2 · cone / max spacing` with
/// `cone` the pixel's cone half-angle (radians, the ray table's w). `lod ≤ 0` or `cone ≤ 0`:
/// 0, never (the shader's `lod_k`, computed in f32 there).
pub fn lod_factor(terrain: &Terrain, lod: f64, cone: f64) -> f64 {
    let s = terrain.frame.spacing[0].max(terrain.frame.spacing[1]);
    if lod > 0.0 && cone > 0.0 {
        lod * 2.0 * cone / s
    } else {
        0.0
    }
}

/// Tolerance (metres) added to the box and to every cell maximum so that rounding never skips
/// a cell the ray touches (a flat terrain has a box of zero height). Shared with the shader.
pub fn height_slack(terrain: &Terrain) -> f64 {
    1e-6 * (1.0 + (terrain.min_height.abs().max(terrain.max_height.abs())) as f64)
}

/// Clips a grid ray to the terrain's bounding box intersected with `[t_min, t_max]`.
pub fn clip_to_box(terrain: &Terrain, r: &GridRay, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
    let [cw, ch] = terrain.cells();
    let slack = height_slack(terrain);
    let lo = DVec3::new(0.0, 0.0, terrain.min_height as f64 - slack);
    let hi = DVec3::new(cw as f64, ch as f64, terrain.max_height as f64 + slack);
    let (mut t0, mut t1) = (t_min, t_max);
    let axes = if r.curv.is_flat() { 3 } else { 2 };
    if axes == 2 {
        (t0, t1) = clip_curved_slab(r, lo.z, hi.z, t0, t1)?;
    }
    for a in 0..axes {
        let (o, d) = (r.o[a], r.d[a]);
        if d.abs() < 1e-300 {
            if o < lo[a] || o > hi[a] {
                return None;
            }
        } else {
            let (mut ta, mut tb) = ((lo[a] - o) / d, (hi[a] - o) / d);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// The curved z-slab: `t` in `[t0, t1]` where the ray's height above the curved datum
/// (a convex quadratic) is at most `hi`; for an origin below `lo` (underground), from where it
/// comes back above `lo`.
fn clip_curved_slab(r: &GridRay, lo: f64, hi: f64, t0: f64, t1: f64) -> Option<(f64, f64)> {
    let (a, b, c) = r.lifted_quadratic();
    let (mut t0, mut t1) = (t0, t1);
    // Roots of a t² + b t + (c − h), stable formula; a > 0.
    let roots = |h: f64| -> Option<(f64, f64)> {
        let cc = c - h;
        let disc = b * b - 4.0 * a * cc;
        if disc < 0.0 {
            return None;
        }
        let q = -0.5 * (b + b.signum() * disc.sqrt());
        let (r1, r2) = (q / a, if q != 0.0 { cc / q } else { 0.0 });
        Some((r1.min(r2), r1.max(r2)))
    };
    if a <= 0.0 {
        // Vertical ray: the flat slab.
        if b.abs() < 1e-300 {
            if c < lo || c > hi {
                return None;
            }
        } else {
            let (ta, tb) = ((lo - c) / b, (hi - c) / b);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        return (t0 <= t1).then_some((t0, t1));
    }
    let (ra, rb) = roots(hi)?;
    t0 = t0.max(ra);
    t1 = t1.min(rb);
    if c < lo {
        if let Some((_, up)) = roots(lo) {
            t0 = t0.max(up);
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// First `s` in `[0, s_max]` where `A s² + B s + C` reaches 0 from above, given `C > 0`.
/// Stable quadratic formula with a linear fallback.
#[inline]
pub fn first_root(a: f64, b: f64, c: f64, s_max: f64) -> Option<f64> {
    let mut best = f64::INFINITY;
    if a.abs() < 1e-12 * (b.abs() + c.abs()).max(1e-300) {
        if b < 0.0 {
            best = -c / b;
        }
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc >= 0.0 {
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            for r in [q / a, if q != 0.0 { c / q } else { f64::INFINITY }] {
                if r >= 0.0 && r < best {
                    best = r;
                }
            }
        }
    }
    (best <= s_max).then_some(best)
}

/// Exact intersection with the bilinear patch of cell `(i, j)` for `t` in `[t_a, t_b]`.
pub fn patch_hit(
    terrain: &Terrain,
    r: &GridRay,
    i: usize,
    j: usize,
    t_a: f64,
    t_b: f64,
) -> Option<f64> {
    patch_hit_at(terrain, r, (0, i, j), t_a, t_b)
}

/// [`patch_hit`] with the bilinear patch of cell `(i, j)` of pyramid level `level`
/// ([`patch_corners`]).
pub fn patch_hit_at(
    terrain: &Terrain,
    r: &GridRay,
    (level, i, j): (usize, usize, usize),
    t_a: f64,
    t_b: f64,
) -> Option<f64> {
    let (qa, qb, qc) = patch_quadratic(terrain, r, (level, i, j), t_a);
    if qc <= 0.0 {
        return Some(t_a);
    }
    first_root(qa, qb, qc, t_b - t_a).map(|s| t_a + s)
}

/// As [`patch_hit`] for a ray that may be below the surface (`*under`, terrain without
/// walls): such a ray hits nothing until it has come up through the surface, and then only
/// where it goes down through it again. `*under` is cleared once the ray is above the
/// surface (at the cell entry or where it comes out within the cell).
pub fn patch_hit_from_below(
    terrain: &Terrain,
    r: &GridRay,
    (level, i, j): (usize, usize, usize),
    t_a: f64,
    t_b: f64,
    under: &mut bool,
) -> Option<f64> {
    let (qa, qb, qc) = patch_quadratic(terrain, r, (level, i, j), t_a);
    let s_max = t_b - t_a;
    if qc > 0.0 {
        *under = false;
        return first_root(qa, qb, qc, s_max).map(|s| t_a + s);
    }
    // q(s) = qa s² + qb s + qc with q(0) ≤ 0. Roots by the stable formula.
    let disc = qb * qb - 4.0 * qa * qc;
    let linear = qa.abs() < 1e-12 * (qb.abs() + qc.abs()).max(1e-300);
    if disc < 0.0 {
        return None; // q < 0 throughout (qa < 0): stays below
    }
    let q = -0.5 * (qb + qb.signum() * disc.sqrt());
    let r2 = if q != 0.0 { qc / q } else { f64::INFINITY };
    if linear {
        // Comes up through the surface where the line crosses 0 (qb > 0), never goes down.
        if r2 >= 0.0 && r2 <= s_max {
            *under = false;
        }
        return None;
    }
    let r1 = q / qa;
    let (lo, hi) = (r1.min(r2), r1.max(r2));
    if qa < 0.0 {
        // Positive between the roots: out at `lo`, back down (a hit from above) at `hi`.
        if lo >= 0.0 && lo <= s_max {
            *under = false;
            if hi <= s_max {
                return Some(t_a + hi);
            }
        }
        None
    } else {
        // Negative between the roots and 0 lies between them: out at `hi`, never down again.
        if hi >= 0.0 && hi <= s_max {
            *under = false;
        }
        None
    }
}

/// Corner heights `(h00, h10, h01, h11)` of the bilinear patch of cell `(i, j)` of pyramid
/// level `level`: the finest samples at `(i, j) · 2^L` and `(i + 1, j + 1) · 2^L` (the
/// decimated grid; level 0: the cell's own samples), the far corner clamped to the grid's last
/// sample (a coarse cell over the grid's edge). The shader's `patch_corners`.
pub fn patch_corners(terrain: &Terrain, level: usize, i: usize, j: usize) -> [f64; 4] {
    let f = &terrain.field;
    let [cw, ch] = terrain.cells();
    let (i0, j0) = (i << level, j << level);
    let (i1, j1) = (((i + 1) << level).min(cw), ((j + 1) << level).min(ch));
    [
        f.at(i0, j0) as f64,
        f.at(i1, j0) as f64,
        f.at(i0, j1) as f64,
        f.at(i1, j1) as f64,
    ]
}

/// The bilinear patch of cell `(i, j)` of `level` along the ray, re-centred on `t_a`: ray
/// height above the patch is `qa s² + qb s + qc` at `t = t_a + s`. Above level 0 the patch
/// spans 2^L samples per side: the same quadratic in the grid scaled by 2^-L (the drop terms
/// stay in the finest grid's units).
fn patch_quadratic(
    terrain: &Terrain,
    r: &GridRay,
    (level, i, j): (usize, usize, usize),
    t_a: f64,
) -> (f64, f64, f64) {
    patch_quadratic_of(patch_corners(terrain, level, i, j), r, (level, i, j), t_a)
}

/// `patch_quadratic` of a patch with the corner heights `(h00, h10, h01, h11)` given (the
/// paged terrain's corners, `cpu::paged`).
pub fn patch_quadratic_of(
    [h00, h10, h01, h11]: [f64; 4],
    r: &GridRay,
    (level, i, j): (usize, usize, usize),
    t_a: f64,
) -> (f64, f64, f64) {
    let (a, b, c, e) = (h00, h10 - h00, h01 - h00, h00 - h10 - h01 + h11);
    let p = r.at(t_a);
    let (qa, qb, qc) = if level == 0 {
        let (u0, v0) = (p.x - i as f64, p.y - j as f64);
        (
            -e * r.d.x * r.d.y,
            r.d.z - b * r.d.x - c * r.d.y - e * (u0 * r.d.y + v0 * r.d.x),
            p.z - (a + b * u0 + c * v0 + e * u0 * v0),
        )
    } else {
        let inv = 1.0 / (1u64 << level) as f64;
        let (u0, v0) = (p.x * inv - i as f64, p.y * inv - j as f64);
        let (dx, dy) = (r.d.x * inv, r.d.y * inv);
        (
            -e * dx * dy,
            r.d.z - b * dx - c * dy - e * (u0 * dy + v0 * dx),
            p.z - (a + b * u0 + c * v0 + e * u0 * v0),
        )
    };
    if r.curv.is_flat() {
        return (qa, qb, qc);
    }
    // The drop along the ray from p: k·(p − eye + d s)², exact in s.
    let k = r.curv.k;
    let (ex, ey) = (p.x - r.curv.eye.x, p.y - r.curv.eye.y);
    (
        qa + k.x * r.d.x * r.d.x + k.y * r.d.y * r.d.y,
        qb + 2.0 * (k.x * ex * r.d.x + k.y * ey * r.d.y),
        qc + r.curv.drop(p.x, p.y),
    )
}

/// Traverses the pyramid; returns the first hit `(t, cell)` in `[t_min, t_max]`. The
/// terrain's `walls` decide what a ray below the surface where it enters the terrain's box
/// meets: with walls (the default) the side walls and floor of the block at once, without
/// them nothing until it comes up through the surface (the surface is seen from above only).
pub fn intersect(
    terrain: &Terrain,
    r: &GridRay,
    t_min: f64,
    t_max: f64,
    max_steps: u32,
    stats: &mut TraversalStats,
) -> Option<(f64, [usize; 2])> {
    intersect_with_walls(terrain, r, t_min, t_max, max_steps, stats, terrain.walls)
}

/// Height of the bilinear surface at grid `(x, y)` clamped to the grid (the shader's
/// `surface_height`).
pub fn surface_height_clamped(terrain: &Terrain, x: f64, y: f64) -> f64 {
    let [cw, ch] = terrain.cells();
    terrain
        .height_at_grid(x.clamp(0.0, cw as f64), y.clamp(0.0, ch as f64))
        .unwrap_or(f64::NAN)
}

/// [`intersect`] with the walls switch given instead of taken from the terrain.
pub fn intersect_with_walls(
    terrain: &Terrain,
    r: &GridRay,
    t_min: f64,
    t_max: f64,
    max_steps: u32,
    stats: &mut TraversalStats,
    walls: bool,
) -> Option<(f64, [usize; 2])> {
    intersect_lod(terrain, r, [t_min, t_max], max_steps, stats, walls, 0.0)
}

/// Whether a cell of `level` entered at `t` may stand in for its samples: its side is within
/// the footprint (`2^L ≤ lod_k · t`, [`lod_factor`]).
#[inline]
fn lod_stops(level: usize, t: f64, lod_k: f64) -> bool {
    level > 0 && ((1u64 << level) as f64) <= lod_k * t
}

/// The level-0 cell under grid point `p` within cell `(ix, iy)` of `level`: the cell a hit
/// reports (the shade pass takes its normal there).
fn finest_cell(terrain: &Terrain, level: usize, ix: i64, iy: i64, p: DVec3) -> [usize; 2] {
    let [cw, ch] = terrain.cells();
    let s = 1i64 << level;
    let pick = |x: f64, i: i64, n: usize| -> usize {
        ((x.floor() as i64).clamp(i * s, (i + 1) * s - 1) as usize).min(n - 1)
    };
    [pick(p.x, ix, cw), pick(p.y, iy, ch)]
}

/// [`intersect_with_walls`] with footprint level of detail: `lod_k` from [`lod_factor`]
/// (0: off, the exact traversal). A hit on a coarse patch reports the level-0 cell under the
/// hit point and its level in `stats.hit_level`.
pub fn intersect_lod(
    terrain: &Terrain,
    r: &GridRay,
    [t_min, t_max]: [f64; 2],
    max_steps: u32,
    stats: &mut TraversalStats,
    walls: bool,
    lod_k: f64,
) -> Option<(f64, [usize; 2])> {
    let (t0, t1) = clip_to_box(terrain, r, t_min, t_max)?;
    // Without walls: is the ray below the surface where it enters the box?
    let mut under = !walls && {
        let p = r.at(t0);
        r.lifted(t0) < surface_height_clamped(terrain, p.x, p.y)
    };
    let pyr = &terrain.pyramid;
    let top = pyr.top();
    let slack = height_slack(terrain);
    let mut level = top;
    let mut t = t0;
    let (mut ix, mut iy) = r.cell_at(t, level, pyr.levels[level].cells);
    let (sx, sy) = r.cell_steps();
    while stats.steps < max_steps {
        stats.steps += 1;
        let s = (1u64 << level) as f64;
        let (tx, ty) = r.cell_exits(level, (ix, iy), (sx, sy));
        let t_exit = tx.min(ty).min(t1).max(t);
        let cell_max = pyr.get(level, ix, iy) as f64;
        let z_low = r.lowest(t, t_exit);
        if z_low <= cell_max + slack && cell_max > PAD as f64 {
            if level > 0 && !lod_stops(level, t, lod_k) {
                // Descend to the child holding the entry point.
                let p = r.at(t);
                let half = s * 0.5;
                let (mx, my) = ((2 * ix + 1) as f64 * half, (2 * iy + 1) as f64 * half);
                let cx = 2 * ix + (p.x > mx || (p.x == mx && sx > 0)) as i64;
                let cy = 2 * iy + (p.y > my || (p.y == my && sy > 0)) as i64;
                level -= 1;
                let l = &pyr.levels[level];
                ix = cx.min(l.cells[0] as i64 - 1);
                iy = cy.min(l.cells[1] as i64 - 1);
                continue;
            }
            stats.patch_tests += 1;
            stats.lod_patches += (level > 0) as u32;
            let cell = (level, ix as usize, iy as usize);
            let hit = if under {
                patch_hit_from_below(terrain, r, cell, t, t_exit, &mut under)
            } else {
                patch_hit_at(terrain, r, cell, t, t_exit)
            };
            if let Some(th) = hit {
                stats.hit_level = level as u32;
                return Some((th, finest_cell(terrain, level, ix, iy, r.at(th))));
            }
        }
        // Advance to the next cell.
        if t_exit >= t1 {
            return None;
        }
        let (ox, oy) = (ix, iy);
        if tx <= ty {
            ix += sx;
        }
        if ty <= tx {
            iy += sy;
        }
        t = t_exit;
        // Climb while the new cell's parent differs from the old one's.
        let (mut ox, mut oy) = (ox, oy);
        while level < top && ((ix >> 1) != (ox >> 1) || (iy >> 1) != (oy >> 1)) {
            level += 1;
            ix >>= 1;
            iy >>= 1;
            ox >>= 1;
            oy >>= 1;
        }
        let l = &pyr.levels[level];
        if ix < 0 || iy < 0 || ix >= l.cells[0] as i64 || iy >= l.cells[1] as i64 {
            return None;
        }
    }
    stats.exhausted = true;
    None
}

/// Full hit record for a grid-space hit. On a curved terrain the point is in the eye's
/// tangent frame (its z is the surface's height less the drop) and the normal tilts with the
/// drop's gradient.
pub fn make_hit(terrain: &Terrain, r: &GridRay, t: f64, cell: [usize; 2]) -> Hit {
    let p = r.at(t);
    let f = &terrain.field;
    let [i, j] = cell;
    let (h00, h10, h01, h11) = (
        f.at(i, j) as f64,
        f.at(i + 1, j) as f64,
        f.at(i, j + 1) as f64,
        f.at(i + 1, j + 1) as f64,
    );
    let (u, v) = (
        (p.x - i as f64).clamp(0.0, 1.0),
        (p.y - j as f64).clamp(0.0, 1.0),
    );
    let e = h00 - h10 - h01 + h11;
    let g = r.curv.drop_gradient(p.x, p.y);
    // Per grid step; a step is `metric` times the frame's spacing in the eye's metric.
    let dhdx = (h10 - h00 + e * v - g.x) / r.curv.metric.x;
    let dhdy = (h01 - h00 + e * u - g.y) / r.curv.metric.y;
    Hit {
        t,
        point: terrain.frame.grid_to_world(p),
        normal: terrain.frame.normal_from_gradient(dhdx, dhdy),
        cell,
    }
}
