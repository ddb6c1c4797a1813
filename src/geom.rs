//! Shared geometry of the model rooms: attitudes (heading, pitch, roll) and placements of
//! objects in the world, with the checks every description applies to them.
//!
//! World frame: metres, z up; heading 0 looks along +y and turns clockwise seen from above,
//! pitch raises the nose, roll lowers the right wing.

use crate::error::check_finite;
use crate::{Error, Result};
use glam::{DMat3, DVec3};

/// (right, down, forward) unit vectors of an attitude in degrees, in a frame whose z is up and
/// whose heading 0 looks along +y: heading turns clockwise seen from above, pitch raises the
/// nose, roll lowers the right wing.
pub fn attitude_basis(heading: f64, pitch: f64, roll: f64) -> (DVec3, DVec3, DVec3) {
    let (h, p, r) = (heading.to_radians(), pitch.to_radians(), roll.to_radians());
    let fwd = DVec3::new(h.sin() * p.cos(), h.cos() * p.cos(), p.sin());
    let right0 = DVec3::new(h.cos(), -h.sin(), 0.0);
    let up0 = right0.cross(fwd);
    let right = right0 * r.cos() - up0 * r.sin();
    let up = up0 * r.cos() + right0 * r.sin();
    (right, -up, fwd)
}

/// Rotation of an attitude (degrees): its columns are the body's x right, y forward and z up
/// in the world (for a display: world from display frame).
pub fn attitude_matrix(heading: f64, pitch: f64, roll: f64) -> DMat3 {
    let (right, down, fwd) = attitude_basis(heading, pitch, roll);
    DMat3::from_cols(right, fwd, -down)
}

/// [`attitude_matrix`] after checking the angles are finite; the error names
/// `field("heading/pitch/roll")`.
pub fn checked_attitude(
    field: &dyn Fn(&str) -> String,
    heading: f64,
    pitch: f64,
    roll: f64,
) -> Result<DMat3> {
    check_finite(&field("heading/pitch/roll"), &[heading, pitch, roll])?;
    Ok(attitude_matrix(heading, pitch, roll))
}

/// A placed object's position: `position` (world metres), or with `above_terrain` set, the
/// same x, y at that height above the ground, where `ground(p)` is the terrain height below
/// `p` (`None` off the terrain). Errors name `field("position")` / `field("above_terrain")`.
pub fn place_above_ground(
    field: &dyn Fn(&str) -> String,
    position: [f64; 3],
    above_terrain: Option<f64>,
    ground: impl Fn(DVec3) -> Option<f64>,
) -> Result<DVec3> {
    check_finite(&field("position"), &position)?;
    let mut p = DVec3::from(position);
    if let Some(agl) = above_terrain {
        check_finite(&field("above_terrain"), &[agl])?;
        let z = ground(p).ok_or_else(|| {
            Error::invalid(
                field("position"),
                "above_terrain is set but the position is outside the terrain",
            )
        })?;
        p.z = z + agl;
    }
    Ok(p)
}
