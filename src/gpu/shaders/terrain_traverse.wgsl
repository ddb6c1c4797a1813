// Ray-terrain traversal through the maximum pyramid; the same algorithm as
// `src/cpu/traverse.rs`, step for step. Expects module-scope `frame`, `heights`, `pyramid`
// and the compile-time switches `CURVED` (curved earth) and `LOD` (footprint level of detail),
// prepended by `gpu::shaders`. The terrain data is read through `cell_max`,
// `patch_corners` and `surface_height` only (the traversal's storage interface): from the
// heights and the pyramid (`terrain_memory.wgsl`) or, with `PAGED`, from the tile pool
// (`terrain_paged.wgsl`, `terrain_paged_window.wgsl`).

struct Ray {
    o: vec3<f32>,
    d: vec3<f32>,
}

struct Trace {
    t: f32,
    cell: vec2<i32>,
    steps: u32,
    patches: u32,
    hit: bool,
    exhausted: bool,
    // NEAR: before its hit (or missing), the ray passed within its reach (a pixel cone's
    // radius, a footprint beam's) of the surface somewhere it did not hit: a feature thinner
    // than the pixel may be there.
    near: bool,
}

fn safe_inv(x: f32) -> f32 {
    if (abs(x) < 1.0e-30) {
        return select(-BIG, BIG, x >= 0.0);
    }
    return 1.0 / x;
}

// The GPU pyramid is a square power-of-two mip chain (side N = frame.pyramid_dims.x at level
// 0, padded with PAD), so a level's row stride and offset are arithmetic: no per-step table
// look-up (a per-lane gather on SIMD software rasterisers).
fn level_side(level: u32) -> u32 {
    return frame.pyramid_dims.x >> level;
}

fn cells_x() -> f32 {
    return f32(frame.grid.x - 1u);
}

fn cells_y() -> f32 {
    return f32(frame.grid.y - 1u);
}

// Curved earth (`CURVED`, a compile-time switch: flat terrains compile without this code).
// The datum lies drop(x, y) = k.x (x - ex)^2 + k.y (y - ey)^2 metres below the eye's tangent
// plane (frame.curvature = ex, ey, k.x, k.y, grid units; `x - ex` taken before squaring); a
// ray's height above it, z(t) + drop(x(t), y(t)), is a convex quadratic A t^2 + B t + C.
// Same as `GridRay::lifted` and friends in `src/cpu/traverse.rs`.
fn drop_at(p: vec2<f32>) -> f32 {
    let e = p - frame.curvature.xy;
    return frame.curvature.z * e.x * e.x + frame.curvature.w * e.y * e.y;
}

// Gradient of the drop (metres per grid step).
fn drop_gradient(p: vec2<f32>) -> vec2<f32> {
    return 2.0 * frame.curvature.zw * (p - frame.curvature.xy);
}

fn lifted(r: Ray, t: f32) -> f32 {
    let p = r.o + r.d * t;
    return p.z + drop_at(p.xy);
}

// (A, B, C) of the ray's height above the curved datum.
fn lifted_quadratic(r: Ray) -> vec3<f32> {
    let k = frame.curvature.zw;
    let e = r.o.xy - frame.curvature.xy;
    return vec3<f32>(k.x * r.d.x * r.d.x + k.y * r.d.y * r.d.y, r.d.z + 2.0 * (k.x * e.x * r.d.x + k.y * e.y * r.d.y), r.o.z + drop_at(r.o.xy));
}

// Lowest height above the curved datum over [ta, tb]: the ends, or the vertex inside.
fn lowest_lifted(r: Ray, ta: f32, tb: f32, q: vec3<f32>) -> f32 {
    var low = min(lifted(r, ta), lifted(r, tb));
    if (q.x > 0.0) {
        let tv = -q.y / (2.0 * q.x);
        if (tv > ta && tv < tb) {
            low = min(low, lifted(r, tv));
        }
    }
    return low;
}

