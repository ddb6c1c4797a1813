// Shade-pass hooks for scenes with free forms: the free-form shadow pass's answer, the
// shadow-ray offset of a free form, and the paper's colour formula
// C = (Qa·Ca + Qd·Cd + Qs·Cs) / (Qa + Qd + Qs), Cd = (n·l)·Clight·Csurf, Cs = (r·v)^p·Clight.

@group(0) @binding(9) var ff_shadow: texture_2d<u32>;

fn objects_shadow(px: vec2<u32>) -> bool {
    return textureLoad(ff_shadow, vec2<i32>(px), 0).x == frame.stamp.x;
}

// Anti-aliasing's centre rays: the sun rays of the pixel's footprint pass a free form that its
// own sun ray misses (the `_near` shadow passes' second channel).
fn objects_shadow_near(px: vec2<u32>) -> bool {
    return frame.stamp.z != 0u && textureLoad(ff_shadow, vec2<i32>(px), 0).y == frame.stamp.x;
}

fn object_shadow_offset(g: vec4<u32>) -> f32 {
    return ff_objects[g.y & 0xffffu].position.w;
}

// Colour of a free-form pixel (G-buffer g) with local normal n seen along dl; lit in 0..1.
fn object_colour(g: vec4<u32>, n: vec3<f32>, dl: vec3<f32>, lit: f32) -> vec3<f32> {
    let ob = ff_objects[g.y & 0xffffu];
    let sun = frame.sun_local.xyz;
    let cs = ob.colour.xyz;
    let q = ob.material.xyz;
    let clight = frame.sun_colour.xyz * frame.sun_local.w;
    let ca = cs * ambient_light(n);
    let cd = clight * cs * (max(dot(n, sun), 0.0) * lit);
    let r = reflect(-sun, n);
    let cspec = clight * (pow(max(dot(r, -dl), 0.0), ob.colour.w) * lit);
    return (q.x * ca + q.y * cd + q.z * cspec) / (q.x + q.y + q.z);
}
