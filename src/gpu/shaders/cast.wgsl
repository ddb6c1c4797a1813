// Cast pass: per pixel, cast the ray from the ray table through the maximum pyramid (starting
// where the tile pre-pass allows) and write the G-buffer: ray distance, cell, work counters.
// Shading is a separate pass: on Mesa's SIMD software rasteriser a fragment pays for every
// instruction of its shader, so the traversal loop runs without the shading code around it.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var tile_start: texture_2d<u32>;

fn primary_ray(e: vec4<f32>) -> Ray {
    var r: Ray;
    r.o = frame.eye.xyz;
    r.d = to_grid_dir(e.xyz);
    return r;
}

// The product: pyramid traversal from the tile's start distance.
@fragment
fn fs_cast(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let e = ray_entry(vec2<u32>(pos.xy));
    if (e.w < 0.0) {
        return no_screen_gbuffer();
    }
    var t_min = 0.0;
    var level = frame.grid.z - 1u;
    if (frame.mode.w != 0u) {
        let s = textureLoad(tile_start, vec2<i32>(vec2<u32>(pos.xy) / TILE), 0).xy;
        t_min = bitcast<f32>(s.x);
        level = s.y;
    }
    // Footprint LOD: the pixel's cone (e.w, half-angle) sets where a cell may stand in for
    // its samples.
    var lod_k = 0.0;
    if (LOD) {
        lod_k = frame.lod.x * e.w;
    }
    // NEAR (anti-aliasing): features within the pixel's cone that its centre ray misses. A
    // near miss needs a level-0 cell no wider than the cone's diameter (`misses_by_less`),
    // which it is from t_w = cell / (2 half-angle) on: the search starts one cell's span along
    // the ray before that (the ray crosses a cell within sqrt 2 / |d.xy| metres of t), and the
    // cells before it are not widened (the flags are the same; the steps fewer).
    let ray = primary_ray(e);
    var near = vec3<f32>(0.0);
    if (NEAR) {
        let t_w = max(frame.spacing.x, frame.spacing.y) / max(2.0 * e.w, 1.0e-30);
        let span = 1.5 / max(length(ray.d.xy), 1.0e-20);
        near = vec3<f32>(0.0, e.w, max(t_w - span, 0.0));
    }
    let tr = traverse_lod(ray, t_min, BIG, frame.mode.y, level, lod_k, near);
    var g = encode_gbuffer(tr);
    if (PAGED && tr.hit) {
        // The paged build: the finest resident level over the hit cell for the shade pass.
        g.z = min(g.z, 0xffffffu) | gbuffer_hint(tr.cell);
    }
    return g;
}

// Benchmark baseline: fixed-step march (its own entry point, so neither pays for the other's
// code on SIMD software rasterisers).
@fragment
fn fs_cast_march(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let e = ray_entry(vec2<u32>(pos.xy));
    if (e.w < 0.0) {
        return no_screen_gbuffer();
    }
    return encode_gbuffer(march(primary_ray(e), 0.0, BIG, frame.mode.y));
}
