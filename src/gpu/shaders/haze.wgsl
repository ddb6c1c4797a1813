// Shared by the shade and volume passes: the local (base-plane) frame and aerial perspective.
// The sRGB transfer functions they also use are in srgb.wgsl (prepended before this file).

fn to_local(d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(frame.local_from_world_0.xyz, d), dot(frame.local_from_world_1.xyz, d), dot(frame.local_from_world_2.xyz, d));
}

// Transmittance of the haze between the eye and a point at distance t and local height zp.
fn haze_transmittance(t: f32, ze: f32, zp: f32) -> f32 {
    let sigma = frame.fog_colour.w;
    if (sigma <= 0.0) {
        return 1.0;
    }
    let hs = frame.fog.x;
    var tau = sigma * t;
    if (hs > 0.0) {
        let dz = zp - ze;
        if (abs(dz) > 1.0e-3 * hs) {
            tau = sigma * t * (exp(-ze / hs) - exp(-zp / hs)) / (dz / hs);
        } else {
            tau = sigma * t * exp(-ze / hs);
        }
    }
    return exp(-tau);
}

// The haze's own colour seen along dl (in-scattered light, brighter towards the sun).
fn haze_scatter(dl: vec3<f32>) -> vec3<f32> {
    return frame.fog_colour.xyz + frame.sun_colour.xyz * (0.25 * pow(max(dot(dl, frame.sun_local.xyz), 0.0), 8.0));
}

// Haze between the eye and a point at distance t and local height zp, seen along dl.
fn aerial_perspective(c: vec3<f32>, t: f32, zp: f32, dl: vec3<f32>) -> vec3<f32> {
    let tau = haze_transmittance(t, frame.eye.z, zp);
    return c * tau + haze_scatter(dl) * (1.0 - tau);
}

