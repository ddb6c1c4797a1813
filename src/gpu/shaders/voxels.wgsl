// Voxel-model passes, drawn over the pixel rectangles the models can cover (`gpu::voxels`):
// the cast (nearest voxel in front of the G-buffer hit replaces it: distance, palette RGBA,
// packed world normal, flags 1 | 32 | instance << 8 | steps << 16) and the shadow pass (sets
// flag 64 where a voxel blocks the sun). On anti-aliasing's centre rays (the `_near` entry
// points) both also set the near-miss bit (31) of a pixel whose ray, or whose sun ray, passes
// a model within its cone (`vox_near_miss`, `vox_shadow_near`). Both read a copy of the
// G-buffer and draw into the G-buffer itself: a pixel they leave as it is discards, at the
// end: a fragment discarded earlier may go on running as a helper invocation on Mesa's CPU
// adapters (its SIMD lanes do not leave the DDA loop), so pixels without work get an empty
// ray interval instead.
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

// Near miss of a voxel model (anti-aliasing's centre rays, the `_near` passes; `d` the ray's
// direction in voxel units per metre, `touched` whether its DDA, searching with this reach,
// came within a brick or the reach of a voxel):
// may the ray, which hits none of the model's voxels before `t_max`, pass within `reach` t of
// one where its pixel is at least a voxel wide (2 half-angles t >= the voxel size)? There the
// model's detail is finer than the pixels: a mast or a twig one voxel wide can lie between
// two centre rays, and no colour difference would mark it; nearer, voxels are wider than
// pixels, a neighbouring centre ray hits any voxel and the colour rules mark the edge.
// * Through the model's box: when the ray crossed an occupied brick (within a brick of a
//   voxel) or an empty one whose gap in every direction is within the reach where the ray
//   leaves it (`VoxTrace::touched`): a voxel at the border of a brick the ray passes beside
//   counts.
// * Beside the box: when it passes within reach t of the bounding box of a slab's occupied
//   voxels (`cone_box_span`, as for free forms). This finds a mast whose box is itself
//   thinner than a pixel.
// Rays that hit a voxel are left to the colour rules (their G-buffer word holds the step
// count in bit 31).
fn vox_near_miss(inst: VoxInstance, d: vec3<f32>, reach: f32, t_max: f32, touched: bool) -> bool {
    let o = inst.eye_local.xyz;
    let iv = vec3<f32>(vox_inv(d.x), vox_inv(d.y), vox_inv(d.z));
    // 2 half-angles = reach / 0.70715.
    let k = 1.41412 * reach / inst.eye_local.w;
    let m = vox_box_span(inst, o, iv, t_max);
    if (m.x <= m.y) {
        return touched && k * m.y >= 1.0;
    }
    // Beside the box: the cone's radius where the ray is, reach t metres (reach t / voxel
    // size in voxel units), around each slab's box.
    var near = false;
    for (var j = 0u; j < VOX_SLABS; j++) {
        let span = cone_box_span(o, d, inst.slab_lo[j].xyz, inst.slab_hi[j].xyz, 0.0, reach / inst.eye_local.w, 0.0, t_max);
        near = near || (inst.slab_lo[j].w != 0.0 && span.x <= span.y && k * span.y >= 1.0);
    }
    return near;
}

// The span [x, y] (empty when x > y) of the ray o + t d (iv = 1 / d, voxel units) over
// t in [0, t_max] through instance `inst`'s model box.
fn vox_box_span(inst: VoxInstance, o: vec3<f32>, iv: vec3<f32>, t_max: f32) -> vec2<f32> {
    let ta = -o * iv;
    let tb = (vec3<f32>(inst.dims.xyz) - o) * iv;
    let lo = min(ta, tb);
    let hi = max(ta, tb);
    return vec2<f32>(max(max(lo.x, lo.y), max(lo.z, 0.0)), min(min(hi.x, hi.y), min(hi.z, t_max)));
}

// The span [x, y] (empty when x > y) of the ray o + t d (iv = 1 / d, voxel units) over
// t in [0, t_max] through instance `inst`'s slab box `j` widened by `widen` voxels; empty for
// a slab not in use.
fn vox_slab_span(inst: VoxInstance, j: u32, o: vec3<f32>, iv: vec3<f32>, widen: f32, t_max: f32) -> vec2<f32> {
    let ta = (inst.slab_lo[j].xyz - widen - o) * iv;
    let tb = (inst.slab_hi[j].xyz + widen - o) * iv;
    let lo = min(ta, tb);
    let hi = max(ta, tb);
    let t0 = max(max(lo.x, lo.y), max(lo.z, 0.0));
    let t1 = min(min(hi.x, hi.y), min(hi.z, t_max));
    return select(vec2<f32>(1.0, 0.0), vec2<f32>(t0, t1), inst.slab_lo[j].w != 0.0);
}