// The curved box: xy slabs as `clip_box`; the z-slab is where the height above the datum is
// at most the highest sample (between the quadratic's roots) and, for an origin below the
// lowest sample, from where it comes back above it (`clip_curved_slab` on the CPU).
fn clip_box_curved(r: Ray, t_min: f32, t_max: f32) -> vec2<f32> {
    let inv = vec2<f32>(safe_inv(r.d.x), safe_inv(r.d.y));
    let ta = -r.o.xy * inv;
    let tb = (vec2<f32>(cells_x(), cells_y()) - r.o.xy) * inv;
    var t0 = max(max(min(ta.x, tb.x), min(ta.y, tb.y)), t_min);
    var t1 = min(min(max(ta.x, tb.x), max(ta.y, tb.y)), t_max);
    let q = lifted_quadratic(r);
    let zlo = frame.heights_range.x - frame.heights_range.w;
    let zhi = frame.heights_range.y + frame.heights_range.w;
    if (q.x > 0.0) {
        let ch = q.z - zhi;
        let disc = q.y * q.y - 4.0 * q.x * ch;
        if (disc < 0.0) {
            return vec2<f32>(1.0, 0.0);
        }
        let s = -0.5 * (q.y + select(-1.0, 1.0, q.y >= 0.0) * sqrt(disc));
        let r1 = s / q.x;
        let r2 = select(0.0, ch / s, s != 0.0);
        t0 = max(t0, min(r1, r2));
        t1 = min(t1, max(r1, r2));
        let cl = q.z - zlo;
        let disc_lo = q.y * q.y - 4.0 * q.x * cl;
        if (cl < 0.0 && disc_lo >= 0.0) {
            let sl = -0.5 * (q.y + select(-1.0, 1.0, q.y >= 0.0) * sqrt(disc_lo));
            t0 = max(t0, max(sl / q.x, select(0.0, cl / sl, sl != 0.0)));
        }
    } else {
        let iz = safe_inv(q.y);
        let za = (zlo - q.z) * iz;
        let zb = (zhi - q.z) * iz;
        t0 = max(t0, min(za, zb));
        t1 = min(t1, max(za, zb));
    }
    return vec2<f32>(t0, t1);
}

// Clip to the terrain box; returns (t0, t1), empty when t0 > t1.
fn clip_box(r: Ray, t_min: f32, t_max: f32) -> vec2<f32> {
    if (CURVED) {
        return clip_box_curved(r, t_min, t_max);
    }
    let lo = vec3<f32>(0.0, 0.0, frame.heights_range.x - frame.heights_range.w);
    let hi = vec3<f32>(cells_x(), cells_y(), frame.heights_range.y + frame.heights_range.w);
    let inv = vec3<f32>(safe_inv(r.d.x), safe_inv(r.d.y), safe_inv(r.d.z));
    let ta = (lo - r.o) * inv;
    let tb = (hi - r.o) * inv;
    let tn = min(ta, tb);
    let tf = max(ta, tb);
    return vec2<f32>(max(max(tn.x, tn.y), max(tn.z, t_min)), min(min(tf.x, tf.y), min(tf.z, t_max)));
}

// NEAR && PAGED: the highest corner of the patch `patch_hit` tested last (the near-miss test
// after a paged patch miss reads it instead of loading the corners again).
var<private> patch_top: f32 = 0.0;

