//! WGSL sources. One file per pass; shared code lives in included files that are prepended
//! here (WGSL has no include directive), after the pass's compile-time switches
//! ([`super::variants`]).

use super::variants::{FfTables, ShadeFeatures, Switches, VolumeSwitches};

const FRAME: &str = include_str!("shaders/frame.wgsl");
const FULLSCREEN: &str = include_str!("shaders/fullscreen.wgsl");
const TRAVERSE: &str = include_str!("shaders/terrain_traverse.wgsl");
/// The paged terrain's reads (`cell_max`, `patch_corners`, `finest_resident`), an include;
/// with [`paged_pools`] (the pool's bindings and `paged_read`).
pub const TERRAIN_PAGED: &str = include_str!("shaders/terrain_paged.wgsl");

/// Most storage bindings a tile pool spans (bindings 3, 5, 6, 7 of group 3).
pub const MAX_POOL_BINDINGS: u32 = 4;

/// The tile pool's bindings and `paged_read(slot, i)` (float `i` of slot `slot`) for a pool of
/// `pools` buffers (1..=[`MAX_POOL_BINDINGS`]) of `2^PagedParams.pool_shift` whole slots
/// each: one buffer reads directly, several choose theirs per read.
pub fn paged_pools(pools: u32) -> String {
    let pools = pools.clamp(1, MAX_POOL_BINDINGS);
    let mut s = String::new();
    for k in 0..pools {
        let binding = if k == 0 { 3 } else { 4 + k };
        s += &format!(
            "@group(3) @binding({binding}) var<storage, read> paged_pool{k}: array<f32>;\n"
        );
    }
    if pools == 1 {
        s += "fn paged_read(slot: u32, i: u32) -> f32 {\n    return paged_pool0[slot * paged.slot_floats + i];\n}\n";
        return s;
    }
    // `pool_slots` is a power of two (`TerrainPool::new`): a shift and a mask, no division.
    s += "fn paged_read(slot: u32, i: u32) -> f32 {\n    let b = slot >> paged.pool_shift;\n    let k = (slot & ((1u << paged.pool_shift) - 1u)) * paged.slot_floats + i;\n    switch b {\n";
    for k in 1..pools {
        s += &format!("        case {k}u: {{ return paged_pool{k}[k]; }}\n");
    }
    s += "        default: { return paged_pool0[k]; }\n    }\n}\n";
    s
}
/// The traversal's window-relative storage interface over [`TERRAIN_PAGED`] (`PAGED` builds).
const TERRAIN_PAGED_WINDOW: &str = include_str!("shaders/terrain_paged_window.wgsl");
/// The traversal's storage interface over the heights and the pyramid (every other build).
const TERRAIN_MEMORY: &str = include_str!("shaders/terrain_memory.wgsl");
/// The cast pass's terrain storage (the tile and shade passes declare theirs).
const CAST_STORAGE: &str = "@group(0) @binding(1) var<storage, read> heights: array<f32>;\n\
                            @group(0) @binding(2) var<storage, read> pyramid: array<f32>;\n";
const GBUFFER: &str = include_str!("shaders/gbuffer.wgsl");
const RAY_TABLE: &str = include_str!("shaders/ray_table.wgsl");
/// A pixel's footprint for anti-aliasing's shadow searches (after RAY_TABLE and FRAME).
const FOOTPRINT: &str = include_str!("shaders/footprint.wgsl");
const FREEFORM: &str = include_str!("shaders/freeform.wgsl");
/// A pixel's cone against a box (`cone_box_span`), for the near-miss searches of free forms
/// and voxel models (after FRAME).
const CONE_BOX: &str = include_str!("shaders/cone_box.wgsl");
const FF_BINS: &str = include_str!("shaders/ff_bins.wgsl");
/// Constants shared by the binning pass and the passes reading its lists (`FF_BIN`,
/// `FF_OVERFLOW`).
pub const FF_CONSTS: &str = include_str!("shaders/ff_consts.wgsl");
const SRGB: &str = include_str!("shaders/srgb.wgsl");
const HAZE: &str = include_str!("shaders/haze.wgsl");
const CLOUDS: &str = include_str!("shaders/clouds.wgsl");
pub(crate) const VOXEL_DDA: &str = include_str!("shaders/voxel_dda.wgsl");
const VOLUME_TYPES: &str = include_str!("shaders/volume_types.wgsl");

