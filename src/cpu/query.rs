//! Terrain queries on the CPU: ray casting, height of terrain, height above terrain, line of
//! sight and sun visibility. All in world coordinates (metres).

use super::traverse::{intersect, make_hit, GridRay, Hit, TraversalStats};
use crate::terrain::Terrain;
use glam::DVec3;

/// Step limit used by the queries (far above what any real traversal needs).
pub const QUERY_MAX_STEPS: u32 = 1 << 20;

/// First hit of the ray `origin + t dir` (`dir` is normalised here) with `t` in `[t_min, t_max]`.
pub fn cast_ray(
    terrain: &Terrain,
    origin: DVec3,
    dir: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<Hit> {
    let dir = dir.normalize();
    let r = GridRay::from_world(terrain, origin, dir);
    let mut stats = TraversalStats::default();
    intersect(terrain, &r, t_min, t_max, QUERY_MAX_STEPS, &mut stats)
        .map(|(t, cell)| make_hit(terrain, &r, t, cell))
}

/// The terrain surface point on the base-plane normal through `p` (for the default horizontal
/// plane: the ground directly below or above `p`); `None` outside the height grid.
pub fn terrain_point_below(terrain: &Terrain, p: DVec3) -> Option<DVec3> {
    let g = terrain.frame.world_to_grid(p);
    let h = terrain.height_at_grid(g.x, g.y)?;
    Some(terrain.frame.grid_to_world(DVec3::new(g.x, g.y, h)))
}

/// Height of `p` above the terrain surface along the base-plane normal (negative below ground).
pub fn height_above_terrain(terrain: &Terrain, p: DVec3) -> Option<f64> {
    let g = terrain.frame.world_to_grid(p);
    terrain.height_at_grid(g.x, g.y).map(|h| g.z - h)
}

/// True when the segment from `a` to `b` does not touch the terrain. Touching at the very end
/// points (within `1e-6` of the length, at least 1 mm) does not count as blocking.
pub fn line_of_sight(terrain: &Terrain, a: DVec3, b: DVec3) -> bool {
    let d = b - a;
    let len = d.length();
    if len == 0.0 {
        return true;
    }
    let eps = (len * 1e-6).max(1e-3);
    cast_ray(terrain, a, d / len, eps, len - eps).is_none()
}

/// Offset (metres along the surface normal) from which shadow rays leave a surface point,
/// shared with the GPU shader so both sides agree on acne-free self-shadowing.
pub fn shadow_offset(terrain: &Terrain) -> f64 {
    0.02 * terrain.field.spacing[0].min(terrain.field.spacing[1])
        + 1e-4 * (terrain.max_height.abs() as f64)
}

/// True when the sun (unit direction `to_sun`) is visible from surface point `p` with normal `n`.
pub fn sun_visible(terrain: &Terrain, p: DVec3, n: DVec3, to_sun: DVec3) -> bool {
    if n.dot(to_sun) <= 0.0 {
        return false;
    }
    cast_ray(
        terrain,
        p + n * shadow_offset(terrain),
        to_sun,
        0.0,
        f64::INFINITY,
    )
    .is_none()
}