// Exact intersection with the bilinear patch of cell (i, j) of `level` over [ta, tb] (above
// level 0 only with LOD: the patch spans 2^level samples, the same quadratic in the grid scaled
// by 2^-level, the drop terms in the finest grid's units): the quadratic
// A s^2 + B s + C in s = t - ta (re-centred on the entry point), stable root formula.
// `under`: the ray is below the surface (terrain without walls, `patch_hit_from_below` on the
// CPU): it hits only after coming up through the surface, where it goes down again.
// Returns (hit t or -1, 1 if the ray is still below the surface after the cell else 0).
fn patch_hit(r: Ray, level: u32, i: i32, j: i32, ta: f32, tb: f32, under: bool) -> vec2<f32> {
    let h = patch_corners(level, vec2<i32>(i, j));
    if (NEAR && PAGED) {
        patch_top = max(max(h.x, h.y), max(h.z, h.w));
    }
    let h00 = h.x;
    let h10 = h.y;
    let h01 = h.z;
    let h11 = h.w;
    let b = h10 - h00;
    let c = h01 - h00;
    let e = h00 - h10 - h01 + h11;
    let p = r.o + r.d * ta;
    var u0 = p.x - f32(i);
    var v0 = p.y - f32(j);
    var dxy = r.d.xy;
    if (LOD || PAGED) {
        // Branch-free (Mesa's SIMD lanes pay for both sides of a branch): at level 0 the
        // scale is 1 and the arithmetic the exact build's, bit for bit.
        let inv = ldexp(1.0, -i32(level));
        u0 = p.x * inv - f32(i);
        v0 = p.y * inv - f32(j);
        dxy = r.d.xy * inv;
    }
    var qa = -e * dxy.x * dxy.y;
    var qb = r.d.z - b * dxy.x - c * dxy.y - e * (u0 * dxy.y + v0 * dxy.x);
    var qc = p.z - (h00 + b * u0 + c * v0 + e * u0 * v0);
    if (CURVED) {
        // The drop along the ray from p: k (p - eye + d s)^2, exact in s.
        let k = frame.curvature.zw;
        let ep = p.xy - frame.curvature.xy;
        qa += k.x * r.d.x * r.d.x + k.y * r.d.y * r.d.y;
        qb += 2.0 * (k.x * ep.x * r.d.x + k.y * ep.y * r.d.y);
        qc += drop_at(p.xy);
    }
    let below = under && qc <= 0.0;
    if (qc <= 0.0 && !below) {
        return vec2<f32>(ta, 0.0);
    }
    var best = BIG;
    var r1 = BIG;
    var r2 = BIG;
    let disc = qb * qb - 4.0 * qa * qc;
    let quadratic = abs(qa) > 1.0e-30;
    if (disc >= 0.0) {
        let q = -0.5 * (qb + select(-1.0, 1.0, qb >= 0.0) * sqrt(disc));
        if (quadratic) {
            r1 = q / qa;
            if (r1 >= 0.0) {
                best = r1;
            }
        }
        if (q != 0.0) {
            r2 = qc / q;
            if (r2 >= 0.0 && r2 < best) {
                best = r2;
            }
        }
    }
    let s_max = tb - ta;
    if (below) {
        // q(0) <= 0. A < 0: positive between the roots, out at the lower, down (a hit from
        // above) at the higher; otherwise out at the higher root, never down again.
        let lo = min(r1, r2);
        let hi = select(r2, max(r1, r2), quadratic);
        if (quadratic && qa < 0.0) {
            if (disc >= 0.0 && lo >= 0.0 && lo <= s_max) {
                if (hi <= s_max) {
                    return vec2<f32>(ta + hi, 0.0);
                }
                return vec2<f32>(-1.0, 0.0);
            }
        } else if (hi >= 0.0 && hi <= s_max) {
            return vec2<f32>(-1.0, 0.0);
        }
        return vec2<f32>(-1.0, 1.0);
    }
    if (best <= s_max) {
        return vec2<f32>(ta + best, 0.0);
    }
    return vec2<f32>(-1.0, 0.0);
}

// Levels to climb after stepping from cell (ox, oy) to (ix, iy): while the parents differ,
// go up (closed form of that loop: the highest differing index bit), at most `room` levels.
fn climb_levels(ix: i32, iy: i32, ox: i32, oy: i32, room: u32) -> u32 {
    let bits = 32u - countLeadingZeros(u32(ix ^ ox) | u32(iy ^ oy));
    return min(max(bits, 1u) - 1u, room);
}

fn cell_at(level: u32, p: vec2<f32>) -> vec2<i32> {
    let s = f32(1u << level);
    let l = frame.levels[level];
    return vec2<i32>(
        clamp(i32(floor(p.x / s)), 0, i32(l.x) - 1),
        clamp(i32(floor(p.y / s)), 0, i32(l.y) - 1),
    );
}