/// Ray generation (compute): pinhole ray table.
pub fn raygen() -> String {
    [FULLSCREEN, include_str!("shaders/raygen.wgsl")].concat()
}

/// The traversal's switches: curved earth (`CURVED` in `terrain_traverse.wgsl`) and
/// footprint level of detail (`LOD`); the terrain in memory (`PAGED` false).
fn traverse_consts(curved: bool, lod: bool, near: bool) -> String {
    super::variants::wgsl_bools(&[
        ("CURVED", curved),
        ("LOD", lod),
        ("PAGED", false),
        ("NEAR", near),
    ])
}

/// Tile pre-pass (fragment); `curved`: the terrain's curved earth (see
/// [`super::variants::ShadeFeatures::curved`]).
pub fn tile(curved: bool) -> String {
    [
        &traverse_consts(curved, false, false),
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        TERRAIN_MEMORY,
        include_str!("shaders/tile_memory.wgsl"),
        TRAVERSE,
        include_str!("shaders/tile.wgsl"),
    ]
    .concat()
}

/// The paged tile pre-pass (`PAGED`): as [`tile`] with the terrain read from the tile pool
/// (group 3), the neighbourhood maxima cell by cell.
pub fn tile_paged(curved: bool, pools: u32) -> String {
    [
        &paged_prelude(curved, pools, false),
        include_str!("shaders/tile_paged.wgsl"),
        TRAVERSE,
        include_str!("shaders/tile.wgsl"),
    ]
    .concat()
}

/// What the paged passes (tile pre-pass, cast) start with: their switches (no footprint LOD;
/// `near` as in [`cast`]), the frame, the full-screen triangle, the ray table and the terrain
/// read from a pool of `pools` bindings through the window-relative interface.
fn paged_prelude(curved: bool, pools: u32, near: bool) -> String {
    let consts = super::variants::wgsl_bools(&[
        ("CURVED", curved),
        ("LOD", false),
        ("PAGED", true),
        ("NEAR", near),
    ]);
    [
        &consts,
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        TERRAIN_PAGED,
        &paged_pools(pools),
        TERRAIN_PAGED_WINDOW,
    ]
    .concat()
}

/// Terrain cast pass (fragment): traversal only, writes the G-buffer; `curved` as in
/// [`tile`]; `lod`: footprint level of detail compiled in (`render.lod`); `near`: near misses
/// within the pixel cone flagged (anti-aliasing's centre rays).
pub fn cast(curved: bool, lod: bool, near: bool) -> String {
    [
        &traverse_consts(curved, lod, near),
        FRAME,
        CAST_STORAGE,
        FULLSCREEN,
        RAY_TABLE,
        TERRAIN_MEMORY,
        TRAVERSE,
        GBUFFER,
        include_str!("shaders/cast.wgsl"),
    ]
    .concat()
}

/// The paged cast pass (`PAGED`): as [`cast`] with the terrain read from the tile pool
/// (group 3, `terrain_paged.wgsl`) and the paged stop rule; built by the renderer in paged
/// mode (`TerrainRenderer::new_paged`); `near` as in [`cast`].
pub fn cast_paged(curved: bool, pools: u32, near: bool) -> String {
    [
        &paged_prelude(curved, pools, near),
        TRAVERSE,
        GBUFFER,
        include_str!("shaders/cast.wgsl"),
    ]
    .concat()
}

/// The shade pass's terrain reads: the heights and the pyramid, or with `paged` the tile pool
/// (the window-relative interface and `sample_height` on the finest resident surface).
fn shade_terrain(paged: u32) -> String {
    if paged > 0 {
        [
            TERRAIN_PAGED,
            &paged_pools(paged),
            TERRAIN_PAGED_WINDOW,
            PAGED_SAMPLES,
        ]
        .concat()
    } else {
        TERRAIN_MEMORY.to_string()
    }
}

