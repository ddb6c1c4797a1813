//! Application layer: headless capture, benchmark, command line.

pub mod bench;
pub mod capture;
pub mod soak;
pub mod verify;
pub mod view;
pub mod volumes;
pub mod voxels;
pub mod warp;
