//! relief: a polygon-free terrain image generator.
//!
//! Layout: rooms in one layer order, imports pointing down (`tests/layers.rs` enforces it;
//! module map in `docs/architecture.md`):
//! * leaves: [`error`] (the error type), [`fileio`] (bounded reads, atomic writes), [`geom`]
//!   (attitudes and placements), [`geodesy`] (WGS84: geodetic ↔ ECEF, east-north-up frames,
//!   radii of curvature);
//! * model, no GPU types: [`terrain`] (height-field loaders, placement, maximum pyramid),
//!   [`db`] (the terrain database: DEMs compiled into one tiled multi-resolution file, read
//!   back in windows),
//!   [`freeform`] (quadric free forms), [`volume`] (density volumes), [`voxel`] (coloured voxel
//!   models), [`display`] (curved screens, projectors, warps), [`cigi`] (the CIGI 3.3 wire layer:
//!   packets, datagrams, the host's state as a `Session`);
//! * [`scene`]: the TOML scene (camera, sun, fog, output, path, the model tables);
//! * [`world`]: a scene's world loaded on the CPU, ready for the renderers;
//! * [`cpu`]: the f64 reference algorithms: they answer queries (height of terrain, line of
//!   sight) and are the oracle the GPU output is tested against;
//! * [`gpu`]: the wgpu passes and their WGSL;
//! * [`app`]: the commands of the `relief` binary (render, view, bench, warp, voxels).

pub mod app;
pub mod cigi;
pub mod colour;
pub mod cpu;
pub mod db;
pub mod display;
pub mod error;
pub mod fileio;
pub mod freeform;
pub mod geodesy;
pub mod geom;
pub mod gpu;
pub mod scene;
pub mod terrain;
pub mod volume;
pub mod voxel;
pub mod world;

pub use error::{Error, Result};