/// The shade pass's samples in the paged build: `shape_hint` takes the finest resident level
/// over the shaded cell from the G-buffer (`gbuffer_hint` in the cast pass), its tile and the
/// four tiles beside it on that level; `sample_height(i, j)` reads sample (i, j) of the window
/// on that level's bilinear surface, from the tile beside where the sample lies across the
/// edge (the normals' 4x4 neighbourhood reaches at most one tile over, along x or along y),
/// clamped to the shaded cell's tile where that one is not resident (a one-sided difference).
/// Loop-free.
const PAGED_SAMPLES: &str = "
var<private> paged_k: u32 = 0u;
var<private> paged_hint_slot: u32 = 0u;
var<private> paged_tile0: vec2<u32> = vec2<u32>(0u);
// The slots of the tiles west, east, south and north of the hint's (PAGED_NONE: not resident).
var<private> paged_side_slots: vec4<u32> = vec4<u32>(0u);

fn shape_hint(g: vec4<u32>, i: i32, j: i32) {
    let k = min(g.z >> 24u, paged.levels - 1u);
    let c = vec2<u32>(paged.origin_x + u32(i), paged.origin_y + u32(j)) >> vec2<u32>(k);
    let t = c >> vec2<u32>(paged.log2_n);
    let dl = paged.levels - 1u - k;
    let slot = paged_slot(dl, t.x, t.y);
    paged_k = k;
    paged_hint_slot = select(slot, 0u, slot == PAGED_NONE);
    paged_tile0 = t << vec2<u32>(paged.log2_n);
    // (t - 1 wraps past 0 to a tile no level has: PAGED_NONE.)
    paged_side_slots = vec4<u32>(
        paged_slot(dl, t.x - 1u, t.y),
        paged_slot(dl, t.x + 1u, t.y),
        paged_slot(dl, t.x, t.y - 1u),
        paged_slot(dl, t.x, t.y + 1u),
    );
}

fn sample_height(i: u32, j: u32) -> f32 {
    let n = f32(paged.tile_n);
    let g = vec2<f32>(vec2<u32>(paged.origin_x + i, paged.origin_y + j));
    let q = g / f32(1u << paged_k) - vec2<f32>(paged_tile0);
    let west = q.x < 0.0;
    let east = q.x > n;
    let south = q.y < 0.0;
    let north = q.y > n;
    var side = select(PAGED_NONE, paged_side_slots.x, west);
    side = select(side, paged_side_slots.y, east);
    side = select(side, paged_side_slots.z, south);
    side = select(side, paged_side_slots.w, north);
    let across = side != PAGED_NONE;
    let shift = vec2<f32>(select(select(0.0, -n, east), n, west), select(select(0.0, -n, north), n, south));
    let p = clamp(select(q, q + shift, across), vec2<f32>(0.0), vec2<f32>(n));
    let a = min(vec2<u32>(p), vec2<u32>(paged.tile_n - 1u));
    let uv = p - vec2<f32>(a);
    let slot = select(paged_hint_slot, side, across);
    // A sample of the level itself (uv 0: always on the finest level) is taken alone: a void
    // beside it (NaN, no source data: past the edge of the data) would make the weighted sum
    // NaN at weight 0.
    let h00 = paged_height(slot, a.x, a.y);
    let h01 = paged_height(slot, a.x, a.y + 1u);
    let s = select(mix(h00, paged_height(slot, a.x + 1u, a.y), uv.x), h00, uv.x == 0.0);
    let m = select(mix(h01, paged_height(slot, a.x + 1u, a.y + 1u), uv.x), h01, uv.x == 0.0);
    return select(mix(s, m, uv.y), s, uv.y == 0.0);
}
";

