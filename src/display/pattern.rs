//! The warp test pattern: every pixel's colour is a pure function of its world ray direction
//! (and of its cone half-angle, which sets the anti-aliasing width), so any image rendered
//! through any distortion table can be compared with any other view of the same directions.
//! `shaders/pattern.wgsl` computes the same colours on the GPU (f32); this is the f64
//! reference that `relief warp verify` and the tests use.
//!
//! Grid mode: azimuth/elevation lines every 5° (every 90° of azimuth thicker), a thick
//! horizon, numeric labels (every 10° of elevation at every 30° of azimuth the elevation in
//! degrees; on the horizon the azimuth), circles every 10° around a boresight and a dot on it, on a background tinted by
//! hemisphere (east/west, above/below the horizon). Grating mode: a sinusoid in elevation,
//! `0.5 + 0.5 cos(2π f el)` (f cycles per radian), for sharpness measurements.
//! Directions: world x east, y north, z up; azimuth clockwise from north.

use glam::DVec3;

/// Grid spacing (degrees).
pub const GRID_DEG: f64 = 5.0;
/// Circle spacing around the boresight (degrees).
pub const CIRCLE_DEG: f64 = 10.0;
const LINE_HALF_WIDTH_DEG: f64 = 0.12;
const MAJOR_HALF_WIDTH_DEG: f64 = 0.25;
const HORIZON_HALF_WIDTH_DEG: f64 = 0.4;
const MIN_FILTER_DEG: f64 = 0.02;
/// Label rows (degrees of elevation) and columns (degrees of azimuth).
pub const LABEL_EL_DEG: f64 = 10.0;
pub const LABEL_AZ_DEG: f64 = 30.0;
/// One glyph pixel (degrees); glyphs are 3x5 pixels in 4-pixel-wide cells.
pub const LABEL_CELL_DEG: f64 = 0.3;
/// Offset of a label from its grid crossing, up and to the right (degrees).
pub const LABEL_GAP_DEG: f64 = 0.4;
/// 3x5 glyphs of `0`..`9` and `-`, rows top to bottom, 15 bits, most significant first
/// (WGSL `pat_glyph`).
const GLYPHS: [u32; 11] = [
    0x7b6f, 0x2c97, 0x73e7, 0x73cf, 0x5bc9, 0x79cf, 0x79ef, 0x7249, 0x7bef, 0x7bcf, 0x1c0,
];

/// Whether a direction at azimuth/elevation (degrees; `el` radians) falls on a lit glyph
/// pixel of a grid label (WGSL `pat_label`).
fn label_ink(az_deg: f64, el_deg: f64, el: f64) -> bool {
    if el_deg.abs() >= 85.0 {
        return false;
    }
    let j = (el_deg / LABEL_EL_DEG).floor();
    let k = (az_deg / LABEL_AZ_DEG).floor();
    let x = (az_deg - k * LABEL_AZ_DEG) * el.cos() - LABEL_GAP_DEG;
    let y = el_deg - j * LABEL_EL_DEG - LABEL_GAP_DEG;
    if x < 0.0 || y < 0.0 {
        return false;
    }
    let value = if j == 0.0 {
        (k * LABEL_AZ_DEG).rem_euclid(360.0) as i32
    } else {
        (j * LABEL_EL_DEG) as i32
    };
    let a = value.unsigned_abs();
    let neg = u32::from(value < 0);
    let digits = 1 + u32::from(a >= 10) + u32::from(a >= 100);
    let ci = (x / (4.0 * LABEL_CELL_DEG)).floor() as u32;
    if ci >= digits + neg {
        return false;
    }
    let gx = ((x - ci as f64 * 4.0 * LABEL_CELL_DEG) / LABEL_CELL_DEG).floor() as u32;
    let gy_up = (y / LABEL_CELL_DEG).floor() as u32;
    if gx >= 3 || gy_up >= 5 {
        return false;
    }
    let glyph = if neg == 1 && ci == 0 {
        GLYPHS[10]
    } else {
        let i = ci - neg;
        GLYPHS[(a / 10u32.pow(digits - 1 - i) % 10) as usize]
    };
    (glyph >> (14 - ((4 - gy_up) * 3 + gx))) & 1 == 1
}

