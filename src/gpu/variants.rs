//! The passes' compile-time variants, as the WGSL sources ([`super::shaders`]) are composed for
//! them: the switch sets prepended as `const`s (see [`super::specialise`] for why) and where
//! the free-form tables live.

use super::types::{FfNodeGpu, FfObjectGpu};
use super::util::{storage_entry, uniform_entry};
use super::ParamSpace;
use crate::volume::Volume;

/// A set of compile-time switches of one pass.
pub trait Switches: Copy + Eq + std::fmt::Debug {
    /// WGSL `const` declarations of the switches, to prepend to the pass source.
    fn wgsl_constants(&self) -> String;
}

/// `const NAME: bool = value;` lines.
pub fn wgsl_bools(switches: &[(&str, bool)]) -> String {
    switches
        .iter()
        .map(|(name, on)| format!("const {name}: bool = {on};\n"))
        .collect()
}

/// Which optional shade-pass features a pipeline carries (`shade.wgsl` constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadeFeatures {
    /// Sun shadow rays (and the free-form and voxel shadow answers).
    pub shadows: bool,
    /// Colour from a draped RGB image instead of the elevation/slope ramp.
    pub drape: bool,
    /// Voxel models in the G-buffer.
    pub voxels: bool,
    /// Density volumes shadow the surfaces (the volume-sun pass's answer).
    pub volume_shadows: bool,
    /// Curved earth (`terrain.curved`): the traversal, normals and heights with the drop of
    /// the datum below the eye's tangent plane (`CURVED`; flat terrains compile without it).
    pub curved: bool,
    /// Footprint level of detail (`render.lod`, `LOD`): shadow rays of terrain hits start
    /// above the finest surface (a coarse patch may lie below it).
    pub lod: bool,
    /// The terrain is read from the paged tile pool (`PAGED`, group 3) over this many storage
    /// bindings (0: the terrain in memory): normals from the finest resident surface, shadow
    /// rays through the paged traversal.
    pub paged: u32,
    /// The drape sampled at mip levels picked by the pixel's footprint, trilinear
    /// (`DRAPE_MIPS`, with `render.antialias`).
    pub drape_mips: bool,
    /// Anti-aliasing's centre rays (`NEAR`): the terrain sun ray looks for rises its
    /// footprint's beam passes within reach of (near misses, flag 64).
    pub near: bool,
    /// Cloud layers (`CLOUDS`, `clouds.wgsl`): composited over every pixel, and the sun
    /// dimmed through them on surfaces.
    pub clouds: bool,
}

impl ShadeFeatures {
    /// Every feature compiled in.
    pub const ALL: ShadeFeatures = ShadeFeatures {
        shadows: true,
        drape: true,
        voxels: true,
        volume_shadows: true,
        curved: true,
        lod: true,
        paged: 0,
        drape_mips: true,
        near: true,
        clouds: true,
    };
    /// None compiled in.
    pub const NONE: ShadeFeatures = ShadeFeatures {
        shadows: false,
        drape: false,
        voxels: false,
        volume_shadows: false,
        curved: false,
        lod: false,
        paged: 0,
        drape_mips: false,
        near: false,
        clouds: false,
    };
}

impl Switches for ShadeFeatures {
    fn wgsl_constants(&self) -> String {
        wgsl_bools(&[
            ("SHADOWS", self.shadows),
            ("DRAPE", self.drape),
            ("VOXELS", self.voxels),
            ("VOLUME_SHADOWS", self.volume_shadows),
            ("CURVED", self.curved),
            ("LOD", self.lod),
            ("PAGED", self.paged > 0),
            ("NEAR", self.near),
            ("DRAPE_MIPS", self.drape_mips),
            ("CLOUDS", self.clouds),
        ])
    }
}

/// The volume pass's compile-time switches (see [`super::specialise`] for why).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VolumeSwitches {
    /// Empty-space skipping through the brick occupancy.
    pub skip: bool,
    /// Early ray termination.
    pub termination: bool,
    /// Jittered sample positions.
    pub jitter: bool,
    /// Mip level from the pixel footprint.
    pub mipmaps: bool,
    /// Rays start at an ellipsoid shell.
    pub shell: bool,
    /// 1-bit slice masks (the 4-D function's `w` slices) instead of densities.
    pub slices: bool,
    /// Self-shadowing: samples lit with the sun's transmittance (`volume::shadow`).
    pub shadow: bool,
    /// Mip texels read through a nearest sampler instead of `textureLoad` (on GL: llvmpipe's
    /// GL path fetches with one level for a whole SIMD block; 1.5x the volume pass there).
    pub sampled_fetch: bool,
}

