// Volume-sun pass: per pixel, the sun's transmittance through one density volume for the
// opaque surface in the G-buffer (terrain, free form or voxel model), read from the volume's
// self-shadowing grid where the ray from the surface towards the sun enters the box (at the
// surface itself when it lies inside), as `Volume::transmittance_to_sun` does. The first
// volume writes the target, the others multiply into it (blend), and the shade pass scales
// the sun's terms by the product: clouds shadow the ground.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer: texture_2d<u32>;
@group(0) @binding(16) var<uniform> vol: Volume;
@group(0) @binding(17) var vol_shadow: texture_3d<f32>;
@group(0) @binding(18) var vol_linear: sampler;

@fragment
fn fs_volume_sun(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer, vec2<i32>(px), 0);
    let e = ray_entry(px);
    // Sky, or no screen under this pixel: nothing to shadow.
    if ((g.w & 1u) == 0u || e.w < 0.0) {
        return vec4<f32>(1.0);
    }
    let dir = e.xyz;
    let rot = mat3x3<f32>(vol.local_from_world_0.xyz, vol.local_from_world_1.xyz, vol.local_from_world_2.xyz);
    // The surface point and the sun in the volume frame (rows of the rotation: dot products).
    let q = vol.eye_local.xyz + dir * rot * bitcast<f32>(g.x);
    let s = frame.sun_world.xyz * rot;
    let ext = vol.extent.xyz;
    let inv = select(vec3<f32>(BIG), 1.0 / s, abs(s) > vec3<f32>(1.0e-30));
    let ta = -q * inv;
    let tb = (ext - q) * inv;
    let lo = min(ta, tb);
    let hi = max(ta, tb);
    let enter = max(max(lo.x, lo.y), max(lo.z, 0.0));
    let leave = min(hi.x, min(hi.y, hi.z));
    if (leave <= enter) {
        return vec4<f32>(1.0);
    }
    return vec4<f32>(textureSampleLevel(vol_shadow, vol_linear, (q + s * enter) / ext, 0.0).x);
}
