//! Terrain queries on the CPU: ray casting, height of terrain, height above terrain, line of
//! sight and sun visibility. All in world coordinates (metres).
//!
//! Curved earth (`terrain.curved`): a query's world frame is the tangent frame of its own
//! origin (the ray's origin, the line of sight's first point), so [`cast_ray`] and
//! [`line_of_sight`] see the surface drop away from there; [`cast_ray_seen_from`] and
//! [`sun_visible_seen_from`] take a picture's curvature instead (shadow rays from its hits).
//! Heights of terrain and above terrain are along the base normal through the point and
//! above MSL: at the point itself the drop is 0, so curvature does not change them.

use super::traverse::{intersect_with_walls, make_hit, GridRay, Hit, TraversalStats};
use crate::terrain::curved::GridCurvature;
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
    let curv = terrain.curvature(origin);
    cast(terrain, curv, origin, dir, [t_min, t_max], terrain.walls)
}

/// [`cast_ray`] in the tangent frame of the eye whose curvature `curv` is
/// ([`Terrain::curvature`]): the rays of one picture, shadow rays included.
pub fn cast_ray_seen_from(
    terrain: &Terrain,
    curv: GridCurvature,
    origin: DVec3,
    dir: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<Hit> {
    cast(terrain, curv, origin, dir, [t_min, t_max], terrain.walls)
}

fn cast(
    terrain: &Terrain,
    curv: GridCurvature,
    origin: DVec3,
    dir: DVec3,
    [t_min, t_max]: [f64; 2],
    walls: bool,
) -> Option<Hit> {
    let dir = dir.normalize();
    let r = GridRay::seen_from(terrain, origin, dir, curv);
    let mut stats = TraversalStats::default();
    intersect_with_walls(
        terrain,
        &r,
        t_min,
        t_max,
        QUERY_MAX_STEPS,
        &mut stats,
        walls,
    )
    .map(|(t, cell)| make_hit(terrain, &r, t, cell))
}

/// The terrain surface point on the base-plane normal through `p` (for the default horizontal
/// plane: the ground directly below or above `p`); `None` outside the height grid.
pub fn terrain_point_below(terrain: &Terrain, p: DVec3) -> Option<DVec3> {
    terrain.point_below(p)
}

/// Height of `p` above the terrain surface along the base-plane normal (negative below ground).
pub fn height_above_terrain(terrain: &Terrain, p: DVec3) -> Option<f64> {
    terrain.height_above(p)
}

/// True when the segment from `a` to `b` does not touch the terrain. The terrain is solid
/// ground: a segment with any point below the surface over the height grid is blocked, so
/// one with an end point underground is blocked even where it never crosses the surface (it
/// may run below the lowest sample). Touching at the very end points (within `1e-6` of the
/// length, at least 1 mm) does not count as blocking. `terrain.walls` plays no part here.
pub fn line_of_sight(terrain: &Terrain, a: DVec3, b: DVec3) -> bool {
    let curv = terrain.curvature(a);
    // The segment in `a`'s tangent frame and metric: it still ends at `b`'s grid position.
    let d = curv.metric_vector(b - a);
    let len = d.length();
    let eps = (len * 1e-6).max(1e-3);
    // Where the segment is over the grid, it is underground from its first point there on
    // if that point is below the surface; otherwise only by crossing the surface downwards,
    // which the traversal finds.
    let (ga, gb) = (
        terrain.frame.world_to_grid(a),
        terrain.frame.world_to_grid(b),
    );
    let [cw, ch] = terrain.cells();
    let (mut s0, mut s1) = (0.0f64, 1.0f64);
    for (lo, hi, pa, pb) in [(0.0, cw as f64, ga.x, gb.x), (0.0, ch as f64, ga.y, gb.y)] {
        let dp = pb - pa;
        if dp == 0.0 {
            if pa < lo || pa > hi {
                return true;
            }
        } else {
            let (ta, tb) = ((lo - pa) / dp, (hi - pa) / dp);
            s0 = s0.max(ta.min(tb));
            s1 = s1.min(ta.max(tb));
        }
    }
    if s0 > s1 {
        return true; // never over the grid
    }
    let first = ga + (gb - ga) * s0;
    let ground =
        terrain.height_at_grid(first.x.clamp(0.0, cw as f64), first.y.clamp(0.0, ch as f64));
    if ground.is_some_and(|h| first.z + curv.drop(first.x, first.y) < h - eps) {
        return false;
    }
    if len == 0.0 {
        return true;
    }
    // Walls on: a segment entering the grid's box below the surface is blocked where it enters.
    cast(terrain, curv, a, d / len, [eps, len - eps], true).is_none()
}

/// True when `p` is over the height grid and more than 1 mm below the terrain surface.
pub fn is_underground(terrain: &Terrain, p: DVec3) -> bool {
    height_above_terrain(terrain, p).is_some_and(|h| h < -1e-3)
}

/// Offset (metres along the surface normal) from which shadow rays leave a surface point,
/// shared with the GPU shader so both sides agree on acne-free self-shadowing.
pub fn shadow_offset(terrain: &Terrain) -> f64 {
    0.02 * terrain.field.spacing[0].min(terrain.field.spacing[1])
        + 1e-4 * (terrain.max_height.abs() as f64)
}

/// True when the sun (unit direction `to_sun`) is visible from surface point `p` with normal `n`
/// (on a curved terrain in `p`'s own tangent frame; see [`sun_visible_seen_from`]).
pub fn sun_visible(terrain: &Terrain, p: DVec3, n: DVec3, to_sun: DVec3) -> bool {
    sun_visible_seen_from(terrain, terrain.curvature(p), p, n, to_sun)
}

/// [`sun_visible`] for a hit of a picture whose eye has curvature `curv` (the shade pass's
/// shadow ray: the same frame as the primary ray).
pub fn sun_visible_seen_from(
    terrain: &Terrain,
    curv: GridCurvature,
    p: DVec3,
    n: DVec3,
    to_sun: DVec3,
) -> bool {
    if n.dot(to_sun) <= 0.0 {
        return false;
    }
    cast_ray_seen_from(
        terrain,
        curv,
        p + n * shadow_offset(terrain),
        to_sun,
        0.0,
        f64::INFINITY,
    )
    .is_none()
}
