//! The size-dependent render targets of a frame (ray table, tile texture, G-buffer, colour,
//! capture data, volume sun, readback buffers) and the bind groups of every pass over them.

use super::blend::{BlendPass, BlendTargets};
use super::objects::{ObjectPasses, ObjectTargets};
use super::table::TableMode;
use super::terrain_passes::TerrainPasses;
use super::util::{buf, padded_row, screen_texture, view, TARGET_USAGE};
use super::volume_set::VolumeSet;
use super::volumes::{CompositeTargets, VolumeTargets, SUN_FORMAT};
use super::voxels::{VoxelPasses, VoxelTargets};
use super::Gpu;
use crate::Result;

/// Screen tile side of the tile pre-pass (WGSL `TILE`).
pub const TILE: u32 = 8;

/// The passes a frame's targets are made for.
pub(crate) struct TargetPasses<'a> {
    pub base: &'a TerrainPasses,
    pub table: Option<&'a TableMode>,
    pub objects: Option<&'a ObjectPasses>,
    pub volumes: &'a VolumeSet,
    pub voxels: Option<&'a VoxelPasses>,
    pub blend: Option<&'a BlendPass>,
}

/// The targets of one frame size and the bind groups that read them.
pub(crate) struct Targets {
    pub width: u32,
    pub height: u32,
    pub tiles: [u32; 2],
    pub raygen_bg: wgpu::BindGroup,
    pub ray_table: wgpu::Texture,
    pub ray_table_view: wgpu::TextureView,
    pub tile_bg: wgpu::BindGroup,
    pub cast_bg: wgpu::BindGroup,
    pub shade_bg: wgpu::BindGroup,
    pub tile_view: wgpu::TextureView,
    pub gbuffer: wgpu::Texture,
    pub gbuffer_view: wgpu::TextureView,
    pub colour: wgpu::Texture,
    pub colour_view: wgpu::TextureView,
    pub data: wgpu::Texture,
    pub data_view: wgpu::TextureView,
    pub colour_rb: wgpu::Buffer,
    pub data_rb: wgpu::Buffer,
    /// Free-form bins, G-buffer and the shade bind group that reads them.
    pub objects: Option<(ObjectTargets, wgpu::BindGroup)>,
    /// Per volume: its passes' bind groups.
    pub volumes: Vec<VolumeTargets>,
    /// The image under the volumes, their results and statistics (with volumes).
    pub composite: Option<CompositeTargets>,
    /// The volume-sun target (the shade pass reads it) and its readback buffer.
    pub volume_sun: wgpu::Texture,
    pub volume_sun_view: wgpu::TextureView,
    pub volume_sun_rb: wgpu::Buffer,
    /// The finished image before the edge blend.
    pub blend: Option<BlendTargets>,
    pub voxels: Option<VoxelTargets>,
}

/// The screen-sized textures of the terrain passes.
struct Screen {
    ray_table: wgpu::Texture,
    ray_table_view: wgpu::TextureView,
    tile_view: wgpu::TextureView,
    colour: wgpu::Texture,
    data: wgpu::Texture,
    gbuffer: wgpu::Texture,
    gbuffer_view: wgpu::TextureView,
    volume_sun: wgpu::Texture,
    volume_sun_view: wgpu::TextureView,
}

impl Screen {
    /// The textures of a `size` frame of `tiles` tiles. The ray table is a storage texture
    /// too (ray generation as a compute dispatch, an anti-aliasing atlas's sample rays), as
    /// are colour and data (the anti-aliasing resolve stores its pixels: `aa_resolve.wgsl`).
    fn new(dev: &wgpu::Device, size: [u32; 2], tiles: [u32; 2]) -> Screen {
        let frame_tex = |label, format| {
            let usage = TARGET_USAGE | wgpu::TextureUsages::STORAGE_BINDING;
            screen_texture(dev, label, size, format, usage)
        };
        let ray_table = frame_tex("ray table", wgpu::TextureFormat::Rgba32Uint);
        let ray_table_view = ray_table.create_view(&Default::default());
        let tex = |label, size, format| screen_texture(dev, label, size, format, TARGET_USAGE);
        let tile_tex = tex("tile start", tiles, wgpu::TextureFormat::Rg32Uint);
        let colour = frame_tex("colour", wgpu::TextureFormat::Rgba8Unorm);
        let data = frame_tex("data", wgpu::TextureFormat::Rgba32Uint);
        let tile_view = tile_tex.create_view(&Default::default());
        let gbuffer = tex("g-buffer", size, wgpu::TextureFormat::Rgba32Uint);
        let gbuffer_view = gbuffer.create_view(&Default::default());
        let volume_sun = tex("volume sun", size, SUN_FORMAT);
        let volume_sun_view = volume_sun.create_view(&Default::default());
        Screen {
            ray_table,
            ray_table_view,
            tile_view,
            colour,
            data,
            gbuffer,
            gbuffer_view,
            volume_sun,
            volume_sun_view,
        }
    }
}