// A ray's walk through the pyramid: current level, cell at that level, entry distance.
struct Walk {
    level: u32,
    cell: vec2<i32>,
    t: f32,
}

// Step direction (±1 per axis) and inverse horizontal direction of a ray.
struct Dir {
    s: vec2<i32>,
    inv: vec2<f32>,
}

fn walk_dir(r: Ray) -> Dir {
    var d: Dir;
    d.s = select(vec2<i32>(-1), vec2<i32>(1), r.d.xy >= vec2<f32>(0.0));
    d.inv = vec2<f32>(safe_inv(r.d.x), safe_inv(r.d.y));
    return d;
}

fn walk_start(r: Ray, t: f32, level: u32) -> Walk {
    var w: Walk;
    w.level = level;
    w.cell = cell_at(level, (r.o + r.d * t).xy);
    w.t = t;
    return w;
}

// Distances at which the ray leaves the walk's cell through its x and y faces.
fn cell_exits(r: Ray, dir: Dir, w: Walk) -> vec2<f32> {
    let far = vec2<f32>(w.cell + max(dir.s, vec2<i32>(0)));
    return (far * f32(1u << w.level) - r.o.xy) * dir.inv;
}

// One level down, to the child cell holding the entry point (ties go the way the ray moves).
fn descend(r: Ray, dir: Dir, w: Walk) -> Walk {
    let p = (r.o + r.d * w.t).xy;
    let mid = vec2<f32>(2 * w.cell + vec2<i32>(1)) * (f32(1u << w.level) * 0.5);
    let upper = (p > mid) | ((p == mid) & (dir.s > vec2<i32>(0)));
    var n: Walk;
    n.level = w.level - 1u;
    n.cell = 2 * w.cell + select(vec2<i32>(0), vec2<i32>(1), upper);
    n.t = w.t;
    return n;
}

// Cross the exit face (both at a corner), move to `t_exit`, then climb while the new cell's
// parent differs from the old one's (never above `top`).
fn advance(dir: Dir, w: Walk, exits: vec2<f32>, t_exit: f32, top: u32) -> Walk {
    let moved = w.cell + select(vec2<i32>(0), dir.s, vec2<bool>(exits.x <= exits.y, exits.y <= exits.x));
    let up = climb_levels(moved.x, moved.y, w.cell.x, w.cell.y, top - w.level);
    var n: Walk;
    n.level = w.level + up;
    n.cell = moved >> vec2<u32>(up);
    n.t = t_exit;
    return n;
}

fn walk_inside(w: Walk) -> bool {
    let side = level_side(w.level);
    return u32(w.cell.x) < side && u32(w.cell.y) < side;
}

// Footprint LOD: the walk's cell (level > 0) may stand in for its samples, its side 2^level
// within the footprint (`2^level <= lod_k * t`, `lod_k` = lod * 2 * cone / larger spacing;
// `lod_stops` on the CPU). One float compare per descent: a test of the cell's far corner
// against the grid's edge here cost 3% of the cast pass on lavapipe, so `patch_corners`
// clamps that corner instead.
fn lod_stops(w: Walk, lod_k: f32) -> bool {
    return f32(1u << w.level) <= lod_k * w.t;
}

// The level-0 cell under grid point p within the walk's cell (`finest_cell` on the CPU).
fn finest_cell(w: Walk, p: vec2<f32>) -> vec2<i32> {
    let s = 1 << w.level;
    let lo = w.cell * s;
    let f = clamp(vec2<i32>(floor(p)), lo, lo + vec2<i32>(s - 1));
    return min(f, vec2<i32>(frame.grid.xy) - vec2<i32>(2));
}

// Top-down pyramid traversal: skip cells the ray segment stays above, descend otherwise,
// exact patch test at level 0, climb after crossings while the parent changes.
fn traverse(r: Ray, t_min: f32, t_max: f32, max_steps: u32) -> Trace {
    return traverse_from(r, t_min, t_max, max_steps, frame.grid.z - 1u);
}

