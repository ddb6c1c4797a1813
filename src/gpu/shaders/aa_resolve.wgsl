// Anti-aliasing, resolve pass: one point per marked pixel m, drawn at that pixel of the
// frame's colour and data targets (the other pixels keep the centre rays'): the colour is the
// mean of its n samples (`aa_atlas_entry`) in linear light, sRGB-encoded once;
// the capture data stay the centre ray's (distance, ids, counters) with flag 128.

@group(0) @binding(1) var aa_pixels: texture_2d<u32>;
@group(0) @binding(2) var sample_colour: texture_2d<f32>;
@group(0) @binding(3) var centre_data: texture_2d<u32>;

struct Point {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) m: u32,
}

@vertex
fn vs_point(@builtin(vertex_index) m: u32) -> Point {
    let px = vec2<f32>(aa_pixel(aa_pixels, m)) + 0.5;
    let size = vec2<f32>(aa.size.xy);
    var out: Point;
    out.position = vec4<f32>(px.x / size.x * 2.0 - 1.0, 1.0 - px.y / size.y * 2.0, 0.0, 1.0);
    out.m = m;
    return out;
}

struct Resolved {
    @location(0) colour: vec4<f32>,
    @location(1) data: vec4<u32>,
}

@fragment
fn fs_resolve(p: Point) -> Resolved {
    let n = aa.size.w;
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < n; k += 1u) {
        sum += srgb_decode(textureLoad(sample_colour, aa_atlas_entry(p.m, k), 0).xyz);
    }
    let d = textureLoad(centre_data, vec2<i32>(p.position.xy), 0);
    var out: Resolved;
    out.colour = vec4<f32>(srgb_encode(sum / f32(n)), 1.0);
    out.data = vec4<u32>(d.xyz, d.w | 128u);
    return out;
}
