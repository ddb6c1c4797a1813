// Voxel models: instance records (mirrored by `gpu::types::VoxInstanceGpu`), the brick table,
// brick pool and palettes, and the hierarchical DDA (`cpu::voxel::dda` step for step): the ray,
// moved into the model's voxel units (t stays in metres), is clipped to the model box, walks
// the brick grid (8³ voxels per brick) by Amanatides–Woo and, inside each occupied brick, its
// voxels the same way, both jumping over the empty space ahead of the ray towards its octant
// (`voxel::skip`). Cells are stepped by integer index and exit axis.

struct VoxInstance {
    // Rows of Rᵀ / voxel size: world direction -> voxel units per metre.
    local_from_world_0: vec4<f32>,
    local_from_world_1: vec4<f32>,
    local_from_world_2: vec4<f32>,
    // Eye in voxel units (computed in f64 on the CPU); w = voxel size in metres.
    eye_local: vec4<f32>,
    // Model size in voxels; w = offset of the shown frame's brick table in `vox_data`.
    dims: vec4<u32>,
    // Brick grid size; w = offset of the frame's palette in `vox_palette`.
    bdims: vec4<u32>,
    // Bounding boxes (voxel units) of the occupied voxels in the model's z slabs, for
    // anti-aliasing's near misses (`vox_near_miss`): lower corners, w = 1 for a slab in use;
    // upper corners.
    slab_lo: array<vec4<f32>, VOX_SLABS>,
    slab_hi: array<vec4<f32>, VOX_SLABS>,
}

// Slab boxes of a `VoxInstance` (`gpu::types::VOX_SLABS`).
const VOX_SLABS: u32 = 4u;

// `vox_instances` (binding 10, a uniform array of the scene's records: one gather per load
// on Mesa's CPU adapters, not a loop over the lanes as from a storage buffer) is declared
// ahead of this file by `gpu::shaders::voxels`.
// The brick tables and the brick pool in one buffer, so that a DDA step loads one word (a
// storage-buffer load costs Mesa's CPU adapters a loop over the SIMD lanes, and both levels'
// code runs in every step). A frame has a brick table per octant of ray directions: a brick's
// entry is the word address in this buffer of its block, or VOX_EMPTY_BIT | how far in voxels
// its box can grow towards the octant and stay empty (`Bricks::brick_gap`, bits 0-15) | how
// far it can grow in every direction (the least of its eight octants' gaps, capped at 0x7fff,
// from bit VOX_NEAR_GAP_SHIFT: anti-aliasing's near misses, `VoxTrace::touched`). A block
// holds, for each octant, its 512 voxels' 4-bit codes (64 words, 8 voxels each): 0 =
// occupied, else the side of the largest empty cube with the voxel as its corner towards that
// octant (`Bricks::pool_jump`); a ray reads only its octant's table and codes. Then the
// palette indices (128 words, 4 voxels each, read once a ray hits).
@group(0) @binding(11) var<storage, read> vox_data: array<u32>;
// sRGB RGBA8 per palette index.
@group(0) @binding(13) var<storage, read> vox_palette: array<u32>;

// Keep in step with `gpu::voxels::EMPTY_BIT`.
const VOX_EMPTY_BIT: u32 = 0x80000000u;
const VOX_BRICK: i32 = 8;
// Words of one octant's voxel codes in a brick's block (`gpu::voxels::CODE_WORDS`).
const VOX_CODE_WORDS: u32 = 64u;
const VOX_MAX_STEPS: u32 = 4096u;
// Shift of an empty brick's gap in every direction in its table entry
// (`gpu::voxels::NEAR_GAP_SHIFT`).
const VOX_NEAR_GAP_SHIFT: u32 = 16u;
// Offset (voxels) a shadow ray leaves a voxel face by (`cpu::voxel::SHADOW_OFFSET_VOXELS`).
const VOX_SHADOW_OFFSET: f32 = 0.01;

