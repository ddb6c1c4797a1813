// The traversal's terrain data in memory: the heights and the square maximum pyramid
// (module-scope `heights` and `pyramid` storage arrays). The paged build reads the tile pool
// instead (`terrain_paged.wgsl`, `terrain_paged_window.wgsl`).

// The paged stop rule's stand-in (the traversal names it behind the constant PAGED = false).
fn paged_stops(level: u32, cell: vec2<i32>) -> bool {
    return false;
}

// Index of cell (ix, iy) of `level` in the square pyramid layout; NO_CELL outside it.
const NO_CELL: u32 = 0xffffffffu;

fn pyramid_index(level: u32, ix: i32, iy: i32) -> u32 {
    let side = level_side(level);
    if (u32(ix) >= side || u32(iy) >= side) {
        return NO_CELL;
    }
    // Levels above: 4 (N² - side²) / 3 = 4 side² (4^L - 1) / 3 cells, and (4^L - 1) / 3 is
    // L ones in base 4 (0x5555… masked): shifts and masks, no integer division per step.
    let ones = 0x55555555u & ((1u << (2u * level)) - 1u);
    return ((ones * side * side) << 2u) + u32(iy) * side + u32(ix);
}

fn pyr_get(level: u32, ix: i32, iy: i32) -> f32 {
    let k = pyramid_index(level, ix, iy);
    if (k == NO_CELL) {
        return PAD;
    }
    return pyramid[k];
}

// The paged build's hints through the G-buffer (terrain_paged_window.wgsl); nothing here.
fn shape_hint(g: vec4<u32>, i: i32, j: i32) {
}

fn gbuffer_hint(cell: vec2<i32>) -> u32 {
    return 0u;
}

fn gbuffer_steps(z: u32) -> u32 {
    return z;
}

fn sample_height(i: u32, j: u32) -> f32 {
    return heights[j * frame.grid.x + i];
}

// The traversal's data access. Maximum of the samples under `cell` of pyramid `level` (PAD
// outside the pyramid).
fn cell_max(level: u32, cell: vec2<i32>) -> f32 {
    return pyr_get(level, cell.x, cell.y);
}

// Corner heights (h00, h10, h01, h11) of the bilinear patch of `cell` of `level`: the finest
// samples at cell * 2^level and (cell + 1) * 2^level (level 0: the cell's own samples), the
// far corner clamped to the grid's last sample (a coarse cell over the grid's edge: LOD only).
// `patch_corners` in `src/cpu/traverse.rs`.
fn patch_corners(level: u32, cell: vec2<i32>) -> vec4<f32> {
    let w = frame.grid.x;
    let i0 = u32(cell.x) << level;
    let j0 = u32(cell.y) << level;
    let base = j0 * w + i0;
    var di = 1u << level;
    var dj = w << level;
    if (LOD) {
        di = min(i0 + di, w - 1u) - i0;
        dj = (min(j0 + (1u << level), frame.grid.y - 1u) - j0) * w;
    }
    return vec4<f32>(heights[base], heights[base + di], heights[base + dj], heights[base + dj + di]);
}

// Bilinear surface height at grid (x, y), clamped to the grid.
fn surface_height(x: f32, y: f32) -> f32 {
    let cx = clamp(x, 0.0, cells_x());
    let cy = clamp(y, 0.0, cells_y());
    let i = min(u32(cx), frame.grid.x - 2u);
    let j = min(u32(cy), frame.grid.y - 2u);
    let u = cx - f32(i);
    let v = cy - f32(j);
    let h00 = sample_height(i, j);
    let h10 = sample_height(i + 1u, j);
    let h01 = sample_height(i, j + 1u);
    let h11 = sample_height(i + 1u, j + 1u);
    return mix(mix(h00, h10, u), mix(h01, h11, u), v);
}

