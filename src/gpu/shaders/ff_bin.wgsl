// Object binning (compute, one invocation per 16x16-pixel bin). From the bin's rays (the ray
// table, so it works through any distortion) and the G-buffer:
// * list 0 (primary rays): objects whose bounding sphere meets the bin's cone of rays before
//   the farthest terrain hit of the bin;
// * list 1 (shadow rays): objects whose bounding sphere comes within reach of the sun-ward
//   extrusion of a sphere around every surface point the bin shows.
// Pixels then test only their bin's objects: cost grows with objects per bin.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var gbuffer: texture_2d<u32>;
@group(0) @binding(8) var<storage, read_write> ff_bins_out: array<u32>;

const FF_BIN: u32 = 16u;

fn angle_between(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return atan2(length(cross(a, b)), dot(a, b));
}

// Pixel k of a walk around the border of the bin [p0, last] (k < 2 * (width + height); the
// corners are visited twice).
fn bin_border(p0: vec2<u32>, last: vec2<u32>, k: u32) -> vec2<u32> {
    let w = last.x - p0.x + 1u;
    let h = last.y - p0.y + 1u;
    if (k < w) {
        return vec2<u32>(p0.x + k, p0.y);
    }
    if (k < 2u * w) {
        return vec2<u32>(p0.x + k - w, last.y);
    }
    if (k < 2u * w + h) {
        return vec2<u32>(p0.x, p0.y + k - 2u * w);
    }
    return vec2<u32>(last.x, p0.y + min(k - 2u * w - h, h - 1u));
}

fn bin_objects(b: vec2<u32>, list: u32) {
    if (b.x >= frame.objects.y || b.y >= frame.objects.z) {
        return;
    }
    let bins = frame.objects.y * frame.objects.z;
    let base = (list * bins + b.y * frame.objects.y + b.x) * (frame.objects.w + 1u);
    let p0 = b * FF_BIN;
    let p1 = min(p0 + FF_BIN, frame.size.xy);
    // Depth range of the bin's surface points (sky: unbounded for primary rays).
    var t_lo = BIG;
    var t_hi = 0.0;
    var hits = 0u;
    var sky = false;
    for (var y = p0.y; y < p1.y; y++) {
        for (var x = p0.x; x < p1.x; x++) {
            let g = textureLoad(gbuffer, vec2<i32>(i32(x), i32(y)), 0);
            if ((g.w & 1u) != 0u) {
                let t = bitcast<f32>(g.x);
                t_lo = min(t_lo, t);
                t_hi = max(t_hi, t);
                hits += 1u;
            } else if ((g.w & 8u) == 0u) {
                sky = true;
            }
        }
    }
    if (list == 0u && sky) {
        t_hi = BIG;
    }
    if ((hits == 0u && !sky) || (list == 1u && hits == 0u)) {
        ff_bins_out[base] = 0u;
        return;
    }
    // Cone of the bin's rays from its border pixels (the ray table is smooth over a bin, so
    // the extreme directions lie on the border), padded by the widest pixel cone and 10%.
    var sum = vec3<f32>(0.0);
    var cone = 0.0;
    let last = p1 - vec2<u32>(1u);
    let perimeter = 2u * ((p1.x - p0.x) + (p1.y - p0.y));
    for (var k = 0u; k < perimeter; k++) {
        let e = ray_entry(bin_border(p0, last, k));
        if (e.w >= 0.0) {
            sum += e.xyz;
            cone = max(cone, e.w);
        }
    }
    let axis = normalize(sum + vec3<f32>(0.0, 0.0, 1.0e-30));
    var theta = 0.0;
    for (var k = 0u; k < perimeter; k++) {
        let e = ray_entry(bin_border(p0, last, k));
        if (e.w >= 0.0) {
            theta = max(theta, angle_between(axis, e.xyz));
        }
    }
    theta = 1.1 * theta + cone + 1.0e-4;
    let eye = frame.eye_world.xyz;
    // Shadow list: a sphere around the bin's surface points (the cone between t_lo and t_hi),
    // padded for the shadow rays' offset from the surface.
    var sc = eye;
    var sr = t_hi;
    if (theta < 0.5) {
        let ax_lo = t_lo * cos(theta);
        sc = eye + axis * (0.5 * (ax_lo + t_hi));
        sr = sqrt(0.25 * (t_hi - ax_lo) * (t_hi - ax_lo) + (t_hi * sin(theta)) * (t_hi * sin(theta)));
    }
    sr += 1.0 + 1.0e-3 * t_hi;
    let sun = frame.sun_world.xyz;
    let cap = frame.objects.w;
    var count = 0u;
    for (var i = 0u; i < frame.objects.x; i++) {
        let sp = ff_objects[i].sphere;
        var keep = false;
        if (list == 0u) {
            let v = sp.xyz - eye;
            let dist = length(v);
            if (dist <= sp.w) {
                keep = true;
            } else if (dist - sp.w <= t_hi) {
                keep = angle_between(axis, v) <= theta + asin(min(sp.w / dist, 1.0)) + 1.0e-4;
            }
        } else {
            let v = sp.xyz - sc;
            let u = max(dot(v, sun), 0.0);
            keep = length(v - sun * u) <= sp.w + sr;
        }
        if (keep) {
            if (count < cap) {
                ff_bins_out[base + 1u + count] = i;
            }
            count += 1u;
        }
    }
    ff_bins_out[base] = count;
}

@compute @workgroup_size(8, 8)
fn cs_bin_primary(@builtin(global_invocation_id) gid: vec3<u32>) {
    bin_objects(gid.xy, 0u);
}

@compute @workgroup_size(8, 8)
fn cs_bin_shadow(@builtin(global_invocation_id) gid: vec3<u32>) {
    bin_objects(gid.xy, 1u);
}
