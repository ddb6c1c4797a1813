//! WGSL sources. One file per pass; shared code lives in included files that are prepended
//! here (WGSL has no include directive).

const FRAME: &str = include_str!("shaders/frame.wgsl");
const FULLSCREEN: &str = include_str!("shaders/fullscreen.wgsl");
const TRAVERSE: &str = include_str!("shaders/terrain_traverse.wgsl");

/// Ray generation (compute): pinhole ray table.
pub fn raygen() -> String {
    include_str!("shaders/raygen.wgsl").to_string()
}

/// Tile pre-pass (fragment).
pub fn tile() -> String {
    [FRAME, FULLSCREEN, TRAVERSE, include_str!("shaders/tile.wgsl")].concat()
}

/// Terrain cast + shade pass (fragment).
pub fn terrain() -> String {
    [FRAME, FULLSCREEN, TRAVERSE, include_str!("shaders/terrain.wgsl")].concat()
}

/// Every composed pass source with its name, for validation.
pub fn all() -> Vec<(&'static str, String)> {
    vec![("raygen", raygen()), ("tile", tile()), ("terrain", terrain())]
}
