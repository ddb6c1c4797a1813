// Voxel-model passes, drawn over the pixel rectangles the models can cover (`gpu::voxels`):
// the cast (nearest voxel in front of the G-buffer hit replaces it: distance, palette RGBA,
// packed world normal, flags 1 | 32 | instance << 8 | steps << 16) and the shadow pass (sets
// flag 64 where a voxel blocks the sun). On anti-aliasing's centre rays the cast also sets
// the near-miss bit (31) of a pixel whose ray misses a model within its cone
// (`vox_near_miss`). Both read a copy of the G-buffer and draw into the G-buffer itself: a
// pixel they leave as it is discards, at the end: a fragment discarded
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

// The pixel cone's reach at unit distance: its corners, sqrt 2 times the half-angle the ray
// table carries (0 where it carries none).
fn vox_reach(px: vec2<u32>) -> f32 {
    return 1.4143 * max(ray_entry(px).w, 0.0);
}

// Near miss of a voxel model (anti-aliasing's centre rays, `frame.stamp.z` = 1; `d` the ray's
// direction in voxel units per metre, `touched` whether its DDA entered an occupied brick):
// may the ray, which hits none of the model's voxels before `t_max`, pass within `reach` t of
// one where its pixel is at least a voxel wide (2 half-angles t >= the voxel size)? There the
// model's detail is finer than the pixels: a mast or a twig one voxel wide can lie between
// two centre rays, and no colour difference would mark it; nearer, voxels are wider than
// pixels, a neighbouring centre ray hits any voxel and the colour rules mark the edge.
// * Through the model's box: when the ray crossed an occupied brick (within a brick of a
//   voxel) or an empty one with a voxel close ahead (`VoxTrace::touched`). A ray crossing
//   only other empty bricks is not flagged, though a voxel at the border of the next brick
//   may lie within its reach; the pixel on the voxel's other side is.
// * Beside the box: when it passes within reach of the bounding box of a slab's occupied
//   voxels, widened by the reach at the far side of its bounding sphere (as for plain free
//   forms). This finds a mast whose box is itself thinner than a pixel.
// Rays that hit a voxel are left to the colour rules (their G-buffer word holds the step
// count in bit 31).
fn vox_near_miss(inst: VoxInstance, d: vec3<f32>, reach: f32, t_max: f32, touched: bool) -> bool {
    let o = inst.eye_local.xyz;
    let iv = vec3<f32>(vox_inv(d.x), vox_inv(d.y), vox_inv(d.z));
    // 2 half-angles = reach / 0.70715.
    let k = 1.41412 * reach / inst.eye_local.w;
    let ma = -o * iv;
    let mb = (vec3<f32>(inst.dims.xyz) - o) * iv;
    let m0 = max(max(min(ma.x, mb.x), min(ma.y, mb.y)), max(min(ma.z, mb.z), 0.0));
    let m1 = min(min(max(ma.x, mb.x), max(ma.y, mb.y)), min(max(ma.z, mb.z), t_max));
    if (m0 <= m1) {
        return touched && k * m1 >= 1.0;
    }
    var near = false;
    for (var j = 0u; j < VOX_SLABS; j++) {
        let lo_b = inst.slab_lo[j].xyz;
        let hi_b = inst.slab_hi[j].xyz;
        let widen = reach * (length(o - 0.5 * (lo_b + hi_b)) + 0.5 * length(hi_b - lo_b));
        let ta = (lo_b - widen - o) * iv;
        let tb = (hi_b + widen - o) * iv;
        let lo = min(ta, tb);
        let hi = max(ta, tb);
        let t0 = max(max(lo.x, lo.y), max(lo.z, 0.0));
        let t1 = min(min(hi.x, hi.y), min(hi.z, t_max));
        near = near || (inst.slab_lo[j].w != 0.0 && t0 <= t1 && k * t1 >= 1.0);
    }
    return near;
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
    // Instances whose DDA came within a brick of a voxel (`VoxTrace::touched`; bit k of
    // x | y << 32).
    var touched = vec2<u32>(0u);
    var m = vox_draw.mask.xy;
    while (any(m != vec2<u32>(0u))) {
        let k = vox_next(&m);
        let inst = vox_instances[k];
        let tr = vox_dda(inst, inst.eye_local.xyz, vox_dir(inst, dw), 0.0, best_t);
        steps += tr.steps;
        let bit = 1u << (k & 31u);
        touched |= select(vec2<u32>(0u), select(vec2<u32>(bit, 0u), vec2<u32>(0u, bit), k >= 32u), tr.touched);
        if (tr.hit && tr.t <= best_t) {
            found = true;
            best = tr;
            best_k = k;
            best_t = tr.t;
        }
    }
    if (!found) {
        // Anti-aliasing's centre rays: a model missed within the pixel cone.
        if (frame.stamp.z != 0u) {
            let reach = vox_reach(px);
            var near = false;
            m = vox_draw.mask.xy;
            while (any(m != vec2<u32>(0u))) {
                let k = vox_next(&m);
                let inst = vox_instances[k];
                let bits = select(touched.x, touched.y, k >= 32u);
                near = near || vox_near_miss(inst, vox_dir(inst, dw), reach, best_t, ((bits >> (k & 31u)) & 1u) != 0u);
            }
            if (near) {
                return vec4<u32>(g.xyz, g.w | 0x80000000u);
            }
        }
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
    let far = vox_far(g);
    let d = vox_dir(inst, dw);
    let tr = vox_dda(inst, inst.eye_local.xyz, d, 0.0, far);
    if (!tr.hit) {
        if (frame.stamp.z != 0u && vox_near_miss(inst, d, vox_reach(px), far, tr.touched)) {
            return vec4<u32>(g.xyz, g.w | 0x80000000u);
        }
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
