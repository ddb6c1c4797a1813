// Shade-pass hooks for scenes with free forms: the free-form shadow pass's answer, and
// free-form shading with the paper's colour formula
// C = (Qa·Ca + Qd·Cd + Qs·Cs) / (Qa + Qd + Qs), Cd = (n·l)·Clight·Csurf, Cs = (r·v)^p·Clight.

@group(0) @binding(9) var ff_shadow: texture_2d<u32>;

fn objects_shadow(px: vec2<u32>, p: vec3<f32>) -> bool {
    return textureLoad(ff_shadow, vec2<i32>(px), 0).x != 0u;
}

fn shade_object(px: vec2<u32>, g: vec4<u32>, dir_w: vec3<f32>) -> Out {
    let t = bitcast<f32>(g.x);
    let id = g.y & 0xffffu;
    let ob = ff_objects[id];
    let nw = oct_decode(g.z);
    let n = to_local(nw);
    let dl = to_local(dir_w);
    let sun = frame.sun_local.xyz;
    var flags = 1u | 16u;
    var lit = select(0.0, 1.0, dot(n, sun) > 0.0);
    var shadow_steps = 0u;
    if (frame.mode.z != 0u && lit > 0.0) {
        let ps = frame.eye_world.xyz + dir_w * t + nw * ob.position.w;
        var sr: Ray;
        sr.o = frame.eye.xyz + to_grid_dir(ps - frame.eye_world.xyz);
        sr.d = frame.sun_grid.xyz;
        let st = traverse(sr, 0.0, BIG, frame.mode.y);
        shadow_steps = st.steps;
        if (st.hit || objects_shadow(px, ps)) {
            lit = 0.0;
            flags |= 2u;
        }
    }
    let cs = ob.colour.xyz;
    let q = ob.material.xyz;
    let clight = frame.sun_colour.xyz * frame.sun_local.w;
    let ca = cs * ambient_light(n);
    let cd = clight * cs * (max(dot(n, sun), 0.0) * lit);
    let r = reflect(-sun, n);
    let cspec = clight * (pow(max(dot(r, -dl), 0.0), ob.colour.w) * lit);
    let c = (q.x * ca + q.y * cd + q.z * cspec) / (q.x + q.y + q.z);
    let zp = frame.eye.z + to_grid_dir(dir_w).z * t;
    var out: Out;
    out.colour = vec4<f32>(srgb_encode(aerial_perspective(c, t, zp, dl)), 1.0);
    out.data = vec4<u32>(g.x, g.y >> 16u, min(shadow_steps, 0xffffu) << 16u, flags | ((id + 1u) << 8u));
    return out;
}
