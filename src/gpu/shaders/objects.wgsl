// Free-form cast pass: per pixel, the nearest free form of the pixel's bin in front of the
// terrain hit replaces it in the G-buffer (distance, object id | iterations << 16, packed
// normal, flags 1 | 16).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer_in: texture_2d<u32>;

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
