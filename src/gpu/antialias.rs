//! Edge anti-aliasing (`[render] antialias`): after the frame of centre rays, the pixels whose
//! rays straddle a discontinuity that shows get `n` sub-pixel rays each, resolved in linear
//! light ([`Antialias`]; design and figures in `docs/antialiasing.md`).
//!
//! 1. **Edges** (`aa_edges.wgsl`): a mask from the centre frame's capture data and colour: a
//!    neighbour showing another surface (sky, terrain, another free form, a voxel model) or
//!    across a shadow boundary, or a kink of 1/distance across the pixel (a crease or a depth
//!    jump on one surface), where the colour changes by more than a threshold; or a colour
//!    step to a neighbour above a larger threshold on one surface (detail finer than the
//!    pixel); or a near miss the centre ray's cone found (flag 64: the centre rays are cast
//!    with the `NEAR` traversal). The mask holds each marked pixel's sample count: 4, 8 or 16
//!    by its contrast with `"edges"` (at most about 2 levels of error against 16 samples:
//!    [`ADAPT_4`], [`ADAPT_8`]), else the chosen count. It becomes the list of marked
//!    pixels (the 16s, then the 8s, then the 4s): read back and made on the CPU (`Marked`)
//!    on CPU adapters, built by compute on GPUs (`gpu_list`, [`crate::gpu::ListChoice`]).
//! 2. The **sample atlas**: a target of the list's samples only (4x4 groups, each holding one
//!    pixel's 16 samples, two pixels' 8 or four pixels' 4), with its own frame targets. Mesa's CPU rasterisers run
//!    every lane of a fragment block, so a full-screen pass with most pixels switched off would
//!    cost nearly a full pass; on the atlas the samples cost what their rays cost, and every
//!    pass runs once for all n samples. **Sample rays** (`aa_rays.wgsl`, one fragment per
//!    marked pixel storing its samples' rays) write its ray table: sub-pixel position k of a
//!    4x4 grid, from the centre table and its derivatives (so every ray generation, pinhole
//!    or distortion table, works the same), the pixel's cone; then the
//!    frame's primary and shading passes run on it (without the tile pre-pass, and with
//!    free-form bins bounding every ray of a bin: neighbouring entries are not neighbouring
//!    rays).
//! 3. **Resolve** (`aa_resolve.wgsl`): one fragment per marked pixel (a compact target, one
//!    texel per marked pixel) takes the mean of its samples and stores it, and the centre
//!    ray's capture data with flag 128, into the frame's colour and data at the pixel
//!    (storage writes); the other pixels are not touched (they keep the centre rays' colour
//!    and data), nor is the frame's ray table.
//!
//! With every pixel marked and n = 16 this is relief's own supersampled reference (4x4 rays
//! inside each pixel, the pixel's own cone).

use super::util::{
    copy_to_readback, float_texture_entry, fullscreen_pipeline, readback_buffer, screen_texture,
    storage_texture_entry, target_state, uint_texture_entry, view,
};
use super::{shaders, Gpu};
use wgpu::TextureFormat as F;

mod gpu_list;
mod list;
#[doc(hidden)]
pub use gpu_list::{list_on_cpu, list_on_gpu};
use list::tile_order;
pub(crate) use list::{batches, sample_rays, Batch, Marked};

/// How a frame is anti-aliased (`[render] antialias`, `--antialias`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize)]
pub struct Antialias {
    /// Sub-pixel rays per anti-aliased pixel: 0 (off), 4, 8 or 16; the most a pixel gets
    /// when `adaptive`.
    pub samples: u32,
    /// Every pixel, not only edges (the supersampled reference).
    pub every_pixel: bool,
    /// Each marked pixel's count (4, 8 or 16) chosen from its contrast ([`ADAPT_4`],
    /// [`ADAPT_8`]; `"edges"`).
    pub adaptive: bool,
}

impl Antialias {
    pub const OFF: Antialias = Antialias {
        samples: 0,
        every_pixel: false,
        adaptive: false,
    };
    /// `"edges"`: 4 to 16 rays per edge pixel, by contrast.
    pub const EDGES: Antialias = Antialias {
        samples: 16,
        every_pixel: false,
        adaptive: true,
    };
    /// The reference: 16 rays (4x4) in every pixel.
    pub const REFERENCE: Antialias = Antialias {
        samples: 16,
        every_pixel: true,
        adaptive: false,
    };

