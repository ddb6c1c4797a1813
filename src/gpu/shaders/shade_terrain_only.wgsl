// Shade-pass hooks for scenes without free forms (never reached; keeps the terrain-only shader
// free of the free-form code, which Mesa's SIMD rasteriser would pay for).

fn objects_shadow(px: vec2<u32>, p: vec3<f32>) -> bool {
    return false;
}

fn shade_object(px: vec2<u32>, g: vec4<u32>, dir_w: vec3<f32>) -> Out {
    var out: Out;
    out.colour = vec4<f32>(1.0, 0.0, 1.0, 1.0);
    out.data = vec4<u32>(INF_BITS, 0u, 0u, g.w & 0xffu);
    return out;
}
