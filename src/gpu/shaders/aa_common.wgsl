// Edge anti-aliasing, shared by its passes (`gpu::antialias`): the parameter block (mirrored
// by `gpu::antialias::AaUniforms`) and the sample list's layout.

struct AaParams {
    // Screen width, height; marked pixels in this batch; the most samples a marked pixel
    // gets (4, 8 or 16).
    size: vec4<u32>,
    // x: atlas width (entries a row, a multiple of 4); y: 1 = every pixel marked (the
    // reference); z: the batch's first place in the list of marked pixels (a list longer than
    // the atlas holds runs in batches); w: 1 = the sample count is chosen per pixel from its
    // contrast (`"edges"`), 0 = every marked pixel gets size.w.
    atlas: vec4<u32>,
    // x: colour contrast (sRGB, 0..1) below which a discontinuity is not worth extra rays;
    // y: inverse-depth kink, relative, above which a surface has a crease; z: colour step to
    // a neighbour above which a pixel is marked on one surface too (detail finer than it).
    limits: vec4<f32>,
    // Adaptive counts (atlas.w = 1): a marked pixel whose largest colour step to a neighbour
    // is at most x gets 4 samples, at most y 8, else 16 (near misses always 16).
    adapt: vec4<f32>,
    // The list holds the pixels with 16 samples first, then those with 8, then those with
    // 4: x, y, z of them. w: the batch's first group (4x4 atlas entries) of the whole list.
    counts: vec4<u32>,
    // Sample k's offset from the pixel centre (pixels): offsets[k / 2].xy or .zw.
    offsets: array<vec4<f32>, 8>,
    // The linear value of each 8-bit sRGB value v: linear[v / 4][v % 4] (exact, and a load
    // instead of a pow per channel and sample on the CPU rasterisers).
    linear: array<vec4<f32>, 64>,
}

@group(0) @binding(0) var<uniform> aa: AaParams;

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

// The atlas is made of 4x4 groups, each holding the samples of one marked pixel with 16, two
// with 8 or four with 4 (the list's pixels with 16 samples come first, so their groups do,
// then the 8s', then the 4s'), so that a fragment block of the rasteriser casts the rays of
// one or two pixels (coherent rays). The groups fill 16x16 bins (a free-form bin; 2x2 tiles
// of the tile pre-pass) of 4x4 groups row by row, and the bins fill the atlas row by row, so
// that a bin or a tile holds consecutive marked pixels of the list, close on the screen: its
// rays' bounds stay tight. A batch's atlas starts at group counts.w of the whole list.
fn aa_group_origin(g: u32) -> vec2<u32> {
    let bins = aa.atlas.x / 16u;
    let b = g / 16u;
    let i = g % 16u;
    return vec2<u32>(((b % bins) * 4u + (i & 3u)) * 4u, ((b / bins) * 4u + (i >> 2u)) * 4u);
}

// The first group of the pixels with 4 samples (those with 8 share a group by two).
fn aa_group4() -> u32 {
    return aa.counts.x + (aa.counts.y + 1u) / 2u;
}

struct AaEntries {
    // The top-left entry of marked pixel m's group in the batch's atlas.
    group: vec2<i32>,
    // Its first sample's place in the group (row by row; 0 with 16 samples: `aa_entry`).
    first: u32,
    // Its samples: 4, 8 or 16.
    n: u32,
}

// The entries of marked pixel m (its place in the whole list).
fn aa_entries(m: u32) -> AaEntries {
    let c = aa.counts;
    var g = m;
    var e: AaEntries;
    e.first = 0u;
    e.n = 16u;
    if (m >= c.x + c.y) {
        let j = m - c.x - c.y;
        g = aa_group4() + j / 4u;
        e.first = (j % 4u) * 4u;
        e.n = 4u;
    } else if (m >= c.x) {
        let j = m - c.x;
        g = c.x + j / 2u;
        e.first = (j % 2u) * 8u;
        e.n = 8u;
    }
    e.group = vec2<i32>(aa_group_origin(g - c.w));
    return e;
}

// Where a pixel's samples lie in its 4x4 group. Mesa's CPU rasterisers shade a 4x4 block as
// two halves of 8 lanes (4x2 entries), each running until its slowest lane is done. A pixel
// with 16 samples has each at its own place in the grid (column e % 4, row e / 4), so that
// the group's upper half casts the rays of the pixel's upper half: across a horizon or a
// ridgeline one half of the group is then mostly sky and the other mostly ground, and
// neither waits for the other's rays (sun rays are cast only where a sample meets a
// surface). On the alps at 1280x720 that took the samples' cast and shade 9-11% less than
// samples in their order (0-3 in row 0, ...); transposing the group of a pixel whose colour
// changes more to its left and right than up and down (its halves then the pixel's left and
// right) saved nothing more on the alps or the airfield. Two pixels with 8 (four with 4) lie
// one after the other, their samples in order: a half is one pixel's 8 samples (two pixels'
// 4), whose rays stay close (the upper halves of two pixels in one half and their lower
// halves in the other measured 1-3% slower).

// The place of sample k in a 16-sample group (row by row): nibble k of the two words.
fn aa_grid_place(k: u32) -> u32 {
    return (select(0xf5c693a0u, 0xbd428e71u, k < 8u) >> (4u * (k % 8u))) & 15u;
}

// Sample k's entry of the pixel whose entries are `e`.
fn aa_entry(e: AaEntries, k: u32) -> vec2<i32> {
    let i = select(e.first + k, aa_grid_place(k), e.n == 16u);
    return e.group + vec2<i32>(i32(i & 3u), i32(i >> 2u));
}

// The linear colour of an 8-bit sRGB texel `c` (0..1, as loaded from an Rgba8Unorm target).
fn aa_decode(c: vec3<f32>) -> vec3<f32> {
    let v = vec3<u32>(round(clamp(c, vec3<f32>(0.0), vec3<f32>(1.0)) * 255.0));
    return vec3<f32>(aa.linear[v.x / 4u][v.x % 4u], aa.linear[v.y / 4u][v.y % 4u], aa.linear[v.z / 4u][v.z % 4u]);
}
