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
    let one = inside && (d0.w & 1u) != 0u && surface_key(da) == k && surface_key(db) == k;
    let w0 = inverse_depth(d0);
    return select(0.0, abs(inverse_depth(da) - 2.0 * w0 + inverse_depth(db)) / w0, one);
}

// The colour step from the pixel (colour `c0`, data `d0`) to its neighbour at `q` (data `dq`;
// 0 where the neighbour shows no screen), and whether the neighbour shows another surface or
// lies across a shadow boundary (y: 1).
fn neighbour_step(c0: vec3<f32>, d0: vec4<u32>, dq: vec4<u32>, q: vec2<i32>) -> vec2<f32> {
    let c = select(0.0, contrast(c0, textureLoad(centre_colour, q, 0).xyz), has_screen(dq));
    let apart = surface_key(dq) != surface_key(d0) || ((dq.w ^ d0.w) & 2u) != 0u;
    return vec2<f32>(c, select(0.0, 1.0, apart));
}

@fragment
fn fs_edges(@builtin(position) pos: vec4<f32>) -> @location(0) u32 {
    // Straight-line code, no arrays or loops: Mesa's CPU rasterisers run a fragment block's
    // every instruction under a lane mask, so what the pass costs is the code it holds.
    // Neighbours off the screen are clamped onto the pixel itself: no step to them.
    let px = vec2<i32>(pos.xy);
    let last = vec2<i32>(aa.size.xy) - 1;
    let d0 = textureLoad(centre_data, px, 0);
    let c0 = textureLoad(centre_colour, px, 0).xyz;
    let qr = vec2<i32>(min(px.x + 1, last.x), px.y);
    let ql = vec2<i32>(max(px.x - 1, 0), px.y);
    let qd = vec2<i32>(px.x, min(px.y + 1, last.y));
    let qu = vec2<i32>(px.x, max(px.y - 1, 0));
    let dr = textureLoad(centre_data, qr, 0);
    let dl = textureLoad(centre_data, ql, 0);
    let dd = textureLoad(centre_data, qd, 0);
    let du = textureLoad(centre_data, qu, 0);
    let sr = neighbour_step(c0, d0, dr, qr);
    let sl = neighbour_step(c0, d0, dl, ql);
    let sd = neighbour_step(c0, d0, dd, qd);
    let su = neighbour_step(c0, d0, du, qu);
    let threshold = aa.limits.x;
    let seen = max(max(sr.x, sl.x), max(sd.x, su.x));
    let apart = max(max(sr.y * sr.x, sl.y * sl.x), max(sd.y * sd.x, su.y * su.x));
    let inside_x = px.x > 0 && px.x < last.x;
    let inside_y = px.y > 0 && px.y < last.y;
    let crease = max(kink(d0, dl, dr, inside_x), kink(d0, du, dd, inside_y));
    // Flag 64: the centre ray passed within its cone of terrain it missed (a ridge or spike
    // thinner than the pixel): marked whatever the colours say.
    let near = (d0.w & 64u) != 0u;
    let mark = apart > threshold || (crease > aa.limits.y && seen > threshold) || seen > aa.limits.z || near;
    // The pixel's sample count: `"edges"` chooses it from the largest colour step to a
    // neighbour (a low-contrast edge's coverage needs fewer samples for the same error in
    // colour); a near miss's centre colour does not show what it missed: all 16.
    let adaptive = select(8u, 4u, seen <= aa.adapt.x);
    let count = select(adaptive, aa.size.w, aa.atlas.w == 0u || near || seen > aa.adapt.y);
    let marked = select(0u, count, mark);
    // Pixels showing no screen are never marked; the reference (atlas.y) marks every other.
    return select(0u, select(marked, aa.size.w, aa.atlas.y != 0u), has_screen(d0));
}
