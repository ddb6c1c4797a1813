//! The shade pass's compile-time switches (see [`super::specialise`] for why).

use super::renderer::target_state;
use super::specialise::{wgsl_bools, SpecialisedPipelines, Switches};

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
}

impl ShadeFeatures {
    /// Every feature compiled in.
    pub const ALL: ShadeFeatures = ShadeFeatures {
        shadows: true,
        drape: true,
        voxels: true,
        volume_shadows: true,
    };
    /// None compiled in.
    pub const NONE: ShadeFeatures = ShadeFeatures {
        shadows: false,
        drape: false,
        voxels: false,
        volume_shadows: false,
    };
}

impl Switches for ShadeFeatures {
    fn wgsl_constants(&self) -> String {
        wgsl_bools(&[
            ("SHADOWS", self.shadows),
            ("DRAPE", self.drape),
            ("VOXELS", self.voxels),
            ("VOLUME_SHADOWS", self.volume_shadows),
        ])
    }
}

/// Shade pipelines (fragment entry `fs_shade`, colour and capture-data targets).
pub type ShadePipelines = SpecialisedPipelines<ShadeFeatures>;

/// Shade pipelines of `source` (e.g. [`super::shaders::shade`]) with bind-group layout `bgl`.
pub fn shade_pipelines(
    space: super::ParamSpace,
    label: &'static str,
    source: impl Fn(ShadeFeatures) -> String + Send + Sync + 'static,
    bgl: wgpu::BindGroupLayout,
) -> ShadePipelines {
    let targets = vec![
        Some(target_state(wgpu::TextureFormat::Rgba8Unorm)),
        Some(target_state(wgpu::TextureFormat::Rgba32Uint)),
    ];
    SpecialisedPipelines::new(space, label, source, "fs_shade", bgl, targets)
}
