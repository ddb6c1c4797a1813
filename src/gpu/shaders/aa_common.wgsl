// Edge anti-aliasing, shared by its passes (`gpu::antialias`): the parameter block (mirrored
// by `gpu::antialias::AaUniforms`) and the sample list's layout.

struct AaParams {
    // Screen width, height; marked pixels in this batch; samples per marked pixel n.
    size: vec4<u32>,
    // x: atlas width (entries a row, a multiple of 4); y: 1 = every pixel marked (the
    // reference); z: the batch's first place in the list of marked pixels (a list longer than
    // the atlas holds runs in batches).
    atlas: vec4<u32>,
    // x: colour contrast (sRGB, 0..1) below which a discontinuity is not worth extra rays;
    // y: inverse-depth kink, relative, above which a surface has a crease; z: colour step to
    // a neighbour above which a pixel is marked on one surface too (detail finer than it).
    limits: vec4<f32>,
    // Sample k's offset from the pixel centre (pixels): offsets[k / 2].xy or .zw.
    offsets: array<vec4<f32>, 8>,
    // The linear value of each 8-bit sRGB value v: linear[v / 4][v % 4] (exact, and a load
    // instead of a pow per channel and sample on the CPU rasterisers).
    linear: array<vec4<f32>, 64>,
}

@group(0) @binding(0) var<uniform> aa: AaParams;

// Unmarked pixels and atlas entries past the list.
const AA_NONE: u32 = 0xffffffffu;

fn aa_inside(q: vec2<i32>) -> bool {
    return q.x >= 0 && q.y >= 0 && q.x < i32(aa.size.x) && q.y < i32(aa.size.y);
}

// Marked pixel m of the list (`aa_pixels`: x | y << 16, row by row in the screen's width).
fn aa_pixel(pixels: texture_2d<u32>, m: u32) -> vec2<i32> {
    let w = aa.size.x;
    let v = textureLoad(pixels, vec2<i32>(i32(m % w), i32(m / w)), 0).x;
    return vec2<i32>(i32(v & 0xffffu), i32(v >> 16u));
}

fn aa_offset(k: u32) -> vec2<f32> {
    let o = aa.offsets[k / 2u];
    return select(o.xy, o.zw, (k & 1u) == 1u);
}

// The atlas is made of 4x4 groups, each holding the n samples (4, 8 or 16) of 16 / n
// consecutive marked pixels, so that a fragment block of the rasteriser casts the rays of
// one or two pixels (coherent rays). The groups fill 16x16 bins (a free-form bin; 2x2 tiles
// of the tile pre-pass) of 4x4 groups row by row, and the bins fill the atlas row by row, so
// that a bin or a tile holds consecutive marked pixels of the list, close on the screen: its
// rays' bounds stay tight.
fn aa_group_origin(g: u32) -> vec2<u32> {
    let bins = aa.atlas.x / 16u;
    let b = g / 16u;
    let i = g % 16u;
    return vec2<u32>(((b % bins) * 4u + (i & 3u)) * 4u, ((b / bins) * 4u + (i >> 2u)) * 4u);
}

// The group of atlas entry `a` (the inverse of `aa_group_origin`).
fn aa_atlas_group(a: vec2<u32>) -> u32 {
    let bins = aa.atlas.x / 16u;
    let b = (a.y / 16u) * bins + a.x / 16u;
    return b * 16u + ((a.y / 4u) & 3u) * 4u + ((a.x / 4u) & 3u);
}

struct AaEntries {
    // The top-left entry of marked pixel m's group.
    group: vec2<i32>,
    // Its first sample's place in the group (row by row).
    first: u32,
}

fn aa_entries(m: u32) -> AaEntries {
    let per = 16u / aa.size.w;
    var e: AaEntries;
    e.group = vec2<i32>(aa_group_origin(m / per));
    e.first = (m % per) * aa.size.w;
    return e;
}

// Sample k's entry of the pixel whose entries are `e`.
fn aa_entry(e: AaEntries, k: u32) -> vec2<i32> {
    let i = e.first + k;
    return e.group + vec2<i32>(i32(i & 3u), i32(i >> 2u));
}

// The marked pixel m (x) and sample k (y) of atlas entry `a`.
fn aa_atlas_sample(a: vec2<u32>) -> vec2<u32> {
    let n = aa.size.w;
    let e = (a.y % 4u) * 4u + a.x % 4u;
    return vec2<u32>(aa_atlas_group(a) * (16u / n) + e / n, e % n);
}

// The linear colour of an 8-bit sRGB texel `c` (0..1, as loaded from an Rgba8Unorm target).
fn aa_decode(c: vec3<f32>) -> vec3<f32> {
    let v = vec3<u32>(round(clamp(c, vec3<f32>(0.0), vec3<f32>(1.0)) * 255.0));
    return vec3<f32>(aa.linear[v.x / 4u][v.x % 4u], aa.linear[v.y / 4u][v.y % 4u], aa.linear[v.z / 4u][v.z % 4u]);
}
