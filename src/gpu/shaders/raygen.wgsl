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
    // Distortion tables: the eye in the display frame.
    eye: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cam: RayGen;
// Distortion tables: per projector pixel, f32 bits of the lit screen point in the display
// frame (xyz) and 1 where there is one (w).
@group(0) @binding(2) var screen_points: texture_2d<u32>;
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

fn screen_point(px: vec2<i32>) -> vec4<f32> {
    let q = clamp(px, vec2<i32>(0), vec2<i32>(cam.size.xy) - 1);
    return bitcast<vec4<f32>>(textureLoad(screen_points, q, 0));
}

// World direction from the eye to a screen point: display x, y, z map to the attitude's
// right, forward and up.
fn table_dir(p: vec3<f32>) -> vec3<f32> {
    let v = p - cam.eye.xyz;
    return normalize(cam.right.xyz * v.x + cam.forward.xyz * v.y - cam.down.xyz * v.z);
}

// Distortion-table ray generation (every frame: the eye and the attitude move; the screen
// points stay while the projector does). Cone = half the largest angle to a 4-neighbour.
@fragment
fn fs_raygen_table(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> {
    let px = vec2<i32>(pos.xy);
    let p = screen_point(px);
    if (p.w == 0.0) {
        return bitcast<vec4<u32>>(vec4<f32>(0.0, 0.0, 1.0, -1.0));
    }
    let d = table_dir(p.xyz);
    var chord = 0.0;
    let offsets = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(-1, 0), vec2<i32>(0, 1), vec2<i32>(0, -1));
    for (var k = 0; k < 4; k += 1) {
        let q = px + offsets[k];
        if (q.x >= 0 && q.y >= 0 && q.x < i32(cam.size.x) && q.y < i32(cam.size.y)) {
            let n = screen_point(q);
            if (n.w != 0.0) {
                chord = max(chord, length(table_dir(n.xyz) - d));
            }
        }
    }
    return bitcast<vec4<u32>>(vec4<f32>(d, asin(min(0.5 * chord, 1.0))));
}
