// Voxel-model passes, drawn over the pixel rectangles the models can cover (`gpu::voxels`):
// the cast (nearest voxel in front of the G-buffer hit replaces it: distance, palette RGBA,
// packed world normal, flags 1 | 32 | instance << 8 | steps << 16) and the shadow pass (sets
// flag 64 where a voxel blocks the sun). Both read a copy of the G-buffer and draw into the
// G-buffer itself: a pixel they leave as it is discards, at the end: a fragment discarded
// earlier may go on running as a helper invocation on Mesa's CPU adapters (its SIMD lanes do
// not leave the DDA loop), so pixels without work get an empty ray interval instead.
//
// Each rectangle (a piece of the partition of the models' rectangles, `cpu::voxel`) runs
// exactly the instances whose own rectangles hold it. A rectangle of one instance is drawn by
// the `_one` entry points: one DDA call on the record `vox_draw.inst`
// (loaded at a fixed offset: one scalar load per component on Mesa's CPU adapters, where
// `vox_instances[k]` at an index they cannot tell is uniform costs a gather per component,
// and the loop over instances around the DDA loop costs more again).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer_in: texture_2d<u32>;

// The instances one rectangle runs (`gpu::types::VoxDrawGpu`, bound by dynamic offset).
struct VoxDraw {
    // Bit k of x | y << 32: instance k runs; z: the instance of a one-instance draw.
    mask: vec4<u32>,
    // A one-instance draw's record (a copy of vox_instances[mask.z]).
    inst: VoxInstance,
}
@group(0) @binding(16) var<uniform> vox_draw: VoxDraw;

// The lowest instance left in `m`, cleared from it (call while any(*m != 0)).
fn vox_next(m: ptr<function, vec2<u32>>) -> u32 {
    let lo = (*m).x != 0u;
    let bits = select((*m).y, (*m).x, lo);
    let rest = bits & (bits - 1u);
    if (lo) {
        (*m).x = rest;
    } else {
        (*m).y = rest;
    }
    return firstTrailingBit(bits) + select(32u, 0u, lo);
}

// Ray interval end of a G-buffer pixel: its hit distance, none (-1) where no ray is (flag 8:
// a projector pixel off the screen).
fn vox_far(g: vec4<u32>) -> f32 {
    return select(select(BIG, bitcast<f32>(g.x), (g.w & 1u) != 0u), -1.0, (g.w & 8u) != 0u);
}

// The G-buffer texel of instance k's hit `tr` along the world ray `dw`.
fn vox_hit(inst: VoxInstance, k: u32, tr: VoxTrace, dw: vec3<f32>, steps: u32) -> vec4<u32> {
    let n = vox_dir_world(inst, vox_normal(tr.axis, vox_dir(inst, dw)));
    let colour = vox_palette[inst.bdims.w + tr.index];
    return vec4<u32>(bitcast<u32>(tr.t), colour, pack4x8snorm(vec4<f32>(n, 0.0)), 1u | 32u | (k << 8u) | (min(steps, 0xffffu) << 16u));
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
    var m = vox_draw.mask.xy;
    while (any(m != vec2<u32>(0u))) {
        let k = vox_next(&m);
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
    return vox_hit(vox_instances[best_k], best_k, best, dw, steps);
}

@fragment
fn fs_voxels_one(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let dw = ray_dir(px);
    let inst = vox_draw.inst;
    let tr = vox_dda(inst, inst.eye_local.xyz, vox_dir(inst, dw), 0.0, vox_far(g));
    if (!tr.hit) {
        discard;
    }
    return vox_hit(inst, vox_draw.mask.z, tr, dw, tr.steps);
}

// Sun-ray origin of a G-buffer pixel in the world, relative to the eye (voxel faces are left
// along their normal); w = 0 where there is nothing to trace: sky, or a surface facing away
// from the sun.
fn vox_shadow_origin(px: vec2<u32>, g: vec4<u32>) -> vec4<f32> {
    var p = ray_dir(px) * bitcast<f32>(g.x);
    if ((g.w & 1u) == 0u) {
        return vec4<f32>(0.0);
    }
    if ((g.w & 32u) != 0u) {
        let n = normalize(unpack4x8snorm(g.z).xyz);
        if (dot(n, frame.sun_world.xyz) <= 0.0) {
            return vec4<f32>(0.0);
        }
        p += n * (VOX_SHADOW_OFFSET * vox_instances[(g.w >> 8u) & 0xffu].eye_local.w);
    }
    return vec4<f32>(p, 1.0);
}

// Whether instance `inst` blocks the sun from the shadow origin `p`.
fn vox_blocks(inst: VoxInstance, p: vec4<f32>) -> bool {
    return vox_dda(inst, inst.eye_local.xyz + vox_dir(inst, p.xyz), vox_dir(inst, frame.sun_world.xyz), 0.0, select(-1.0, BIG, p.w != 0.0)).hit;
}

@fragment
fn fs_vox_shadow(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let p = vox_shadow_origin(px, g);
    var blocked = false;
    var m = vox_draw.mask.xy;
    while (any(m != vec2<u32>(0u))) {
        if (vox_blocks(vox_instances[vox_next(&m)], p)) {
            blocked = true;
            break;
        }
    }
    if (!blocked) {
        discard;
    }
    return vec4<u32>(g.xyz, g.w | 64u);
}

@fragment
fn fs_vox_shadow_one(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    if (!vox_blocks(vox_draw.inst, vox_shadow_origin(px, g))) {
        discard;
    }
    return vec4<u32>(g.xyz, g.w | 64u);
}