struct VoxTrace {
    hit: bool,
    t: f32,
    // Axis the ray entered the voxel through; 3 = it started inside.
    axis: u32,
    index: u32,
    steps: u32,
    // Whether the ray entered an occupied brick or crossed an empty one that may have a voxel
    // within the reach of where the ray leaves it (anti-aliasing's near misses,
    // `vox_near_miss`, `vox_shadow_near`).
    touched: bool,
}

fn vox_dir(inst: VoxInstance, d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(inst.local_from_world_0.xyz, d), dot(inst.local_from_world_1.xyz, d), dot(inst.local_from_world_2.xyz, d));
}

// World unit vector of a voxel-frame direction.
fn vox_dir_world(inst: VoxInstance, n: vec3<f32>) -> vec3<f32> {
    return normalize(inst.local_from_world_0.xyz * n.x + inst.local_from_world_1.xyz * n.y + inst.local_from_world_2.xyz * n.z);
}

fn vox_inv(d: f32) -> f32 {
    return select(1.0 / d, BIG, abs(d) < 1.0e-30);
}

// Outward face normal (voxel frame) of a hit entered through `axis` along d.
fn vox_normal(axis: u32, d: vec3<f32>) -> vec3<f32> {
    var a = axis;
    if (a > 2u) {
        let ad = abs(d);
        a = select(select(2u, 1u, ad.y >= ad.z), 0u, ad.x >= ad.y && ad.x >= ad.z);
    }
    var n = vec3<f32>(0.0);
    n[a] = select(1.0, -1.0, d[a] > 0.0);
    return n;
}

// Index of voxel `c` in its brick's block.
fn vox_local(c: vec3<i32>) -> u32 {
    let l = c & vec3<i32>(VOX_BRICK - 1);
    return u32(l.x + VOX_BRICK * (l.y + VOX_BRICK * l.z));
}

