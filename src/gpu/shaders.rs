//! WGSL sources. One file per pass; shared code lives in included files that are prepended
//! here (WGSL has no include directive).

const FRAME: &str = include_str!("shaders/frame.wgsl");
const FULLSCREEN: &str = include_str!("shaders/fullscreen.wgsl");
const TRAVERSE: &str = include_str!("shaders/terrain_traverse.wgsl");
const GBUFFER: &str = include_str!("shaders/gbuffer.wgsl");
const RAY_TABLE: &str = include_str!("shaders/ray_table.wgsl");

/// Ray generation (compute): pinhole ray table.
pub fn raygen() -> String {
    [FULLSCREEN, include_str!("shaders/raygen.wgsl")].concat()
}

/// Tile pre-pass (fragment).
pub fn tile() -> String {
    [
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        TRAVERSE,
        include_str!("shaders/tile.wgsl"),
    ]
    .concat()
}

/// Terrain cast pass (fragment): traversal only, writes the G-buffer.
pub fn cast() -> String {
    [
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        TRAVERSE,
        GBUFFER,
        include_str!("shaders/cast.wgsl"),
    ]
    .concat()
}

/// Shade pass (fragment): lighting, shadow rays, fog, sky from the G-buffer.
pub fn shade() -> String {
    [
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        TRAVERSE,
        GBUFFER,
        include_str!("shaders/shade.wgsl"),
    ]
    .concat()
}

/// Every composed pass source with its name, for validation.
pub fn all() -> Vec<(&'static str, String)> {
    vec![
        ("raygen", raygen()),
        ("tile", tile()),
        ("cast", cast()),
        ("shade", shade()),
    ]
}
