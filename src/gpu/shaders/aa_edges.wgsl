// Anti-aliasing, edge pass: from the centre rays' frame (colour, capture data, ray table),
// marks the pixels whose rays straddle a discontinuity that shows: a different surface
// (sky, terrain, free form by id, voxel model), a shadow boundary, or a crease or depth jump
// on one surface (1/distance is affine along a plane's image, so its second difference
// across the pixel is a kink), where the colour also changes by more than the contrast
// threshold; or a colour step to a neighbour above the detail threshold. The mask holds the
// sub-pixel rays the pixel gets (0, 4, 8 or 16); read back, it makes the sample list.

@group(0) @binding(2) var centre_colour: texture_2d<f32>;
@group(0) @binding(3) var centre_data: texture_2d<u32>;

// Flag 8 of the capture data: the pixel shows no screen (distortion tables).
fn has_screen(d: vec4<u32>) -> bool {
    return (d.w & 8u) == 0u;
}

// What surface a pixel shows: the hit, free-form and voxel flags and the free form's id
// (capture data flags, `shade.wgsl`); 0 for the sky.
fn surface_key(d: vec4<u32>) -> u32 {
    return (d.w & 0x31u) | (d.w & 0xffffff00u);
}

fn inverse_depth(d: vec4<u32>) -> f32 {
    return 1.0 / max(bitcast<f32>(d.x), 1.0e-6);
}

fn contrast(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let d = abs(a - b);
    return max(d.x, max(d.y, d.z));
}

// The kink of 1/distance across a pixel from its neighbours on either side `da` and `db`
// along one axis, relative (0 where the three pixels do not show one surface or a neighbour
// lies off the screen: `inside`).
fn kink(d0: vec4<u32>, da: vec4<u32>, db: vec4<u32>, inside: bool) -> f32 {
    let k = surface_key(d0);
    if (!inside || (d0.w & 1u) == 0u || surface_key(da) != k || surface_key(db) != k) {
        return 0.0;
    }
    let w0 = inverse_depth(d0);
    return abs(inverse_depth(da) - 2.0 * w0 + inverse_depth(db)) / w0;
}

@fragment
fn fs_edges(@builtin(position) pos: vec4<f32>) -> @location(0) u32 {
    let px = vec2<i32>(pos.xy);
    let d0 = textureLoad(centre_data, px, 0);
    if (!has_screen(d0)) {
        return 0u;
    }
    if (aa.atlas.y != 0u) {
        return aa.size.w;
    }
    let c0 = textureLoad(centre_colour, px, 0).xyz;
    let key = surface_key(d0);
    let threshold = aa.limits.x;
    var mark = false;
    var seen = 0.0;
    // Right, left, down, up: each neighbour's data is loaded once (the kinks use them too).
    let ring = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(-1, 0), vec2<i32>(0, 1), vec2<i32>(0, -1));
    var d: array<vec4<u32>, 4>;
    var inside: array<bool, 4>;
    for (var k = 0; k < 4; k += 1) {
        let q = px + ring[k];
        inside[k] = aa_inside(q);
        d[k] = d0;
        if (inside[k]) {
            let dq = textureLoad(centre_data, q, 0);
            d[k] = dq;
            if (has_screen(dq)) {
                let c = contrast(c0, textureLoad(centre_colour, q, 0).xyz);
                seen = max(seen, c);
                let apart = surface_key(dq) != key || ((dq.w ^ d0.w) & 2u) != 0u;
                mark = mark || (apart && c > threshold);
            }
        }
    }
    let crease = max(kink(d0, d[1], d[0], inside[0] && inside[1]), kink(d0, d[3], d[2], inside[2] && inside[3]));
    // Flag 64: the centre ray passed within its cone of terrain it missed (a ridge or spike
    // thinner than the pixel): marked whatever the colours say.
    let near = (d0.w & 64u) != 0u;
    mark = mark || (crease > aa.limits.y && seen > threshold) || seen > aa.limits.z || near;
    if (!mark) {
        return 0u;
    }
    // The pixel's sample count: `"edges"` chooses it from the largest colour step to a
    // neighbour (a low-contrast edge's coverage needs fewer samples for the same error in
    // colour); a near miss's centre colour does not show what it missed: all 16.
    if (aa.atlas.w == 0u || near || seen > aa.adapt.y) {
        return aa.size.w;
    }
    return select(8u, 4u, seen <= aa.adapt.x);
}
