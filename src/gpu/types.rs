//! `#[repr(C)]` GPU structs. Each mirrors a WGSL struct named in its doc comment.

use bytemuck::{Pod, Zeroable};

/// Maximum pyramid levels the shaders address (`Frame.levels` length).
pub const MAX_LEVELS: usize = 16;

/// Mirrors WGSL `Frame` in `shaders/frame.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniforms {
    pub eye: [f32; 4],
    pub grid_from_world: [[f32; 4]; 3],
    pub local_from_world: [[f32; 4]; 3],
    pub sun_local: [f32; 4],
    pub sun_grid: [f32; 4],
    pub sun_colour: [f32; 4],
    pub up_local: [f32; 4],
    pub sky_zenith: [f32; 4],
    pub sky_horizon: [f32; 4],
    pub fog_colour: [f32; 4],
    pub fog: [f32; 4],
    pub spacing: [f32; 4],
    pub heights_range: [f32; 4],
    pub drape_map: [f32; 4],
    pub size: [u32; 4],
    pub grid: [u32; 4],
    pub mode: [u32; 4],
    pub drape_size: [u32; 4],
    pub march: [f32; 4],
    pub pyramid_dims: [u32; 4],
    pub eye_world: [f32; 4],
    pub sun_world: [f32; 4],
    pub objects: [u32; 4],
    pub stamp: [u32; 4],
    /// Curved earth: eye grid x, y, `GridCurvature::k` x, y (zero on a flat terrain).
    pub curvature: [f32; 4],
    /// Footprint LOD: x = `render.lod` scale · 2 / larger spacing (0: off), yzw unused.
    pub lod: [f32; 4],
    /// Cloud layers (`cpu::clouds::Deck`): two rows each, (base, top, extinction,
    /// threshold) and (mean density, 1 / feature, seed, relief).
    pub clouds: [[f32; 4]; 2 * crate::scene::clouds::MAX_CLOUD_LAYERS],
    /// Layers, grid spacing x, y (m), unused.
    pub cloud_info: [f32; 4],
    pub levels: [[u32; 4]; MAX_LEVELS],
}

/// Mirrors WGSL `RayGen` in `shaders/raygen.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct RayGenUniforms {
    pub right: [f32; 4],
    pub down: [f32; 4],
    pub forward: [f32; 4],
    pub intrinsics: [f32; 4],
    pub size: [u32; 4],
    pub eye: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<FrameUniforms>() == 16 * (37 + MAX_LEVELS));
const _: () = assert!(std::mem::size_of::<RayGenUniforms>() == 96);

/// Mirrors WGSL `FfObject` in `shaders/freeform.wgsl`: one placed free form.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FfObjectGpu {
    /// Rows of the object-from-world rotation; `[0][3]`: a bound on `|∇F'|` over the box
    /// widened by `[1][3]` metres (`FreeForm::gradient_bound`, anti-aliasing's near misses).
    pub local_from_world: [[f32; 4]; 3],
    /// World position of the object origin; w = shadow-ray offset (m).
    pub position: [f32; 4],
    /// Bounding box in the object frame; w = f32 bits of the first node / node count.
    pub box_min: [f32; 4],
    pub box_max: [f32; 4],
    /// Linear RGB; w = specular exponent.
    pub colour: [f32; 4],
    /// Qa, Qd, Qs; 1 for a convex solid (`FreeForm::is_convex`), else 0.
    pub material: [f32; 4],
    /// World bounding sphere: centre, radius.
    pub sphere: [f32; 4],
}

/// Mirrors WGSL `FfNode` in `shaders/freeform.wgsl`: one quadric of a perturbation tree.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FfNodeGpu {
    /// A, B, C, D.
    pub q0: [f32; 4],
    /// E, F, G, H.
    pub q1: [f32; 4],
    /// I, K, weight, depth.
    pub q2: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<FfObjectGpu>() == 144);
const _: () = assert!(std::mem::size_of::<FfNodeGpu>() == 48);

/// Mirrors WGSL `Volume` in `shaders/volume_types.wgsl`: one density volume's placement, grid and
/// switches for the volume pass.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct VolumeUniforms {
    /// Eye in the volume frame (metres from the box corner); w = step in metres.
    pub eye_local: [f32; 4],
    /// Rows of the rotation world -> volume frame.
    pub local_from_world: [[f32; 4]; 3],
    /// Columns of the rotation volume frame -> world (the volume's axes in the world).
    pub world_from_local: [[f32; 4]; 3],
    /// Box size in metres; w = smallest voxel side in metres.
    pub extent: [f32; 4],
    /// Voxel spacing in metres; w = transmittance below which a ray stops.
    pub spacing: [f32; 4],
    /// Voxels x, y, z; mip levels.
    pub dims: [u32; 4],
    /// Bricks x, y, z; switches (1 skip, 2 early termination, 4 jitter, 8 mip-maps, 16 shell,
    /// 32 slice masks).
    pub bricks: [u32; 4],
    /// Ambient, diffuse, specular weights; shininess.
    pub material: [f32; 4],
    /// Shell ellipsoid centre (volume frame, metres); w unused.
    pub shell_centre: [f32; 4],
    /// Shell radii (metres); w unused.
    pub shell_radii: [f32; 4],
}

/// Mirrors WGSL `VoxInstance` in `shaders/voxel_dda.wgsl`: one placed voxel model, rewritten
/// every frame (eye in voxel units, shown animation frame).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct VoxInstanceGpu {
    /// Rows of Rᵀ / voxel size (world direction -> voxel units per metre).
    pub local_from_world: [[f32; 4]; 3],
    /// Eye in voxel units; w = voxel size (m).
    pub eye_local: [f32; 4],
    /// Model size in voxels; w = brick-table offset of the shown frame.
    pub dims: [u32; 4],
    /// Brick grid size; w = palette offset of the shown frame.
    pub bdims: [u32; 4],
    /// Bounding boxes (voxel units) of the occupied voxels in the model's z slabs
    /// (`cpu::voxel::cover_boxes`, at most [`VOX_SLABS`]), for anti-aliasing's near misses:
    /// lower corners, w = 1 where the slab holds voxels, 0 for an unused slot.
    pub slab_lo: [[f32; 4]; VOX_SLABS],
    /// Upper corners of the same boxes.
    pub slab_hi: [[f32; 4]; VOX_SLABS],
}

/// Slab boxes in a `VoxInstanceGpu` (WGSL `VOX_SLABS`).
pub const VOX_SLABS: usize = crate::cpu::voxel::COVER_SLABS as usize;

const _: () = assert!(std::mem::size_of::<VoxInstanceGpu>() == 96 + 32 * VOX_SLABS);

/// Mirrors WGSL `VoxDraw` in `shaders/voxels.wgsl`: the instances one rectangle of a voxel
/// pass runs, bound by dynamic offset. `mask[0] | mask[1] << 32`: bit k = instance k;
/// `mask[2]`: the instance of a one-instance draw, whose record `inst` repeats.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct VoxDrawGpu {
    pub mask: [u32; 4],
    pub inst: VoxInstanceGpu,
}

impl VoxDrawGpu {
    /// The record of a draw of `instances` (a mask) out of this frame's instance `records`.
    pub fn new(instances: u64, records: &[VoxInstanceGpu]) -> VoxDrawGpu {
        let first = instances.trailing_zeros() as usize;
        VoxDrawGpu {
            mask: [instances as u32, (instances >> 32) as u32, first as u32, 0],
            inst: match instances.count_ones() {
                1 => records[first],
                _ => VoxInstanceGpu::zeroed(),
            },
        }
    }
}
