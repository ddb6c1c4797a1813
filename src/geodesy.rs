//! WGS84 geodesy for the curved earth: geodetic (latitude, longitude, height above the
//! ellipsoid) ↔ earth-centred earth-fixed (ECEF) coordinates, the local east-north-up frame,
//! the radii of curvature, and the drop of the ellipsoid below a tangent plane.
//!
//! Angles in degrees, lengths in metres. Heights here are above the ellipsoid; the terrain
//! database holds heights above mean sea level (the geoid), which differ by the geoid
//! undulation (within ±110 m worldwide, slowly varying).

use glam::{DMat3, DVec3};

/// WGS84 semi-major axis (m).
pub const A: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const F: f64 = 1.0 / 298.257_223_563;
/// WGS84 semi-minor axis (m).
pub const B: f64 = A * (1.0 - F);
/// First eccentricity squared.
pub const E2: f64 = F * (2.0 - F);

/// A point given by geodetic latitude and longitude (degrees) and height above the ellipsoid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geodetic {
    pub lat: f64,
    pub lon: f64,
    pub height: f64,
}

/// Prime-vertical radius of curvature N(φ) (m): east-west, and the distance from the surface
/// to the polar axis along the normal.
pub fn prime_vertical_radius(lat: f64) -> f64 {
    let s = lat.to_radians().sin();
    A / (1.0 - E2 * s * s).sqrt()
}

/// Meridional radius of curvature M(φ) (m): north-south.
pub fn meridional_radius(lat: f64) -> f64 {
    let s = lat.to_radians().sin();
    A * (1.0 - E2) / (1.0 - E2 * s * s).powf(1.5)
}

/// Radius of curvature of the normal section at azimuth `azimuth` (degrees from true north,
/// clockwise) — Euler's formula `1/R = cos²α/M + sin²α/N`.
pub fn radius_in_azimuth(lat: f64, azimuth: f64) -> f64 {
    let (s, c) = azimuth.to_radians().sin_cos();
    1.0 / (c * c / meridional_radius(lat) + s * s / prime_vertical_radius(lat))
}

/// ECEF position of a geodetic point.
pub fn to_ecef(p: Geodetic) -> DVec3 {
    let (sl, cl) = p.lat.to_radians().sin_cos();
    let (so, co) = p.lon.to_radians().sin_cos();
    let n = prime_vertical_radius(p.lat);
    DVec3::new(
        (n + p.height) * cl * co,
        (n + p.height) * cl * so,
        (n * (1.0 - E2) + p.height) * sl,
    )
}

/// ECEF position of geodetic `[lat, lon, height]` (degrees, metres): [`to_ecef`] of an array.
pub fn ecef_of([lat, lon, height]: [f64; 3]) -> DVec3 {
    to_ecef(Geodetic { lat, lon, height })
}

/// Geodetic `[lat, lon, height]` of ECEF `x`: [`from_ecef`] as an array.
pub fn lla_of(x: DVec3) -> [f64; 3] {
    let g = from_ecef(x);
    [g.lat, g.lon, g.height]
}

/// Geodetic coordinates of an ECEF position: Bowring's formula, then four fixed-point steps
/// `φ = atan(z / (p·(1 − e²·N/(N + h))))` (below a micrometre for heights from −100 km to the
/// Moon's distance; tested to 1e-6 m from −10 km to 1000 km).
pub fn from_ecef(x: DVec3) -> Geodetic {
    let lon = x.y.atan2(x.x);
    let p = (x.x * x.x + x.y * x.y).sqrt();
    if p < 1e-9 {
        // On the polar axis.
        let lat = if x.z >= 0.0 { 90.0 } else { -90.0 };
        return Geodetic {
            lat,
            lon: 0.0,
            height: x.z.abs() - B,
        };
    }
    let ep2 = E2 / (1.0 - E2);
    let theta = (x.z * A).atan2(p * B);
    let (st, ct) = theta.sin_cos();
    let mut lat = (x.z + ep2 * B * st * st * st).atan2(p - E2 * A * ct * ct * ct);
    for _ in 0..4 {
        let (sl, cl) = lat.sin_cos();
        let n = A / (1.0 - E2 * sl * sl).sqrt();
        let h = p * cl + x.z * sl - A * (1.0 - E2 * sl * sl).sqrt();
        lat = (x.z / (p * (1.0 - E2 * n / (n + h)))).atan();
    }
    let (sl, cl) = lat.sin_cos();
    let height = p * cl + x.z * sl - A * (1.0 - E2 * sl * sl).sqrt();
    Geodetic {
        lat: lat.to_degrees(),
        lon: lon.to_degrees(),
        height,
    }
}

/// Columns east, north, up of the local tangent frame at (lat, lon), in ECEF.
pub fn enu_basis(lat: f64, lon: f64) -> DMat3 {
    let (sl, cl) = lat.to_radians().sin_cos();
    let (so, co) = lon.to_radians().sin_cos();
    DMat3::from_cols(
        DVec3::new(-so, co, 0.0),
        DVec3::new(-sl * co, -sl * so, cl),
        DVec3::new(cl * co, cl * so, sl),
    )
}

/// Height of the ECEF point `x` above the tangent plane of the ellipsoid at `origin` (its up
/// vector at the origin's latitude, longitude; the plane through the origin point): for a
/// point on the ellipsoid far from the origin this is minus the curvature drop.
pub fn height_above_tangent_plane(origin: Geodetic, x: DVec3) -> f64 {
    let up = enu_basis(origin.lat, origin.lon).z_axis;
    (x - to_ecef(origin)).dot(up)
}

/// The curved earth seen from one point: the osculating paraboloid of the ellipsoid at the
/// point's foot, `drop(e, n) = e²/(2N) + n²/(2M)` metres below the tangent plane at horizontal
/// offsets `e` (east) and `n` (north) metres, with the radii of curvature at the point's
/// latitude (Euler: the normal section in any azimuth has curvature `cos²α/M + sin²α/N`).
///
/// Against the exact ellipsoid this drops the quartic term (`r⁴/8R³`: 0.8 m at 200 km) and the
/// change of the radii with latitude (≈ 0.3 m at 200 km at mid latitudes): below a metre up to
/// 200 km, 0.02 arc-minutes of elevation there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Curvature {
    /// `1/(2N)` (per metre): the drop per square metre of eastward offset.
    pub east: f64,
    /// `1/(2M)` (per metre): the drop per square metre of northward offset.
    pub north: f64,
}

impl Curvature {
    /// The paraboloid at geodetic latitude `lat` (degrees).
    pub fn at(lat: f64) -> Curvature {
        Curvature {
            east: 0.5 / prime_vertical_radius(lat),
            north: 0.5 / meridional_radius(lat),
        }
    }
    /// No curvature (a flat earth).
    pub const FLAT: Curvature = Curvature {
        east: 0.0,
        north: 0.0,
    };
    /// Drop (m) of the surface below the tangent plane at offsets `east`, `north` (m).
    pub fn drop(&self, east: f64, north: f64) -> f64 {
        self.east * east * east + self.north * north * north
    }
}
