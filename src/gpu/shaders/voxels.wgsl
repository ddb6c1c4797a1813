// Voxel-model passes, drawn over the pixel rectangles the models can cover (`gpu::voxels`):
// the cast (nearest voxel in front of the G-buffer hit replaces it: distance, palette RGBA,
// packed world normal, flags 1 | 32 | instance << 8 | steps << 16) and the shadow pass (sets
// flag 64 where a voxel blocks the sun). Both read a copy of the G-buffer and draw into the
// G-buffer itself: a pixel they leave as it is discards, at the end: a fragment discarded
// earlier may go on running as a helper invocation on Mesa's CPU adapters (its SIMD lanes do
// not leave the DDA loop), so pixels without work get an empty ray interval instead.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer_in: texture_2d<u32>;

fn vox_far(g: vec4<u32>) -> f32 {
    return select(BIG, bitcast<f32>(g.x), (g.w & 1u) != 0u);
}

@fragment
fn fs_voxels(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let dw = ray_dir(px);
    // Flag 8: no ray here (a projector pixel off the screen).
    var best_t = select(vox_far(g), -1.0, (g.w & 8u) != 0u);
    var found = false;
    var best: VoxTrace;
    var best_k = 0u;
    var steps = 0u;
    for (var k = 0u; k < VOX_INSTANCES; k++) {
        let inst = vox_instances[k];
        let tr = vox_dda(inst, inst.eye_local.xyz, vox_dir(inst, dw), 0.0, best_t);
        steps += tr.steps;
        if (tr.hit && tr.t <= best_t) {
            found = true;
            best = tr;
            best_k = k;
            best_t = tr.t;
        }
    }
    if (!found) {
        discard;
    }
    let inst = vox_instances[best_k];
    let n = vox_dir_world(inst, vox_normal(best.axis, vox_dir(inst, dw)));
    let colour = vox_palette[inst.bdims.w + best.index];
    return vec4<u32>(bitcast<u32>(best.t), colour, pack4x8snorm(vec4<f32>(n, 0.0)), 1u | 32u | (best_k << 8u) | (min(steps, 0xffffu) << 16u));
}

// Sun-ray origin of a G-buffer pixel in the world, relative to the eye (voxel faces are left
// along their normal); w = 0 where the surface faces away from the sun.
fn vox_shadow_origin(px: vec2<u32>, g: vec4<u32>) -> vec4<f32> {
    var p = ray_dir(px) * bitcast<f32>(g.x);
    if ((g.w & 32u) != 0u) {
        let n = normalize(unpack4x8snorm(g.z).xyz);
        if (dot(n, frame.sun_world.xyz) <= 0.0) {
            return vec4<f32>(p, 0.0);
        }
        p += n * (VOX_SHADOW_OFFSET * vox_instances[(g.w >> 8u) & 0xffu].eye_local.w);
    }
    return vec4<f32>(p, 1.0);
}

@fragment
fn fs_vox_shadow(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let p = vox_shadow_origin(px, g);
    // Sky (no finite origin), and surfaces facing away from the sun: nothing to trace.
    let live = (g.w & 1u) != 0u && p.w != 0.0;
    let o = select(vec3<f32>(0.0), p.xyz, live);
    let t_max = select(-1.0, BIG, live);
    var blocked = false;
    for (var k = 0u; k < VOX_INSTANCES; k++) {
        let inst = vox_instances[k];
        let tr = vox_dda(inst, inst.eye_local.xyz + vox_dir(inst, o), vox_dir(inst, frame.sun_world.xyz), 0.0, t_max);
        if (tr.hit) {
            blocked = true;
            break;
        }
    }
    if (!blocked) {
        discard;
    }
    return vec4<u32>(g.xyz, g.w | 64u);
}
