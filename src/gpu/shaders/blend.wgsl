// Edge-blend pass: multiplies the finished image by each pixel's blend factor
// (`display::blend`): per edge Bourke's ramp f(x) = 0.5 (2x)^p below 0.5, 1 - 0.5 (2(1-x))^p
// above, the product over the edges, then ^(1/gamma) for the projector's response.

struct BlendParams {
    // Image width, height.
    size: vec4<u32>,
    // Ramp widths (fractions of the image) of the left, right, top and bottom edges; 0 = none.
    widths: vec4<f32>,
    // Curve exponents of the same edges.
    exponents: vec4<f32>,
    // x: 1 / gamma; y: 1 when the geometric mask applies.
    gamma: vec4<f32>,
}

@group(0) @binding(0) var<uniform> blend: BlendParams;
@group(0) @binding(1) var blend_src: texture_2d<f32>;
// Geometric blend weights (display::blend::geometric_weights), one per pixel.
@group(0) @binding(2) var blend_mask: texture_2d<f32>;

fn blend_ramp(d: f32, width: f32, p: f32) -> f32 {
    if (width <= 0.0) {
        return 1.0;
    }
    let x = clamp(d / width, 0.0, 1.0);
    if (x < 0.5) {
        return 0.5 * pow(2.0 * x, p);
    }
    return 1.0 - 0.5 * pow(2.0 * (1.0 - x), p);
}

@fragment
fn fs_blend(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let px = vec2<u32>(pos.xy);
    let c = textureLoad(blend_src, vec2<i32>(px), 0);
    let uv = (vec2<f32>(px) + 0.5) / vec2<f32>(blend.size.xy);
    let w = blend_ramp(uv.x, blend.widths.x, blend.exponents.x)
        * blend_ramp(1.0 - uv.x, blend.widths.y, blend.exponents.y)
        * blend_ramp(uv.y, blend.widths.z, blend.exponents.z)
        * blend_ramp(1.0 - uv.y, blend.widths.w, blend.exponents.w);
    var m = 1.0;
    if (blend.gamma.y > 0.0) {
        m = textureLoad(blend_mask, vec2<i32>(px), 0).x;
    }
    return vec4<f32>(unorm8(c.xyz * pow(w * m, blend.gamma.x)), c.w);
}
