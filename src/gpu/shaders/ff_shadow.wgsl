// Free-form shadow passes: per lit-facing surface pixel of a bin with shadow-list objects,
// does a free form block the ray to the sun? Writes the frame's stamp (first channel) where
// one does and discards elsewhere (the target is never cleared: older stamps mean "not
// blocked"); the `_near` twins write the second channel. One entry point per object kind,
// each drawn only over the bins whose shadow list holds objects of its kind
// (`vs_bins_shadow_*`). Its own passes so that the shade pass carries no intersection code.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer: texture_2d<u32>;

// Origin of the pixel's shadow ray (w = 1), or w = 0 where no ray is needed (sky, a free-form
// surface facing away from the sun).
fn shadow_origin(px: vec2<u32>) -> vec4<f32> {
    let g = textureLoad(gbuffer, vec2<i32>(px), 0);
    if ((g.w & 1u) == 0u) {
        return vec4<f32>(0.0);
    }
    let sun = frame.sun_world.xyz;
    var p = frame.eye_world.xyz + ray_dir(px) * bitcast<f32>(g.x);
    if ((g.w & 16u) != 0u) {
        // Leave a free form's surface along its normal (terrain points need no offset: the
        // terrain is not a free form).
        let n = oct_decode(g.z);
        if (dot(n, sun) <= 0.0) {
            return vec4<f32>(0.0);
        }
        p += n * ff_objects[g.y & 0xffffu].position.w;
    }
    return vec4<f32>(p, 1.0);
}

@fragment
fn fs_ff_shadow_plain(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let o = shadow_origin(px);
    if (o.w == 0.0 || !ff_plain_blocked(px, o.xyz, frame.sun_world.xyz)) {
        discard;
    }
    return vec4<u32>(frame.stamp.x, 0u, 0u, 0u);
}

@fragment
fn fs_ff_shadow_general(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<u32>(pos.xy);
    let o = shadow_origin(px);
    if (o.w == 0.0 || !ff_blocked(px, o.xyz, frame.sun_world.xyz)) {
        discard;
    }
    return vec4<u32>(frame.stamp.x, 0u, 0u, 0u);
}

// The `_near` shadow passes (anti-aliasing's centre rays, drawn after the ordinary ones with
// only the second channel written): a pixel whose sun ray no object of the kind blocks gets
// the frame's stamp there when the sun rays of its footprint, a beam `footprint_beam` wide,
// pass within reach of one (its own free form left out): a mast's shadow, thinner than the
// pixel, can lie between two pixels' sun rays. The shade pass turns it into flag 64.
fn shadow_near(px: vec2<u32>, general: bool) -> vec4<u32> {
    let o = shadow_origin(px);
    let sun = frame.sun_world.xyz;
    if (o.w == 0.0) {
        discard;
    }
    let g = textureLoad(gbuffer, vec2<i32>(px), 0);
    let own = select(FF_NONE, g.y & 0xffffu, (g.w & 16u) != 0u);
    let cone = vec2<f32>(pixel_beam(px, bitcast<f32>(g.x), sun), 0.0);
    var near: bool;
    if (general) {
        near = !ff_blocked(px, o.xyz, sun) && ff_general_near(px, 1u, o.xyz, sun, cone, BIG, own);
    } else {
        near = !ff_plain_blocked(px, o.xyz, sun) && ff_plain_near(px, 1u, o.xyz, sun, cone, BIG, own);
    }
    if (!near) {
        discard;
    }
    return vec4<u32>(0u, frame.stamp.x, 0u, 0u);
}

@fragment
fn fs_ff_shadow_plain_near(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return shadow_near(vec2<u32>(pos.xy), false);
}

@fragment
fn fs_ff_shadow_general_near(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return shadow_near(vec2<u32>(pos.xy), true);
}
