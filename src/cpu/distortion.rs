//! CPU reference of the per-frame distortion ray table: projector pixel → screen point (cached
//! while the projector is fixed) → unit direction from the eye, rotated into the world by the
//! vehicle attitude, plus each pixel's cone half-angle from its neighbours.

use crate::display::{Projector, Screen};
use crate::scene::attitude_basis;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// The screen point lit by each projector pixel (display frame), `None` where the pixel misses
/// the lens field or the screen. Depends only on the projector and the screen.
#[derive(Clone, Debug)]
pub struct ScreenPoints {
    pub width: u32,
    pub height: u32,
    /// Row-major from the top-left.
    pub points: Vec<Option<DVec3>>,
}

/// Screen points of a projector (pixel centres).
pub fn screen_points(screen: &Screen, projector: &Projector) -> ScreenPoints {
    let (w, h) = (projector.width, projector.height);
    let origin = DVec3::from(projector.position);
    let points = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let (x, y) = ((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
            projector
                .ray(x, y)
                .and_then(|d| screen.intersect(origin, d))
        })
        .collect();
    ScreenPoints {
        width: w,
        height: h,
        points,
    }
}

/// World-from-display rotation for a vehicle attitude (degrees): display x right, y forward,
/// z up map to the attitude's right, forward and up.
pub fn world_from_display(heading: f64, pitch: f64, roll: f64) -> DMat3 {
    let (right, down, fwd) = attitude_basis(heading, pitch, roll);
    DMat3::from_cols(right, fwd, -down)
}

/// One frame's ray table: per pixel the unit world direction and cone half-angle (radians),
/// `None` for pixels that show no screen (black).
#[derive(Clone, Debug)]
pub struct RayTable {
    pub width: u32,
    pub height: u32,
    pub rays: Vec<Option<(DVec3, f64)>>,
}

/// Computes the table for the eye at `eye` (display frame) and the given rotation.
pub fn ray_table(points: &ScreenPoints, eye: DVec3, world_from_display: DMat3) -> RayTable {
    let (w, h) = (points.width as i64, points.height as i64);
    let dir = |x: i64, y: i64| -> Option<DVec3> {
        if x < 0 || y < 0 || x >= w || y >= h {
            return None;
        }
        points.points[(y * w + x) as usize].map(|p| (world_from_display * (p - eye)).normalize())
    };
    let rays = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let (x, y) = (k % w, k / w);
            let d = dir(x, y)?;
            // Half the largest angle to a 4-neighbour that shows screen.
            let cone = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                .iter()
                .filter_map(|(dx, dy)| dir(x + dx, y + dy))
                .map(|n| 0.5 * d.angle_between(n))
                .fold(0.0, f64::max);
            Some((d, cone))
        })
        .collect();
    RayTable {
        width: points.width,
        height: points.height,
        rays,
    }
}

/// The projector image point (u, v) (pixel centres at +0.5) that lights screen point `s`: the
/// inverse of [`screen_points`]' mapping, through the lens inverse and, for a mirror dome, the
/// mirror point that reflects the projector onto `s`. `None` when the lens cannot reach `s` or
/// the projector's ray through (u, v) meets the screen elsewhere first.
pub fn projector_coord(screen: &Screen, projector: &Projector, s: DVec3) -> Option<(f64, f64)> {
    let origin = DVec3::from(projector.position);
    let aim = match screen {
        Screen::MirrorDome { .. } => screen.mirror_point(origin, s)?,
        _ => s,
    };
    let (u, v) = projector.pixel(aim - origin)?;
    let back = screen.intersect(origin, projector.ray(u, v)?)?;
    let scale = (s - origin).length().max(1.0);
    (back.distance(s) < 1e-6 * scale).then_some((u, v))
}