// As `traverse`, starting at pyramid level `start_level` (≤ top) instead of the top: valid from
// any level, since a cell is only skipped after its own maximum was tested.
fn traverse_from(r: Ray, t_min: f32, t_max: f32, max_steps: u32, start_level: u32) -> Trace {
    return traverse_lod(r, t_min, t_max, max_steps, start_level, 0.0, vec3<f32>(0.0));
}

// As `traverse_from` with footprint level of detail (`LOD` pipelines; `lod_k` see `lod_stops`,
// 0: never): a cell within the ray's footprint that the ray cannot skip is intersected as
// its level's bilinear patch instead of being descended into.
// NEAR (anti-aliasing's centre rays): the ray's reach at t is near.x + near.y t (the pixel
// cone: (0, its half-angle); a footprint's beam of sun rays: (its radius, 0)); cells the ray
// passes within its reach of are tested too, and a patch it misses by less than that beyond
// t = near.z sets `near`. The hits are those of the exact traversal; without NEAR (a
// compile-time constant) it is the exact one, step for step.
fn traverse_lod(r: Ray, t_min: f32, t_max: f32, max_steps: u32, start_level: u32, lod_k: f32, near: vec3<f32>) -> Trace {
    var res: Trace;
    res.t = BIG;
    res.hit = false;
    res.exhausted = false;
    res.near = false;
    res.steps = 0u;
    res.patches = 0u;
    let tt = clip_box(r, t_min, t_max);
    if (tt.x > tt.y) {
        return res;
    }
    let t1 = tt.y;
    let top = frame.grid.z - 1u;
    let dir = walk_dir(r);
    var w = walk_start(r, tt.x, min(start_level, top));
    var lq = vec3<f32>(0.0);
    if (CURVED) {
        lq = lifted_quadratic(r);
    }
    // Terrain without walls: is the ray below the surface where it enters the box?
    var under = false;
    if (frame.mode.z != 0u) {
        let p0 = r.o + r.d * tt.x;
        var z0 = p0.z;
        if (CURVED) {
            z0 = lifted(r, tt.x);
        }
        under = z0 < surface_height(p0.x, p0.y);
    }
    // Two nested loops for SIMD rasterisers: the inner one only steps through the pyramid and
    // stops at a level-0 cell the segment may touch; the patch test runs after it, once for
    // all lanes that stopped, instead of inside every stepping iteration that one lane needs
    // (the same visits and step counts as the CPU reference's single loop).
    loop {
        var candidate = false;
        var exits = vec2<f32>(0.0);
        var t_exit = 0.0;
        // NEAR: the candidate cell's own maximum and the segment's lowest point, for the
        // near-miss test after its patch test (kept, not loaded again).
        var cand_max = 0.0;
        var cand_low = 0.0;
        loop {
            if (res.steps >= max_steps) {
                res.exhausted = true;
                break;
            }
            res.steps += 1u;
            exits = cell_exits(r, dir, w);
            t_exit = max(min(min(exits.x, exits.y), t1), w.t);
            let cell_top = cell_max(w.level, w.cell) + frame.heights_range.w;
            var cmax = cell_top;
            if (NEAR) {
                // Near misses count from near.z on: the reach widens no cell before it.
                cmax += select(0.0, near.x + near.y * t_exit, t_exit >= near.z);
            }
            var z_low = min(r.o.z + r.d.z * w.t, r.o.z + r.d.z * t_exit);
            if (CURVED) {
                z_low = lowest_lifted(r, w.t, t_exit, lq);
            }
            if (z_low <= cmax) {
                // PAGED: descend only while the finer level is resident over the cell, else
                // intersect the finest resident level's patch (`intersect_paged` on the CPU).
                if (w.level > 0u && !(LOD && lod_stops(w, lod_k)) && !(PAGED && paged_stops(w.level, w.cell))) {
                    w = descend(r, dir, w);
                    continue;
                }
                candidate = true;
                cand_max = cell_top;
                cand_low = z_low;
                break;
            }
            if (t_exit >= t1) {
                break;
            }
            w = advance(dir, w, exits, t_exit, top);
            if (!walk_inside(w)) {
                break;
            }
        }
        if (!candidate) {
            break;
        }
        res.patches += 1u;
        // Level 0 unless LOD (a constant then: the exact build keeps its level-0 addressing).
        let ph = patch_hit(r, select(0u, w.level, LOD || PAGED), w.cell.x, w.cell.y, w.t, t_exit, under);
        under = ph.y != 0.0;
        let th = ph.x;
        if (NEAR && th < 0.0 && !res.near && w.t >= near.z) {
            // PAGED: the cell may be a coarser level's (its finer ones not resident), whose
            // maximum bounds finer samples the patch does not show: the rise the samples
            // would meet is the patch's own, up to its highest corner.
            var rise = cand_max;
            if (PAGED) {
                rise = patch_top + frame.heights_range.w;
            }
            res.near = misses_by_less(near.x + near.y * t_exit, rise - cand_low, select(0u, w.level, PAGED));
        }
        if (th >= 0.0) {
            res.hit = true;
            res.t = th;
            res.cell = w.cell;
            if ((LOD || PAGED) && w.level > 0u) {
                res.cell = finest_cell(w, (r.o + r.d * th).xy);
            }
            return res;
        }
        if (t_exit >= t1) {
            break;
        }
        w = advance(dir, w, exits, t_exit, top);
        if (!walk_inside(w)) {
            break;
        }
    }
    return res;
}

