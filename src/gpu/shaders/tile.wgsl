// Tile pre-pass: one fragment per 8x8 screen tile finds, through the pyramid, a distance
// before which no ray of the tile can hit the terrain (see `cone_start`). The terrain pass
// starts every pixel ray of the tile there, at the pyramid level where the cone stopped.

// The terrain comes through the traversal's `cell_max` and the pass's `dilated_max` (the
// maximum over a cell's 3x3 neighbourhood): `tile_memory.wgsl` (the dilated pyramid) or
// `tile_paged.wgsl` (the tile pool).

@group(0) @binding(0) var<uniform> frame: Frame;

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
    let dir = walk_dir(r);
    var w = walk_start(r, t, top);
    var steps = 0u;
    loop {
        steps += 1u;
        if (steps > max_steps) {
            return cone_result(w.t, w.level);
        }
        let s = f32(1u << w.level);
        let exits = cell_exits(r, dir, w);
        let t_exit = max(min(min(exits.x, exits.y), t1), w.t);
        if (w.level < top && rg * t_exit > s) {
            // The cone is wider than a cell here: test the parent instead.
            w.level += 1u;
            w.cell = w.cell >> vec2<u32>(1u);
            continue;
        }
        // At the top level: the highest sample (in memory the top level is one cell; a paged
        // traversal's top level has many, and the box clip bounds every hit by the range).
        var m = frame.heights_range.y + frame.heights_range.w;
        if (!PAGED) {
            m = cell_max(top, vec2<i32>(0, 0));
        }
        if (w.level < top) {
            m = dilated_max(w.level, w.cell);
        }
        let z_low = min(r.o.z + r.d.z * w.t, r.o.z + r.d.z * t_exit) - theta * t_exit;
        if (z_low <= m) {
            if (w.level > 0u && rg * t_exit <= s * 0.5) {
                w = descend(r, dir, w);
                continue;
            }
            return cone_result(w.t, w.level);
        }
        if (t_exit >= t1) {
            return cone_result(t1, top);
        }
        w = advance(dir, w, exits, t_exit, top);
        if (!walk_inside(w)) {
            return cone_result(t1, top);
        }
    }
    return cone_result(w.t, w.level);
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

// Tile cone of a distortion table, whose tiles need not map to great-circle quadrilaterals:
// exact over all the tile's rays that show screen (mean direction, then the largest chord).
@fragment
fn fs_tile_table(@builtin(position) pos: vec4<f32>) -> @location(0) vec2<u32> {
    let tile = vec2<u32>(pos.xy);
    let x0 = tile.x * TILE;
    let y0 = tile.y * TILE;
    let x1 = min(x0 + TILE, frame.size.x);
    let y1 = min(y0 + TILE, frame.size.y);
    var sum = vec3<f32>(0.0);
    for (var y = y0; y < y1; y += 1u) {
        for (var x = x0; x < x1; x += 1u) {
            let e = ray_entry(vec2<u32>(x, y));
            if (e.w >= 0.0) {
                sum += e.xyz;
            }
        }
    }
    if (dot(sum, sum) == 0.0) {
        return vec2<u32>(bitcast<u32>(BIG), frame.grid.z - 1u);
    }
    let c = normalize(sum);
    var chord = 0.0;
    for (var y = y0; y < y1; y += 1u) {
        for (var x = x0; x < x1; x += 1u) {
            let e = ray_entry(vec2<u32>(x, y));
            if (e.w >= 0.0) {
                chord = max(chord, length(e.xyz - c));
            }
        }
    }
    var r: Ray;
    r.o = frame.eye.xyz;
    r.d = to_grid_dir(c);
    let s = cone_start(r, chord * 1.001 + 1.0e-6, 1024u);
    return vec2<u32>(bitcast<u32>(max(s.t * 0.999 - 1.0, 0.0)), s.level);
}
