// Present pass of the window (`relief view`): copies the renderer's colour target (sRGB-encoded
// Rgba8Unorm) to the swap-chain image, or shows a debug view of the data target, and draws the
// text overlay with a built-in 5x7 bitmap font. Prepended: fullscreen.wgsl, srgb.wgsl.

// Mirrors `PresentUniforms` in src/app/view/present.rs.
struct Present {
    // source (render) width, height; destination (surface) width, height
    sizes: vec4<u32>,
    // view (0 colour, 1 depth, 2 traversal steps), decode sRGB (surface view is *Srgb),
    // overlay columns, overlay rows (0 = no overlay)
    mode: vec4<u32>,
    // overlay scale (pixels per font pixel), origin x, origin y, unused
    overlay: vec4<u32>,
    // overlay characters, 4 per u32 (little-endian bytes), row-major
    text: array<vec4<u32>, 24>,
    // glyphs of ASCII 32..127, two words each: rows 0-3 (5 bits each), rows 4-6
    font: array<vec4<u32>, 48>,
}

@group(0) @binding(0) var<uniform> pr: Present;
@group(0) @binding(1) var colour: texture_2d<f32>;
@group(0) @binding(2) var data: texture_2d<u32>;

// A glyph is 5x7 pixels in a 6x9 cell (one pixel of space right, one above and below).
const CELL_W: u32 = 6u;
const CELL_H: u32 = 9u;

// Blue → cyan → green → yellow → red for x in 0..1 (display values).
fn heat(x: f32) -> vec3<f32> {
    let v = clamp(x, 0.0, 1.0) * 4.0;
    return clamp(vec3<f32>(v - 2.0, 2.0 - abs(v - 2.0), 2.0 - v), vec3<f32>(0.0), vec3<f32>(1.0));
}

fn text_char(i: u32) -> u32 {
    let w = pr.text[i / 16u][(i / 4u) % 4u];
    return (w >> ((i % 4u) * 8u)) & 0xffu;
}

fn glyph_word(g: u32, k: u32) -> u32 {
    let i = 2u * g + k;
    return pr.font[i / 4u][i % 4u];
}

// -1 outside the overlay box, 0 box background, 1 glyph pixel.
fn overlay_pixel(p: vec2<u32>) -> f32 {
    let cols = pr.mode.z;
    let rows = pr.mode.w;
    let s = max(pr.overlay.x, 1u);
    let origin = pr.overlay.yz;
    if (cols == 0u || rows == 0u || p.x < origin.x || p.y < origin.y) {
        return -1.0;
    }
    let q = (p - origin) / s;
    let cx = q.x / CELL_W;
    let cy = q.y / CELL_H;
    if (cx >= cols || cy >= rows) {
        return -1.0;
    }
    let ch = text_char(cy * cols + cx);
    let gx = q.x % CELL_W;
    let gy = q.y % CELL_H;
    if (ch <= 32u || ch >= 128u || gx >= 5u || gy < 1u || gy >= 8u) {
        return 0.0;
    }
    let row = gy - 1u;
    var bits: u32;
    if (row < 4u) {
        bits = glyph_word(ch - 32u, 0u) >> (row * 5u);
    } else {
        bits = glyph_word(ch - 32u, 1u) >> ((row - 4u) * 5u);
    }
    return f32((bits >> (4u - gx)) & 1u);
}

@fragment
fn fs_present(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let dst = vec2<u32>(pos.xy);
    let src_size = max(pr.sizes.xy, vec2<u32>(1u));
    let dst_size = max(pr.sizes.zw, vec2<u32>(1u));
    // Nearest source pixel (the identity when the sizes agree).
    let src = min((2u * dst + 1u) * src_size / (2u * dst_size), src_size - 1u);
    var c: vec3<f32>;
    switch pr.mode.x {
        case 1u: {
            let d = textureLoad(data, src, 0);
            if ((d.w & 1u) == 0u) {
                c = vec3<f32>(0.05, 0.05, 0.2);
            } else {
                // Log scale, white at 10 m, black at 200 km.
                let t = bitcast<f32>(d.x);
                let x = clamp(log2(max(t, 10.0) / 10.0) / log2(20000.0), 0.0, 1.0);
                c = vec3<f32>(1.0 - x);
            }
        }
        case 2u: {
            let d = textureLoad(data, src, 0);
            c = heat(log2(1.0 + f32(d.y)) / log2(513.0));
        }
        default: {
            c = textureLoad(colour, src, 0).rgb;
        }
    }
    let o = overlay_pixel(dst);
    if (o >= 0.0) {
        c = mix(c * 0.3, vec3<f32>(1.0), o);
    }
    if (pr.mode.y != 0u) {
        c = srgb_decode(c);
    }
    return vec4<f32>(c, 1.0);
}
