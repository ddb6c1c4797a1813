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

/// The directions a channel's rays take from an eye, as a cone (display frame): what the terrain
/// pager needs to want the tiles a channel sees, where no pinhole frustum describes them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayBundle {
    /// Unit mean direction of the rays (display frame).
    pub axis: DVec3,
    /// The largest angle between a ray and the axis (radians).
    pub half_angle: f64,
    /// The smallest angle between a ray and its right or lower neighbour (radians).
    pub pixel: f64,
}

impl ScreenPoints {
    /// The rays from `eye` through the lit screen points as a cone ([`RayBundle`]); `None`
    /// where no pixel lights the screen.
    pub fn ray_bundle(&self, eye: DVec3) -> Option<RayBundle> {
        let w = self.width as usize;
        let dir = |k: usize| {
            self.points[k]
                .map(|p| (p - eye).normalize())
                .filter(|d| d.is_finite())
        };
        let (sum, lit) = (0..self.points.len())
            .filter_map(dir)
            .fold((DVec3::ZERO, 0usize), |(s, n), d| (s + d, n + 1));
        if lit == 0 {
            return None;
        }
        // Rays all round (a full-sphere master) may have no mean: any axis, the cone then
        // opens to the whole sphere.
        let axis = sum.try_normalize().unwrap_or(DVec3::Y);
        let (mut half, mut pixel) = (0f64, f64::INFINITY);
        for k in 0..self.points.len() {
            let Some(d) = dir(k) else { continue };
            half = half.max(d.angle_between(axis));
            let right = (k % w + 1 < w).then(|| dir(k + 1)).flatten();
            let below = (k + w < self.points.len()).then(|| dir(k + w)).flatten();
            for n in [right, below].into_iter().flatten() {
                pixel = pixel.min(d.angle_between(n).max(1e-9));
            }
        }
        pixel = if pixel.is_finite() {
            pixel
        } else {
            half.max(1e-6)
        };
        Some(RayBundle {
            axis,
            half_angle: half,
            pixel,
        })
    }
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
