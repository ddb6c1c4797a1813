// Cloud layers (`[[clouds]]`, CIGI weather layers 1-3): `cpu::clouds`, step for step, in
// f32. Layer k is frame.clouds[2k] = (base, top, extinction, threshold) and
// frame.clouds[2k + 1] = (mean density, 1 / feature, seed, relief); frame.cloud_info = (layers,
// grid spacing x, y in metres, 0). Needs frame.wgsl, haze.wgsl and to_grid_dir.

const CLOUD_VIEW_SAMPLES: u32 = 8u;
const CLOUD_SUN_SAMPLES: u32 = 4u;
const CLOUD_REACH: f32 = 200000.0;
const CLOUD_SOFT: f32 = 0.06;
const CLOUD_SUN_SCATTER: f32 = 0.1;
const CLOUD_SUN_Z_MIN: f32 = 0.05;
const CLOUD_ALBEDO: f32 = 0.9;
const CLOUD_MAX_LAYERS: u32 = 3u;
const CLOUD_FADE_FROM: f32 = 0.125;
const CLOUD_FADE_TO: f32 = 0.625;

// The weight of the layer's mean in a sample standing for `cells` cloud cells (`fade`).
fn cloud_fade(cells: f32) -> f32 {
    return clamp((cells - CLOUD_FADE_FROM) / (CLOUD_FADE_TO - CLOUD_FADE_FROM), 0.0, 1.0);
}

fn cloud_hash(ix: i32, iy: i32, seed: u32) -> f32 {
    var h = (bitcast<u32>(ix) * 0x8da6b343u) ^ (bitcast<u32>(iy) * 0xd8163841u) ^ (seed * 0xcb1ab31fu);
    h ^= h >> 16u;
    h *= 0x7feb352du;
    h ^= h >> 15u;
    h *= 0x846ca68bu;
    h ^= h >> 16u;
    return f32(h >> 8u) / 16777216.0;
}

fn cloud_value(x: f32, y: f32, seed: u32) -> f32 {
    let f = floor(vec2<f32>(x, y));
    let i = vec2<i32>(f);
    let t = vec2<f32>(x, y) - f;
    let s = t * t * (3.0 - 2.0 * t);
    let a = cloud_hash(i.x, i.y, seed);
    let b = cloud_hash(i.x + 1, i.y, seed);
    let c = cloud_hash(i.x, i.y + 1, seed);
    let d = cloud_hash(i.x + 1, i.y + 1, seed);
    let ab = a + (b - a) * s.x;
    let cd = c + (d - c) * s.x;
    return ab + (cd - ab) * s.y;
}

fn cloud_pattern(x: f32, y: f32, seed: u32) -> f32 {
    return (cloud_value(x, y, seed) + 0.5 * cloud_value(2.0 * x, 2.0 * y, seed + 1u) + 0.25 * cloud_value(4.0 * x, 4.0 * y, seed + 2u)) / 1.75;
}

const CLOUD_RELIEF: f32 = 0.2;
const CLOUD_EDGE_TOP: f32 = 0.35;
const CLOUD_TOP_SOFT: f32 = 0.3;

// The cloud column of layer k above grid point q (samples): its cover and the height of its
// top (cells are domes, `Deck::cell`).
fn cloud_column(k: u32, q: vec2<f32>) -> vec2<f32> {
    let a = frame.clouds[2u * k];
    let b = frame.clouds[2u * k + 1u];
    let m = q * frame.cloud_info.yz * b.y;
    let e = cloud_pattern(m.x, m.y, u32(b.z)) - a.w;
    let cover = clamp(e / CLOUD_SOFT, 0.0, 1.0);
    let rise = sqrt(clamp(e / CLOUD_RELIEF, 0.0, 1.0));
    let sink = b.w * (1.0 - CLOUD_EDGE_TOP) * (1.0 - rise);
    return vec2<f32>(cover, a.x + (a.y - a.x) * (1.0 - sink));
}