// The G-buffer texel of instance k's hit `tr` along the world ray `dw`.
fn vox_hit(inst: VoxInstance, k: u32, tr: VoxTrace, dw: vec3<f32>, steps: u32) -> vec4<u32> {
    let n = vox_dir_world(inst, vox_normal(tr.axis, vox_dir(inst, dw)));
    let colour = vox_palette[inst.bdims.w + tr.index];
    return vec4<u32>(bitcast<u32>(tr.t), colour, pack4x8snorm(vec4<f32>(n, 0.0)), 1u | 32u | (k << 8u) | (min(steps, 0xffffu) << 16u));
}

// The cast over instances `vox_draw.mask` (several) for pixel `px`; `near` (a constant of
// the entry point: the `_near` ones, anti-aliasing's centre rays) adds the near-miss search.
fn voxels_cast(px: vec2<u32>, near: bool) -> vec4<u32> {
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let dw = ray_dir(px);
    let reach = vox_reach(px);
    var best_t = vox_far(g);
    var found = false;
    var best: VoxTrace;
    var best_k = 0u;
    var steps = 0u;
    // Instances whose DDA came within a brick or the cone's reach of a voxel
    // (`VoxTrace::touched`; bit k of x | y << 32).
    var touched = vec2<u32>(0u);
    var m = vox_draw.mask.xy;
    while (any(m != vec2<u32>(0u))) {
        let k = vox_next(&m);
        let inst = vox_instances[k];
        let tr = vox_dda(inst, inst.eye_local.xyz, vox_dir(inst, dw), 0.0, best_t, near, vec2<f32>(0.0, reach / inst.eye_local.w));
        steps += tr.steps;
        if (near) {
            let bit = 1u << (k & 31u);
            touched |= select(vec2<u32>(0u), select(vec2<u32>(bit, 0u), vec2<u32>(0u, bit), k >= 32u), tr.touched);
        }
        if (tr.hit && tr.t <= best_t) {
            found = true;
            best = tr;
            best_k = k;
            best_t = tr.t;
        }
    }
    if (!found) {
        if (near) {
            var missed = false;
            m = vox_draw.mask.xy;
            while (any(m != vec2<u32>(0u))) {
                let k = vox_next(&m);
                let inst = vox_instances[k];
                let bits = select(touched.x, touched.y, k >= 32u);
                missed = missed || vox_near_miss(inst, vox_dir(inst, dw), reach, best_t, ((bits >> (k & 31u)) & 1u) != 0u);
            }
            if (missed) {
                return vec4<u32>(g.xyz, g.w | 0x80000000u);
            }
        }
        discard;
    }
    return vox_hit(vox_instances[best_k], best_k, best, dw, steps);
}

// The cast of the one instance `vox_draw.inst` for pixel `px` (see `voxels_cast`).
fn voxels_cast_one(px: vec2<u32>, near: bool) -> vec4<u32> {
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let dw = ray_dir(px);
    let inst = vox_draw.inst;
    let far = vox_far(g);
    let d = vox_dir(inst, dw);
    let tr = vox_dda(inst, inst.eye_local.xyz, d, 0.0, far, near, vec2<f32>(0.0, vox_reach(px) / inst.eye_local.w));
    if (!tr.hit) {
        if (near && vox_near_miss(inst, d, vox_reach(px), far, tr.touched)) {
            return vec4<u32>(g.xyz, g.w | 0x80000000u);
        }
        discard;
    }
    return vox_hit(inst, vox_draw.mask.z, tr, dw, tr.steps);
}

// Each pass has a `_near` twin for anti-aliasing's centre rays: with the near-miss search
// inlined, frames without anti-aliasing lost 25% of the cast's speed (the tree filling the
// view, `relief bench voxels`: 20 -> 26 ms) and a third of the shadow pass's.
@fragment
fn fs_voxels(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return voxels_cast(vec2<u32>(pos.xy), false);
}

@fragment
fn fs_voxels_near(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return voxels_cast(vec2<u32>(pos.xy), true);
}

@fragment
fn fs_voxels_one(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return voxels_cast_one(vec2<u32>(pos.xy), false);
}

