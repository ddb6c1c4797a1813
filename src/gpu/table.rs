//! Ray generation from a distortion table: the screen points of one projector uploaded once,
//! the pipelines that turn them into the ray table and the tile cones, and the eye point.

use super::terrain_passes::TerrainPasses;
use super::util::{fullscreen_pipeline, target_state, uniform_entry};
use super::Gpu;
use crate::display::screen_points::ScreenPoints;
use crate::{Error, Result};

/// The cached screen points of one projector, the table pipelines and the current eye point.
pub(crate) struct TableMode {
    pub bgl: wgpu::BindGroupLayout,
    pub raygen: wgpu::RenderPipeline,
    pub tile: wgpu::RenderPipeline,
    pub points_view: wgpu::TextureView,
    pub size: [u32; 2],
    pub eye: glam::DVec3,
    /// The channel's view offset (display frame rotation applied before the vehicle's).
    pub offset: glam::DMat3,
}

impl TableMode {
    /// Uploads the projector's screen `points` and builds the table pipelines from the terrain
    /// passes' modules; the view offset starts as the identity.
    pub fn new(
        gpu: &Gpu,
        base: &TerrainPasses,
        points: &ScreenPoints,
        eye: glam::DVec3,
    ) -> Result<TableMode> {
        let dev = &gpu.device;
        let max = gpu.limits.max_texture_dimension_2d;
        if points.width > max || points.height > max {
            return Err(Error::Limit {
                what: "projector resolution".into(),
                msg: format!(
                    "{}x{} is larger than the adapter's {max}x{max} texture limit",
                    points.width, points.height
                ),
            });
        }
        let texture = upload_points(gpu, points);
        let fs = wgpu::ShaderStages::FRAGMENT;
        let bgl = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("raygen (table)"),
            entries: &[
                uniform_entry(gpu.params, 0, fs),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: fs,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let raygen = fullscreen_pipeline(
            dev,
            "raygen (table)",
            &base.raygen_mod,
            "fs_raygen_table",
            &bgl,
            &[Some(target_state(wgpu::TextureFormat::Rgba32Uint))],
        );
        let tile = base.tile_pipeline(gpu, "tile (table)", "fs_tile_table");
        Ok(TableMode {
            bgl,
            raygen,
            tile,
            points_view: texture.create_view(&Default::default()),
            size: [points.width, points.height],
            eye,
            offset: glam::DMat3::IDENTITY,
        })
    }
}

/// The screen points as an Rgba32Uint texture (f32 bits of x, y, z and 1; zeros where the
/// pixel shows no screen).
fn upload_points(gpu: &Gpu, points: &ScreenPoints) -> wgpu::Texture {
    let texels: Vec<[f32; 4]> = points
        .points
        .iter()
        .map(|p| p.map_or([0.0; 4], |p| [p.x as f32, p.y as f32, p.z as f32, 1.0]))
        .collect();
    let size = wgpu::Extent3d {
        width: points.width,
        height: points.height,
        depth_or_array_layers: 1,
    };
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("screen points"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Uint,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    gpu.queue.write_texture(
        texture.as_image_copy(),
        bytemuck::cast_slice(&texels),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(points.width * 16),
            rows_per_image: Some(points.height),
        },
        size,
    );
    texture
}
