// Free-form cast passes: per pixel of a bin with objects, the nearest free form of the pixel's
// bin in front of the current hit replaces it in the G-buffer (distance, object id |
// iterations << 16, packed unit normal, flags 1 | 16); pixels without a nearer free form
// pass their input through. Two entry points, one per object kind: plain
// objects in closed form, then perturbed ones by the enclosure search, each drawn only over
// the bins that list objects of its kind (`vs_bins_primary_*`).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer_in: texture_2d<u32>;

// The pixel's current hit distance (BIG for sky); negative where the pixel shows no screen.
fn current_far(px: vec2<u32>) -> f32 {
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    if ((g.w & 8u) != 0u) {
        return -1.0;
    }
    return select(BIG, bitcast<f32>(g.x), (g.w & 1u) != 0u);
}

fn gbuffer_hit(best: FfNearest, n: vec3<f32>) -> vec4<u32> {
    return vec4<u32>(bitcast<u32>(best.hit.t), best.id | (min(best.iterations, 0xffffu) << 16u), oct_encode(n), 1u | 16u);
}

@fragment
fn fs_objects_plain(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let far = current_far(px);
    let e = ray_entry(px);
    let best = ff_plain_nearest(px, 0u, frame.eye_world.xyz, e.xyz, 0.0, far);
    if (far < 0.0 || !best.hit.hit) {
        var g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
        // Anti-aliasing's centre rays: a plain object missed within the pixel's cone (its
        // corners: sqrt 2 times the half-angle) sets the near-miss bit (31), as the terrain's
        // NEAR cast does.
        let near = ff_plain_near(px, 0u, frame.eye_world.xyz, e.xyz, vec2<f32>(0.0, 1.4143 * max(e.w, 0.0)), max(far, 0.0), FF_NONE);
        g.w |= select(0u, 0x80000000u, near && far >= 0.0);
        return g;
    }
    return gbuffer_hit(best, best.hit.n);
}

// The perturbed objects' cast; with `near` (anti-aliasing's centre rays), a ray that hits none
// sets the near-miss bit where it passes one within the pixel's cone (`ff_general_near`).
fn objects_general(px: vec2<u32>, near: bool) -> vec4<u32> {
    let far = current_far(px);
    let best = ff_nearest(px, 0u, frame.eye_world.xyz, ray_dir(px), 0.0, far);
    if (far < 0.0 || !best.hit.hit) {
        var g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
        if (near) {
            let e = ray_entry(px);
            let missed = ff_general_near(px, 0u, frame.eye_world.xyz, e.xyz, vec2<f32>(0.0, 1.4143 * max(e.w, 0.0)), max(far, 0.0), FF_NONE);
            g.w |= select(0u, 0x80000000u, missed && far >= 0.0);
        }
        return g;
    }
    return gbuffer_hit(best, ff_normal(best.id, best.hit, frame.eye_world.xyz, ray_dir(px)));
}

@fragment
fn fs_objects_general(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return objects_general(vec2<u32>(pos.xy), false);
}

// A pipeline of its own: the near-miss search is a second enclosure search inlined in the
// shader, which cost frames without anti-aliasing 2-4% in `fs_objects_general` on Mesa's CPU
// adapters even where it never ran.
@fragment
fn fs_objects_general_near(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return objects_general(vec2<u32>(pos.xy), true);
}

// The input G-buffer unchanged: drawn over the bins the other kind's pass covers, so that
// a pass's target holds the whole result over every listed bin.
@fragment
fn fs_copy_gbuffer(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return textureLoad(gbuffer_in, vec2<i32>(vec2<u32>(pos.xy)), 0);
}
