//! relief: a polygon-free terrain image generator.
//!
//! Layout (each folder is one layer of the data flow):
//! * [`scene`]: the TOML scene model (camera, sun, fog, output, camera path). No GPU types.
//! * [`terrain`]: height-field loaders (SRTM `.hgt`, GeoTIFF, 16-bit PNG, procedural),
//!   placement in the world and the maximum-LOD pyramid.
//! * [`db`]: the terrain database: DEMs compiled into one tiled multi-resolution file, its
//!   reader and windows of it as height fields.
//! * [`cpu`]: the CPU reference algorithms (f64): ray–terrain traversal, queries
//!   (height of terrain, line of sight), dense marching oracle. These answer queries and are
//!   the oracle the GPU output is tested against.
//! * [`freeform`]: quadric free forms with recursive perturbations (model, scene tables).
//! * [`volume`]: density volumes (NRRD, raw, procedural), transfer functions, brick grid.
//! * [`voxel`]: coloured voxel models (`.vox` import, segment format, brick grid, scene tables).
//! * [`display`]: curved-screen display model (screen, projectors, eye) for pre-distortion.
//! * [`world`]: a scene's world loaded on the CPU (terrain and pyramid, free forms, volumes,
//!   voxel models), ready for the renderers.
//! * [`gpu`]: wgpu passes (ray generation, tile pre-pass, terrain cast + shade) and readback.
//! * [`app`]: headless capture, benchmark and command-line front end.
//! * [`fileio`]: bounded reads (memory budget, declared vs actual sizes) and atomic writes.

pub mod app;
pub mod cpu;
pub mod db;
pub mod display;
pub mod error;
pub mod fileio;
pub mod freeform;
pub mod geom;
pub mod gpu;
pub mod scene;
pub mod terrain;
pub mod volume;
pub mod voxel;
pub mod world;

pub use error::{Error, Result};
