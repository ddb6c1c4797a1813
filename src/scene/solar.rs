//! The sun's position for a date, a time of day (UTC) and a place: NOAA's solar calculator
//! equations (after Meeus, *Astronomical Algorithms*), good to about 0.01° for dates between
//! 1800 and 2100. Geometric position: no atmospheric refraction.

/// A calendar date and time of day, UTC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UtcTime {
    pub year: i32,
    /// 1..=12.
    pub month: u32,
    /// 1..=31.
    pub day: u32,
    /// Seconds since midnight (0..86400).
    pub seconds: f64,
}

impl UtcTime {
    /// A valid date (the day within its month, Gregorian leap years) and time of day.
    pub fn new(year: i32, month: u32, day: u32, seconds: f64) -> Option<UtcTime> {
        let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
        let days = match month {
            1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
            4 | 6 | 9 | 11 => 30,
            2 if leap => 29,
            2 => 28,
            _ => return None,
        };
        let ok = (1..=days).contains(&day) && (0.0..86400.0).contains(&seconds);
        ok.then_some(UtcTime {
            year,
            month,
            day,
            seconds,
        })
    }

    /// Julian day (Meeus, ch. 7; Gregorian calendar).
    pub fn julian_day(&self) -> f64 {
        let (mut y, mut m) = (f64::from(self.year), f64::from(self.month));
        if self.month <= 2 {
            y -= 1.0;
            m += 12.0;
        }
        let a = (y / 100.0).floor();
        let b = 2.0 - a + (a / 4.0).floor();
        (365.25 * (y + 4716.0)).floor() + (30.6001 * (m + 1.0)).floor() + f64::from(self.day) + b
            - 1524.5
            + self.seconds / 86400.0
    }
}

/// The sun's apparent ecliptic longitude (degrees) at `jc` Julian centuries from J2000.
pub fn apparent_longitude(jc: f64) -> f64 {
    let sin = |d: f64| d.to_radians().sin();
    let l0 = (280.46646 + jc * (36000.76983 + jc * 0.0003032)).rem_euclid(360.0);
    let m = 357.52911 + jc * (35999.05029 - 0.0001537 * jc);
    let c = sin(m) * (1.914602 - jc * (0.004817 + 0.000014 * jc))
        + sin(2.0 * m) * (0.019993 - 0.000101 * jc)
        + sin(3.0 * m) * 0.000289;
    let omega = 125.04 - 1934.136 * jc;
    l0 + c - 0.00569 - 0.00478 * sin(omega)
}

/// Azimuth (clockwise from true north, [0, 360)) and elevation (degrees) of a body at
/// declination `decl` and local hour angle `ha` (degrees, west positive) seen from latitude
/// `lat`.
pub fn horizontal(lat: f64, decl: f64, ha: f64) -> (f64, f64) {
    let (sin, cos) = (|d: f64| d.to_radians().sin(), |d: f64| d.to_radians().cos());
    let el = (sin(lat) * sin(decl) + cos(lat) * cos(decl) * cos(ha))
        .clamp(-1.0, 1.0)
        .asin()
        .to_degrees();
    let az = sin(ha)
        .atan2(cos(ha) * sin(lat) - decl.to_radians().tan() * cos(lat))
        .to_degrees();
    ((az + 180.0).rem_euclid(360.0), el)
}

/// The sun seen from latitude `lat`, longitude `lon` (degrees, east positive) at `t`:
/// `(azimuth, elevation)` in degrees, azimuth clockwise from true north in [0, 360),
/// elevation above the horizon (negative at night).
pub fn sun_position(t: UtcTime, lat: f64, lon: f64) -> (f64, f64) {
    let jc = (t.julian_day() - 2_451_545.0) / 36_525.0;
    let (sin, cos) = (|d: f64| d.to_radians().sin(), |d: f64| d.to_radians().cos());
    let l0 = (280.46646 + jc * (36000.76983 + jc * 0.0003032)).rem_euclid(360.0);
    let m = 357.52911 + jc * (35999.05029 - 0.0001537 * jc);
    let e = 0.016708634 - jc * (0.000042037 + 0.0000001267 * jc);
    let omega = 125.04 - 1934.136 * jc;
    let lambda = apparent_longitude(jc);
    let eps0 =
        23.0 + (26.0 + (21.448 - jc * (46.815 + jc * (0.00059 - jc * 0.001813))) / 60.0) / 60.0;
    let eps = eps0 + 0.00256 * cos(omega);
    let decl = (sin(eps) * sin(lambda)).asin().to_degrees();
    let y = (eps / 2.0).to_radians().tan().powi(2);
    let eot = 4.0
        * (y * sin(2.0 * l0) - 2.0 * e * sin(m) + 4.0 * e * y * sin(m) * cos(2.0 * l0)
            - 0.5 * y * y * sin(4.0 * l0)
            - 1.25 * e * e * sin(2.0 * m))
        .to_degrees();
    // True solar time (minutes) and the hour angle (degrees, 0 at local noon, west positive).
    let tst = (t.seconds / 60.0 + eot + 4.0 * lon).rem_euclid(1440.0);
    let ha = tst / 4.0 - 180.0;
    horizontal(lat, decl, ha)
}
