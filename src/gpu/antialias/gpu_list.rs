//! The list of marked pixels built on the GPU (`aa_list.wgsl`, [`crate::gpu::ListChoice`]):
//! three compute dispatches turn the edge mask into the list [`super::Marked`] makes on the
//! CPU, entry for entry, and the CPU reads back only the lengths of its three parts (16
//! bytes, which size the atlas and its batches) instead of the mask (a byte a pixel), which
//! it would then walk and upload again as the list. The default on GPUs; Mesa's CPU adapters
//! run compute on about one core and keep the CPU list (figures in `docs/antialiasing.md`).

use super::super::util::{
    buf, copy_to_readback, pipeline_layout, read_buffer, readback_buffer, storage_entry,
    storage_texture_entry, uint_texture_entry, uniform_entry, view,
};
use super::super::{shaders, Gpu};
use crate::Result;

/// Mirrors WGSL `ListParams` in `shaders/aa_list.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct ListUniforms {
    size: [u32; 4],
}

/// The three pipelines (count, scan, place) and their bind-group layout, built once.
pub(crate) struct ListPasses {
    count: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    place: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

/// The buffers of one screen size: the parameters, the tiles in list order, the per-tile
/// counts (then places) with the parts' lengths after them, and the lengths' readback.
pub(crate) struct ListTargets {
    /// The passes' pipelines: count, scan, place.
    pipelines: [wgpu::ComputePipeline; 3],
    tiles: u32,
    /// Workgroups of a dispatch over the tiles: as wide as the adapter allows, then rows.
    groups: [u32; 2],
    tile_counts: wgpu::Buffer,
    lengths_rb: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// Kept alive for the bind group.
    _buffers: [wgpu::Buffer; 2],
}

const LENGTHS_BYTES: u64 = 16;

impl ListPasses {
    pub fn new(gpu: &Gpu) -> ListPasses {
        let dev = &gpu.device;
        let cs = wgpu::ShaderStages::COMPUTE;
        let layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("aa list"),
            entries: &[
                uniform_entry(gpu.params, 0, cs),
                uint_texture_entry(1, cs),
                storage_entry(2, cs, true),
                storage_entry(3, cs, false),
                storage_texture_entry(4, cs, wgpu::TextureFormat::R32Uint),
            ],
        });
        let module =
            super::super::shader_module(dev, gpu.params, "aa_list.wgsl", &shaders::aa_list());
        let pl = pipeline_layout(dev, &layout);
        let pipeline = |entry: &str| {
            dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pl),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        ListPasses {
            count: pipeline("cs_count"),
            scan: pipeline("cs_scan"),
            place: pipeline("cs_place"),
            layout,
        }
    }

    /// The buffers of a `size` screen whose tiles the list takes in `order`
    /// ([`super::tile_order`]), reading the edge mask `mask` and writing the list into `list`
    /// (an `R32Uint` screen-sized storage texture).
    pub fn targets(
        &self,
        gpu: &Gpu,
        size: [u32; 2],
        order: &[u32],
        mask: &wgpu::TextureView,
        list: &wgpu::TextureView,
    ) -> ListTargets {
        use wgpu::util::DeviceExt;
        let dev = &gpu.device;
        let init = |label, contents: &[u8], usage| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let u = ListUniforms {
            size: [size[0], size[1], 0, 0],
        };
        let params = init(
            "aa list parameters",
            bytemuck::bytes_of(&u),
            super::super::PARAM_USAGE,
        );
        let tiles = init(
            "aa list tiles",
            bytemuck::cast_slice(order),
            wgpu::BufferUsages::STORAGE,
        );
        let n = order.len() as u32;
        let tile_counts = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("aa list tile counts"),
            size: (u64::from(n) + 1) * LENGTHS_BYTES,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let lengths_rb = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("aa list lengths readback"),
            size: LENGTHS_BYTES,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let bind_group = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("aa list"),
            layout: &self.layout,
            entries: &[
                buf(0, &params),
                view(1, mask),
                buf(2, &tiles),
                buf(3, &tile_counts),
                view(4, list),
            ],
        });
        // 64 tiles a workgroup (`list_tile`).
        let wide = dev.limits().max_compute_workgroups_per_dimension.max(1);
        let workgroups = n.div_ceil(64);
        let x = workgroups.clamp(1, wide);
        ListTargets {
            pipelines: [&self.count, &self.scan, &self.place].map(Clone::clone),
            tiles: n,
            groups: [x, workgroups.div_ceil(x).max(1)],
            tile_counts,
            lengths_rb,
            bind_group,
            _buffers: [params, tiles],
        }
    }
}

