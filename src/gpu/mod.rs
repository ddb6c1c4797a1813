//! GPU layer (wgpu): device selection, the terrain renderer's passes and readback.
//!
//! Passes per frame, in order (optional ones only when the scene has what they draw):
//! 1. ray generation (compute or fragment, [`KernelChoice`]; from a distortion table with a
//!    display): the ray table;
//! 2. tile pre-pass (fragment, one fragment per 8x8 tile): where each tile's rays start;
//! 3. terrain cast (fragment, full screen: pyramid traversal or fixed-step march): the G-buffer;
//! 4. free forms: binning (compute, per 16x16 bin) and cast (fragment, quads over the bins);
//! 5. voxel models: cast (fragment, over the rectangles the models cover);
//! 6. voxel and free-form shadow rays (fragment, same rectangles and bins);
//! 7. volume sun (fragment): the sun's transmittance through the volumes at the surfaces;
//! 8. shade (fragment, full screen: lighting, shadow rays, fog, sky), its variant chosen by
//!    compile-time features;
//! 9. volumes: one integration pass per volume, then the composite pass over the shaded image;
//! 10. edge blend (fragment) of a display channel;
//!
//! then the copies to the readback buffers when capturing. The warp test pattern replaces
//! passes 2–9.
//!
//! Files (their imports form no cycle; `renderer` is the only one that knows every pass):
//! * `device` — [`Gpu`]: adapter and device, [`GpuOptions`] (kernel path, pass tracing),
//!   [`ParamSpace`] of the parameter blocks;
//! * `util` — bind-group and pipeline helpers, screen textures, full-screen draws, readback;
//! * `types` — the `#[repr(C)]` Pod structs mirroring the WGSL structs;
//! * `uniforms` — the `Frame` and `RayGen` parameter blocks filled in on the CPU;
//! * `frame` — [`RenderSettings`], [`Stage`], [`PassTimes`], [`FrameOutput`];
//! * `pyramid` — the square maximum pyramid the GPU reads and its dilation;
//! * `variants` — compile-time switches of the passes and where the free-form tables live;
//! * `shaders` — the WGSL sources composed per pass and variant (`shaders/*.wgsl`);
//! * `specialise` — pipelines built per switch combination;
//! * `shade` — the shade pass's pipelines;
//! * `terrain_passes` — terrain data and the ray-generation, tile, cast and shade pipelines;
//! * `table` — ray generation from a distortion table;
//! * `objects` — free-form binning, cast and shadow passes;
//! * `voxels` — voxel-model cast and shadow passes;
//! * `volumes` — the volume, volume-sun and composite passes of one volume;
//! * `volume_set` — a scene's volumes as one set;
//! * `pattern` — the warp test pattern;
//! * `blend` — the edge blend;
//! * `targets` — the size-dependent targets and bind groups;
//! * `readback` — captured targets read back and decoded;
//! * `antialias` — edge anti-aliasing: sub-pixel rays where the centre rays straddle an edge;
//! * `renderer` — [`TerrainRenderer`]: holds the passes and records a frame.

pub mod antialias;
pub mod blend;
pub mod device;
pub mod frame;
pub mod objects;
pub mod pattern;
pub mod pyramid;
pub(crate) mod readback;
pub mod renderer;
pub mod shade;
pub mod shaders;
pub mod specialise;
pub(crate) mod table;
pub(crate) mod targets;
pub(crate) mod terrain_passes;
pub mod terrain_pool;
pub mod types;
pub mod uniforms;
pub(crate) mod util;
pub mod variants;
pub(crate) mod volume_set;
pub mod volumes;
pub mod voxels;

pub use antialias::Antialias;
pub(crate) use device::shader_module;
pub use device::{
    Gpu, GpuOptions, KernelChoice, KernelPath, ListChoice, ParamSpace, PARAM_USAGE,
    STORAGE_BUFFERS_PER_STAGE,
};
pub use frame::{
    FrameOutput, PassTimes, RenderSettings, Stage, TraceMode, FLAG_ANTIALIASED, FLAG_NEAR_MISS,
};
pub use renderer::TerrainRenderer;
pub use util::check_buffer_limit;
pub use volume_set::MAX_VOLUMES;