// Density of layer k at height z in column col, faded to the layer's mean where a sample
// stands for w of a cloud cell or more.
fn cloud_density(k: u32, col: vec2<f32>, z: f32, w: f32) -> f32 {
    let a = frame.clouds[2u * k];
    let d = col.x * clamp((col.y - z) / (CLOUD_TOP_SOFT * (a.y - a.x)), 0.0, 1.0);
    return mix(d, frame.clouds[2u * k + 1u].x, w);
}

// Where ze + dz s + a s^2 <= h: (lo, hi), empty when lo > hi.
fn cloud_below(ze: f32, dz: f32, a: f32, h: f32) -> vec2<f32> {
    let c = ze - h;
    if (a <= 1.0e-12) {
        if (dz > 0.0) {
            return vec2<f32>(-BIG, -c / dz);
        }
        if (dz < 0.0) {
            return vec2<f32>(-c / dz, BIG);
        }
        return select(vec2<f32>(BIG, -BIG), vec2<f32>(-BIG, BIG), c <= 0.0);
    }
    let disc = dz * dz - 4.0 * a * c;
    if (disc < 0.0) {
        return vec2<f32>(BIG, -BIG);
    }
    let q = -0.5 * (dz + select(-1.0, 1.0, dz >= 0.0) * sqrt(disc));
    if (q == 0.0) {
        return vec2<f32>(0.0);
    }
    let r0 = q / a;
    let r1 = c / q;
    return vec2<f32>(min(r0, r1), max(r0, r1));
}

// Linear colour of cloud at height z in layer k, in a column whose top is at `top`.
fn cloud_colour(k: u32, z: f32, top: f32) -> vec3<f32> {
    let a = frame.clouds[2u * k];
    let mean = frame.clouds[2u * k + 1u].x;
    let h = clamp((z - a.x) / (top - a.x), 0.0, 1.0);
    let sun = frame.sun_local.xyz;
    let depth = max(top - z, 0.0) / max(sun.z, CLOUD_SUN_Z_MIN);
    let direct = frame.sun_colour.xyz * (frame.sun_local.w * max(sun.z, 0.0) * exp(-CLOUD_SUN_SCATTER * a.z * mean * depth));
    let ambient = 0.5 * (frame.sky_zenith.xyz + frame.sky_horizon.xyz) * frame.sky_zenith.w;
    return (direct + ambient * (0.5 + 0.5 * h)) * CLOUD_ALBEDO;
}

