// The paged terrain: database tiles in a pool of fixed slots, found through a page table
// (src/gpu/terrain_pool.rs fills both from db::pager's uploads). CPU twin: src/cpu/paged.rs.
//
// Virtual levels: level 0 is the finest database level's cells, level k cells of 2^k of them;
// cells are addressed by their index on the finest level's global cell grid (anchored at
// longitude -180, latitude -90). A virtual cell is read from the finest resident database tile
// that covers it: database level F - j holds it in its in-tile pyramid level k - j (cells of
// 2^k finest cells), or, where j > k (only a coarser level is resident), in the coarse cell
// containing it, whose maximum bounds every finer sample in its footprint. So `cell_max` is
// always a conservative bound, and `patch_corners` the surface of the finest resident level.
//
// Slot layout (f32): the (N+1)^2 heights row by row (row 0 south), then the in-tile maximum
// pyramid (N^2 cell maxima, then each coarser in-tile level, down to 1). A pool larger than
// the adapter's storage-binding size spans several buffers of whole slots (`paged_read`).

struct PagedParams {
    tile_n: u32,       // cells per tile side N (a power of two)
    log2_n: u32,
    levels: u32,       // database levels (0 the coarsest)
    slot_floats: u32,  // floats per slot
    origin_x: u32,     // the traversal window's sample (0, 0) on the finest level's global grid
    origin_y: u32,     // (a multiple of 2^top: see terrain_paged_window.wgsl)
    map_side: u32,     // the residency map: entries a side at its level 0 (a power of two)
    map_levels: u32,   // and its levels (virtual levels log2_n ..= log2_n + map_levels - 1)
    pool_shift: u32,   // 2^pool_shift slots per pool buffer where the pool spans several
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

struct PagedLevel {
    table_offset: u32, // this level's first entry in paged_table
    x0: u32,           // tile range x0..x0+width, y0..y0+height
    y0: u32,
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(3) @binding(0) var<uniform> paged: PagedParams;
@group(3) @binding(1) var<storage, read> paged_levels: array<PagedLevel>;
@group(3) @binding(2) var<storage, read> paged_table: array<u32>;
// The pool itself, `paged_read(slot, i)`: one storage binding or several (a pool over the
// adapter's binding size), declared by `gpu::shaders::paged_pools`.
// The residency map (db::pager::residency): per tile-sized cell of the window, per virtual
// level from log2_n up, the finest resident level's coarseness j (top 8 bits) and its slot.
@group(3) @binding(4) var<storage, read> paged_map: array<u32>;

const PAGED_NONE: u32 = 0xffffffffu;
const PAGED_PAD: f32 = -1e30;

// The slot holding tile (x, y) of database level `dl`, or PAGED_NONE.
fn paged_slot(dl: u32, x: u32, y: u32) -> u32 {
    let lv = paged_levels[dl];
    if (x < lv.x0 || y < lv.y0 || x - lv.x0 >= lv.width || y - lv.y0 >= lv.height) {
        return PAGED_NONE;
    }
    return paged_table[lv.table_offset + (y - lv.y0) * lv.width + (x - lv.x0)];
}

// Offset of in-tile pyramid level m in a slot.
fn paged_max_offset(m: u32) -> u32 {
    let n = paged.tile_n;
    let side = n >> m;
    // 4 (n^2 - side^2) / 3: m ones in base 4 times 4 side^2 (as pyramid_index).
    let ones = 0x55555555u & ((1u << (2u * m)) - 1u);
    return (n + 1u) * (n + 1u) + ((ones * side * side) << 2u);
}

// The index of the residency map's entry over virtual cell `cell` of level `level` (global index):
// `ResidencyMap::entry`, operation for operation; PAGED_NONE off the map.
fn paged_map_index(level: u32, cell: vec2<u32>) -> u32 {
    let k = select(0u, level - paged.log2_n, level > paged.log2_n);
    if (k >= paged.map_levels) {
        return PAGED_NONE;
    }
    let shift = paged.log2_n + k - level;
    let s = paged.map_side >> k;
    let first = vec2<u32>(paged.origin_x, paged.origin_y) >> vec2<u32>(paged.log2_n + k);
    let t = (cell >> vec2<u32>(shift)) - first;
    if (t.x >= s || t.y >= s) {
        return PAGED_NONE;
    }
    // Level k starts at 4 (side^2 - s^2) / 3: k ones in base 4 (as pyramid_index).
    let ones = 0x55555555u & ((1u << (2u * k)) - 1u);
    return ((ones * s * s) << 2u) + t.y * s + t.x;
}

const PAGED_SLOT_MASK: u32 = 0x00ffffffu;

// The coarseness j (virtual level of the database level F - j) of the finest resident
// database level over virtual cell `cell` of level `level`; PAGED_NONE where nothing is
// resident. One read of the residency map.
fn finest_resident(level: u32, cell: vec2<u32>) -> u32 {
    let e = paged_map_read(level, cell);
    return select(e >> 24u, PAGED_NONE, e == PAGED_NONE);
}

fn paged_map_read(level: u32, cell: vec2<u32>) -> u32 {
    let i = paged_map_index(level, cell);
    if (i == PAGED_NONE) {
        return PAGED_NONE;
    }
    return paged_map[i];
}

// The map entry the last `paged_cell_max` read: the traversal asks `paged_stops` about the
// same cell right after (terrain_paged_window.wgsl), which then needs no second read.
var<private> paged_last_entry: u32 = 0xffffffffu;

// A bound on the terrain over virtual cell `cell` of level `level`: its maximum from the
// finest resident level (a coarser cell's maximum where that is all there is).
fn paged_cell_max(level: u32, cell: vec2<u32>) -> f32 {
    let e = paged_map_read(level, cell);
    paged_last_entry = e;
    if (e == PAGED_NONE) {
        return PAGED_PAD;
    }
    let j = e >> 24u;
    let slot = e & PAGED_SLOT_MASK;
    // In the tile of database level F - j: where j <= level, in-tile pyramid level m = level - j
    // of side N >> m, the cell at `cell` modulo the side; where j > level (only a coarser level
    // is resident), the coarse cell containing it, at in-tile level 0.
    let up = j <= level;
    let m = select(0u, level - j, up);
    let side = paged.tile_n >> m;
    let c = cell >> vec2<u32>(select(j - level, 0u, up));
    let local = c & vec2<u32>(side - 1u);
    return paged_read(slot, paged_max_offset(m) + local.y * side + local.x);
}

// Height of sample (i, j) of the tile in `slot`.
fn paged_height(slot: u32, i: u32, j: u32) -> f32 {
    return paged_read(slot, j * (paged.tile_n + 1u) + i);
}

// The bilinear patch corners (south-west, south-east, north-west, north-east) of virtual
// cell `cell` at level `level`: the samples of database level F - level where resident,
// otherwise that cell's corners on the finest resident coarser level's bilinear surface (which
// is continuous, so neighbouring cells meet without cracks).
fn paged_patch_corners(level: u32, cell: vec2<u32>) -> vec4<f32> {
    let f = paged.levels - 1u;
    let e = paged_map_read(level, cell);
    if (e == PAGED_NONE || level > f) {
        return vec4<f32>(PAGED_PAD);
    }
    let jr = e >> 24u;
    let j = max(jr, level);
    // Cell corners in units of level-(F - j) samples: (cell << level) >> j, fractional.
    let s = f32(1u << (j - level));
    let base = cell >> vec2<u32>(j - level);
    let frac0 = vec2<f32>(cell - (base << vec2<u32>(j - level))) / s;
    // The map's slot where the finest resident level is this one or coarser; a finer level
    // resident under a coarser patch (footprint LOD) reads this level's from the page table.
    var slot = e & PAGED_SLOT_MASK;
    if (jr < level) {
        let t = base >> vec2<u32>(paged.log2_n);
        slot = paged_slot(f - j, t.x, t.y);
    }
    let a = base & vec2<u32>(paged.tile_n - 1u);
    let h00 = paged_height(slot, a.x, a.y);
    let h10 = paged_height(slot, a.x + 1u, a.y);
    let h01 = paged_height(slot, a.x, a.y + 1u);
    let h11 = paged_height(slot, a.x + 1u, a.y + 1u);
    let inv = 1.0 / s;
    var out: vec4<f32>;
    for (var k = 0u; k < 4u; k = k + 1u) {
        let uv = frac0 + vec2<f32>(f32(k & 1u), f32(k >> 1u)) * inv;
        let south = mix(h00, h10, uv.x);
        let north = mix(h01, h11, uv.x);
        out[k] = mix(south, north, uv.y);
    }
    return out;
}
