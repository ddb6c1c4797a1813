//! The shade pass's pipelines, specialised by its compile-time features (see
//! [`super::specialise`] for why).

use super::specialise::SpecialisedPipelines;
use super::util::target_state;
use super::variants::ShadeFeatures;
use super::ParamSpace;

/// Shade pipelines (fragment entry `fs_shade`, colour and capture-data targets).
pub type ShadePipelines = SpecialisedPipelines<ShadeFeatures>;

/// Shade pipelines of `source` (e.g. [`super::shaders::shade`]) with bind-group layout `bgl`.
pub fn shade_pipelines(
    space: ParamSpace,
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