/// Shade pass (fragment): lighting, shadow rays, fog, sky from the G-buffer, with the
/// optional features `f` compiled in.
pub fn shade(f: ShadeFeatures) -> String {
    [
        &f.wgsl_constants(),
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        &shade_terrain(f.paged),
        TRAVERSE,
        FOOTPRINT,
        GBUFFER,
        SRGB,
        HAZE,
        CLOUDS,
        include_str!("shaders/shade.wgsl"),
        include_str!("shaders/shade_terrain_only.wgsl"),
    ]
    .concat()
}

/// Shade pass for scenes with free forms: as [`shade`], plus free-form shading and the
/// free-form shadow pass's answers; `tables`: see [`freeform`].
pub fn shade_objects(f: ShadeFeatures, tables: FfTables) -> String {
    [
        &f.wgsl_constants(),
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        &shade_terrain(f.paged),
        TRAVERSE,
        FOOTPRINT,
        GBUFFER,
        &freeform(false, tables),
        SRGB,
        HAZE,
        CLOUDS,
        include_str!("shaders/shade.wgsl"),
        include_str!("shaders/shade_objects.wgsl"),
    ]
    .concat()
}

/// The free-form intersection code. `small`: every perturbed object of the scene has at most
/// [`FF_RAY_NODES`] nodes, so the interval search keeps each node's along-ray quadratic for the
/// whole ray instead of reloading and recomputing it at every enclosure. `tables`: the buffers
/// the object records and quadrics are read from.
pub fn freeform(small: bool, tables: FfTables) -> String {
    let decl = match tables {
        FfTables::Uniform { objects, nodes } => format!(
            "@group(0) @binding(6) var<uniform> ff_objects: array<FfObject, {objects}>;\n\
             @group(0) @binding(7) var<uniform> ff_nodes: array<FfNode, {nodes}>;\n"
        ),
        FfTables::Storage => {
            "@group(0) @binding(6) var<storage, read> ff_objects: array<FfObject>;\n\
             @group(0) @binding(7) var<storage, read> ff_nodes: array<FfNode>;\n"
                .to_string()
        }
    };
    format!("const FF_SMALL: bool = {small};\n{decl}{CONE_BOX}{FREEFORM}")
}

/// Most nodes (base quadric and perturbations) of a perturbed object for the `small` free-form
/// code (`FF_RAY_NODES` in `freeform.wgsl`).
pub const FF_RAY_NODES: usize = 4;

/// Object binning (compute): per 16x16 bin, the free forms primary and shadow rays test;
/// `tables`: see [`freeform`].
pub fn ff_bin(tables: FfTables) -> String {
    [
        FRAME,
        RAY_TABLE,
        &freeform(false, tables),
        FF_CONSTS,
        FOOTPRINT,
        include_str!("shaders/ff_bin.wgsl"),
    ]
    .concat()
}

/// Free-form shadow pass (fragment): shadow rays against the bins' shadow lists; `small` and
/// `tables`: see [`freeform`].
pub fn ff_shadow(small: bool, tables: FfTables) -> String {
    [
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        &freeform(small, tables),
        FF_CONSTS,
        FF_BINS,
        FOOTPRINT,
        include_str!("shaders/ff_shadow.wgsl"),
    ]
    .concat()
}

/// Free-form cast pass (fragment): nearest free form in front of the terrain hit; `small` and
/// `tables`: see [`freeform`].
pub fn objects(small: bool, tables: FfTables) -> String {
    [
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        &freeform(small, tables),
        FF_CONSTS,
        FF_BINS,
        include_str!("shaders/objects.wgsl"),
    ]
    .concat()
}

/// Volume pass (fragment): integrates a density volume in front of the opaque depth and
/// composites it over the shaded image, with the sampling switches `sw` compiled in.
pub fn volume(sw: VolumeSwitches) -> String {
    [
        &sw.wgsl_constants(),
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        SRGB,
        HAZE,
        VOLUME_TYPES,
        include_str!("shaders/volume.wgsl"),
    ]
    .concat()
}

