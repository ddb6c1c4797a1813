// The ray table: per pixel, the f32 bits of the unit world direction (xyz) and cone
// half-angle (w; negative where the pixel shows no screen and stays black), written by the
// ray-generation pass.
@group(0) @binding(3) var ray_table: texture_2d<u32>;

fn ray_entry(px: vec2<u32>) -> vec4<f32> {
    return bitcast<vec4<f32>>(textureLoad(ray_table, vec2<i32>(px), 0));
}

fn ray_dir(px: vec2<u32>) -> vec3<f32> {
    return ray_entry(px).xyz;
}