impl VolumeSwitches {
    /// Every switch on.
    pub const ALL: VolumeSwitches = VolumeSwitches {
        skip: true,
        termination: true,
        jitter: true,
        mipmaps: true,
        shell: true,
        slices: true,
        shadow: true,
        sampled_fetch: true,
    };
    /// Every switch off.
    pub const NONE: VolumeSwitches = VolumeSwitches {
        skip: false,
        termination: false,
        jitter: false,
        mipmaps: false,
        shell: false,
        slices: false,
        shadow: false,
        sampled_fetch: false,
    };

    /// The switches volume `v` renders with (`sampled_fetch` off: see [`VolumeSwitches::on`]).
    pub fn of(v: &Volume) -> VolumeSwitches {
        let s = &v.settings;
        VolumeSwitches {
            skip: s.skip,
            termination: s.early_termination,
            jitter: s.jitter,
            mipmaps: s.mipmaps,
            shell: v.shell.is_some(),
            slices: v.grid.slices > 0,
            shadow: v.sun_shadow.is_some(),
            sampled_fetch: false,
        }
    }

    /// The switches volume `v` renders with on the adapter `info`: texels of the mip levels
    /// sampled on GL, loaded elsewhere.
    pub fn on(v: &Volume, info: &wgpu::AdapterInfo) -> VolumeSwitches {
        VolumeSwitches {
            sampled_fetch: v.settings.mipmaps && info.backend == wgpu::Backend::Gl,
            ..VolumeSwitches::of(v)
        }
    }
}

impl Switches for VolumeSwitches {
    fn wgsl_constants(&self) -> String {
        wgsl_bools(&[
            ("SKIP", self.skip),
            ("TERMINATION", self.termination),
            ("JITTER", self.jitter),
            ("MIPMAPS", self.mipmaps),
            ("SHELL", self.shell),
            ("SLICES", self.slices),
            ("SHADOW", self.shadow),
            ("SAMPLED_FETCH", self.sampled_fetch),
        ])
    }
}

/// Where the free-form records ([`FfObjectGpu`]) and quadrics ([`FfNodeGpu`]) live on the GPU.
///
/// Uniform buffers where the scene fits the adapter's uniform-binding size (64 KiB on Mesa and
/// most GPUs: 455 objects, 1365 quadrics): Mesa's CPU adapters load a uniform at a per-pixel
/// index as one gather, but a storage-buffer load as a loop over the SIMD lanes with an
/// execution-mask and a bounds branch per component (gallivm's `emit_load_mem`), and an object
/// record is 36 components. Measured on the airfield (GL/llvmpipe, 1280x720, A/B of per-pass
/// minimums): binning, casts and shadow passes 35 → 29 ms. Larger scenes use storage buffers,
/// with the same code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FfTables {
    /// Uniform arrays of exactly these many objects and nodes (the WGSL array sizes).
    Uniform { objects: u32, nodes: u32 },
    /// Runtime-sized storage arrays.
    Storage,
}

impl FfTables {
    /// Uniform buffers if `objects` records and `nodes` quadrics fit in `max_uniform` bytes
    /// each, else storage buffers.
    pub fn choose(objects: usize, nodes: usize, max_uniform: u64) -> FfTables {
        let fits = |n: usize, size: usize| n >= 1 && (n * size) as u64 <= max_uniform;
        if fits(objects, std::mem::size_of::<FfObjectGpu>())
            && fits(nodes, std::mem::size_of::<FfNodeGpu>())
        {
            FfTables::Uniform {
                objects: objects as u32,
                nodes: nodes as u32,
            }
        } else {
            FfTables::Storage
        }
    }

    pub(crate) fn uniform(&self) -> bool {
        matches!(self, FfTables::Uniform { .. })
    }

    /// Storage buffers the most demanding free-form stage binds: the shade pass (heights,
    /// pyramid, drape), plus the object records where they are not in a uniform buffer,
    /// plus the frame block and uniform-sized tables where parameter blocks are storage.
    pub(crate) fn storage_buffers(&self, space: ParamSpace) -> u32 {
        let params_in_storage = space == ParamSpace::Storage;
        3 + u32::from(!self.uniform() || params_in_storage) + u32::from(params_in_storage)
    }

    /// Bind-group-layout entry of table `binding` (6: objects, 7: nodes).
    pub(crate) fn entry(
        &self,
        space: ParamSpace,
        binding: u32,
        vis: wgpu::ShaderStages,
    ) -> wgpu::BindGroupLayoutEntry {
        if self.uniform() {
            uniform_entry(space, binding, vis)
        } else {
            storage_entry(binding, vis, true)
        }
    }
}