    /// `n` rays (4, 8 or 16) in every edge pixel.
    pub const fn edges(n: u32) -> Antialias {
        Antialias {
            samples: n,
            every_pixel: false,
            adaptive: false,
        }
    }
    pub fn is_on(self) -> bool {
        self.samples > 0
    }

    /// The choice in words: `off`, `edges`, `edges N` (N in every edge pixel) or `every pixel
    /// N` (the reference); the bench's configurations and the window's overlay.
    pub fn name(self) -> String {
        match (self.samples, self.every_pixel, self.adaptive) {
            (0, _, _) => "off".into(),
            (_, false, true) => "edges".into(),
            (n, false, false) => format!("edges {n}"),
            (n, true, _) => format!("every pixel {n}"),
        }
    }

    /// Sub-pixel rays each anti-aliased pixel gets, the most when adaptive (0 when off; see
    /// [`samples`]).
    pub fn rays_per_pixel(self) -> u32 {
        if self.is_on() {
            samples(self)
        } else {
            0
        }
    }

    /// The scene's (or the command line's) choice.
    pub fn from_option(o: crate::scene::AntialiasOption) -> Antialias {
        Antialias {
            samples: o.samples(),
            every_pixel: o.every_pixel(),
            adaptive: o.adaptive(),
        }
    }
}

/// Colour contrast (sRGB, 0..1) below which a discontinuity gets no extra rays.
pub const CONTRAST: f32 = 2.0 / 255.0;
/// Relative kink of 1/distance across a pixel above which a surface has a crease or jump.
pub const KINK: f32 = 0.02;
/// Colour contrast to a neighbour (sRGB, 0..1) above which a pixel is marked on one surface
/// too: detail finer than the pixel (far slopes, a drape's texture).
pub const DETAIL: f32 = 12.0 / 255.0;
/// Adaptive counts (`"edges"`): a marked pixel whose largest colour step to a neighbour (sRGB,
/// 0..1) is at most this gets 4 samples. A straight edge's coverage from the first 4 samples
/// of the 4x4 grid differs from all 16's by at most a quarter of the pixel (0.078 in the mean
/// over random edges), from the first 8's by at most an eighth (0.044): with these two
/// limits the colour of an edge pixel moves by at most about 2 levels from the 16 samples'.
pub const ADAPT_4: f32 = 8.0 / 255.0;
/// Adaptive counts: at most this (and above [`ADAPT_4`]), 8 samples; above it, 16 (and near
/// misses, whose centre colour does not show what they missed, always 16).
pub const ADAPT_8: f32 = 16.0 / 255.0;

/// Sample positions on the 4x4 grid inside a pixel (column, row), ordered so that the first 4
/// are a rotated grid (one per row and column) and the first 8 two of them (two per row and
/// column); all 16 are the reference's.
const GRID: [[u8; 2]; 16] = [
    [1, 0],
    [3, 1],
    [2, 3],
    [0, 2],
    [2, 0],
    [0, 1],
    [1, 3],
    [3, 2],
    [0, 0],
    [2, 2],
    [3, 0],
    [1, 2],
    [2, 1],
    [0, 3],
    [1, 1],
    [3, 3],
];

/// Sample `k`'s offset from the pixel centre in pixels.
pub fn sample_offset(k: usize) -> [f32; 2] {
    GRID[k % 16].map(|i| (f32::from(i) + 0.5) / 4.0 - 0.5)
}

/// Mirrors WGSL `AaParams` in `shaders/aa_common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AaUniforms {
    pub size: [u32; 4],
    pub atlas: [u32; 4],
    pub limits: [f32; 4],
    pub adapt: [f32; 4],
    pub counts: [u32; 4],
    pub offsets: [[f32; 4]; 8],
    pub linear: [[f32; 4]; 64],
}

