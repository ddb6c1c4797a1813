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

/// The heading, pitch and roll (degrees) of a rotation as [`attitude_matrix`] makes it (columns
/// right, forward, up): the inverse of `attitude_matrix` for pitch within (−90°, 90°); at ±90°
/// the roll is taken as 0. Heading in [0, 360).
pub fn attitude_angles(m: DMat3) -> (f64, f64, f64) {
    let (right, fwd) = (m.x_axis, m.y_axis);
    let pitch = fwd.z.clamp(-1.0, 1.0).asin();
    let horizontal = fwd.x.hypot(fwd.y);
    if horizontal < 1e-12 {
        // Straight up or down: the heading is where the up vector's opposite points.
        let up = m.z_axis * -pitch.signum();
        let heading = up.x.atan2(up.y).to_degrees().rem_euclid(360.0);
        return (heading, pitch.to_degrees(), 0.0);
    }
    let h = fwd.x.atan2(fwd.y);
    let right0 = DVec3::new(h.cos(), -h.sin(), 0.0);
    let up0 = right0.cross(fwd);
    let roll = (-right.dot(up0)).atan2(right.dot(right0));
    (
        h.to_degrees().rem_euclid(360.0),
        pitch.to_degrees(),
        roll.to_degrees(),
    )
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

/// What placing an object needs from the terrain: the ground below a point (for
/// `above_terrain`) and world positions of geodetic coordinates (for `geodetic`).
/// `terrain::Terrain` implements it.
pub trait Ground {
    /// World z of the terrain surface below `p`; `None` off the terrain.
    fn ground_z(&self, p: DVec3) -> Option<f64>;
    /// World position of `[lat, lon, alt]` (degrees, metres above mean sea level); errors
    /// name `field` (no geographic reference, not a position, off the terrain).
    fn geodetic_to_world(&self, field: &str, lla: [f64; 3]) -> Result<DVec3>;
}

/// A placed object's anchor: `position` (world metres) or `geodetic` (`[lat, lon, alt]`
/// through the terrain's geographic reference), exactly one of them; with `above_terrain`
/// set, the same x, y at that height above the ground. Errors name `field("position")`,
/// `field("geodetic")`, `field("position/geodetic")` or `field("above_terrain")`.
pub fn place(
    field: &dyn Fn(&str) -> String,
    position: Option<[f64; 3]>,
    geodetic: Option<[f64; 3]>,
    above_terrain: Option<f64>,
    ground: &dyn Ground,
) -> Result<DVec3> {
    let mut p = match (position, geodetic) {
        (Some(_), Some(_)) => {
            return Err(Error::invalid(
                field("position/geodetic"),
                "both are set: place the object by one of them, `position = [x, y, z]` \
                 (world metres) or `geodetic = [lat, lon, alt]` (degrees, metres above sea level)",
            ))
        }
        (None, None) => {
            return Err(Error::invalid(
                field("position/geodetic"),
                "neither is set: give `position = [x, y, z]` (world metres) or \
                 `geodetic = [lat, lon, alt]` (degrees, metres above sea level)",
            ))
        }
        (Some(pos), None) => {
            check_finite(&field("position"), &pos)?;
            DVec3::from(pos)
        }
        (None, Some(lla)) => ground.geodetic_to_world(&field("geodetic"), lla)?,
    };
    if let Some(agl) = above_terrain {
        check_finite(&field("above_terrain"), &[agl])?;
        let key = if geodetic.is_some() {
            "geodetic"
        } else {
            "position"
        };
        let z = ground.ground_z(p).ok_or_else(|| {
            Error::invalid(
                field(key),
                "above_terrain is set but the position is outside the terrain",
            )
        })?;
        p.z = z + agl;
    }
    Ok(p)
}
