// Tile pre-pass: one fragment per 8x8 screen tile finds, through the pyramid, a distance
// before which no ray of the tile can hit the terrain (see `cone_start`). The terrain pass
// starts every pixel ray of the tile there, at the pyramid level where the cone stopped.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> heights: array<f32>;
@group(0) @binding(2) var<storage, read> pyramid: array<f32>;
// The pyramid dilated by one cell: each cell holds the maximum of its 3x3 neighbourhood.
@group(0) @binding(4) var<storage, read> dilated: array<f32>;

// Same layout as `pyr_get`.
fn dilated_get(level: u32, ix: i32, iy: i32) -> f32 {
    let side = level_side(level);
    if (u32(ix) >= side || u32(iy) >= side) {
        return PAD;
    }
    let n = frame.pyramid_dims.x;
    let offset = (n * n - side * side) / 3u * 4u;
    return dilated[offset + u32(iy) * side + u32(ix)];
}



// Tile pre-pass: traverse the pyramid with a cone around the tile's central ray `r`.
// Every ray of the tile stays within `theta * t` of the central ray's point at t (theta is the
// largest chord |d_i - d_c| over the tile's unit directions), so while the cone radius is below
// the cell size the 3x3 neighbourhood maximum (the dilated pyramid) bounds what any tile ray can meet. Returns a
// distance before which no tile ray can hit the terrain (BIG: none can ever hit) and the
// pyramid level at which the pixel rays may start their own traversal there.
struct ConeStart {
    t: f32,
    level: u32,
}

fn cone_result(t: f32, level: u32) -> ConeStart {
    var c: ConeStart;
    c.t = t;
    c.level = level;
    return c;
}

fn cone_start(r: Ray, theta: f32, max_steps: u32) -> ConeStart {
    let zmax = frame.heights_range.y;
    let top = frame.grid.z - 1u;
    if (r.o.z > zmax && r.d.z >= theta) {
        return cone_result(BIG, top);
    }
    let inv = vec2<f32>(safe_inv(r.d.x), safe_inv(r.d.y));
    let ta = (vec2<f32>(0.0, 0.0) - r.o.xy) * inv;
    let tb = (vec2<f32>(cells_x(), cells_y()) - r.o.xy) * inv;
    let t0 = max(max(min(ta.x, tb.x), min(ta.y, tb.y)), 0.0);
    let t1 = min(max(ta.x, tb.x), max(ta.y, tb.y));
    if (t0 > 0.0 || t0 > t1) {
        return cone_result(0.0, top);
    }
    // Below this distance the whole cone is above the highest sample.
    var t = 0.0;
    if (r.o.z > zmax) {
        t = (r.o.z - zmax) / (theta - r.d.z);
    }
    if (t >= t1) {
        return cone_result(t1, top);
    }
    let rg = theta * min(frame.spacing.z, frame.spacing.w);
    var level = top;
    let sx = select(-1, 1, r.d.x >= 0.0);
    let sy = select(-1, 1, r.d.y >= 0.0);
    var c = cell_at(level, (r.o + r.d * t).xy);
    var ix = c.x;
    var iy = c.y;
    var steps = 0u;
    loop {
        steps += 1u;
        if (steps > max_steps) {
            return cone_result(t, level);
        }
        let s = f32(1u << level);
        let tx = (f32(ix + select(0, 1, sx > 0)) * s - r.o.x) * inv.x;
        let ty = (f32(iy + select(0, 1, sy > 0)) * s - r.o.y) * inv.y;
        let t_exit = max(min(min(tx, ty), t1), t);
        if (level < top && rg * t_exit > s) {
            level += 1u;
            ix = ix >> 1u;
            iy = iy >> 1u;
            continue;
        }
        var m = pyr_get(top, 0, 0);
        if (level < top) {
            m = dilated_get(level, ix, iy);
        }
        let z_low = min(r.o.z + r.d.z * t, r.o.z + r.d.z * t_exit) - theta * t_exit;
        if (z_low <= m) {
            if (level > 0u && rg * t_exit <= s * 0.5) {
                let p = r.o + r.d * t;
                let half = s * 0.5;
                let mx = f32(2 * ix + 1) * half;
                let my = f32(2 * iy + 1) * half;
                let cx = 2 * ix + select(0, 1, p.x > mx || (p.x == mx && sx > 0));
                let cy = 2 * iy + select(0, 1, p.y > my || (p.y == my && sy > 0));
                level -= 1u;
                ix = cx;
                iy = cy;
                continue;
            }
            return cone_result(t, level);
        }
        if (t_exit >= t1) {
            return cone_result(t1, top);
        }
        let ox = ix;
        let oy = iy;
        if (tx <= ty) {
            ix += sx;
        }
        if (ty <= tx) {
            iy += sy;
        }
        t = t_exit;
        let up = climb_levels(ix, iy, ox, oy, top - level);
        level += up;
        ix = ix >> up;
        iy = iy >> up;
        let side = level_side(level);
        if (u32(ix) >= side || u32(iy) >= side) {
            return cone_result(t1, top);
        }
    }
    return cone_result(t, level);
}


@fragment
fn fs_tile(@builtin(position) pos: vec4<f32>) -> @location(0) vec2<u32> {
    let tile = vec2<u32>(pos.xy);
    let x0 = tile.x * TILE;
    let y0 = tile.y * TILE;
    let x1 = min(x0 + TILE, frame.size.x) - 1u;
    let y1 = min(y0 + TILE, frame.size.y) - 1u;
    // The tile's pixel-centre rays of a pinhole ray table fill a spherical quadrilateral whose
    // edges are great-circle arcs (a convex spherical polygon), so the ray farthest from any
    // direction inside it is a corner: the four corner rays bound the whole tile's cone.
    let d00 = ray_dir(vec2<u32>(x0, y0));
    let d10 = ray_dir(vec2<u32>(x1, y0));
    let d01 = ray_dir(vec2<u32>(x0, y1));
    let d11 = ray_dir(vec2<u32>(x1, y1));
    let c = normalize(d00 + d10 + d01 + d11);
    let chord = max(max(length(d00 - c), length(d10 - c)), max(length(d01 - c), length(d11 - c)));
    let theta = chord * 1.001 + 1.0e-6;
    var r: Ray;
    r.o = frame.eye.xyz;
    r.d = to_grid_dir(c);
    let s = cone_start(r, theta, 1024u);
    // A small safety margin against rounding in the cone test.
    return vec2<u32>(bitcast<u32>(max(s.t * 0.999 - 1.0, 0.0)), s.level);
}
