//! The edge-blend pass: after everything else, the finished image is copied aside and written
//! back multiplied by each pixel's blend factor (`shaders/blend.wgsl`; CPU reference
//! [`crate::display::blend`]).

use super::util::{
    buf, float_texture_entry, fullscreen_pipeline, screen_texture, target_state, uniform_entry,
};
use super::{shaders, Gpu};
use crate::display::blend::{Blend, ChannelBlend};
use crate::{Error, Result};

/// Mirrors WGSL `BlendParams` in `shaders/blend.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BlendUniforms {
    pub size: [u32; 4],
    pub widths: [f32; 4],
    pub exponents: [f32; 4],
    pub gamma: [f32; 4],
}

/// Pipeline and parameters of the blend pass.
pub(crate) struct BlendPass {
    bgl: wgpu::BindGroupLayout,
    pub pipeline: wgpu::RenderPipeline,
    ub: wgpu::Buffer,
    pub blend: Blend,
    /// Geometric weights (R32Float, the channel's size; 1x1 of 1.0 without).
    mask: wgpu::TextureView,
    mask_size: Option<[u32; 2]>,
}

/// Size-dependent resources: the copy of the finished image the pass reads.
pub(crate) struct BlendTargets {
    pub src: wgpu::Texture,
    pub bg: wgpu::BindGroup,
}

impl BlendPass {
    pub fn new(gpu: &Gpu, cb: &ChannelBlend) -> Result<BlendPass> {
        let blend = cb.blend;
        let dev = &gpu.device;
        let fs = wgpu::ShaderStages::FRAGMENT;
        let bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("blend"),
            entries: &[
                uniform_entry(gpu.params, 0, fs),
                float_texture_entry(1, fs, wgpu::TextureViewDimension::D2),
                float_texture_entry(2, fs, wgpu::TextureViewDimension::D2),
            ],
        });
        let module = super::shader_module(dev, gpu.params, "blend.wgsl", &shaders::blend());
        let pipeline = fullscreen_pipeline(
            dev,
            "blend",
            &module,
            "fs_blend",
            &bgl,
            &[Some(target_state(wgpu::TextureFormat::Rgba8Unorm))],
        );
        let ub = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("blend uniforms"),
            size: std::mem::size_of::<BlendUniforms>() as u64,
            usage: super::PARAM_USAGE,
            mapped_at_creation: false,
        });
        let (size, data) = match &cb.mask {
            Some(m) => ([cb.width, cb.height], m.as_slice()),
            None => ([1, 1], &[1.0f32][..]),
        };
        let max = gpu.limits.max_texture_dimension_2d;
        if size[0] > max || size[1] > max {
            return Err(Error::Limit {
                what: "blend mask".into(),
                msg: format!("{}x{} over the adapter's {max}", size[0], size[1]),
            });
        }
        let tex = screen_texture(
            dev,
            "blend mask",
            size,
            wgpu::TextureFormat::R32Float,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        );
        gpu.queue.write_texture(
            tex.as_image_copy(),
            bytemuck::cast_slice(data),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(size[0] * 4),
                rows_per_image: Some(size[1]),
            },
            wgpu::Extent3d {
                width: size[0],
                height: size[1],
                depth_or_array_layers: 1,
            },
        );
        Ok(BlendPass {
            bgl,
            pipeline,
            ub,
            blend,
            mask: tex.create_view(&Default::default()),
            mask_size: cb.mask.as_ref().map(|_| [cb.width, cb.height]),
        })
    }

    pub fn targets(&self, gpu: &Gpu, width: u32, height: u32) -> Result<BlendTargets> {
        if let Some([w, h]) = self.mask_size.filter(|s| *s != [width, height]) {
            return Err(Error::invalid(
                "blend",
                format!(
                    "the channel's geometric blend is {w}x{h}, the frame {width}x{height}: \
                     render at the projector's resolution"
                ),
            ));
        }
        let dev = &gpu.device;
        let src = screen_texture(
            dev,
            "image before the blend",
            [width, height],
            wgpu::TextureFormat::Rgba8Unorm,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        );
        let view = src.create_view(&Default::default());
        let e = |e: Option<crate::display::blend::BlendEdge>| {
            e.map_or((0.0, 1.0), |e| (e.width as f32, e.exponent as f32))
        };
        let b = &self.blend;
        let edges = [e(b.left), e(b.right), e(b.top), e(b.bottom)];
        let u = BlendUniforms {
            size: [width, height, 0, 0],
            widths: edges.map(|x| x.0),
            exponents: edges.map(|x| x.1),
            gamma: [
                (1.0 / b.gamma) as f32,
                self.mask_size.is_some() as u32 as f32,
                0.0,
                0.0,
            ],
        };
        gpu.queue.write_buffer(&self.ub, 0, bytemuck::bytes_of(&u));
        let bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blend"),
            layout: &self.bgl,
            entries: &[
                buf(0, &self.ub),
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&self.mask),
                },
            ],
        });
        Ok(BlendTargets { src, bg })
    }
}
