// Shared declarations: the per-frame uniform block (mirrored by `gpu::types::FrameUniforms`).

struct Frame {
    // Eye position in the grid frame (x, y in samples, z in metres along the base normal).
    eye: vec4<f32>,
    // Rows of the linear map world direction -> grid direction (t stays in metres).
    grid_from_world_0: vec4<f32>,
    grid_from_world_1: vec4<f32>,
    grid_from_world_2: vec4<f32>,
    // Rows of the rotation world -> metric local frame (axis_x, axis_y, normal).
    local_from_world_0: vec4<f32>,
    local_from_world_1: vec4<f32>,
    local_from_world_2: vec4<f32>,
    // Sun direction in the local frame; w = intensity.
    sun_local: vec4<f32>,
    // Sun direction in the grid frame (for shadow rays).
    sun_grid: vec4<f32>,
    // Sun colour (linear); w = cosine of the sun disc's angular radius.
    sun_colour: vec4<f32>,
    // World up in the local frame.
    up_local: vec4<f32>,
    // Sky colours (linear); zenith.w = ambient strength.
    sky_zenith: vec4<f32>,
    sky_horizon: vec4<f32>,
    // Haze colour (linear); w = extinction per metre at the base plane (0 = no fog).
    fog_colour: vec4<f32>,
    // x = haze scale height in metres (0 = uniform).
    fog: vec4<f32>,
    // Sample spacing: sx, sy, 1/sx, 1/sy (metres).
    spacing: vec4<f32>,
    // min height, max height, shadow-ray offset (m), height slack (m) added to box and cell maxima.
    heights_range: vec4<f32>,
    // Drape texel = offset + scale * grid: offset.xy, scale.xy.
    drape_map: vec4<f32>,
    // width, height, tiles x, tiles y.
    size: vec4<u32>,
    // samples x, samples y, pyramid levels, unused (the shade pass is built with or without
    // the drape, see gpu::shade).
    grid: vec4<u32>,
    // x: 0 = pyramid traversal, 1 = fixed-step march; y: max steps; z: 1 = terrain without
    // side walls (terrain.walls = false: rays below the surface where they enter the box pass
    // under it), 0 = walls (the default); w: tile pre-pass on.
    mode: vec4<u32>,
    // drape width, height, mip levels (level l follows level l - 1 in `drape`, each side
    // halved rounding up).
    drape_size: vec4<u32>,
    // x: march step in cells, y: bisection count.
    march: vec4<f32>,
    // x: side N of the square power-of-two pyramid's level 0 (level L has side N >> L).
    pyramid_dims: vec4<u32>,
    // World-frame eye (free forms live in world coordinates).
    eye_world: vec4<f32>,
    // World-frame unit vector towards the sun.
    sun_world: vec4<f32>,
    // x: free-form count, y, z: object bins across and down, w: bin capacity.
    objects: vec4<u32>,
    // x: this frame's stamp (never 0; the free-form shadow pass marks blocked pixels with it,
    // so its target needs no clear); y: 1 in the anti-aliasing sample atlas (neighbouring
    // entries need not be neighbouring rays: free-form bins bound every ray); z: 1 for the
    // centre rays of an anti-aliased frame (free forms missed within the pixel cone are
    // flagged, `ff_plain_near`); w: unused.
    stamp: vec4<u32>,
    // Curved earth (`CURVED` pipelines): eye grid x, y; drop per squared grid step along x, y
    // (metres): the datum lies k.x (x - ex)^2 + k.y (y - ey)^2 below the eye's tangent plane.
    curvature: vec4<f32>,
    // Footprint level of detail (`LOD` pipelines): x = lod scale * 2 / larger sample spacing
    // (m), times a pixel's cone half-angle: `lod_k` of `lod_stops`; 0 = off.
    lod: vec4<f32>,
    // Cloud layers (`CLOUDS` pipelines, clouds.wgsl): layer k is clouds[2k] = (base, top,
    // extinction, threshold), clouds[2k + 1] = (mean density, 1 / feature, seed, relief).
    clouds: array<vec4<f32>, 6>,
    // x: layers, y, z: grid spacing in metres (the clouds' pattern is fixed to the ground).
    cloud_info: vec4<f32>,
    // Per level: cells x, cells y, row stride, offset into `pyramid`.
    levels: array<vec4<u32>, 16>,
}

// Pixels per screen tile side in the tile pre-pass.
const TILE: u32 = 8u;
// Finite stand-ins for infinity (WGSL lets drivers assume no Inf/NaN).
const BIG: f32 = 1.0e30;
const PAD: f32 = -1.0e30;
