// The tile pre-pass's terrain in memory: the heights, the pyramid and the pyramid dilated by
// one cell (each cell the maximum of its 3x3 neighbourhood, `gpu::pyramid`).

@group(0) @binding(1) var<storage, read> heights: array<f32>;
@group(0) @binding(2) var<storage, read> pyramid: array<f32>;
@group(0) @binding(4) var<storage, read> dilated: array<f32>;

// The maximum over cell `cell` of `level` and its 8 neighbours (PAD outside the pyramid).
fn dilated_max(level: u32, cell: vec2<i32>) -> f32 {
    let k = pyramid_index(level, cell.x, cell.y);
    if (k == NO_CELL) {
        return PAD;
    }
    return dilated[k];
}
