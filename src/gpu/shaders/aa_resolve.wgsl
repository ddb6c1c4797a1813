// Anti-aliasing, resolve (`fs_resolve`, full screen over the rows of the compact target the
// batch fills: one fragment per marked pixel of the batch, row by row in the screen's width):
// the mean of the pixel's 4, 8 or 16 samples (`aa_entries`) in linear light, sRGB-encoded
// once, stored into the frame's colour at the pixel, and the centre ray's capture data
// (distance, ids, counters; from the copy taken before the samples) with flag 128 into its
// data. The other pixels keep the centre rays' colour and data untouched and cost nothing.
// The fragment blocks of this pass are full; Mesa's CPU rasterisers shade a whole block for a
// one-pixel point, so a point per marked pixel drawn over the frame's targets cost about twice
// what the means themselves did. The pass's own output goes to the attachment a render pass
// needs, which is discarded.

@group(0) @binding(1) var aa_pixels: texture_2d<u32>;
@group(0) @binding(2) var sample_colour: texture_2d<f32>;
@group(0) @binding(3) var centre_data: texture_2d<u32>;
@group(0) @binding(5) var frame_colour: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(6) var frame_data: texture_storage_2d<rgba32uint, write>;

@fragment
fn fs_resolve(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let q = vec2<u32>(pos.xy);
    let i = q.y * aa.size.x + q.x;
    let e = aa_entries(aa.atlas.z + i);
    let marked = i < aa.size.z;
    let n = select(0u, e.n, marked);
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < n; k += 1u) {
        sum += aa_decode(textureLoad(sample_colour, aa_entry(e, k), 0).xyz);
    }
    let mean = vec4<f32>(srgb_encode8(sum / f32(max(n, 1u))), 1.0);
    if (marked) {
        let px = aa_pixel(aa_pixels, aa.atlas.z + i);
        let d = textureLoad(centre_data, px, 0);
        textureStore(frame_colour, px, mean);
        textureStore(frame_data, px, vec4<u32>(d.xyz, d.w | 128u));
    }
    return vec4<f32>(0.0);
}