/// The passes' pipelines and parameters.
pub(crate) struct AntialiasPasses {
    /// The tile pre-pass over every ray of a tile (the atlas's tiles are not pinhole
    /// quadrilaterals).
    pub tile: wgpu::RenderPipeline,
    edges: wgpu::RenderPipeline,
    rays: wgpu::RenderPipeline,
    resolve: wgpu::RenderPipeline,
    /// The list built on the GPU ([`crate::gpu::ListChoice`]); `None`: on the CPU.
    list: Option<gpu_list::ListPasses>,
    layouts: [wgpu::BindGroupLayout; 3],
    params: wgpu::Buffer,
}

/// Rows of the atlas come in multiples of this (fewer new atlases as the list changes; a
/// multiple of its 16-entry bins).
const ATLAS_ROWS: u32 = 32;

/// The atlas's width for a `width` frame: a multiple of 16 (its 4x4 groups, the free-form
/// bins) at least 64.
pub fn atlas_width(width: u32) -> u32 {
    width.div_ceil(16).max(4) * 16
}

/// Samples per marked pixel of `aa`: 4, 8 or 16 (a divisor of a 4x4 group; other counts are
/// rounded up to the next of these).
pub fn samples(aa: Antialias) -> u32 {
    match aa.samples {
        0..=4 => 4,
        5..=8 => 8,
        _ => 16,
    }
}

/// The screen-sized textures: a copy of the centre frame's capture data, the mask and its
/// readback, the list of marked pixels, the attachment of the passes run once a marked pixel,
/// the bind group of the edge pass, and the views the resolve reads and writes.
pub(crate) struct AntialiasTargets {
    pub size: [u32; 2],
    pub centre_data: wgpu::Texture,
    centre_rays_view: wgpu::TextureView,
    mask: wgpu::Texture,
    mask_view: wgpu::TextureView,
    source: ListSource,
    pixels: wgpu::Texture,
    pixels_view: wgpu::TextureView,
    /// The attachment a render pass needs, for the passes of one fragment per marked pixel
    /// ([`compact_pass`]): their results are storage writes, it is discarded.
    compact_view: wgpu::TextureView,
    centre_data_view: wgpu::TextureView,
    edges_bg: wgpu::BindGroup,
    /// The frame's colour and data, which the resolve writes at the marked pixels.
    frame: [wgpu::TextureView; 2],
}

/// Where the list of marked pixels comes from.
enum ListSource {
    /// The edge mask read back into `mask_rb`, the list made on the CPU (the screen's tiles
    /// taken in the order `tiles`, [`tile_order`]) and uploaded.
    Cpu {
        mask_rb: wgpu::Buffer,
        tiles: Vec<u32>,
    },
    /// Built on the GPU; only its parts' lengths are read back.
    Gpu(gpu_list::ListTargets),
}

/// The sample atlas of one size: its own frame targets (every pass of the samples runs on
/// them) and the bind groups of the sample rays and the resolve.
pub(crate) struct Atlas {
    pub targets: super::targets::Targets,
    rays_bg: wgpu::BindGroup,
    resolve_bg: wgpu::BindGroup,
}

fn texture(gpu: &Gpu, label: &str, size: [u32; 2], format: F) -> wgpu::Texture {
    screen_texture(&gpu.device, label, size, format, super::util::TARGET_USAGE)
}

fn view_of(t: &wgpu::Texture) -> wgpu::TextureView {
    t.create_view(&Default::default())
}