/// What the pattern draws.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatternParams {
    /// Unit world direction at the centre of the circles.
    pub boresight: DVec3,
    /// Grating frequency in cycles per radian of elevation; 0 = the grid.
    pub grating: f64,
}

impl PatternParams {
    /// The grid around `boresight`.
    pub fn grid(boresight: DVec3) -> PatternParams {
        PatternParams {
            boresight: boresight.normalize(),
            grating: 0.0,
        }
    }
}

fn round(x: f64) -> f64 {
    (x + 0.5).floor()
}

/// Box-filtered coverage of a line of half width `half` at angular distance `dist` for a pixel
/// of half width `filter` (all degrees).
fn cover(dist: f64, half: f64, filter: f64) -> f64 {
    ((half + filter - dist) / (2.0 * filter)).clamp(0.0, 1.0)
}

fn mix(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// Colour (display code values in 0..1, not linear light) of unit world direction `d` seen by
/// a pixel of cone half-angle `cone` (radians).
pub fn pattern_colour(d: DVec3, cone: f64, p: &PatternParams) -> [f64; 3] {
    let el = d.z.atan2(d.truncate().length());
    if p.grating > 0.0 {
        let v = 0.5 + 0.5 * (std::f64::consts::TAU * p.grating * el).cos();
        return [v; 3];
    }
    let el_deg = el.to_degrees();
    let az_deg = d.x.atan2(d.y).to_degrees();
    let filter = cone.to_degrees().max(MIN_FILTER_DEG);
    let mut c = [
        0.08 + if d.x >= 0.0 { 0.07 } else { 0.0 },
        0.08,
        0.10 + if el < 0.0 { 0.08 } else { 0.0 },
    ];
    // Elevation lines (parallels).
    let k_el = round(el_deg / GRID_DEG);
    let grid_el = cover(
        (el_deg - k_el * GRID_DEG).abs(),
        LINE_HALF_WIDTH_DEG,
        filter,
    );
    // Azimuth lines (meridians), up to 85° elevation; the angular distance shrinks with
    // cos(elevation).
    let k_az = round(az_deg / GRID_DEG);
    let half_az = if (k_az * GRID_DEG) % 90.0 == 0.0 {
        MAJOR_HALF_WIDTH_DEG
    } else {
        LINE_HALF_WIDTH_DEG
    };
    let grid_az = if el_deg.abs() < 85.0 {
        cover((az_deg - k_az * GRID_DEG).abs() * el.cos(), half_az, filter)
    } else {
        0.0
    };
    c = mix(c, [0.85, 0.85, 0.85], grid_el.max(grid_az));
    if label_ink(az_deg, el_deg, el) {
        c = [1.0, 1.0, 1.0];
    }
    // Circles around the boresight, and a dot on it.
    let ang = d
        .cross(p.boresight)
        .length()
        .atan2(d.dot(p.boresight))
        .to_degrees();
    let k_c = round(ang / CIRCLE_DEG);
    let circle = if k_c >= 1.0 {
        cover((ang - k_c * CIRCLE_DEG).abs(), LINE_HALF_WIDTH_DEG, filter)
    } else {
        cover(ang, 0.5, filter)
    };
    c = mix(c, [0.2, 0.9, 0.9], circle);
    // Horizon.
    let horizon = cover(el_deg.abs(), HORIZON_HALF_WIDTH_DEG, filter);
    mix(c, [1.0, 0.8, 0.2], horizon)
}

/// The pattern colour as RGBA8.
pub fn pattern_rgba8(d: DVec3, cone: f64, p: &PatternParams) -> [u8; 4] {
    let c = pattern_colour(d, cone, p);
    let q = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c[0]), q(c[1]), q(c[2]), 255]
}
