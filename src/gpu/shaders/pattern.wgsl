// Warp test pattern (fragment): colour from the ray table's direction and cone only, no scene.
// Mirrors display::pattern::pattern_colour (f64 reference); keep the two in step.

struct Pattern {
    // xyz: unit world boresight (circle centre); w: grating cycles per radian of elevation
    // (0 = the grid).
    boresight: vec4<f32>,
}

@group(0) @binding(0) var<uniform> pat: Pattern;

struct PatternOut {
    @location(0) colour: vec4<f32>,
    @location(1) data: vec4<u32>,
}

const GRID_DEG: f32 = 5.0;
const CIRCLE_DEG: f32 = 10.0;
const LINE_HALF: f32 = 0.12;
const MAJOR_HALF: f32 = 0.25;
const HORIZON_HALF: f32 = 0.4;
const MIN_FILTER: f32 = 0.02;
const DEG: f32 = 57.29577951308232;
const PATTERN_INF_BITS: u32 = 0x7f800000u;

// Labels (display::pattern::label_ink): every 10° of elevation at every 30° of azimuth the
// elevation, on the horizon the azimuth, in 3x5-pixel glyphs of 0.3°.
const LABEL_EL: f32 = 10.0;
const LABEL_AZ: f32 = 30.0;
const LABEL_CELL: f32 = 0.3;
const LABEL_GAP: f32 = 0.4;

// 3x5 glyph bits of 0..9 and '-' (10), rows top to bottom, most significant first.
fn pat_glyph(c: u32) -> u32 {
    switch c {
        case 0u: { return 0x7b6fu; }
        case 1u: { return 0x2c97u; }
        case 2u: { return 0x73e7u; }
        case 3u: { return 0x73cfu; }
        case 4u: { return 0x5bc9u; }
        case 5u: { return 0x79cfu; }
        case 6u: { return 0x79efu; }
        case 7u: { return 0x7249u; }
        case 8u: { return 0x7befu; }
        case 9u: { return 0x7bcfu; }
        default: { return 0x1c0u; }
    }
}

fn pat_label(az_deg: f32, el_deg: f32, el: f32) -> bool {
    if (abs(el_deg) >= 85.0) {
        return false;
    }
    let j = floor(el_deg / LABEL_EL);
    let k = floor(az_deg / LABEL_AZ);
    let x = (az_deg - k * LABEL_AZ) * cos(el) - LABEL_GAP;
    let y = el_deg - j * LABEL_EL - LABEL_GAP;
    if (x < 0.0 || y < 0.0) {
        return false;
    }
    var value = i32(j * LABEL_EL);
    if (j == 0.0) {
        // Floored modulo without a negative `%` operand (see `half_az` below).
        let deg = i32(k * LABEL_AZ);
        value = deg - 360 * i32(floor(f32(deg) / 360.0));
    }
    let a = u32(abs(value));
    let neg = select(0u, 1u, value < 0);
    let digits = 1u + select(0u, 1u, a >= 10u) + select(0u, 1u, a >= 100u);
    let ci = u32(floor(x / (4.0 * LABEL_CELL)));
    if (ci >= digits + neg) {
        return false;
    }
    let gx = u32(floor((x - f32(ci) * 4.0 * LABEL_CELL) / LABEL_CELL));
    let gy_up = u32(floor(y / LABEL_CELL));
    if (gx >= 3u || gy_up >= 5u) {
        return false;
    }
    var c = 10u;
    if (!(neg == 1u && ci == 0u)) {
        let p = digits - 1u - (ci - neg);
        let scale = select(select(1u, 10u, p == 1u), 100u, p == 2u);
        c = (a / scale) % 10u;
    }
    return ((pat_glyph(c) >> (14u - ((4u - gy_up) * 3u + gx))) & 1u) == 1u;
}

fn cover(dist: f32, half: f32, fw: f32) -> f32 {
    return clamp((half + fw - dist) / (2.0 * fw), 0.0, 1.0);
}

fn pattern_colour(d: vec3<f32>, cone: f32) -> vec3<f32> {
    // atan2 forms: Mesa's f32 asin/acos are off by ~1e-4 rad, its atan2 is not.
    let el = atan2(d.z, length(d.xy));
    if (pat.boresight.w > 0.0) {
        return vec3<f32>(0.5 + 0.5 * cos(6.283185307179586 * pat.boresight.w * el));
    }
    let el_deg = el * DEG;
    let az_deg = atan2(d.x, d.y) * DEG;
    let fw = max(cone * DEG, MIN_FILTER);
    var c = vec3<f32>(select(0.08, 0.15, d.x >= 0.0), 0.08, select(0.10, 0.18, el < 0.0));
    let k_el = floor(el_deg / GRID_DEG + 0.5);
    let grid_el = cover(abs(el_deg - k_el * GRID_DEG), LINE_HALF, fw);
    let k_az = floor(az_deg / GRID_DEG + 0.5);
    // `%` of non-negative operands only: GLSL leaves a negative operand's remainder
    // undefined, and naga's GL output differs from WGSL there.
    let half_az = select(LINE_HALF, MAJOR_HALF, (abs(i32(k_az)) % 18) == 0);
    var grid_az = 0.0;
    if (abs(el_deg) < 85.0) {
        grid_az = cover(abs(az_deg - k_az * GRID_DEG) * cos(el), half_az, fw);
    }
    c = mix(c, vec3<f32>(0.85), max(grid_el, grid_az));
    if (pat_label(az_deg, el_deg, el)) {
        c = vec3<f32>(1.0);
    }
    let b = pat.boresight.xyz;
    let ang = atan2(length(cross(d, b)), dot(d, b)) * DEG;
    let k_c = floor(ang / CIRCLE_DEG + 0.5);
    var circle = cover(ang, 0.5, fw);
    if (k_c >= 1.0) {
        circle = cover(abs(ang - k_c * CIRCLE_DEG), LINE_HALF, fw);
    }
    c = mix(c, vec3<f32>(0.2, 0.9, 0.9), circle);
    let horizon = cover(abs(el_deg), HORIZON_HALF, fw);
    return mix(c, vec3<f32>(1.0, 0.8, 0.2), horizon);
}

@fragment
fn fs_pattern(@builtin(position) pos: vec4<f32>) -> PatternOut {
    let e = ray_entry(vec2<u32>(pos.xy));
    var out: PatternOut;
    if (e.w < 0.0) {
        out.colour = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        out.data = vec4<u32>(PATTERN_INF_BITS, 0u, 0u, 8u);
        return out;
    }
    out.colour = vec4<f32>(unorm8(pattern_colour(e.xyz, e.w)), 1.0);
    out.data = vec4<u32>(PATTERN_INF_BITS, 0u, 0u, 0u);
    return out;
}
