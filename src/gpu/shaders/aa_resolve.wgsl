// Anti-aliasing, resolve pass (full screen): a marked pixel of this batch (`aa_index`: its
// place in the list of marked pixels) gets the mean of its n samples (`aa_atlas_entry`) in
// linear light, sRGB-encoded once, and the centre ray's capture data (distance, ids,
// counters) with flag 128; every other pixel keeps what the centre copies hold (the centre
// ray's, or an earlier batch's). The loop's bound is per pixel, so a fragment block without a
// marked pixel leaves it at once.

@group(0) @binding(1) var aa_index: texture_2d<u32>;
@group(0) @binding(2) var sample_colour: texture_2d<f32>;
@group(0) @binding(3) var centre_data: texture_2d<u32>;
@group(0) @binding(4) var centre_colour: texture_2d<f32>;

struct Resolved {
    @location(0) colour: vec4<f32>,
    @location(1) data: vec4<u32>,
}

@fragment
fn fs_resolve(@builtin(position) pos: vec4<f32>) -> Resolved {
    let px = vec2<i32>(pos.xy);
    let m = textureLoad(aa_index, px, 0).x - aa.atlas.z;
    let marked = m < aa.size.z;
    let n = select(0u, aa.size.w, marked);
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < n; k += 1u) {
        sum += aa_decode(textureLoad(sample_colour, aa_atlas_entry(m, k), 0).xyz);
    }
    let d = textureLoad(centre_data, px, 0);
    let c = textureLoad(centre_colour, px, 0);
    var out: Resolved;
    out.colour = select(c, vec4<f32>(srgb_encode(sum / f32(max(n, 1u))), 1.0), marked);
    out.data = select(d, vec4<u32>(d.xyz, d.w | 128u), marked);
    return out;
}
