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
    let x1 = min(x0 + TILE, frame.size.x) - 1u;
    let y1 = min(y0 + TILE, frame.size.y) - 1u;
    // The tile's pixel-centre rays of a pinhole ray table fill a spherical quadrilateral whose
    // edges are great-circle arcs (a convex spherical polygon), so the ray farthest from any
    // direction inside it is a corner: the four corner rays bound the whole tile's cone.
    let w = frame.size.x;
    let d00 = rays[y0 * w + x0].xyz;
    let d10 = rays[y0 * w + x1].xyz;
    let d01 = rays[y1 * w + x0].xyz;
    let d11 = rays[y1 * w + x1].xyz;
    let c = normalize(d00 + d10 + d01 + d11);
    let chord = max(max(length(d00 - c), length(d10 - c)), max(length(d01 - c), length(d11 - c)));
    let theta = chord * 1.001 + 1.0e-6;
    var r: Ray;
    r.o = frame.eye.xyz;
    r.d = to_grid_dir(c);
    let s = cone_start(r, theta, 1024u);
    // A small safety margin against rounding in the cone test.
    return vec2<u32>(bitcast<u32>(max(s.t * 0.999 - 1.0, 0.0)), s.level);
}