// The colour seen along world direction dir_w (local dl) up to distance tmax through the
// layers, over `behind` (already hazed). Each span is hazed once, at its opacity-weighted
// distance and height.
fn clouds_over(behind: vec3<f32>, tmax_in: f32, dir_w: vec3<f32>, dl: vec3<f32>) -> vec3<f32> {
    let n = min(u32(frame.cloud_info.x), CLOUD_MAX_LAYERS);
    let g = to_grid_dir(dir_w);
    var a = 0.0;
    if (CURVED) {
        a = frame.curvature.z * g.x * g.x + frame.curvature.w * g.y * g.y;
    }
    let ze = frame.eye.z;
    let tmax = min(tmax_in, CLOUD_REACH);
    let scatter = haze_scatter(dl);
    // Each layer's (at most two) spans, then composited nearest first.
    var s0: array<f32, 6>;
    var s1: array<f32, 6>;
    var layer: array<u32, 6>;
    var count = 0u;
    for (var k = 0u; k < n; k++) {
        let c = frame.clouds[2u * k];
        var u = cloud_below(ze, g.z, a, c.y);
        if (u.x > u.y) {
            continue;
        }
        u = vec2<f32>(max(u.x, 0.0), min(u.y, tmax));
        let l = cloud_below(ze, g.z, a, c.x);
        var lo = vec2<f32>(u.x, u.y);
        var hi = vec2<f32>(1.0, 0.0);
        if (l.x <= l.y) {
            lo = vec2<f32>(u.x, min(u.y, l.x));
            hi = vec2<f32>(max(u.x, l.y), u.y);
        }
        if (lo.y > lo.x) {
            s0[count] = lo.x;
            s1[count] = lo.y;
            layer[count] = k;
            count++;
        }
        if (hi.y > hi.x) {
            s0[count] = hi.x;
            s1[count] = hi.y;
            layer[count] = k;
            count++;
        }
    }
    var acc = vec3<f32>(0.0);
    var tr = 1.0;
    var done = 0u;
    for (var m = 0u; m < count; m++) {
        // The nearest span not yet composited.
        var best = 0u;
        var start = BIG;
        for (var j = 0u; j < count; j++) {
            let free = ((done >> j) & 1u) == 0u;
            if (free && s0[j] < start) {
                start = s0[j];
                best = j;
            }
        }
        done |= 1u << best;
        let k = layer[best];
        let c = frame.clouds[2u * k];
        let inv_feature = frame.clouds[2u * k + 1u].y;
        let len = s1[best] - start;
        let cells = len * inv_feature;
        let p = select(min(1.0 + log2(cells / 2.0) / 3.0, 4.0), 1.0, cells <= 2.0);
        let nf = f32(CLOUD_VIEW_SAMPLES);
        // The span's light and opacity, and its opacity-weighted distance and height, for one
        // haze over the span.
        var light = vec3<f32>(0.0);
        var weight = 0.0;
        var sw = 0.0;
        var zw = 0.0;
        for (var i = 0u; i < CLOUD_VIEW_SAMPLES; i++) {
            let fi = f32(i);
            let ds = len * (pow((fi + 1.0) / nf, p) - pow(fi / nf, p));
            let s = start + len * pow((fi + 0.5) / nf, p);
            let q = frame.eye.xy + g.xy * s;
            let z = ze + g.z * s + a * s * s;
            let w = cloud_fade(ds * inv_feature);
            let col = cloud_column(k, q);
            let density = cloud_density(k, col, z, w);
            let alpha = 1.0 - exp(-c.z * density * ds);
            let back = min(0.5 * ds, 1.0 / (c.z * max(density, 0.05)));
            let z_lit = z - (g.z + 2.0 * a * s) * back;
            let f = tr * alpha;
            light += cloud_colour(k, z_lit, mix(col.y, c.y, w)) * f;
            weight += f;
            sw += s * f;
            zw += z * f;
            tr *= 1.0 - alpha;
        }
        let at = max(weight, 1.0e-30);
        let tau = haze_transmittance(sw / at, ze, zw / at);
        acc += light * tau + scatter * ((1.0 - tau) * weight);
    }
    return acc + behind * tr;
}

// The sun's transmittance through the layers to a surface at grid point p (x, y in samples,
// z in metres above mean sea level).
fn cloud_sun(p: vec3<f32>) -> f32 {
    let n = min(u32(frame.cloud_info.x), CLOUD_MAX_LAYERS);
    let sg = frame.sun_grid.xyz;
    let sun_z = max(sg.z, CLOUD_SUN_Z_MIN);
    var tau = 0.0;
    for (var k = 0u; k < n; k++) {
        let c = frame.clouds[2u * k];
        if (p.z >= c.y) {
            // Above the layer: the sun's path does not cross it.
            continue;
        }
        let inv_feature = frame.clouds[2u * k + 1u].y;
        let s0 = max(c.x - p.z, 0.0) / sun_z;
        let s1 = max(c.y - p.z, 0.0) / sun_z;
        let ds = (s1 - s0) / f32(CLOUD_SUN_SAMPLES);
        let w = cloud_fade(ds * inv_feature);
        for (var i = 0u; i < CLOUD_SUN_SAMPLES; i++) {
            let s = s0 + (f32(i) + 0.5) * ds;
            tau += c.z * cloud_density(k, cloud_column(k, p.xy + sg.xy * s), p.z + sun_z * s, w) * ds;
        }
    }
    return exp(-tau);
}