impl AntialiasPasses {
    pub fn new(gpu: &Gpu, base: &super::terrain_passes::TerrainPasses) -> AntialiasPasses {
        let dev = &gpu.device;
        let fs = wgpu::ShaderStages::FRAGMENT;
        let p = super::util::uniform_entry(gpu.params, 0, fs);
        let u = |b| uint_texture_entry(b, fs);
        let f = |b| float_texture_entry(b, fs, wgpu::TextureViewDimension::D2);
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        };
        let store = |b, format| storage_texture_entry(b, fs, format);
        let layouts = [
            layout("aa edges", &[p, f(2), u(3)]),
            layout("aa rays", &[p, u(1), u(2), store(3, F::Rgba32Uint)]),
            layout(
                "aa resolve",
                &[
                    p,
                    u(1),
                    f(2),
                    u(3),
                    store(5, F::Rgba8Unorm),
                    store(6, F::Rgba32Uint),
                ],
            ),
        ];
        let module = |name: &str, src: String| super::shader_module(dev, gpu.params, name, &src);
        let state = |t: F| Some(target_state(t));
        let edges = fullscreen_pipeline(
            dev,
            "aa edges",
            &module("aa_edges.wgsl", shaders::aa_edges()),
            "fs_edges",
            &layouts[0],
            &[state(F::R8Uint)],
        );
        let rays = fullscreen_pipeline(
            dev,
            "aa rays",
            &module("aa_rays.wgsl", shaders::aa_rays()),
            "fs_sample_rays",
            &layouts[1],
            &[state(F::R8Unorm)],
        );
        let resolve = fullscreen_pipeline(
            dev,
            "aa resolve",
            &module("aa_resolve.wgsl", shaders::aa_resolve()),
            "fs_resolve",
            &layouts[2],
            &[state(F::R8Unorm)],
        );
        let on_gpu = gpu.options.aa_list.on_gpu(&gpu.info);
        AntialiasPasses {
            tile: base.tile_pipeline(gpu, "tile (anti-aliasing atlas)", "fs_tile_table"),
            edges,
            rays,
            resolve,
            list: on_gpu.then(|| gpu_list::ListPasses::new(gpu)),
            layouts,
            params: dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("aa parameters"),
                size: std::mem::size_of::<AaUniforms>() as u64,
                usage: super::PARAM_USAGE,
                mapped_at_creation: false,
            }),
        }
    }

    /// Writes the parameters of a `size` frame anti-aliased as `aa`, for `batch` of the list
    /// (the edge pass reads none of it).
    pub fn write_params(&self, gpu: &Gpu, size: [u32; 2], aa: Antialias, batch: &Batch) {
        let mut offsets = [[0.0f32; 4]; 8];
        for (k, o) in offsets.iter_mut().enumerate() {
            let (a, b) = (sample_offset(2 * k), sample_offset(2 * k + 1));
            *o = [a[0], a[1], b[0], b[1]];
        }
        let u = AaUniforms {
            size: [size[0], size[1], batch.count, samples(aa)],
            atlas: [
                atlas_width(size[0]),
                aa.every_pixel as u32,
                batch.first,
                (aa.adaptive && !aa.every_pixel) as u32,
            ],
            limits: [CONTRAST, KINK, DETAIL, 0.0],
            adapt: [ADAPT_4, ADAPT_8, 0.0, 0.0],
            counts: [
                batch.counts[0],
                batch.counts[1],
                batch.counts[2],
                batch.group,
            ],
            offsets,
            linear: std::array::from_fn(|i| {
                std::array::from_fn(|j| crate::colour::srgb_to_linear((4 * i + j) as u8) as f32)
            }),
        };
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&u));
    }

    fn group(&self, gpu: &Gpu, k: usize, entries: &[wgpu::BindGroupEntry]) -> wgpu::BindGroup {
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("aa"),
            layout: &self.layouts[k],
            entries,
        })
    }

    /// The screen-sized targets of a `size` frame whose centre rays are `ray_table` and whose
    /// colour and data targets are `frame` (the samples run on the atlas's own targets: the
    /// frame's ray table stays).
    pub fn targets(
        &self,
        gpu: &Gpu,
        size: [u32; 2],
        ray_table: &wgpu::TextureView,
        frame: [&wgpu::TextureView; 2],
    ) -> AntialiasTargets {
        let centre_data = texture(gpu, "aa centre data", size, F::Rgba32Uint);
        let compact = texture(gpu, "aa compact passes", size, F::R8Unorm);
        let mask = texture(gpu, "aa mask", size, F::R8Uint);
        let list_usage = super::util::TARGET_USAGE | wgpu::TextureUsages::STORAGE_BINDING;
        let pixels = screen_texture(
            &gpu.device,
            "aa marked pixels",
            size,
            F::R32Uint,
            list_usage,
        );
        let (data_v, mask_v, pixels_v) = (view_of(&centre_data), view_of(&mask), view_of(&pixels));
        let tiles = tile_order(size[0], size[1]);
        let edges_bg = self.group(
            gpu,
            0,
            &[
                super::util::buf(0, &self.params),
                view(2, frame[0]),
                view(3, &data_v),
            ],
        );
        let source = match &self.list {
            Some(l) => ListSource::Gpu(l.targets(gpu, size, &tiles, &mask_v, &pixels_v)),
            None => ListSource::Cpu {
                mask_rb: readback_buffer(&gpu.device, "aa mask readback", size[0], size[1]),
                tiles,
            },
        };
        AntialiasTargets {
            size,
            centre_data,
            centre_rays_view: ray_table.clone(),
            mask_view: mask_v,
            mask,
            source,
            pixels_view: pixels_v,
            pixels,
            compact_view: view_of(&compact),
            centre_data_view: data_v,
            edges_bg,
            frame: frame.map(Clone::clone),
        }
    }

    /// The atlas over `targets` (its frame targets) for the screen targets `t`.
    pub fn atlas(
        &self,
        gpu: &Gpu,
        t: &AntialiasTargets,
        targets: super::targets::Targets,
    ) -> Atlas {
        let params = || super::util::buf(0, &self.params);
        let rays_bg = self.group(
            gpu,
            1,
            &[
                params(),
                view(1, &t.centre_rays_view),
                view(2, &t.pixels_view),
                view(3, &targets.ray_table_view),
            ],
        );
        let resolve_bg = self.group(
            gpu,
            2,
            &[
                params(),
                view(1, &t.pixels_view),
                view(2, &targets.colour_view),
                view(3, &t.centre_data_view),
                view(5, &t.frame[0]),
                view(6, &t.frame[1]),
            ],
        );
        Atlas {
            targets,
            rays_bg,
            resolve_bg,
        }
    }

    /// Records the edge mask over the centre frame, then its readback copy or the list's
    /// passes on the GPU.
    pub fn encode_edges(&self, enc: &mut wgpu::CommandEncoder, t: &AntialiasTargets) {
        super::util::encode_fullscreen(enc, "aa edges", &self.edges, &t.edges_bg, &[&t.mask_view]);
        match &t.source {
            ListSource::Gpu(lt) => lt.encode(enc),
            ListSource::Cpu { mask_rb, .. } => copy_to_readback(enc, &t.mask, mask_rb, t.size[0]),
        }
    }

    /// Records the sample rays of the batch's `count` marked pixels into the atlas's ray
    /// table: the table cleared to "no ray", then one fragment per marked pixel over the
    /// first rows of the compact target storing its samples' rays.
    pub fn encode_rays(
        &self,
        enc: &mut wgpu::CommandEncoder,
        a: &Atlas,
        t: &AntialiasTargets,
        count: u32,
    ) {
        // Direction (0, 0, 1), cone -1: an entry that casts no ray.
        let none = wgpu::Color {
            r: 0.0,
            g: 0.0,
            b: f64::from(1.0f32.to_bits()),
            a: f64::from((-1.0f32).to_bits()),
        };
        let clear = wgpu::Operations {
            load: wgpu::LoadOp::Clear(none),
            store: wgpu::StoreOp::Store,
        };
        drop(render_pass(
            enc,
            "aa rays clear",
            &a.targets.ray_table_view,
            clear,
        ));
        let mut p = compact_pass(enc, "aa sample rays", t, count);
        p.set_pipeline(&self.rays);
        p.set_bind_group(0, &a.rays_bg, &[]);
        p.draw(0..3, 0..1);
    }

    /// Records the resolve of the batch's `count` marked pixels into the frame's colour and
    /// data targets (their other pixels are kept): one fragment per marked pixel over the
    /// first rows of the compact target.
    pub fn encode_resolve(
        &self,
        enc: &mut wgpu::CommandEncoder,
        a: &Atlas,
        t: &AntialiasTargets,
        count: u32,
    ) {
        let mut p = compact_pass(enc, "aa resolve", t, count);
        p.set_pipeline(&self.resolve);
        p.set_bind_group(0, &a.resolve_bg, &[]);
        p.draw(0..3, 0..1);
    }
}