/// Volume composite pass (fragment): the `count` volumes' results sorted per pixel by the
/// medium's depth and composited over the shaded image.
pub fn volume_composite(count: u32) -> String {
    [
        &format!("const VOL_COUNT: u32 = {count}u;\n"),
        FRAME,
        FULLSCREEN,
        SRGB,
        HAZE,
        include_str!("shaders/volume_composite.wgsl"),
    ]
    .concat()
}

/// Volume-sun pass (fragment): per pixel, the sun's transmittance through one volume for the
/// opaque surface in the G-buffer.
pub fn volume_sun() -> String {
    [
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        VOLUME_TYPES,
        include_str!("shaders/volume_sun.wgsl"),
    ]
    .concat()
}

/// Voxel-model passes (fragment): hierarchical-DDA cast and shadow rays over rectangles, for
/// `instances` model instances (at most `voxel::desc::MAX_INSTANCES`, so the records always
/// fit a uniform buffer).
pub fn voxels(instances: u32) -> String {
    let n = instances.max(1);
    [
        &format!("@group(0) @binding(10) var<uniform> vox_instances: array<VoxInstance, {n}>;\n"),
        FRAME,
        FULLSCREEN,
        RAY_TABLE,
        CONE_BOX,
        VOXEL_DDA,
        include_str!("shaders/voxels.wgsl"),
    ]
    .concat()
}

/// Warp test pattern (fragment): colour from the ray table only.
pub fn pattern() -> String {
    [
        FULLSCREEN,
        RAY_TABLE,
        SRGB,
        include_str!("shaders/pattern.wgsl"),
    ]
    .concat()
}

/// Edge-blend pass (fragment): the finished image times each pixel's blend factor.
pub fn blend() -> String {
    [FULLSCREEN, SRGB, include_str!("shaders/blend.wgsl")].concat()
}

/// Edge anti-aliasing (`gpu::antialias`), fragment passes sharing `aa_common.wgsl`: the edge
/// mask, the sample rays, the resolve.
const AA_COMMON: &str = include_str!("shaders/aa_common.wgsl");

pub fn aa_edges() -> String {
    [FULLSCREEN, AA_COMMON, include_str!("shaders/aa_edges.wgsl")].concat()
}

pub fn aa_rays() -> String {
    [FULLSCREEN, AA_COMMON, include_str!("shaders/aa_rays.wgsl")].concat()
}

/// The list of marked pixels built on the GPU (compute, `gpu::antialias::gpu_list`).
pub fn aa_list() -> String {
    include_str!("shaders/aa_list.wgsl").to_string()
}

pub fn aa_resolve() -> String {
    [
        FULLSCREEN,
        SRGB,
        AA_COMMON,
        include_str!("shaders/aa_resolve.wgsl"),
    ]
    .concat()
}

/// The window's present pass (fragment): the colour target or a debug view of the data target
/// to the swap-chain image, with the text overlay.
pub fn present() -> String {
    [FULLSCREEN, SRGB, include_str!("shaders/present.wgsl")].concat()
}

/// The value of `const NAME: u32 = <decimal>u;` in WGSL `src`, evaluated at compile time to tie
/// a Rust constant to its WGSL twin (`const _: () = assert!(wgsl_u32(..) == RUST_CONST);`).
/// Panics (a compile error in a constant) when `src` has no such line.
pub const fn wgsl_u32(src: &str, name: &str) -> u32 {
    const fn starts_with(s: &[u8], at: usize, p: &[u8]) -> bool {
        if at + p.len() > s.len() {
            return false;
        }
        let mut k = 0;
        while k < p.len() {
            if s[at + k] != p[k] {
                return false;
            }
            k += 1;
        }
        true
    }
    let (s, n) = (src.as_bytes(), name.as_bytes());
    let mut i = 0;
    while i < s.len() {
        let at_line = i == 0 || s[i - 1] == b'\n';
        let mut j = i + 6;
        if at_line
            && starts_with(s, i, b"const ")
            && starts_with(s, j, n)
            && starts_with(s, j + n.len(), b": u32 = ")
        {
            j += n.len() + 8;
            let mut v: u32 = 0;
            let mut digits = 0;
            while j < s.len() && s[j].is_ascii_digit() {
                v = v * 10 + (s[j] - b'0') as u32;
                j += 1;
                digits += 1;
            }
            if digits > 0 && j < s.len() && s[j] == b'u' {
                return v;
            }
        }
        i += 1;
    }
    panic!("no `const NAME: u32 = <decimal>u;` line for the name in the WGSL source")
}

