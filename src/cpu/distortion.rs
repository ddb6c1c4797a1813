//! CPU reference of the per-frame distortion ray table: projector pixel → screen point (cached
//! while the projector is fixed) → unit direction from the eye, rotated into the world by the
//! vehicle attitude, plus each pixel's cone half-angle from its neighbours.

use crate::display::screen_points::ScreenPoints;
/// World-from-display rotation for a vehicle attitude (degrees): display x right, y forward,
/// z up map to the attitude's right, forward and up.
pub use crate::geom::attitude_matrix as world_from_display;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

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
