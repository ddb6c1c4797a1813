//! Dense fixed-step marching with bisection: an independent (slow) oracle for tests.

use super::traverse::{clip_to_box, GridRay};
use crate::terrain::Terrain;
use glam::DVec3;

/// First crossing of the surface found by stepping `step_cells` grid cells at a time (measured
/// along the larger horizontal axis) and refining by bisection to f64 precision.
/// Returns the distance in metres along the unit world ray.
pub fn march(
    terrain: &Terrain,
    origin: DVec3,
    dir: DVec3,
    t_max: f64,
    step_cells: f64,
) -> Option<f64> {
    let r = GridRay::from_world(terrain, origin, dir.normalize());
    let (t0, t1) = clip_to_box(terrain, &r, 0.0, t_max)?;
    let f = |t: f64| {
        let p = r.at(t);
        terrain
            .height_at_grid(p.x, p.y)
            .map(|h| p.z + r.curv.drop(p.x, p.y) - h)
    };
    let dt = step_cells / r.d.x.abs().max(r.d.y.abs()).max(1e-9);
    let mut prev_t = t0;
    if f(t0).is_some_and(|v| v <= 0.0) {
        return Some(t0);
    }
    let mut k = 1u64;
    loop {
        let t = (t0 + dt * k as f64).min(t1);
        if let Some(v) = f(t) {
            if v <= 0.0 {
                let (mut lo, mut hi) = (prev_t, t);
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if mid <= lo || mid >= hi {
                        break;
                    }
                    if f(mid).is_some_and(|v| v <= 0.0) {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                return Some(hi);
            }
        }
        if t >= t1 {
            return None;
        }
        prev_t = t;
        k += 1;
    }
}
