//! Where each projector pixel lands on the screen (display frame), and back: the part of the
//! distortion table that depends only on the projector and the screen, computed once and
//! uploaded; the per-frame rays from the eye are [`crate::cpu::distortion::ray_table`] on the
//! CPU and the GPU ray-generation pass.

use super::{Projector, Screen};
use glam::DVec3;
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