/// Every composed pass source with its name, for validation.
pub fn all() -> Vec<(&'static str, String)> {
    const UNIFORM: FfTables = FfTables::Uniform {
        objects: 56,
        nodes: 120,
    };
    vec![
        ("raygen", raygen()),
        ("tile", tile(false)),
        ("tile (curved)", tile(true)),
        ("cast", cast(false, false, false)),
        ("cast (curved)", cast(true, false, false)),
        ("cast (lod)", cast(false, true, false)),
        ("cast (curved, lod)", cast(true, true, false)),
        ("cast (near)", cast(false, false, true)),
        ("cast (curved, near)", cast(true, false, true)),
        ("cast (paged)", cast_paged(false, 1, false)),
        (
            "cast (curved, paged, 4 pool bindings)",
            cast_paged(true, 4, false),
        ),
        ("cast (paged, near)", cast_paged(false, 1, true)),
        (
            "cast (curved, paged, near, 2 pool bindings)",
            cast_paged(true, 2, true),
        ),
        ("tile (paged)", tile_paged(false, 1)),
        ("tile (curved, paged, 2 pool bindings)", tile_paged(true, 2)),
        ("shade", shade(ShadeFeatures::ALL)),
        ("shade (no options)", shade(ShadeFeatures::NONE)),
        (
            "shade (paged)",
            shade(ShadeFeatures {
                paged: 1,
                near: false,
                ..ShadeFeatures::ALL
            }),
        ),
        (
            "shade (paged, near)",
            shade(ShadeFeatures {
                paged: 2,
                lod: false,
                ..ShadeFeatures::ALL
            }),
        ),
        (
            "shade_objects (paged, 3 pool bindings)",
            shade_objects(
                ShadeFeatures {
                    paged: 3,
                    near: false,
                    ..ShadeFeatures::ALL
                },
                FfTables::Storage,
            ),
        ),
        (
            "shade_objects (paged, near)",
            shade_objects(
                ShadeFeatures {
                    paged: 1,
                    lod: false,
                    ..ShadeFeatures::ALL
                },
                UNIFORM,
            ),
        ),
        ("shade_objects", shade_objects(ShadeFeatures::ALL, UNIFORM)),
        (
            "shade_objects (no options, storage tables)",
            shade_objects(ShadeFeatures::NONE, FfTables::Storage),
        ),
        ("ff_bin", ff_bin(UNIFORM)),
        ("ff_bin (storage tables)", ff_bin(FfTables::Storage)),
        ("objects", objects(false, UNIFORM)),
        ("objects (small)", objects(true, UNIFORM)),
        (
            "objects (storage tables)",
            objects(false, FfTables::Storage),
        ),
        ("ff_shadow", ff_shadow(false, UNIFORM)),
        ("ff_shadow (small)", ff_shadow(true, UNIFORM)),
        (
            "ff_shadow (small, storage tables)",
            ff_shadow(true, FfTables::Storage),
        ),
        ("volume", volume(VolumeSwitches::ALL)),
        ("volume (no options)", volume(VolumeSwitches::NONE)),
        ("volume_sun", volume_sun()),
        ("volume_composite (1 volume)", volume_composite(1)),
        ("volume_composite (8 volumes)", volume_composite(8)),
        ("blend", blend()),
        ("aa_edges", aa_edges()),
        ("aa_rays", aa_rays()),
        ("aa_resolve", aa_resolve()),
        ("aa_list", aa_list()),
        ("voxels", voxels(2)),
        ("pattern", pattern()),
        ("present", present()),
    ]
}
