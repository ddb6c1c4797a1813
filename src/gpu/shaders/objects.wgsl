// Free-form cast pass: per pixel, the nearest free form of the pixel's bin in front of the
// terrain hit replaces it in the G-buffer (distance, object id | iterations << 16, packed
// normal, flags 1 | 16).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer_in: texture_2d<u32>;

// Stencil mark passes (no colour output): keep only pixels whose ray enters the box of an
// object of the pixel's bin list (before the terrain for primary rays; from the visible
// surface towards the sun for shadow rays, binding 4 then being the final G-buffer), so the
// free-form passes behind a stencil test skip the rest of the screen. Box tests only: no
// intersection code here.
@fragment
fn fs_mark_primary(@builtin(position) pos: vec4<f32>) {
    let px = vec2<u32>(pos.xy);
    if (ff_bins[ff_bin_base(px, 0u)] == 0u) {
        discard;
    }
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    var far = BIG;
    if ((g.w & 1u) != 0u) {
        far = bitcast<f32>(g.x);
    }
    var w = ff_walk(px, 0u);
    if ((g.w & 8u) != 0u || ff_next(&w, frame.eye_world.xyz, ray_dir(px), 0.0, far) == 0xffffffffu) {
        discard;
    }
}

@fragment
fn fs_mark_shadow(@builtin(position) pos: vec4<f32>) {
    let px = vec2<u32>(pos.xy);
    if (ff_bins[ff_bin_base(px, 1u)] == 0u) {
        discard;
    }
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    if ((g.w & 1u) == 0u) {
        discard;
    }
    let p = frame.eye_world.xyz + ray_dir(px) * bitcast<f32>(g.x);
    var w = ff_walk(px, 1u);
    if (ff_next(&w, p, frame.sun_world.xyz, 0.0, BIG) == 0xffffffffu) {
        discard;
    }
}

@fragment
fn fs_objects(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    if ((g.w & 8u) != 0u) {
        return g;
    }
    var far = BIG;
    if ((g.w & 1u) != 0u) {
        far = bitcast<f32>(g.x);
    }
    let best = ff_nearest(px, 0u, frame.eye_world.xyz, ray_dir(px), 0.0, far);
    if (!best.hit.hit) {
        return g;
    }
    let n = ff_normal(best.id, best.hit, frame.eye_world.xyz, ray_dir(px));
    return vec4<u32>(bitcast<u32>(best.hit.t), best.id | (min(best.iterations, 0xffffu) << 16u), oct_encode(n), 1u | 16u);
}
