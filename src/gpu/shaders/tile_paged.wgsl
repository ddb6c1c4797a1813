// The tile pre-pass's terrain in the tile pool (`PAGED` builds): no dilated pyramid is kept.
// The 3x3 neighbourhood of cell c of level L lies within the 2x2 parent cells
// ((c - 1) >> 1 ..= (c + 1) >> 1) of level L + 1, and a parent's `cell_max` bounds its
// children's (the in-tile pyramid is the max of 2x2, and where only a coarser level is resident
// parent and child read the same coarse cell): four reads a step instead of nine, a slightly
// looser bound (a 4x4 neighbourhood). PAD off the window. Called below the top level only.

fn dilated_max(level: u32, cell: vec2<i32>) -> f32 {
    let lo = (cell - vec2<i32>(1)) >> vec2<u32>(1u);
    let hi = (cell + vec2<i32>(1)) >> vec2<u32>(1u);
    let up = level + 1u;
    return max(
        max(cell_max(up, lo), cell_max(up, vec2<i32>(hi.x, lo.y))),
        max(cell_max(up, vec2<i32>(lo.x, hi.y)), cell_max(up, hi)),
    );
}
