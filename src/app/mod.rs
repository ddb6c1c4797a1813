//! Application layer: headless capture, benchmark, command line.

pub mod bench;
pub mod capture;
pub mod view;
pub mod voxels;
pub mod warp;
