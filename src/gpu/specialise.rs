//! Full-screen pipelines specialised by compile-time switches.
//!
//! Mesa's CPU rasterisers (lavapipe, llvmpipe) execute both sides of every branch for the
//! whole SIMD block, even when the condition is one uniform value for every pixel, and run a
//! loop body at least once: a feature switched off at run time still costs its full price.
//! Measured on GL/llvmpipe at 1280x720: the shadow ray of a shade pass with shadows off cost
//! 18 ms of 72 ms, the drape lookup of a terrain without a drape 12 ms. So each combination of
//! switches in use gets its own pipeline, with the switches as WGSL `const`s prepended to the
//! pass source, built on first use (Mesa compiles a pipeline in 0.1–0.3 s). On GPUs the
//! branches would be cheap; the specialisation costs them nothing.
//!
//! (Constants in the source rather than pipeline `override`s: one source per variant is what
//! the naga validation test checks, and every variant is a complete, valid module.)

use super::util::{pipeline_layout_with, render_pipeline_in};
use super::variants::Switches;
use super::ParamSpace;

/// The pipelines of one full-screen fragment pass, one per switch combination used so far.
pub struct SpecialisedPipelines<S: Switches> {
    space: ParamSpace,
    label: &'static str,
    source: Box<dyn Fn(S) -> String + Send + Sync>,
    entry: &'static str,
    bgl: wgpu::BindGroupLayout,
    targets: Vec<Option<wgpu::ColorTargetState>>,
    /// Bind group 3 of every pipeline (the paged terrain's tile pool), if any.
    group3: Option<wgpu::BindGroupLayout>,
    built: Vec<(S, wgpu::RenderPipeline)>,
}

impl<S: Switches> SpecialisedPipelines<S> {
    /// Pipelines of fragment entry point `entry` of `source(switches)` (full-screen vertex
    /// stage, parameter blocks in `space`), bind-group layout `bgl`, colour `targets`; none
    /// built yet.
    pub fn new(
        space: ParamSpace,
        label: &'static str,
        source: impl Fn(S) -> String + Send + Sync + 'static,
        entry: &'static str,
        bgl: wgpu::BindGroupLayout,
        targets: Vec<Option<wgpu::ColorTargetState>>,
    ) -> SpecialisedPipelines<S> {
        SpecialisedPipelines {
            space,
            label,
            source: Box::new(source),
            entry,
            bgl,
            targets,
            group3: None,
            built: Vec::new(),
        }
    }

    /// The same pipelines with bind group 3 `bgl` in their layout (the paged terrain).
    pub fn with_group3(mut self, bgl: wgpu::BindGroupLayout) -> SpecialisedPipelines<S> {
        self.group3 = Some(bgl);
        self.built.clear();
        self
    }

    /// Builds the pipeline for `switches` unless it exists; returns its index for
    /// [`SpecialisedPipelines::get`].
    pub fn prepare(&mut self, dev: &wgpu::Device, switches: S) -> usize {
        if let Some(i) = self.built.iter().position(|(s, _)| *s == switches) {
            return i;
        }
        let module = super::shader_module(dev, self.space, self.label, &(self.source)(switches));
        let layout = pipeline_layout_with(dev, &self.bgl, self.group3.as_ref());
        let pipeline = render_pipeline_in(
            dev,
            self.label,
            &module,
            ["vs_fullscreen", self.entry],
            &layout,
            &self.targets,
            None,
        );
        log::debug!("{}: pipeline for {switches:?}", self.label);
        self.built.push((switches, pipeline));
        self.built.len() - 1
    }

    /// A pipeline [`SpecialisedPipelines::prepare`] returned the index of.
    pub fn get(&self, index: usize) -> &wgpu::RenderPipeline {
        &self.built[index].1
    }
}
