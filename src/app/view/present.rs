//! The present pass: renderer colour target (or a debug view) → swap-chain image, with the text
//! overlay drawn by a 5x7 bitmap font in the same pass (`src/gpu/shaders/present.wgsl`).

use bytemuck::{Pod, Zeroable};

/// Overlay text grid: at most this many columns and rows.
pub const OVERLAY_COLS: usize = 64;
pub const OVERLAY_ROWS: usize = 6;
const TEXT_WORDS: usize = 24 * 4;

/// WGSL source of the present pass (with the shared full-screen vertex stage).
pub fn present_shader() -> String {
    crate::gpu::shaders::present()
}

/// Mirrors WGSL `Present` in `present.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct PresentUniforms {
    /// Source width, height; destination width, height.
    pub sizes: [u32; 4],
    /// View (0 colour, 1 depth, 2 steps), decode sRGB, overlay columns, overlay rows.
    pub mode: [u32; 4],
    /// Overlay scale, origin x, origin y, unused.
    pub overlay: [u32; 4],
    pub text: [[u32; 4]; 24],
    pub font: [[u32; 4]; 48],
}

const _: () = assert!(std::mem::size_of::<PresentUniforms>() == 16 * (3 + 24 + 48));
const _: () = assert!(OVERLAY_COLS * OVERLAY_ROWS <= TEXT_WORDS * 4);

/// Debug views of the present pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewMode {
    Colour = 0,
    Depth = 1,
    Steps = 2,
}

impl ViewMode {
    pub fn next(self) -> ViewMode {
        match self {
            ViewMode::Colour => ViewMode::Depth,
            ViewMode::Depth => ViewMode::Steps,
            ViewMode::Steps => ViewMode::Colour,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            ViewMode::Colour => "COLOUR",
            ViewMode::Depth => "DEPTH",
            ViewMode::Steps => "STEPS",
        }
    }

    /// `colour` (or `color`), `depth` or `steps` (the command line's `--debug-view`).
    pub fn parse(s: &str) -> Result<ViewMode, String> {
        match s {
            "colour" | "color" => Ok(ViewMode::Colour),
            "depth" => Ok(ViewMode::Depth),
            "steps" => Ok(ViewMode::Steps),
            _ => Err(format!("`{s}`: use colour, depth or steps")),
        }
    }
}

/// 5x7 glyphs, rows top to bottom, bit 4 = leftmost pixel.
const GLYPHS: &[(char, [u8; 7])] = &[
    ('0', [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E]),
    ('1', [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E]),
    ('2', [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F]),
    ('3', [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E]),
    ('4', [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02]),
    ('5', [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E]),
    ('6', [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E]),
    ('7', [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08]),
    ('8', [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E]),
    ('9', [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C]),
    ('A', [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11]),
    ('B', [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E]),
    ('C', [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E]),
    ('D', [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C]),
    ('E', [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F]),
    ('F', [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10]),
    ('G', [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F]),
    ('H', [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11]),
    ('I', [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E]),
    ('J', [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C]),
    ('K', [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11]),
    ('L', [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F]),
    ('M', [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11]),
    ('N', [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11]),
    ('O', [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E]),
    ('P', [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10]),
    ('Q', [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D]),
    ('R', [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11]),
    ('S', [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E]),
    ('T', [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04]),
    ('U', [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E]),
    ('V', [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04]),
    ('W', [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A]),
    ('X', [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11]),
    ('Y', [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04]),
    ('Z', [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F]),
    ('.', [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C]),
    (',', [0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08]),
    (':', [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00]),
    ('-', [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00]),
    ('+', [0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00]),
    ('/', [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00]),
    ('%', [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03]),
    ('(', [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02]),
    (')', [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08]),
    ('=', [0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00]),
    ('_', [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F]),
    ('!', [0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x04]),
    ('?', [0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04]),
    ('*', [0x00, 0x04, 0x15, 0x0E, 0x15, 0x04, 0x00]),
    ('\'', [0x0C, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00]),
    ('[', [0x0E, 0x08, 0x08, 0x08, 0x08, 0x08, 0x0E]),
    (']', [0x0E, 0x02, 0x02, 0x02, 0x02, 0x02, 0x0E]),
    ('<', [0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02]),
    ('>', [0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08]),
    ('|', [0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04]),
    ('#', [0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A]),
];

