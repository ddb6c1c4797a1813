// Shade-pass hooks for scenes without free forms (never reached with effect; keeps the
// terrain-only shader free of the free-form code, which Mesa's SIMD rasteriser would pay for).

fn objects_shadow(px: vec2<u32>) -> bool {
    return false;
}

fn objects_shadow_near(px: vec2<u32>) -> bool {
    return false;
}

fn object_shadow_offset(g: vec4<u32>) -> f32 {
    return 0.0;
}

fn oct_decode(u: u32) -> vec3<f32> {
    return vec3<f32>(0.0, 0.0, 1.0);
}

fn object_colour(g: vec4<u32>, n: vec3<f32>, dl: vec3<f32>, lit: f32) -> vec3<f32> {
    return vec3<f32>(1.0, 0.0, 1.0);
}
