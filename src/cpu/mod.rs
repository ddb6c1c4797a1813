//! CPU reference algorithms (f64). They answer queries (height of terrain, line of sight) and
//! are the oracle the GPU output is tested against. The traversal here is the same algorithm
//! as `gpu/shaders/terrain_traverse.wgsl`, step for step.

pub mod bodies;
pub mod clouds;
pub mod contact;
pub mod database;
pub mod distortion;
pub mod freeform;
pub mod march;
pub mod paged;
pub mod query;
pub mod traverse;
pub mod volume;
pub mod voxel;

pub use query::{
    cast_ray, cast_ray_seen_from, height_above_terrain, line_of_sight, sun_visible,
    sun_visible_seen_from, terrain_point_below,
};
pub use traverse::{GridRay, Hit, TraversalStats};