@fragment
fn fs_voxels_one_near(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return voxels_cast_one(vec2<u32>(pos.xy), true);
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

// The sun ray from the shadow origin `p` of G-buffer pixel `g` at `px` through instance
// `inst` (`near`: tracking `VoxTrace::touched` within the footprint's beam, see
// `vox_shadow_near`).
fn vox_sun_trace(inst: VoxInstance, p: vec4<f32>, g: vec4<u32>, px: vec2<u32>, near: bool) -> VoxTrace {
    let beam = vox_reach(px) * bitcast<f32>(g.x) / inst.eye_local.w;
    return vox_dda(inst, inst.eye_local.xyz + vox_dir(inst, p.xyz), vox_dir(inst, frame.sun_world.xyz), 0.0, select(-1.0, BIG, p.w != 0.0), near, vec2<f32>(beam, 0.0));
}

// Anti-aliasing's centre rays (the `_near` shadow passes): the near-miss bit (31) for
// G-buffer pixel `g` (terrain or a free form; a voxel hit keeps its step count in bit 31)
// whose footprint is at least a voxel wide (2 half-angles times its distance `t`: the sun
// rays of the footprint form a beam that wide), when its sun ray `tr` from `p` met a voxel of
// `inst`, came within a brick or the beam of one (`VoxTrace::touched`, searched with the
// beam, `vox_sun_trace`), or passed within √2 footprint
// radii of a slab's box (a mast's shadow between two pixels' sun rays). A crown finer than
// the pixels dapples the ground below at a scale no centre ray's shadow shows: gaps let the
// sun through a shadowed pixel, leaves shade part of a lit one.
fn vox_shadow_near(inst: VoxInstance, tr: VoxTrace, g: vec4<u32>, px: vec2<u32>, p: vec4<f32>) -> bool {
    let t = bitcast<f32>(g.x);
    let reach = vox_reach(px);
    let k = 1.41412 * reach / inst.eye_local.w;
    if ((g.w & 33u) != 1u || p.w == 0.0 || k * t < 1.0) {
        return false;
    }
    let o = inst.eye_local.xyz + vox_dir(inst, p.xyz);
    let d = vox_dir(inst, frame.sun_world.xyz);
    let iv = vec3<f32>(vox_inv(d.x), vox_inv(d.y), vox_inv(d.z));
    let m = vox_box_span(inst, o, iv, BIG);
    if (m.x <= m.y) {
        return tr.hit || tr.touched;
    }
    var near = false;
    for (var j = 0u; j < VOX_SLABS; j++) {
        let span = vox_slab_span(inst, j, o, iv, reach * t / inst.eye_local.w, BIG);
        near = near || span.x <= span.y;
    }
    return near;
}

// The shadow pass over instances `vox_draw.mask` for pixel `px` (`near`: see `voxels_cast`).
fn vox_shadow(px: vec2<u32>, near: bool) -> vec4<u32> {
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let p = vox_shadow_origin(px, g);
    var blocked = false;
    var flagged = false;
    var m = vox_draw.mask.xy;
    while (any(m != vec2<u32>(0u))) {
        let inst = vox_instances[vox_next(&m)];
        let tr = vox_sun_trace(inst, p, g, px, near);
        if (near) {
            flagged = flagged || vox_shadow_near(inst, tr, g, px, p);
        }
        if (tr.hit) {
            blocked = true;
            break;
        }
    }
    if (!blocked && !flagged) {
        discard;
    }
    return vec4<u32>(g.xyz, g.w | select(0u, 64u, blocked) | select(0u, 0x80000000u, flagged));
}

// The shadow pass of the one instance `vox_draw.inst` for pixel `px`.
fn vox_shadow_one(px: vec2<u32>, near: bool) -> vec4<u32> {
    let g = textureLoad(gbuffer_in, vec2<i32>(px), 0);
    let p = vox_shadow_origin(px, g);
    let tr = vox_sun_trace(vox_draw.inst, p, g, px, near);
    let flagged = near && vox_shadow_near(vox_draw.inst, tr, g, px, p);
    if (!tr.hit && !flagged) {
        discard;
    }
    return vec4<u32>(g.xyz, g.w | select(0u, 64u, tr.hit) | select(0u, 0x80000000u, flagged));
}

@fragment
fn fs_vox_shadow(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return vox_shadow(vec2<u32>(pos.xy), false);
}

@fragment
fn fs_vox_shadow_near(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return vox_shadow(vec2<u32>(pos.xy), true);
}

@fragment
fn fs_vox_shadow_one(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return vox_shadow_one(vec2<u32>(pos.xy), false);
}

@fragment
fn fs_vox_shadow_one_near(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return vox_shadow_one(vec2<u32>(pos.xy), true);
}
