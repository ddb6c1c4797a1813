// Anti-aliasing, the list of marked pixels built on the GPU (`gpu::antialias::gpu_list`;
// compute, three dispatches): the edge mask's marked pixels, the 16s, then the 8s, then the
// 4s, each part tile by tile in the order of `tiles` (8x8 tiles along a Hilbert curve) and
// row by row inside a tile: the list `Marked::from_mask_in` makes on the CPU, entry for entry.
// 1. `cs_count`, an invocation per tile: the tile's pixels of each part;
// 2. `cs_scan`, one workgroup: each tile's place in each part (an exclusive scan), and the
//    parts' lengths after the last tile (the only figures the CPU reads back);
// 3. `cs_place`, an invocation per tile: each marked pixel stored at its place in the list
//    (x | y << 16, row by row in the screen's width, as the other passes read it).

struct ListParams {
    // Screen width and height.
    size: vec4<u32>,
}

@group(0) @binding(0) var<uniform> lp: ListParams;
// The edge mask: each pixel's sample count (16, 8 or 4), 0 where unmarked.
@group(0) @binding(1) var mask: texture_2d<u32>;
// The screen's 8x8 tiles (x | y << 16) in list order.
@group(0) @binding(2) var<storage, read> tiles: array<u32>;
// One entry per tile, then one more: the tile's pixels with 16, 8 and 4 samples (`cs_count`),
// then (`cs_scan`) the places in each part before the tile; the last entry the parts' lengths.
@group(0) @binding(3) var<storage, read_write> tile_counts: array<vec4<u32>>;
@group(0) @binding(4) var list: texture_storage_2d<r32uint, write>;

// The list's part of a pixel: 0 (16 samples), 1 (8), 2 (4) or 3 (unmarked, or off the screen).
fn list_part(p: vec2<u32>) -> u32 {
    if (p.x >= lp.size.x || p.y >= lp.size.y) {
        return 3u;
    }
    let n = textureLoad(mask, vec2<i32>(p), 0).x;
    return select(select(select(3u, 2u, n == 4u), 1u, n == 8u), 0u, n == 16u);
}

// Tile of invocation `local` of a workgroup of a dispatch as wide as `groups.x`: one
// invocation a tile, no workgroup memory, no barrier (a workgroup a tile with barriers made
// lavapipe's edges and list 32-50 ms instead of 21 at 1280x720: llvmpipe runs a workgroup's
// invocations as coroutines that suspend at each barrier).
fn list_tile(wg: vec3<u32>, groups: vec3<u32>, local: u32) -> u32 {
    return (wg.y * groups.x + wg.x) * 64u + local;
}

fn tile_origin(t: u32) -> vec2<u32> {
    let tile = tiles[t];
    return vec2<u32>(tile & 0xffffu, tile >> 16u) * 8u;
}

@compute @workgroup_size(64)
fn cs_count(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    let t = list_tile(wg, groups, li);
    if (t >= arrayLength(&tiles)) {
        return;
    }
    let o = tile_origin(t);
    var c = vec4<u32>(0u);
    for (var y = 0u; y < 8u; y += 1u) {
        for (var x = 0u; x < 8u; x += 1u) {
            let part = list_part(o + vec2<u32>(x, y));
            c += vec4<u32>(select(vec3<u32>(0u), vec3<u32>(1u), vec3<u32>(part) == vec3<u32>(0u, 1u, 2u)), 0u);
        }
    }
    tile_counts[t] = c;
}

const SCAN: u32 = 256u;
var<workgroup> sums: array<vec4<u32>, 256>;

// Each of the 256 invocations sums a run of consecutive tiles; the runs' sums are scanned in
// workgroup memory (Hillis and Steele); each invocation then walks its run again, writing
// every tile's places before it.
@compute @workgroup_size(256)
fn cs_scan(@builtin(local_invocation_index) li: u32) {
    let n = arrayLength(&tile_counts) - 1u;
    let run = (n + SCAN - 1u) / SCAN;
    let first = min(li * run, n);
    let end = min(first + run, n);
    var own = vec4<u32>(0u);
    for (var t = first; t < end; t += 1u) {
        own += tile_counts[t];
    }
    sums[li] = own;
    for (var d = 1u; d < SCAN; d *= 2u) {
        workgroupBarrier();
        let v = sums[li] + select(vec4<u32>(0u), sums[select(0u, li - d, li >= d)], li >= d);
        workgroupBarrier();
        sums[li] = v;
    }
    workgroupBarrier();
    var at = sums[li] - own;
    for (var t = first; t < end; t += 1u) {
        let c = tile_counts[t];
        tile_counts[t] = at;
        at += c;
    }
    if (li == SCAN - 1u) {
        tile_counts[n] = sums[SCAN - 1u];
    }
}

@compute @workgroup_size(64)
fn cs_place(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    let t = list_tile(wg, groups, li);
    if (t >= arrayLength(&tiles)) {
        return;
    }
    let lengths = tile_counts[arrayLength(&tile_counts) - 1u];
    // The next place in each part: the part's start, then the tile's place in it.
    var at = tile_counts[t] + vec4<u32>(0u, lengths.x, lengths.x + lengths.y, 0u);
    let o = tile_origin(t);
    let w = lp.size.x;
    for (var y = 0u; y < 8u; y += 1u) {
        for (var x = 0u; x < 8u; x += 1u) {
            let p = o + vec2<u32>(x, y);
            let part = list_part(p);
            if (part < 3u) {
                let m = at[part];
                at[part] = m + 1u;
                textureStore(list, vec2<i32>(i32(m % w), i32(m / w)), vec4<u32>(p.x | (p.y << 16u), 0u, 0u, 0u));
            }
        }
    }
}