impl ListTargets {
    /// Records the list's three dispatches over the mask and the copy of its parts' lengths
    /// to their readback ([`ListTargets::lengths`] once submitted).
    pub fn encode(&self, enc: &mut wgpu::CommandEncoder) {
        let [x, y] = self.groups;
        // A pass each: the scan reads every tile's count, the placing every tile's place.
        let labels = ["aa list count", "aa list scan", "aa list place"];
        for ((label, pipeline), groups) in
            labels
                .iter()
                .zip(&self.pipelines)
                .zip([[x, y], [1, 1], [x, y]])
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(label),
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.dispatch_workgroups(groups[0], groups[1], 1);
        }
        enc.copy_buffer_to_buffer(
            &self.tile_counts,
            u64::from(self.tiles) * LENGTHS_BYTES,
            &self.lengths_rb,
            0,
            LENGTHS_BYTES,
        );
    }

    /// The list's parts' lengths (pixels with 16, 8 and 4 samples), after
    /// [`ListTargets::encode`] was submitted.
    pub fn lengths(&self, gpu: &Gpu) -> Result<[u32; 3]> {
        let bytes = read_buffer(gpu, &self.lengths_rb, LENGTHS_BYTES as u32, 1)?;
        let v: [u32; 4] = bytemuck::pod_read_unaligned(&bytes);
        Ok([v[0], v[1], v[2]])
    }
}

/// Refuses a mask that is not `w` x `h` bytes.
fn check_mask(mask: &[u8], w: u32, h: u32) -> Result<()> {
    if w == 0 || h == 0 || mask.len() as u64 != u64::from(w) * u64::from(h) {
        return Err(crate::Error::invalid(
            "mask",
            format!("{} bytes for a {w}x{h} screen", mask.len()),
        ));
    }
    Ok(())
}

/// The list of a `w` x `h` edge mask (a byte a pixel: 16, 8, 4 or unmarked) built on the
/// GPU, read back: its pixels (x | y << 16) and its parts' lengths. For tests, which compare
/// it with [`list_on_cpu`]; frames never read the list back.
#[doc(hidden)]
pub fn list_on_gpu(gpu: &Gpu, mask: &[u8], w: u32, h: u32) -> Result<(Vec<u32>, [u32; 3])> {
    check_mask(mask, w, h)?;
    let most = gpu.device.limits().max_texture_dimension_2d;
    if w.max(h) > most {
        return Err(crate::Error::invalid(
            "mask",
            format!("{w}x{h} is over the adapter's {most} texels a side"),
        ));
    }
    let dev = &gpu.device;
    let texture = |label, format, usage| {
        super::super::util::screen_texture(dev, label, [w, h], format, usage)
    };
    let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
    let mask_t = texture("aa list test mask", wgpu::TextureFormat::R8Uint, usage);
    let list_usage = wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC;
    let list_t = texture(
        "aa list test list",
        wgpu::TextureFormat::R32Uint,
        list_usage,
    );
    let extent = mask_t.size();
    gpu.queue.write_texture(
        mask_t.as_image_copy(),
        mask,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(w),
            rows_per_image: Some(h),
        },
        extent,
    );
    let passes = ListPasses::new(gpu);
    let order = super::tile_order(w, h);
    let view_of = |t: &wgpu::Texture| t.create_view(&Default::default());
    let targets = passes.targets(gpu, [w, h], &order, &view_of(&mask_t), &view_of(&list_t));
    let rb = readback_buffer(dev, "aa list test readback", w * 4, h);
    let mut enc = dev.create_command_encoder(&Default::default());
    targets.encode(&mut enc);
    copy_to_readback(&mut enc, &list_t, &rb, w * 4);
    gpu.queue.submit([enc.finish()]);
    let lengths = targets.lengths(gpu)?;
    let bytes = read_buffer(gpu, &rb, w * 4, h)?;
    let total = lengths.iter().map(|&n| n as usize).sum::<usize>();
    let pixels: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
    Ok((pixels[..total.min(pixels.len())].to_vec(), lengths))
}

/// The list of a `w` x `h` edge mask made on the CPU (what frames on CPU adapters use), as
/// [`list_on_gpu`] returns it.
#[doc(hidden)]
pub fn list_on_cpu(mask: &[u8], w: u32, h: u32) -> Result<(Vec<u32>, [u32; 3])> {
    check_mask(mask, w, h)?;
    let m = super::Marked::from_mask_in(mask, w, h, &super::tile_order(w, h));
    Ok((m.pixels, m.counts))
}
