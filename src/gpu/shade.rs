//! Shade-pass pipelines specialised by compile-time feature constants.
//!
//! Mesa's CPU rasterisers execute both sides of every branch for the whole SIMD block, even
//! when the condition is the same uniform value for every pixel, so a feature that is switched
//! off at run time still costs its full price. Measured on GL/llvmpipe at 1280x720: the shadow
//! ray of a pass with shadows off cost 18 ms of a 72 ms shade pass, the drape lookup of a
//! terrain without a drape 12 ms. Each combination in use gets its own pipeline instead, built
//! on first use (lavapipe and llvmpipe compile a pipeline in 0.1–0.3 s).

use super::renderer::{render_pipeline, target_state};

/// Which optional shade-pass features a pipeline carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadeFeatures {
    /// Sun shadow rays (and the free-form and voxel shadow answers).
    pub shadows: bool,
    /// Colour from a draped RGB image instead of the elevation/slope ramp.
    pub drape: bool,
    /// Voxel models in the G-buffer.
    pub voxels: bool,
}

impl ShadeFeatures {
    /// Every feature compiled in.
    pub const ALL: ShadeFeatures = ShadeFeatures {
        shadows: true,
        drape: true,
        voxels: true,
    };
    /// None compiled in.
    pub const NONE: ShadeFeatures = ShadeFeatures {
        shadows: false,
        drape: false,
        voxels: false,
    };

    /// The WGSL constants `shade.wgsl` branches on, to prepend to its source. (Constants in
    /// the source rather than pipeline `override`s: naga 30's SPIR-V writer fails on an
    /// override inside `&&`, "Expression [..] is not cached".)
    pub fn wgsl_constants(&self) -> String {
        format!(
            "const SHADOWS: bool = {};\nconst DRAPE: bool = {};\nconst VOXELS: bool = {};\n",
            self.shadows, self.drape, self.voxels
        )
    }
}

/// The shade pipelines of one shade source (terrain only, or with free forms), one per
/// feature combination used so far.
pub struct ShadePipelines {
    label: &'static str,
    source: fn(ShadeFeatures) -> String,
    bgl: wgpu::BindGroupLayout,
    built: Vec<(ShadeFeatures, wgpu::RenderPipeline)>,
}

impl ShadePipelines {
    /// Pipelines of the shade source `source` (e.g. [`super::shaders::shade`]) with bind
    /// group layout `bgl`; none built yet.
    pub fn new(
        label: &'static str,
        source: fn(ShadeFeatures) -> String,
        bgl: wgpu::BindGroupLayout,
    ) -> ShadePipelines {
        ShadePipelines {
            label,
            source,
            bgl,
            built: Vec::new(),
        }
    }

    /// Builds the pipeline for `features` unless it exists; returns its index for
    /// [`ShadePipelines::get`].
    pub fn prepare(&mut self, dev: &wgpu::Device, features: ShadeFeatures) -> usize {
        if let Some(i) = self.built.iter().position(|(f, _)| *f == features) {
            return i;
        }
        let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(self.label),
            source: wgpu::ShaderSource::Wgsl((self.source)(features).into()),
        });
        let targets = [
            Some(target_state(wgpu::TextureFormat::Rgba8Unorm)),
            Some(target_state(wgpu::TextureFormat::Rgba32Uint)),
        ];
        let pipeline = render_pipeline(
            dev,
            self.label,
            &module,
            ["vs_fullscreen", "fs_shade"],
            &self.bgl,
            &targets,
            None,
        );
        log::debug!("{}: pipeline for {features:?}", self.label);
        self.built.push((features, pipeline));
        self.built.len() - 1
    }

    /// A pipeline [`ShadePipelines::prepare`] returned the index of.
    pub fn get(&self, index: usize) -> &wgpu::RenderPipeline {
        &self.built[index].1
    }
}
