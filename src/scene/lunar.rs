//! The moon's position and phase for a date, a time of day (UTC) and a place: Meeus,
//! *Astronomical Algorithms* (2nd ed.), chapter 47 with the largest periodic terms of its
//! tables 47.A and 47.B (about 0.05° in longitude and latitude, 0.1% in distance; no
//! nutation), the topocentric elevation lowered by the horizontal parallax (up to 0.95°), and
//! the illuminated fraction of chapter 48. Geometric position: no atmospheric refraction.

use super::solar::{apparent_longitude, horizontal, UtcTime};

/// Where the moon is and how much of it is lit, seen from a place on the earth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoonPosition {
    /// Degrees clockwise from true north, [0, 360).
    pub azimuth: f64,
    /// Degrees above the horizon (topocentric).
    pub elevation: f64,
    /// Illuminated fraction of the disc, 0 (new) to 1 (full).
    pub illuminated: f64,
    /// Geocentric ecliptic longitude and latitude (degrees) and distance (km).
    pub longitude: f64,
    pub latitude: f64,
    pub distance: f64,
}

/// Table 47.A's largest terms: multiples of D, M, M', F; Σl (1e-6°) and Σr (1e-3 km).
const LR: [([i8; 4], f64, f64); 14] = [
    ([0, 0, 1, 0], 6_288_774.0, -20_905_355.0),
    ([2, 0, -1, 0], 1_274_027.0, -3_699_111.0),
    ([2, 0, 0, 0], 658_314.0, -2_955_968.0),
    ([0, 0, 2, 0], 213_618.0, -569_925.0),
    ([0, 1, 0, 0], -185_116.0, 48_888.0),
    ([0, 0, 0, 2], -114_332.0, -3_149.0),
    ([2, 0, -2, 0], 58_793.0, 246_158.0),
    ([2, -1, -1, 0], 57_066.0, -152_138.0),
    ([2, 0, 1, 0], 53_322.0, -170_733.0),
    ([2, -1, 0, 0], 45_758.0, -204_586.0),
    ([0, 1, -1, 0], -40_923.0, -129_620.0),
    ([1, 0, 0, 0], -34_720.0, 108_743.0),
    ([0, 1, 1, 0], -30_383.0, 104_755.0),
    ([2, 0, 0, -2], 15_327.0, 10_321.0),
];

/// Table 47.B's largest terms: multiples of D, M, M', F; Σb (1e-6°).
const B: [([i8; 4], f64); 10] = [
    ([0, 0, 0, 1], 5_128_122.0),
    ([0, 0, 1, 1], 280_602.0),
    ([0, 0, 1, -1], 277_693.0),
    ([2, 0, 0, -1], 173_237.0),
    ([2, 0, -1, 1], 55_413.0),
    ([2, 0, -1, -1], 46_271.0),
    ([2, 0, 0, 1], 32_573.0),
    ([0, 0, 2, 1], 17_198.0),
    ([2, 0, 1, -1], 9_266.0),
    ([0, 0, 2, -1], 8_822.0),
];

