// Ray generation pass (pinhole): one unit world direction per pixel plus the pixel's cone
// half-angle, written to the ray table (an Rgba32Uint texture of f32 bits) that the other passes read.
// Compute and fragment entry points write the same table; the renderer picks one per adapter. A distortion table replaces
// this pass for curved screens.

struct RayGen {
    // World-from-camera rotation columns (right, down, forward).
    right: vec4<f32>,
    down: vec4<f32>,
    forward: vec4<f32>,
    // fx, fy, cx, cy in pixels.
    intrinsics: vec4<f32>,
    // width, height.
    size: vec4<u32>,
}

@group(0) @binding(0) var<uniform> cam: RayGen;
// Compute path only: the ray table as a storage texture.
@group(0) @binding(1) var ray_table_out: texture_storage_2d<rgba32uint, write>;

// Unit world direction (xyz) and cone half-angle (w) of pixel `px`'s centre.
fn pinhole_ray(px: vec2<u32>) -> vec4<f32> {
    let u = (f32(px.x) + 0.5 - cam.intrinsics.z) / cam.intrinsics.x;
    let v = (f32(px.y) + 0.5 - cam.intrinsics.w) / cam.intrinsics.y;
    let d = normalize(cam.right.xyz * u + cam.down.xyz * v + cam.forward.xyz);
    // Half the angle subtended by one pixel at this image position.
    let cone = 0.5 / (cam.intrinsics.x * (1.0 + u * u + v * v));
    return vec4<f32>(d, cone);
}

// Compute entry point (GPUs).
@compute @workgroup_size(8, 8, 1)
fn cs_raygen(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= cam.size.x || id.y >= cam.size.y) {
        return;
    }
    textureStore(ray_table_out, vec2<i32>(id.xy), bitcast<vec4<u32>>(pinhole_ray(id.xy)));
}

// Fragment entry point (software rasterisers, where fragments use every core).
@fragment
fn fs_raygen(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    return bitcast<vec4<u32>>(pinhole_ray(vec2<u32>(pos.xy)));
}