// `near` (a constant where called: anti-aliasing's `_near` passes) also tracks
// `VoxTrace::touched` with the reach `reach.x + reach.y t` in voxels: every brick the ray
// crosses counts, so until one has touched, its jumps over empty bricks stay that reach
// inside their gap in every direction (the bricks a jump passes may lie beside voxels the
// jump's one-sided box leaves out; with the reach R at the span's far end, a point of the
// brick's box grown by g - 1 - R lies at least R from any voxel).
fn vox_dda(inst: VoxInstance, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, near: bool, reach: vec2<f32>) -> VoxTrace {
    var r: VoxTrace;
    r.hit = false;
    r.steps = 0u;
    r.touched = false;
    let iv = vec3<f32>(vox_inv(d.x), vox_inv(d.y), vox_inv(d.z));
    let ta = -o * iv;
    let tb = (vec3<f32>(inst.dims.xyz) - o) * iv;
    let lo = min(ta, tb);
    let hi = max(ta, tb);
    var axis = 0u;
    var t0 = lo.x;
    if (lo.y > t0) {
        t0 = lo.y;
        axis = 1u;
    }
    if (lo.z > t0) {
        t0 = lo.z;
        axis = 2u;
    }
    let t1 = min(min(min(hi.x, hi.y), hi.z), t_max);
    if (t0 < t_min) {
        t0 = t_min;
        axis = 3u;
    }
    // Also refuses a NaN interval (a non-finite origin).
    if (!(t0 <= t1)) {
        return r;
    }
    let pos = d >= vec3<f32>(0.0);
    let flat = iv == vec3<f32>(BIG);
    let bd = vec3<i32>(inst.bdims.xyz);
    // This ray's octant (`voxel::skip::octant`): its brick table and its codes in a block.
    let oct = dot(select(vec3<u32>(0u), vec3<u32>(1u, 2u, 4u), pos), vec3<u32>(1u));
    let table = inst.dims.w + oct * u32(bd.x * bd.y * bd.z);
    let codes = VOX_CODE_WORDS * oct;
    // Brick level (`cell` in bricks of 8³ voxels) or voxel level (`cell` in voxels, inside the
    // brick whose block starts at word `block`). Every step runs all of this on Mesa's CPU
    // adapters (both sides of a branch, masked), so both levels share one load and one exit.
    // Anti-aliasing's near search: the reach at the far end of the span, in whole voxels.
    let far_reach = i32(ceil(min(reach.x + reach.y * t1, 32768.0)));
    var fine = false;
    var cell = clamp(vec3<i32>(floor((o + d * t0) / f32(VOX_BRICK))), vec3<i32>(0), bd - 1);
    var block = 0u;
    var t = t0;
    var local = 0u;
    for (var i = 0u; i < VOX_MAX_STEPS; i++) {
        r.steps += 1u;
        local = vox_local(cell);
        let w = vox_data[select(table + u32(cell.x + bd.x * (cell.y + bd.y * cell.z)), block + codes + (local >> 3u), fine)];
        let side = i32((w >> ((local & 7u) * 4u)) & 15u);
        if (fine && side == 0) {
            r.hit = true;
            break;
        }
        // An occupied brick is entered without moving: its cube is the brick itself and the
        // next cell is the voxel at the current point, clamped into it.
        let enter = !fine && (w & VOX_EMPTY_BIT) == 0u;
        // A box of voxels [lo, hi) holding the current cell, known to be empty, grown from the
        // cell towards the ray's octant: an empty brick by its gap (less the reach while a near
        // search has not touched); the brick being entered not at all; a voxel to the empty
        // cube at its corner.
        let gap_ahead = i32(w & 0xffffu);
        let gap_around = i32((w >> VOX_NEAR_GAP_SHIFT) & 0x7fffu);
        let gap = select(gap_ahead, max(min(gap_ahead, gap_around - far_reach), 1), near && !r.touched);
        let ext = select(select(gap, 1, enter), side, fine) - 1;
        let base = select(cell * VOX_BRICK, cell, fine);
        let lo = base - select(vec3<i32>(ext), vec3<i32>(0), pos);
        let hi = base + select(VOX_BRICK, 1, fine) + select(vec3<i32>(0), vec3<i32>(ext), pos);
        let te = select((vec3<f32>(select(lo, hi, pos)) - o) * iv, vec3<f32>(BIG), flat);
        // Exit axis: x before y before z on ties.
        let ex = te.x <= te.y && te.x <= te.z;
        let ey = !ex && te.y <= te.z;
        if (!enter) {
            t = min(min(te.x, te.y), te.z);
            axis = select(select(2u, 1u, ey), 0u, ex);
        }
        if (near) {
            // An empty brick whose every voxel within g - 1 of its box is empty (g its gap
            // around): a point of it lies at least g - 1 voxels from any voxel, and the reach
            // is largest where the ray leaves it (t, now). A jump beyond the brick stays
            // farther than that from every voxel (above).
            r.touched = r.touched || enter || (!fine && f32(gap_around - 1) <= reach.x + reach.y * t);
        }
        if (t > t1) {
            return r;
        }
        // The voxel beyond the exit face along the exit axis; along the others the exit
        // point's voxel, clamped into the cube.
        let q = clamp(vec3<i32>(floor(o + d * t)), lo, hi - 1);
        let next = select(q, select(lo - 1, hi, pos), vec3<bool>(ex, ey, !ex && !ey) & vec3<bool>(!enter));
        let next_brick = next >> vec3<u32>(3u);
        fine = enter || (fine && all(next_brick == cell >> vec3<u32>(3u)));
        block = select(block, w, enter);
        cell = select(next_brick, next, fine);
        if (!fine && (any(cell < vec3<i32>(0)) || any(cell >= bd))) {
            return r;
        }
    }
    if (r.hit) {
        // The palette index, after the block's codes.
        r.t = t;
        r.axis = axis;
        r.index = (vox_data[block + 8u * VOX_CODE_WORDS + (local >> 2u)] >> ((local & 3u) * 8u)) & 0xffu;
    }
    return r;
}
