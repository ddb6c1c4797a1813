// Voxel-model passes: a stencil mark (rays that enter a model box before the current hit),
// the cast (nearest voxel in front of the G-buffer hit replaces it: distance, palette RGBA,
// packed world normal, flags 1 | 32 | instance << 8 | steps << 16), and for shadows a mark
// (sun rays from visible surface points that enter a model box) and the shadow pass (sets flag
// 64 where a voxel blocks the sun). The stencil keeps the DDA out of pixels no model can touch.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer_in: texture_2d<u32>;

fn vox_far(g: vec4<u32>) -> f32 {
    return select(BIG, bitcast<f32>(g.x), (g.w & 1u) != 0u);
}

@fragment
fn fs_vox_mark(@builtin(position) pos: vec4<f32>) {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let far = vox_far(g);
    let dw = ray_dir(px);
    var any = false;
    for (var k = 0u; k < VOX_INSTANCES; k++) {
        let inst = vox_instances[k];
        let b = vox_box(inst, inst.eye_local.xyz, vox_dir(inst, dw));
        any = any || (b.x <= min(b.y, far) && b.y >= 0.0);
    }
    if (!any || (g.w & 8u) != 0u) {
        discard;
    }
}

@fragment
fn fs_voxels(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let dw = ray_dir(px);
    var best_t = vox_far(g);
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
        return g;
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
fn fs_vox_mark_shadow(@builtin(position) pos: vec4<f32>) {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    if ((g.w & 1u) == 0u) {
        discard;
    }
    let p = vox_shadow_origin(px, g);
    var any = false;
    for (var k = 0u; k < VOX_INSTANCES; k++) {
        let inst = vox_instances[k];
        let b = vox_box(inst, inst.eye_local.xyz + vox_dir(inst, p.xyz), vox_dir(inst, frame.sun_world.xyz));
        any = any || (b.x <= b.y && b.y >= 0.0);
    }
    if (!any || p.w == 0.0) {
        discard;
    }
}

@fragment
fn fs_vox_shadow(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let p = vox_shadow_origin(px, g);
    var blocked = false;
    for (var k = 0u; k < VOX_INSTANCES; k++) {
        let inst = vox_instances[k];
        let tr = vox_dda(inst, inst.eye_local.xyz + vox_dir(inst, p.xyz), vox_dir(inst, frame.sun_world.xyz), 0.0, BIG);
        if (tr.hit) {
            blocked = true;
            break;
        }
    }
    return vec4<u32>(g.xyz, g.w | select(0u, 64u, blocked));
}
