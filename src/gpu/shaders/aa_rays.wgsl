// Anti-aliasing, sample-ray pass over the sample atlas (`aa_atlas_sample`: sample k of marked
// pixel m of the list). Its ray leaves from the sample's sub-pixel position: the centre direction
// moved along the table's own derivatives (one-sided differences towards the sample, the
// other side at the screen's or the table's edge), so it works through any ray table
// (pinhole, distortion table, dome master); its cone stays the pixel's. Entries past the
// list cast no ray (cone -1).

@group(0) @binding(1) var centre_rays: texture_2d<u32>;
@group(0) @binding(2) var aa_pixels: texture_2d<u32>;

fn centre_ray(q: vec2<i32>) -> vec4<f32> {
    return bitcast<vec4<f32>>(textureLoad(centre_rays, q, 0));
}

// Change of the direction per pixel along `axis`, measured towards the side `o` points to.
// Each neighbour is loaded once, before the branches: Mesa's CPU rasterisers run both sides
// of a branch under a lane mask, so a load written in a condition and again in its body
// costs two. (Off the screen a load is bounds-checked and its value unused.)
fn table_slope(px: vec2<i32>, axis: vec2<i32>, o: f32, d0: vec3<f32>) -> vec3<f32> {
    let s = select(-1, 1, o >= 0.0);
    let near = px + axis * s;
    let far = px - axis * s;
    let rn = centre_ray(near);
    let rf = centre_ray(far);
    if (aa_inside(near) && rn.w >= 0.0) {
        return (rn.xyz - d0) * f32(s);
    }
    if (aa_inside(far) && rf.w >= 0.0) {
        return (d0 - rf.xyz) * f32(s);
    }
    return vec3<f32>(0.0);
}

@fragment
fn fs_sample_rays(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let mk = aa_atlas_sample(vec2<u32>(pos.xy));
    if (mk.x == AA_NONE) {
        return bitcast<vec4<u32>>(vec4<f32>(0.0, 0.0, 1.0, -1.0));
    }
    let px = aa_pixel(aa_pixels, mk.x);
    let e = centre_ray(px);
    let o = aa_offset(mk.y);
    let d = normalize(e.xyz + o.x * table_slope(px, vec2<i32>(1, 0), o.x, e.xyz) + o.y * table_slope(px, vec2<i32>(0, 1), o.y, e.xyz));
    return bitcast<vec4<u32>>(vec4<f32>(d, e.w));
}