/// The terrain passes' bind groups over the screen textures: ray generation (from the
/// distortion table's points with one), tile pre-pass, cast and shade.
fn terrain_bind_groups(dev: &wgpu::Device, p: &TargetPasses, s: &Screen) -> [wgpu::BindGroup; 4] {
    let d = &p.base.data;
    let bgl = &p.base.bgl;
    let raygen_bg = dev.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("raygen"),
        layout: p.table.map_or(&bgl.raygen, |t| &t.bgl),
        entries: &if let Some(table) = p.table {
            vec![buf(0, &d.raygen_ub), view(2, &table.points_view)]
        } else if p.base.raygen_is_compute() {
            vec![buf(0, &d.raygen_ub), view(1, &s.ray_table_view)]
        } else {
            vec![buf(0, &d.raygen_ub)]
        },
    });
    let common = [
        buf(0, &d.frame_ub),
        buf(1, &d.heights),
        buf(2, &d.pyramid),
        view(3, &s.ray_table_view),
    ];
    let group = |label, layout, extra: &[wgpu::BindGroupEntry]| {
        let mut entries = common.to_vec();
        entries.extend_from_slice(extra);
        dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
    };
    let tile_bg = group("tile", &bgl.tile, &[buf(4, &d.dilated)]);
    let cast_bg = group("cast", &bgl.cast, &[view(4, &s.tile_view)]);
    let shade_bg = group(
        "shade",
        &bgl.shade,
        &[
            view(4, &s.gbuffer_view),
            buf(5, &d.drape),
            view(19, &s.volume_sun_view),
        ],
    );
    [raygen_bg, tile_bg, cast_bg, shade_bg]
}

/// The free-form passes' targets and the shade bind group that reads them (with free forms).
fn object_targets(
    gpu: &Gpu,
    p: &TargetPasses,
    s: &Screen,
    size: [u32; 2],
) -> Result<Option<(ObjectTargets, wgpu::BindGroup)>> {
    let Some(o) = p.objects else {
        return Ok(None);
    };
    let d = &p.base.data;
    let ot = o.targets(
        gpu,
        size[0],
        size[1],
        &d.frame_ub,
        &s.ray_table_view,
        &s.gbuffer_view,
    )?;
    let bg = o.shade_bind_group(
        gpu,
        [&d.frame_ub, &d.heights, &d.pyramid, &d.drape],
        [&s.ray_table_view, &s.volume_sun_view],
        &ot,
    );
    Ok(Some((ot, bg)))
}

impl Targets {
    /// Creates the targets of a `width` x `height` frame and the bind groups of the passes `p`.
    pub fn new(gpu: &Gpu, p: &TargetPasses, width: u32, height: u32) -> Result<Targets> {
        let dev = &gpu.device;
        let size = [width, height];
        let tiles = [width.div_ceil(TILE), height.div_ceil(TILE)];
        let s = Screen::new(dev, size, tiles);
        let rb = |label, bpp: u32| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: padded_row(width * bpp) as u64 * height as u64,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        let [raygen_bg, tile_bg, cast_bg, shade_bg] = terrain_bind_groups(dev, p, &s);
        let objects = object_targets(gpu, p, &s, size)?;
        // The G-buffer the casts end in (see `TerrainRenderer::encode_primary`).
        let final_gbuffer_view = objects
            .as_ref()
            .map_or(&s.gbuffer_view, |(ot, _)| &ot.final_view);
        let frame_ub = &p.base.data.frame_ub;
        let volumes = p.volumes.targets(
            gpu,
            frame_ub,
            &s.ray_table_view,
            &s.data,
            final_gbuffer_view,
        );
        let composite = p
            .volumes
            .composite
            .as_ref()
            .map(|c| c.targets(gpu, width, height, frame_ub));
        let voxels = p
            .voxels
            .map(|v| v.targets(gpu, width, height, frame_ub, &s.ray_table_view));
        let blend = p.blend.map(|b| b.targets(gpu, width, height)).transpose()?;
        Ok(Targets {
            blend,
            volumes,
            composite,
            objects,
            voxels,
            width,
            height,
            tiles,
            raygen_bg,
            ray_table: s.ray_table,
            ray_table_view: s.ray_table_view,
            tile_bg,
            cast_bg,
            shade_bg,
            tile_view: s.tile_view,
            gbuffer: s.gbuffer,
            gbuffer_view: s.gbuffer_view,
            colour_view: s.colour.create_view(&Default::default()),
            data_view: s.data.create_view(&Default::default()),
            colour: s.colour,
            data: s.data,
            colour_rb: rb("colour readback", 4),
            volume_sun_rb: rb("volume sun readback", 1),
            volume_sun: s.volume_sun,
            volume_sun_view: s.volume_sun_view,
            data_rb: rb("data readback", 16),
        })
    }
}