/// A render pass with the one colour attachment `view`.
fn render_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    view: &wgpu::TextureView,
    ops: wgpu::Operations<wgpu::Color>,
) -> wgpu::RenderPass<'e> {
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops,
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// A pass of one fragment per marked pixel of a batch of `count` (rows of the screen's width
/// of the compact target; past `count` a fragment does nothing). Its results are storage
/// writes: the compact target is only the attachment a render pass needs, and is discarded.
fn compact_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    t: &AntialiasTargets,
    count: u32,
) -> wgpu::RenderPass<'e> {
    // SAFETY: nothing reads the compact target (discarded below); a clear of the whole target
    // would cost Mesa's CPU adapters a pass of its own.
    let load = wgpu::LoadOp::DontCare(unsafe { wgpu::LoadOpDontCare::enabled() });
    let ops = wgpu::Operations {
        load,
        store: wgpu::StoreOp::Discard,
    };
    let mut p = render_pass(enc, label, &t.compact_view, ops);
    let rows = count.div_ceil(t.size[0]).max(1);
    p.set_viewport(0.0, 0.0, t.size[0] as f32, rows as f32, 0.0, 1.0);
    p
}

impl AntialiasTargets {
    /// The list of marked pixels in place for the sample passes (after
    /// [`AntialiasPasses::encode_edges`] was submitted): the mask read back, the list made
    /// and uploaded, or the list built on the GPU; returns its parts' lengths (pixels with 16,
    /// 8 and 4 samples).
    pub fn list(&self, gpu: &Gpu) -> crate::Result<[u32; 3]> {
        let (mask_rb, tiles) = match &self.source {
            ListSource::Gpu(lt) => return lt.lengths(gpu),
            ListSource::Cpu { mask_rb, tiles } => (mask_rb, tiles),
        };
        let [w, h] = self.size;
        let bytes = super::util::read_buffer(gpu, mask_rb, w, h)?;
        let list = Marked::from_mask_in(&bytes, w, h, tiles);
        if !list.pixels.is_empty() {
            self.write_pixels(gpu, &list.pixels);
        }
        Ok(list.counts)
    }

