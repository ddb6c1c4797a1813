// Tile pre-pass: one fragment per 8x8 screen tile finds, through the pyramid, a distance
// before which no ray of the tile can hit the terrain (see `cone_start`). The terrain pass
// starts every pixel ray of the tile there, at the pyramid level where the cone stopped.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> heights: array<f32>;
@group(0) @binding(2) var<storage, read> pyramid: array<f32>;
@group(0) @binding(3) var<storage, read> rays: array<vec4<f32>>;

@fragment
fn fs_tile(@builtin(position) pos: vec4<f32>) -> @location(0) vec2<u32> {
    let tile = vec2<u32>(pos.xy);
    let x0 = tile.x * TILE;
    let y0 = tile.y * TILE;
    let x1 = min(x0 + TILE, frame.size.x);
    let y1 = min(y0 + TILE, frame.size.y);
    // One read per ray: the mean direction c and the spread around the first ray d0; then
    // |d - c| <= |d - d0| + |d0 - c| bounds every ray's chord to c.
    let d0 = rays[y0 * frame.size.x + x0].xyz;
    var sum = vec3<f32>(0.0);
    var spread = 0.0;
    for (var y = y0; y < y1; y += 1u) {
        for (var x = x0; x < x1; x += 1u) {
            let d = rays[y * frame.size.x + x].xyz;
            sum += d;
            spread = max(spread, length(d - d0));
        }
    }
    let c = normalize(sum);
    let theta = (spread + length(d0 - c)) * 1.001 + 1.0e-6;
    var r: Ray;
    r.o = frame.eye.xyz;
    r.d = to_grid_dir(c);
    let s = cone_start(r, theta, 1024u);
    // A small safety margin against rounding in the cone test.
    return vec2<u32>(bitcast<u32>(max(s.t * 0.999 - 1.0, 0.0)), s.level);
}
