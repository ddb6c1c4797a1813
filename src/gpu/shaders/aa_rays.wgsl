// Anti-aliasing, sample rays (`fs_sample_rays`, full screen over the rows of a compact target
// the batch fills: one fragment per marked pixel of the batch, row by row in the screen's
// width). Each of the pixel's 4, 8 or 16 sample rays leaves from the sample's sub-pixel
// position: the centre direction moved along the table's own derivatives (one-sided
// differences towards the sample, the other side at the screen's or the table's edge), so it
// works through any ray table (pinhole, distortion table, dome master); its cone stays the
// pixel's. The fragment stores them into the atlas's ray table at the samples' entries
// (`aa_entry`); the table was cleared to "no ray" (cone -1) first, so entries past the list
// cast none. One fragment a pixel loads the centre rays once for all its samples: a fragment
// per atlas entry loaded them per sample, and Mesa's CPU rasterisers spent more on that pass
// than on the centre frame's ray generation.

@group(0) @binding(1) var centre_rays: texture_2d<u32>;
@group(0) @binding(2) var aa_pixels: texture_2d<u32>;
@group(0) @binding(3) var atlas_rays: texture_storage_2d<rgba32uint, write>;

fn centre_ray(q: vec2<i32>) -> vec4<f32> {
    return bitcast<vec4<f32>>(textureLoad(centre_rays, q, 0));
}

// Change of the direction per pixel along `axis`, measured on the +axis side (`plus`) and on
// the -axis side (`minus`), both per pixel towards +axis; each falls back on the other
// side's difference where its neighbour is off the screen or shows no ray, and is 0 where
// both are. (Off the screen a load is bounds-checked and its value unused.)
struct Slopes {
    plus: vec3<f32>,
    minus: vec3<f32>,
}

fn table_slopes(px: vec2<i32>, axis: vec2<i32>, d0: vec3<f32>) -> Slopes {
    let a = px + axis;
    let b = px - axis;
    let ra = centre_ray(a);
    let rb = centre_ray(b);
    let va = aa_inside(a) && ra.w >= 0.0;
    let vb = aa_inside(b) && rb.w >= 0.0;
    let forward = ra.xyz - d0;
    let backward = d0 - rb.xyz;
    var s: Slopes;
    s.plus = select(select(vec3<f32>(0.0), backward, vb), forward, va);
    s.minus = select(select(vec3<f32>(0.0), forward, va), backward, vb);
    return s;
}

@fragment
fn fs_sample_rays(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let q = vec2<u32>(pos.xy);
    let i = q.y * aa.size.x + q.x;
    if (i >= aa.size.z) {
        return vec4<f32>(0.0);
    }
    let m = aa.atlas.z + i;
    let e = aa_entries(m);
    let px = aa_pixel(aa_pixels, m);
    let c = centre_ray(px);
    let sx = table_slopes(px, vec2<i32>(1, 0), c.xyz);
    let sy = table_slopes(px, vec2<i32>(0, 1), c.xyz);
    for (var k = 0u; k < e.n; k += 1u) {
        let o = aa_offset(k);
        let dx = select(sx.minus, sx.plus, o.x >= 0.0);
        let dy = select(sy.minus, sy.plus, o.y >= 0.0);
        let d = normalize(c.xyz + o.x * dx + o.y * dy);
        textureStore(atlas_rays, aa_entry(e, k), bitcast<vec4<u32>>(vec4<f32>(d, c.w)));
    }
    return vec4<f32>(0.0);
}
