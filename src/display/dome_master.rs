//! Dome masters: the fulldome content format, an angular (equidistant) fisheye of `fov`
//! degrees (180 for a hemisphere) in a square image; the zenith at the centre, the front (display
//! +y) at the bottom, display +x to the right. Radius in the image is proportional to the
//! angle from the zenith.

use crate::{Error, Result};
use glam::DVec3;

/// Display-frame unit direction of the point (x, y) (pixels, continuous, row 0 at the top)
/// of a `size x size` dome master of `fov` degrees; `None` outside the fisheye circle.
pub fn direction(x: f64, y: f64, size: u32, fov: f64) -> Option<DVec3> {
    let half = 0.5 * size as f64;
    let u = (x - half) / half;
    let v = (y - half) / half;
    let r = u.hypot(v);
    if r > 1.0 {
        return None;
    }
    let theta = r * 0.5 * fov.to_radians();
    if r == 0.0 {
        return Some(DVec3::Z);
    }
    let s = theta.sin() / r;
    Some(DVec3::new(u * s, v * s, theta.cos()))
}

/// The dome-master point (pixels, continuous) of a display-frame direction; `None` beyond the
/// fisheye's field.
pub fn pixel(d: DVec3, size: u32, fov: f64) -> Option<(f64, f64)> {
    let d = d.try_normalize()?;
    let theta = d.z.clamp(-1.0, 1.0).acos();
    let r = theta / (0.5 * fov.to_radians());
    if r > 1.0 {
        return None;
    }
    let rho = d.x.hypot(d.y);
    let half = 0.5 * size as f64;
    if rho == 0.0 {
        return Some((half, half));
    }
    Some((half + half * r * d.x / rho, half + half * r * d.y / rho))
}

/// Checks a dome-master field of view; `field` names the option.
pub fn check_fov(field: &str, fov: f64) -> Result<()> {
    if fov.is_finite() && fov > 0.0 && fov <= 360.0 {
        Ok(())
    } else {
        Err(Error::invalid(
            field,
            format!("dome-master field of view must be in (0, 360] degrees, got {fov}"),
        ))
    }
}
