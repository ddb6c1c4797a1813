// sRGB transfer functions, shared by the passes that read or write sRGB-encoded colour (shade,
// volume, volume composite, the anti-aliasing resolve) and the window's present pass; and the
// rounding of what the passes write to 8-bit colour targets.

// `v` (0..1) at its nearest 8-bit level. A pass that writes to an Rgba8Unorm target rounds
// itself: Vulkan lets the conversion return either of the two nearest levels, and an NVIDIA
// H200 returned the lower one for about 3% of channel values that lavapipe, llvmpipe and the
// CPU reference round up (measured; docs/benchmarks.md#gpu-figures). A level k/255 converts to
// k on every adapter.
fn unorm8(v: vec3<f32>) -> vec3<f32> {
    return floor(clamp(v, vec3<f32>(0.0), vec3<f32>(1.0)) * 255.0 + 0.5) / 255.0;
}

// Linear colour `c` sRGB-encoded at its nearest 8-bit level: what a pass writes to an 8-bit
// colour target.
fn srgb_encode8(c: vec3<f32>) -> vec3<f32> {
    return unorm8(srgb_encode(c));
}

fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let x = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
    return select(1.055 * pow(x, vec3<f32>(1.0 / 2.4)) - 0.055, 12.92 * x, x <= vec3<f32>(0.0031308));
}

fn srgb_decode(c: vec3<f32>) -> vec3<f32> {
    return select(pow((c + 0.055) / 1.055, vec3<f32>(2.4)), c / 12.92, c <= vec3<f32>(0.04045));
}