/// The font table of [`PresentUniforms::font`]: glyph `c - 32` at words `2g`, `2g + 1`.
pub fn font_words() -> [[u32; 4]; 48] {
    let mut words = [0u32; 192];
    for (c, rows) in GLYPHS {
        let g = *c as usize - 32;
        let pack = |rs: &[u8]| {
            rs.iter()
                .enumerate()
                .fold(0u32, |w, (i, r)| w | (u32::from(r & 0x1f) << (5 * i)))
        };
        words[2 * g] = pack(&rows[..4]);
        words[2 * g + 1] = pack(&rows[4..]);
    }
    let mut out = [[0u32; 4]; 48];
    for (i, w) in words.iter().enumerate() {
        out[i / 4][i % 4] = *w;
    }
    out
}

/// Pixel (`x`, `y`) of glyph `c` as the shader reads it (lower case as upper case; characters
/// without a glyph are blank). For tests of the font table.
pub fn glyph_pixel(font: &[[u32; 4]; 48], c: char, x: u32, y: u32) -> bool {
    let c = c.to_ascii_uppercase() as u32;
    if !(33..128).contains(&c) || x >= 5 || y >= 7 {
        return false;
    }
    let g = (c - 32) as usize;
    let (k, row) = if y < 4 { (0, y) } else { (1, y - 4) };
    let i = 2 * g + k;
    (font[i / 4][i % 4] >> (5 * row) >> (4 - x)) & 1 == 1
}

/// Packs overlay lines into the text grid; returns the words, columns and rows used. Lower case
/// is shown as upper case; lines and columns beyond the grid are cut.
pub fn pack_text(lines: &[String]) -> ([[u32; 4]; 24], u32, u32) {
    let rows = lines.len().min(OVERLAY_ROWS);
    let cols = lines
        .iter()
        .take(rows)
        .map(|l| l.chars().count())
        .max()
        .unwrap_or(0)
        .min(OVERLAY_COLS);
    let mut bytes = vec![b' '; TEXT_WORDS * 4];
    for (r, line) in lines.iter().take(rows).enumerate() {
        for (c, ch) in line.chars().take(cols).enumerate() {
            let ch = ch.to_ascii_uppercase();
            bytes[r * cols + c] = if ch.is_ascii() { ch as u8 } else { b'?' };
        }
    }
    let mut out = [[0u32; 4]; 24];
    for (i, w) in bytes.chunks_exact(4).enumerate() {
        out[i / 4][i % 4] = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
    }
    (out, cols as u32, rows as u32)
}

/// The present pipeline for one swap-chain format.
pub struct PresentPass {
    pipeline: wgpu::RenderPipeline,
    bgl: wgpu::BindGroupLayout,
    uniforms: wgpu::Buffer,
    /// The pipeline writes linear values that the `*Srgb` target encodes.
    pub decode_srgb: bool,
}

impl PresentPass {
    /// A pipeline drawing into views of `format` (parameters bound in `gpu.params`).
    pub fn new(gpu: &crate::gpu::Gpu, format: wgpu::TextureFormat) -> PresentPass {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("present.wgsl"),
            source: wgpu::ShaderSource::Wgsl(gpu.params.wgsl(&present_shader()).into()),
        });
        let fs = wgpu::ShaderStages::FRAGMENT;
        let texture = |binding, sample_type| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: fs,
            ty: wgpu::BindingType::Texture {
                sample_type,
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let bgl = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("present"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: fs,
                    ty: wgpu::BindingType::Buffer {
                        ty: gpu.params.binding_type(),
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                texture(1, wgpu::TextureSampleType::Float { filterable: false }),
                texture(2, wgpu::TextureSampleType::Uint),
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("present"),
            bind_group_layouts: &[Some(&bgl)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("present"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_fullscreen"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_present"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("present uniforms"),
            size: std::mem::size_of::<PresentUniforms>() as u64,
            usage: crate::gpu::PARAM_USAGE,
            mapped_at_creation: false,
        });
        PresentPass {
            pipeline,
            bgl,
            uniforms,
            decode_srgb: format.is_srgb(),
        }
    }

    /// Records the pass from `colour`/`data` (the renderer's targets) into `target`.
    pub fn encode(
        &self,
        gpu: &crate::gpu::Gpu,
        enc: &mut wgpu::CommandEncoder,
        colour: &wgpu::TextureView,
        data: &wgpu::TextureView,
        target: &wgpu::TextureView,
        uniforms: &PresentUniforms,
    ) {
        let mut u = *uniforms;
        u.mode[1] = self.decode_srgb as u32;
        gpu.queue
            .write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&u));
        let bg = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("present"),
            layout: &self.bgl,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.uniforms.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(colour),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(data),
                },
            ],
        });
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("present"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bg, &[]);
        pass.draw(0..3, 0..1);
    }
}
