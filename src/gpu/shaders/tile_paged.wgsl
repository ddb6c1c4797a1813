// The tile pre-pass's terrain in the tile pool (`PAGED` builds): no dilated pyramid is kept,
// so the 3x3 neighbourhood's maximum is read cell by cell (`cell_max`: the finest resident
// level's bound, PAD off the window). Nine reads a step, one fragment per 8x8 pixels.

fn dilated_max(level: u32, cell: vec2<i32>) -> f32 {
    var m = PAGED_PAD;
    for (var dy = -1; dy <= 1; dy += 1) {
        for (var dx = -1; dx <= 1; dx += 1) {
            m = max(m, cell_max(level, cell + vec2<i32>(dx, dy)));
        }
    }
    return m;
}
