// Anti-aliasing, resolve: two passes.
// 1. `fs_mean` (full screen over the first rows of the `means` target, one texel per marked
//    pixel of the batch, row by row in the screen's width): the mean of its 4, 8 or 16 samples
//    (`aa_entries`) in linear light, sRGB-encoded once. Its fragment blocks are full: Mesa's
//    CPU rasterisers shade a whole block for a point, so averaging there would cost each
//    marked pixel a block's worth of sample loads.
// 2. `vs_scatter`/`fs_scatter`: one point per marked pixel of the batch (vertex m: place
//    aa.atlas.z + m of the list), drawn over the frame's colour and data targets (loaded, not
//    cleared), so that the other pixels keep the centre rays' colour and data untouched and
//    cost nothing. Its pixel gets its mean and the centre ray's capture data (distance, ids,
//    counters; from the copy taken before the samples) with flag 128.

@group(0) @binding(1) var aa_pixels: texture_2d<u32>;
@group(0) @binding(2) var sample_colour: texture_2d<f32>;
@group(0) @binding(3) var centre_data: texture_2d<u32>;
@group(0) @binding(4) var means: texture_2d<f32>;

@fragment
fn fs_mean(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let q = vec2<u32>(pos.xy);
    let i = q.y * aa.size.x + q.x;
    let e = aa_entries(aa.atlas.z + i);
    let n = select(0u, e.n, i < aa.size.z);
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < n; k += 1u) {
        sum += aa_decode(textureLoad(sample_colour, aa_entry(e, k), 0).xyz);
    }
    return vec4<f32>(srgb_encode8(sum / f32(max(n, 1u))), 1.0);
}

struct Point {
    @builtin(position) position: vec4<f32>,
    // The batch's marked pixel the point resolves.
    @location(0) @interpolate(flat) m: u32,
}

@vertex
fn vs_scatter(@builtin(vertex_index) m: u32) -> Point {
    let px = vec2<f32>(aa_pixel(aa_pixels, aa.atlas.z + m)) + 0.5;
    let size = vec2<f32>(aa.size.xy);
    var p: Point;
    p.position = vec4<f32>(px.x / size.x * 2.0 - 1.0, 1.0 - px.y / size.y * 2.0, 0.0, 1.0);
    p.m = m;
    return p;
}

struct Resolved {
    @location(0) colour: vec4<f32>,
    @location(1) data: vec4<u32>,
}

@fragment
fn fs_scatter(p: Point) -> Resolved {
    let w = aa.size.x;
    let d = textureLoad(centre_data, vec2<i32>(p.position.xy), 0);
    var out: Resolved;
    out.colour = textureLoad(means, vec2<i32>(i32(p.m % w), i32(p.m / w)), 0);
    out.data = vec4<u32>(d.xyz, d.w | 128u);
    return out;
}
