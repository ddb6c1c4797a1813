// Volume composite pass: per pixel, the volume passes' results (P, T and the medium's
// contribution-weighted depth per volume) sorted farthest first and composited over the shaded
// image, c = P + T c, in linear light, encoded to sRGB once. Ordering per pixel by where each
// medium actually lies along the ray (not by box) is exact for media that do not interleave
// along the ray, whether or not their boxes overlap. `cpu::volume::composite_sorted` does the
// same. VOL_COUNT (the scene's volumes, 1 ..= 8) is prepended.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var colour_in: texture_2d<f32>;
// Per volume (array layer): f32 bits of P and T; statistics with the depth bits in z.
@group(0) @binding(2) var results: texture_2d_array<u32>;
@group(0) @binding(3) var stats: texture_2d_array<u32>;

@fragment
fn fs_composite(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let px = vec2<i32>(pos.xy);
    var c = srgb_decode(textureLoad(colour_in, px, 0).xyz);
    // Insertion sort of the volume indices by depth, farthest first; ties keep scene order.
    var order: array<u32, VOL_COUNT>;
    var depth: array<f32, VOL_COUNT>;
    for (var m = 0u; m < VOL_COUNT; m++) {
        let d = bitcast<f32>(textureLoad(stats, px, m, 0).z);
        var k = m;
        while (k > 0u && depth[k - 1u] < d) {
            depth[k] = depth[k - 1u];
            order[k] = order[k - 1u];
            k -= 1u;
        }
        depth[k] = d;
        order[k] = m;
    }
    for (var k = 0u; k < VOL_COUNT; k++) {
        let r = bitcast<vec4<f32>>(textureLoad(results, px, order[k], 0));
        c = r.xyz + r.w * c;
    }
    return vec4<f32>(srgb_encode8(c), 1.0);
}