/// The moon seen from latitude `lat`, longitude `lon` (degrees, east positive) at `t`.
pub fn moon_position(t: UtcTime, lat: f64, lon: f64) -> MoonPosition {
    let jd = t.julian_day();
    let jc = (jd - 2_451_545.0) / 36_525.0;
    let (sin, cos) = (|d: f64| d.to_radians().sin(), |d: f64| d.to_radians().cos());
    let lp = 218.316_447_7 + 481_267.881_234_21 * jc;
    let args = [
        297.850_192_1 + 445_267.111_403_4 * jc,
        357.529_109_2 + 35_999.050_290_9 * jc,
        134.963_396_4 + 477_198.867_505_5 * jc,
        93.272_095 + 483_202.017_523_3 * jc,
    ];
    let e = 1.0 - 0.002_516 * jc;
    // Terms with M are scaled by E (the earth's eccentricity decreasing), twice with 2M.
    let angle = |m: [i8; 4]| -> (f64, f64) {
        let a: f64 = (0..4).map(|k| f64::from(m[k]) * args[k]).sum();
        (a, e.powi(i32::from(m[1].unsigned_abs())))
    };
    let (mut sl, mut sr, mut sb) = (0.0, 0.0, 0.0);
    for (m, l, r) in LR {
        let (a, f) = angle(m);
        sl += l * f * sin(a);
        sr += r * f * cos(a);
    }
    for (m, b) in B {
        let (a, f) = angle(m);
        sb += b * f * sin(a);
    }
    let longitude = (lp + sl / 1e6).rem_euclid(360.0);
    let latitude = sb / 1e6;
    let distance = 385_000.56 + sr / 1e3;
    // Equatorial coordinates, then the local hour angle from the mean sidereal time.
    let eps = 23.439_291_1 - 0.013_004_2 * jc;
    let ra = (sin(longitude) * cos(eps) - latitude.to_radians().tan() * sin(eps))
        .atan2(cos(longitude))
        .to_degrees();
    let decl = (sin(latitude) * cos(eps) + cos(latitude) * sin(eps) * sin(longitude))
        .clamp(-1.0, 1.0)
        .asin()
        .to_degrees();
    let theta = 280.460_618_37 + 360.985_647_366_29 * (jd - 2_451_545.0);
    let (azimuth, geocentric) = horizontal(lat, decl, theta + lon - ra);
    let parallax = (6378.14 / distance).asin().to_degrees();
    let elevation = geocentric - parallax * cos(geocentric);
    // Phase angle from the elongation (Meeus 48.2 and 48.3, the sun 1 au away).
    let sun = apparent_longitude(jc);
    let psi = (cos(latitude) * cos(longitude - sun))
        .clamp(-1.0, 1.0)
        .acos();
    let r = 149_597_870.7;
    let i = (r * psi.sin()).atan2(distance - r * psi.cos());
    MoonPosition {
        azimuth,
        elevation,
        illuminated: (1.0 + i.cos()) / 2.0,
        longitude,
        latitude,
        distance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::solar::sun_position;

    /// Meeus's examples 47.a and 48.a: 1992 April 12, 0h TD (UTC here; ΔT ≈ 59 s moves the
    /// moon 0.01°): λ 133.162655°, β −3.229126°, Δ 368 409.7 km, illuminated 0.6786.
    #[test]
    fn meeus_examples() {
        let t = UtcTime::new(1992, 4, 12, 0.0).unwrap();
        let m = moon_position(t, 0.0, 0.0);
        eprintln!("{m:?}");
        assert!((m.longitude - 133.162_655).abs() < 0.08, "{m:?}");
        assert!((m.latitude + 3.229_126).abs() < 0.05, "{m:?}");
        assert!((m.distance - 368_409.7).abs() < 400.0, "{m:?}");
        assert!((m.illuminated - 0.6786).abs() < 0.005, "{m:?}");
    }

    /// At a full moon (2024 June 22, 01:08 UTC) it is lit whole and stands opposite the sun:
    /// rising as the sun sets, azimuths 180° apart within the moon's latitude and parallax.
    #[test]
    fn a_full_moon_stands_opposite_the_sun() {
        let t = UtcTime::new(2024, 6, 22, 3600.0 + 8.0 * 60.0).unwrap();
        for (lat, lon) in [(47.4, 9.5), (-33.9, 151.2), (34.5, -118.0)] {
            let m = moon_position(t, lat, lon);
            let (saz, sel) = sun_position(t, lat, lon);
            eprintln!("{lat}, {lon}: moon {m:?}, sun {saz:.2} {sel:.2}");
            assert!(m.illuminated > 0.995, "{m:?}");
            let daz = ((m.azimuth - saz).rem_euclid(360.0) - 180.0).abs();
            assert!(
                (m.elevation + sel).abs() < 7.0 && (daz < 12.0 || sel.abs() > 60.0),
                "{m:?} against the sun at {saz}, {sel}"
            );
        }
        // A new moon (2024 June 6, 12:38 UTC) is dark.
        let t = UtcTime::new(2024, 6, 6, 12.0 * 3600.0 + 38.0 * 60.0).unwrap();
        assert!(moon_position(t, 47.4, 9.5).illuminated < 0.005);
    }
}
