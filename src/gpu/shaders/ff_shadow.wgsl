// Free-form shadow pass: per lit-facing surface pixel, does a free form of the pixel's shadow
// list block the ray to the sun? Writes 1 (blocked) or 0 for the shade pass. Its own pass so
// that the shade pass carries no intersection code.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer: texture_2d<u32>;

@fragment
fn fs_ff_shadow(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer, vec2<i32>(px), 0);
    if ((g.w & 1u) == 0u) {
        return vec4<u32>(0u);
    }
    let sun = frame.sun_world.xyz;
    var p = frame.eye_world.xyz + ray_dir(px) * bitcast<f32>(g.x);
    if ((g.w & 16u) != 0u) {
        // Leave a free form's surface along its normal (terrain points need no offset: the
        // terrain is not a free form).
        let n = oct_decode(g.z);
        if (dot(n, sun) <= 0.0) {
            return vec4<u32>(0u);
        }
        p += n * ff_objects[g.y & 0xffffu].position.w;
    }
    return vec4<u32>(select(0u, 1u, ff_blocked(px, p, sun)), 0u, 0u, 0u);
}