    /// Uploads the list of marked pixels (row by row in the screen's width).
    fn write_pixels(&self, gpu: &Gpu, list: &[u32]) {
        let w = self.size[0];
        let rows = (list.len() as u32).div_ceil(w);
        let mut data = list.to_vec();
        data.resize((rows * w) as usize, 0);
        write_rows(gpu, &self.pixels, &data, w, rows);
    }

    /// The most rows an atlas has: about the frame's own (its targets then take about as
    /// much memory as the frame's); a longer list runs in batches.
    fn max_rows(&self) -> u32 {
        self.size[1].div_ceil(ATLAS_ROWS).max(1) * ATLAS_ROWS
    }

    /// Groups (4x4 entries: one pixel's 16 samples, two pixels' 8 or four pixels' 4) one
    /// atlas holds.
    pub fn batch_groups(&self) -> u32 {
        (atlas_width(self.size[0]) / 4) * (self.max_rows() / 4)
    }

    /// The atlas size for a batch of `groups`: [`atlas_width`], rows of 16x16 bins (16
    /// groups of 4x4 entries: a row of bins holds `w` groups) in multiples of [`ATLAS_ROWS`].
    pub fn atlas_size(&self, groups: u32) -> [u32; 2] {
        let w = atlas_width(self.size[0]);
        let rows = groups.div_ceil(w) * 16;
        [
            w,
            (rows.div_ceil(ATLAS_ROWS).max(1) * ATLAS_ROWS).min(self.max_rows()),
        ]
    }
}

/// Records a copy of all of `from` into `to` (same size and format: the centre frame's data
/// kept for the resolve).
pub(crate) fn copy_whole(enc: &mut wgpu::CommandEncoder, from: &wgpu::Texture, to: &wgpu::Texture) {
    enc.copy_texture_to_texture(from.as_image_copy(), to.as_image_copy(), from.size());
}

/// Writes `rows` rows of `w` u32 texels of `data` into the top of `texture`.
fn write_rows(gpu: &Gpu, texture: &wgpu::Texture, data: &[u32], w: u32, rows: u32) {
    gpu.queue.write_texture(
        texture.as_image_copy(),
        bytemuck::cast_slice(data),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(w * 4),
            rows_per_image: Some(rows),
        },
        wgpu::Extent3d {
            width: w,
            height: rows,
            depth_or_array_layers: 1,
        },
    );
}
