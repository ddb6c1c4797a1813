// Ray generation pass (pinhole): one unit world direction per pixel plus the pixel's cone
// half-angle, written to the ray table that the cast passes read. A distortion table replaces
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
@group(0) @binding(1) var<storage, read_write> rays: array<vec4<f32>>;

@compute @workgroup_size(8, 8, 1)
fn cs_raygen(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= cam.size.x || id.y >= cam.size.y) {
        return;
    }
    let u = (f32(id.x) + 0.5 - cam.intrinsics.z) / cam.intrinsics.x;
    let v = (f32(id.y) + 0.5 - cam.intrinsics.w) / cam.intrinsics.y;
    let d = normalize(cam.right.xyz * u + cam.down.xyz * v + cam.forward.xyz);
    // Half the angle subtended by one pixel at this image position.
    let cone = 0.5 / (cam.intrinsics.x * (1.0 + u * u + v * v));
    rays[id.y * cam.size.x + id.x] = vec4<f32>(d, cone);
}