// NEAR: whether the ray's segment through a cell's box of `level` (0 but where a paged
// traversal stops at a coarser level), missing its patch, may pass within `reach` (at the
// segment's far end) of a feature thinner than the pixel: the cell is no wider than twice the
// reach and the ray passes more than the reach below the cell's highest corner (`depth`), so
// a steep rise stands beside it. (A ray grazing a surface from above is left to the edge
// rules: flagging it would mark every far slope.)
fn misses_by_less(reach: f32, depth: f32, level: u32) -> bool {
    return max(frame.spacing.x, frame.spacing.y) * f32(1u << level) <= 2.0 * reach && depth > reach;
}

// Baseline for the benchmark: fixed steps of `frame.march.x` cells plus bisection.
fn march(r: Ray, t_min: f32, t_max: f32, max_steps: u32) -> Trace {
    var res: Trace;
    res.t = BIG;
    res.hit = false;
    res.exhausted = false;
    res.near = false;
    res.steps = 0u;
    res.patches = 0u;
    let tt = clip_box(r, t_min, t_max);
    if (tt.x > tt.y) {
        return res;
    }
    let dt = frame.march.x / max(max(abs(r.d.x), abs(r.d.y)), 1.0e-6);
    var t = tt.x;
    loop {
        if (res.steps >= max_steps) {
            res.exhausted = true;
            break;
        }
        res.steps += 1u;
        let tn = min(t + dt, tt.y);
        let p = r.o + r.d * tn;
        if (p.z <= surface_height(p.x, p.y)) {
            var lo = t;
            var hi = tn;
            for (var k = 0u; k < u32(frame.march.y); k += 1u) {
                let mid = 0.5 * (lo + hi);
                let q = r.o + r.d * mid;
                if (q.z <= surface_height(q.x, q.y)) {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            res.hit = true;
            res.t = hi;
            res.cell = vec2<i32>(i32(min(p.x, cells_x() - 0.5)), i32(min(p.y, cells_y() - 0.5)));
            return res;
        }
        if (tn >= tt.y) {
            break;
        }
        t = tn;
    }
    return res;
}

// World unit direction -> grid-frame direction.
fn to_grid_dir(d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(frame.grid_from_world_0.xyz, d), dot(frame.grid_from_world_1.xyz, d), dot(frame.grid_from_world_2.xyz, d));
}
