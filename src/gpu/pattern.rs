//! The warp test-pattern pass: after ray generation, one full-screen fragment pass writes each
//! pixel's colour from its ray-table entry (`shaders/pattern.wgsl`; CPU reference
//! [`crate::display::pattern`]). It replaces the tile, cast and shade passes while set, so the
//! terrain passes carry none of its code.

use super::util::{
    encode_fullscreen, fullscreen_pipeline, target_state, uint_texture_entry, uniform_entry,
};
use super::{shaders, Gpu};
use crate::display::pattern::PatternParams;

/// `Pattern` in `pattern.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PatternUniforms {
    pub boresight: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<PatternUniforms>() == 16);

/// Pipeline, layout and uniforms of the pattern pass.
pub(crate) struct PatternPass {
    bgl: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    ub: wgpu::Buffer,
}

impl PatternPass {
    pub fn new(gpu: &Gpu) -> PatternPass {
        let dev = &gpu.device;
        let fs = wgpu::ShaderStages::FRAGMENT;
        let bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pattern"),
            entries: &[uniform_entry(gpu.params, 0, fs), uint_texture_entry(3, fs)],
        });
        let module = super::shader_module(dev, gpu.params, "pattern", &shaders::pattern());
        let pipeline = fullscreen_pipeline(
            dev,
            "pattern",
            &module,
            "fs_pattern",
            &bgl,
            &[
                Some(target_state(wgpu::TextureFormat::Rgba8Unorm)),
                Some(target_state(wgpu::TextureFormat::Rgba32Uint)),
            ],
        );
        let ub = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("pattern uniforms"),
            size: std::mem::size_of::<PatternUniforms>() as u64,
            usage: super::PARAM_USAGE,
            mapped_at_creation: false,
        });
        PatternPass { bgl, pipeline, ub }
    }

    /// Uploads the parameters and records the pass into `colour` and `data`.
    pub fn encode(
        &self,
        gpu: &Gpu,
        params: &PatternParams,
        enc: &mut wgpu::CommandEncoder,
        ray_table: &wgpu::TextureView,
        colour: &wgpu::TextureView,
        data: &wgpu::TextureView,
    ) {
        let b = params.boresight;
        let u = PatternUniforms {
            boresight: [b.x as f32, b.y as f32, b.z as f32, params.grating as f32],
        };
        gpu.queue.write_buffer(&self.ub, 0, bytemuck::bytes_of(&u));
        let bg = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pattern"),
            layout: &self.bgl,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.ub.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(ray_table),
                },
            ],
        });
        encode_fullscreen(enc, "pattern", &self.pipeline, &bg, &[colour, data]);
    }
}
