// The traversal's storage interface on the tile pool (`PAGED` builds): window cell `cell` of
// pyramid level `level` is global cell (origin >> level) + cell of virtual level `level`; the
// window's origin is a multiple of 2^top finest samples, so every window cell lies in one cell
// of every coarser database level (`cpu::paged::PagedTerrain`, the CPU twin).

fn paged_global(level: u32, cell: vec2<i32>) -> vec2<u32> {
    return (vec2<u32>(paged.origin_x, paged.origin_y) >> vec2<u32>(level)) + vec2<u32>(cell);
}

fn cell_max(level: u32, cell: vec2<i32>) -> f32 {
    return paged_cell_max(level, paged_global(level, cell));
}

fn patch_corners(level: u32, cell: vec2<i32>) -> vec4<f32> {
    return paged_patch_corners(level, paged_global(level, cell));
}

// Whether a ray stops at this cell (level > 0): the finest level resident over it is this one
// or coarser (`PagedTerrain::stops`). The traversal asks right after `cell_max` of the same
// cell, whose map entry is kept (`paged_last_entry`).
fn paged_stops(level: u32, cell: vec2<i32>) -> bool {
    let e = paged_last_entry;
    return e == PAGED_NONE || (e >> 24u) >= level;
}

// The finest resident level's coarseness over hit cell `cell` (level 0) in the G-buffer's
// steps word, bits 24..31: the shade pass reads its normals there without a search loop
// (loops in the shade pass cost lavapipe ~150 ms a 160x120 frame, whatever they do).
fn gbuffer_hint(cell: vec2<i32>) -> u32 {
    return min(finest_resident(0u, paged_global(0u, cell)), 255u) << 24u;
}

fn gbuffer_steps(z: u32) -> u32 {
    return z & 0xffffffu;
}

// Bilinear height of the finest resident surface at grid (x, y), clamped to the grid.
fn surface_height(x: f32, y: f32) -> f32 {
    let cx = clamp(x, 0.0, cells_x());
    let cy = clamp(y, 0.0, cells_y());
    let i = min(u32(cx), frame.grid.x - 2u);
    let j = min(u32(cy), frame.grid.y - 2u);
    let h = patch_corners(0u, vec2<i32>(i32(i), i32(j)));
    let u = cx - f32(i);
    let v = cy - f32(j);
    return mix(mix(h.x, h.y, u), mix(h.z, h.w, u), v);
}
