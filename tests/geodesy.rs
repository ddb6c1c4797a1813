//! WGS84 geodesy against published values and closed forms written here independently.

use glam::DVec3;
use relief::geodesy::{self, Geodetic};

#[test]
fn ecef_of_reference_points() {
    // The equator at the prime meridian, the pole, and (45°, 45°, 0): values in every
    // geodesy text (X = Y = N(45°)·cos²45°, Z = N(45°)(1 − e²)·sin 45°).
    let e = geodesy::to_ecef(Geodetic {
        lat: 0.0,
        lon: 0.0,
        height: 0.0,
    });
    assert!(
        (e - DVec3::new(6_378_137.0, 0.0, 0.0)).length() < 1e-6,
        "{e}"
    );
    let pole = geodesy::to_ecef(Geodetic {
        lat: 90.0,
        lon: 0.0,
        height: 0.0,
    });
    assert!(
        (pole.z - 6_356_752.314_245).abs() < 1e-5 && pole.x.abs() < 1e-6,
        "{pole}"
    );
    let p = geodesy::to_ecef(Geodetic {
        lat: 45.0,
        lon: 45.0,
        height: 0.0,
    });
    let want = DVec3::new(3_194_419.145, 3_194_419.145, 4_487_348.409);
    assert!((p - want).abs().max_element() < 2e-3, "{p} vs {want}");
    // Height adds along the normal.
    let up = geodesy::to_ecef(Geodetic {
        lat: 45.0,
        lon: 45.0,
        height: 1000.0,
    });
    let n = geodesy::enu_basis(45.0, 45.0).z_axis;
    assert!((up - p - n * 1000.0).length() < 1e-6);
}

#[test]
fn geodetic_round_trips_to_a_micrometre() {
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..100_000 {
        let g = Geodetic {
            lat: -90.0 + 180.0 * next(),
            lon: -180.0 + 360.0 * next(),
            height: -10_000.0 + 1_010_000.0 * next(),
        };
        let x = geodesy::to_ecef(g);
        let back = geodesy::from_ecef(x);
        assert!(
            (geodesy::to_ecef(back) - x).length() < 1e-6,
            "{g:?} -> {back:?}"
        );
        assert!((back.height - g.height).abs() < 1e-6, "{g:?} -> {back:?}");
    }
    let pole = geodesy::from_ecef(DVec3::new(0.0, 0.0, -6_356_752.314_245 - 50.0));
    assert!(
        pole.lat == -90.0 && (pole.height - 50.0).abs() < 1e-6,
        "{pole:?}"
    );
}

#[test]
fn radii_of_curvature_and_the_drop_below_a_tangent_plane() {
    // M and N at the equator and the pole: b²/a, a; a²/b, a²/b.
    let (a, b) = (6_378_137.0, 6_356_752.314_245_179);
    assert!((geodesy::meridional_radius(0.0) - b * b / a).abs() < 1e-6);
    assert!((geodesy::prime_vertical_radius(0.0) - a).abs() < 1e-6);
    assert!((geodesy::meridional_radius(90.0) - a * a / b).abs() < 1e-6);
    assert!((geodesy::prime_vertical_radius(90.0) - a * a / b).abs() < 1e-6);
    assert!(
        (geodesy::radius_in_azimuth(47.0, 0.0) - geodesy::meridional_radius(47.0)).abs() < 1e-6
    );
    assert!(
        (geodesy::radius_in_azimuth(47.0, 90.0) - geodesy::prime_vertical_radius(47.0)).abs()
            < 1e-6
    );
    // 100 km north along the surface from 47° N: the ellipsoid lies about d²/(2M) = 785 m
    // below the tangent plane (the figure), within the sphere approximation's error.
    let o = Geodetic {
        lat: 47.0,
        lon: 9.0,
        height: 0.0,
    };
    let m = geodesy::meridional_radius(47.0);
    let dlat = (100_000.0 / m).to_degrees();
    let far = geodesy::to_ecef(Geodetic {
        lat: 47.0 + dlat,
        lon: 9.0,
        height: 0.0,
    });
    let drop = -geodesy::height_above_tangent_plane(o, far);
    let sphere = m * (1.0 - (100_000.0 / m).cos());
    assert!(
        (drop - sphere).abs() < 0.5,
        "drop {drop} m, sphere of radius M {sphere} m"
    );
    assert!((drop - 785.0).abs() < 5.0, "drop {drop} m");
}
