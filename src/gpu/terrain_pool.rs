//! The paged terrain on the GPU: a storage buffer of fixed slots and the page table, filled
//! from [`crate::db::pager::Pager`]'s uploads with `queue.write_buffer` (the pager already
//! keeps each frame's uploads within its byte budget), read by `terrain_paged.wgsl`
//! (`cell_max`, `patch_corners`, `finest_resident`).
//!
//! Bound as group 3 of the paged cast and shade pipelines
//! ([`super::TerrainRenderer::new_paged`]).

use super::Gpu;
use crate::db::pager::{PageTable, ResidencyMap, Upload};
use crate::terrain::HeightMapping;
use crate::Result;

/// `PagedParams` in `terrain_paged.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PagedParams {
    pub tile_n: u32,
    pub log2_n: u32,
    pub levels: u32,
    pub slot_floats: u32,
    /// The traversal window's sample (0, 0) on the finest level's global grid (a multiple of
    /// 2^top; 0 until the renderer binds the pool).
    pub origin: [u32; 2],
    /// The residency map's entries a side at its level 0, and its levels
    /// ([`ResidencyMap::shape`]; a one-entry placeholder until the window is set).
    pub map_side: u32,
    pub map_levels: u32,
    /// 2^`pool_shift` slots per pool buffer where the pool spans several
    /// ([`TerrainPool::bindings`]).
    pub pool_shift: u32,
    pub pad: [u32; 3],
}

/// `PagedLevel` in `terrain_paged.wgsl`: a level's page-table offset and tile range.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PagedLevel {
    pub table_offset: u32,
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
    pub pad: [u32; 3],
}

/// The pool, the page table and their parameters on the GPU.
pub struct TerrainPool {
    pub params: wgpu::Buffer,
    pub levels: wgpu::Buffer,
    pub table: wgpu::Buffer,
    /// The pool: one buffer, or several of `pool_slots` whole slots each where the pool
    /// exceeds the adapter's storage-binding size.
    pub pools: Vec<wgpu::Buffer>,
    /// The residency map ([`ResidencyMap`]) of the window.
    pub map: wgpu::Buffer,
    /// Group 3's layout and bind group (the buffers above).
    pub bgl: wgpu::BindGroupLayout,
    pub bind_group: wgpu::BindGroup,
    params_host: PagedParams,
    /// The page table as last applied, and the window's map of it (none until
    /// [`TerrainPool::set_window`]).
    table_host: PageTable,
    map_host: Option<ResidencyMap>,
    slot_floats: u64,
    slots: usize,
    pool_slots: usize,
    n: usize,
    /// The traversal's top level over the window (`cpu::paged::traversal_top`; 0 until
    /// [`TerrainPool::set_window`]).
    traversal_top: u32,
    /// The scene's sea level and vertical scale, applied to each tile as it is copied in.
    heights: HeightMapping,
}

/// The binding of pool buffer `k` (`gpu::shaders::paged_pools`).
fn pool_binding(k: usize) -> u32 {
    if k == 0 {
        3
    } else {
        4 + k as u32
    }
}

/// Group 3's layout: `PagedParams` (uniform), levels, page table, the residency map (4) and
/// `pools` pool buffers (3, 5, 6, 7) (storage).
fn pool_layout(gpu: &Gpu, pools: usize) -> wgpu::BindGroupLayout {
    use super::util::{storage_entry, uniform_entry};
    let fs = wgpu::ShaderStages::FRAGMENT;
    let mut entries = vec![
        uniform_entry(gpu.params, 0, fs),
        storage_entry(1, fs, true),
        storage_entry(2, fs, true),
        storage_entry(4, fs, true),
    ];
    entries.extend((0..pools).map(|k| storage_entry(pool_binding(k), fs, true)));
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("terrain pool"),
            entries: &entries,
        })
}

/// The level records and parameters for `table` with tiles of `n` cells.
pub fn layout(table: &PageTable, n: usize) -> (PagedParams, Vec<PagedLevel>) {
    let levels = table
        .levels()
        .iter()
        .zip(table.offsets())
        .map(|(l, &off)| PagedLevel {
            table_offset: off as u32,
            x0: l.x0,
            y0: l.y0,
            width: l.x1 - l.x0,
            height: l.y1 - l.y0,
            pad: [0; 3],
        })
        .collect::<Vec<_>>();
    let params = PagedParams {
        tile_n: n as u32,
        log2_n: n.trailing_zeros(),
        levels: levels.len() as u32,
        slot_floats: crate::db::Tile::floats(n) as u32,
        origin: [0; 2],
        map_side: 1,
        map_levels: 1,
        pool_shift: 0,
        pad: [0; 3],
    };
    (params, levels)
}

impl TerrainPool {
    /// Buffers for `slots` slots of tiles of `n` cells and the page table's shape. A pool
    /// larger than the adapter's storage-binding size is split into buffers of whole slots
    /// (lavapipe and GL bind 128 MiB: a 256 MB pool of 256-cell tiles takes four of 128
    /// slots); an error naming `--terrain-memory` where it would need more than
    /// [`shaders::MAX_POOL_BINDINGS`] (or more slots than the residency map's 24 bits hold).
    ///
    /// [`shaders::MAX_POOL_BINDINGS`]: super::shaders::MAX_POOL_BINDINGS
    pub fn new(gpu: &Gpu, table: &PageTable, n: usize, slots: usize) -> Result<TerrainPool> {
        Self::with_binding_limit(gpu, table, n, slots, u64::MAX)
    }

    /// [`TerrainPool::new`] splitting the pool at `limit` bytes a buffer where that is below
    /// the adapter's binding size (tests: the split path on any adapter).
    pub fn with_binding_limit(
        gpu: &Gpu,
        table: &PageTable,
        n: usize,
        slots: usize,
        limit: u64,
    ) -> Result<TerrainPool> {
        use wgpu::util::DeviceExt;
        let (mut params, levels) = layout(table, n);
        let slot_floats = params.slot_floats as u64;
        let slot_bytes = slot_floats * 4;
        let limit = gpu
            .limits
            .max_storage_buffer_binding_size
            .min(gpu.limits.max_buffer_size)
            .min(limit);
        // One buffer where the whole pool fits, otherwise buffers of a power of two of slots
        // (the shader splits a slot number with a shift and a mask: no division per read).
        let fit = (limit / slot_bytes) as usize;
        let pool_slots = if fit >= slots {
            slots.max(1)
        } else if fit == 0 {
            0
        } else {
            1 << fit.ilog2()
        };
        let max = super::shaders::MAX_POOL_BINDINGS as usize;
        let too_many = slots > crate::db::pager::residency::SLOT_MASK as usize;
        if pool_slots == 0 || slots.div_ceil(pool_slots) > max || too_many {
            let most = pool_slots as u64 * max as u64 * slot_bytes;
            return Err(crate::Error::Limit {
                what: "terrain pool".into(),
                msg: format!(
                    "{} bytes needed, the adapter {} binds {limit} bytes per storage buffer and \
                     the pool spans at most {max} of them ({most} bytes of whole tiles): give a \
                     smaller --terrain-memory",
                    slot_bytes * slots as u64,
                    gpu.info.name
                ),
            });
        }
        let buffers = slots.div_ceil(pool_slots).max(1);
        params.pool_shift = pool_slots.trailing_zeros();
        let dev = &gpu.device;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let init = |label: &str, contents: &[u8], usage| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let params_buf = init(
            "paged params",
            bytemuck::bytes_of(&params),
            super::PARAM_USAGE,
        );
        let levels_buf = init("paged levels", bytemuck::cast_slice(&levels), storage);
        let table_buf = init("paged table", bytemuck::cast_slice(table.raw()), storage);
        let pools: Vec<wgpu::Buffer> = (0..buffers)
            .map(|k| {
                let here = pool_slots.min(slots - (k * pool_slots).min(slots));
                dev.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("terrain pool"),
                    size: (here as u64 * slot_bytes).max(4),
                    usage: storage,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let map = init(
            "residency map",
            bytemuck::bytes_of(&crate::db::pager::residency::MAP_NONE),
            storage,
        );
        let bgl = pool_layout(gpu, pools.len());
        let bind_group = bind(
            gpu,
            &bgl,
            [&params_buf, &levels_buf, &table_buf, &map],
            &pools,
        );
        Ok(TerrainPool {
            params: params_buf,
            levels: levels_buf,
            table: table_buf,
            pools,
            map,
            bgl,
            bind_group,
            params_host: params,
            table_host: table.clone(),
            map_host: None,
            slot_floats,
            slots,
            pool_slots,
            n,
            traversal_top: 0,
            heights: HeightMapping::IDENTITY,
        })
    }

    /// The storage bindings the pool spans (`ShadeFeatures::paged`, `shaders::paged_pools`).
    pub fn bindings(&self) -> u32 {
        self.pools.len() as u32
    }

    /// Sets the traversal window: its sample (0, 0) on the finest level's global grid (on a
    /// tile's corner: `cpu::paged::check_origin`) and its pyramid's top level; makes the
    /// window's residency map of the page table as last applied for the traversal's top
    /// level ([`TerrainPool::traversal_top`]).
    pub fn set_window(&mut self, gpu: &Gpu, origin: [u32; 2], top: u32) {
        use wgpu::util::DeviceExt;
        let o = [origin[0] as i64, origin[1] as i64];
        self.traversal_top = crate::cpu::paged::traversal_top(o, top as usize) as u32;
        let m = ResidencyMap::new(
            &self.table_host,
            self.n.trailing_zeros(),
            [origin[0] as u64, origin[1] as u64],
            self.traversal_top,
            top,
        );
        (self.params_host.map_side, self.params_host.map_levels) = m.shape();
        self.params_host.origin = origin;
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&self.params_host));
        self.map = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("residency map"),
                contents: bytemuck::cast_slice(m.raw()),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            });
        self.bind_group = bind(
            gpu,
            &self.bgl,
            [&self.params, &self.levels, &self.table, &self.map],
            &self.pools,
        );
        self.map_host = Some(m);
    }

    /// Cells a tile side.
    pub fn tile_cells(&self) -> usize {
        self.n
    }

    /// The level the paged traversal starts from: the window pyramid's top where the window
    /// is aligned to its top cell, else the highest level its origin is aligned to.
    pub fn traversal_top(&self) -> u32 {
        self.traversal_top
    }

    /// Slots in the pool and their bytes on the GPU.
    pub fn size(&self) -> (usize, u64) {
        (self.slots, self.slots as u64 * self.slot_floats * 4)
    }

    /// Sets the sea level and vertical scale the tiles copied in from now on get (the
    /// scene's `[terrain]`, as its window would have on load; the identity until set).
    pub fn set_height_mapping(&mut self, heights: HeightMapping) {
        self.heights = heights;
    }

    /// Copies this frame's uploads into their slots (heights and cell maxima through the
    /// height mapping), the page table as it now stands and the window's residency map of it.
    pub fn apply(&mut self, gpu: &Gpu, uploads: &[Upload], table: &PageTable) {
        for u in uploads {
            debug_assert_eq!(u.tile.n, self.n);
            let (b, s) = (
                u.slot as usize / self.pool_slots,
                u.slot as usize % self.pool_slots,
            );
            let pool = &self.pools[b];
            let at = s as u64 * self.slot_floats * 4;
            let h = u.tile.heights.len() as u64 * 4;
            if self.heights.is_identity() {
                gpu.queue
                    .write_buffer(pool, at, bytemuck::cast_slice(&u.tile.heights));
                gpu.queue
                    .write_buffer(pool, at + h, bytemuck::cast_slice(&u.tile.maxima));
            } else {
                let m = self.heights;
                let heights: Vec<f32> = u.tile.heights.iter().map(|&v| m.sample(v)).collect();
                let maxima: Vec<f32> = u.tile.maxima.iter().map(|&v| m.maximum(v)).collect();
                gpu.queue
                    .write_buffer(pool, at, bytemuck::cast_slice(&heights));
                gpu.queue
                    .write_buffer(pool, at + h, bytemuck::cast_slice(&maxima));
            }
        }
        if !uploads.is_empty() {
            gpu.queue
                .write_buffer(&self.table, 0, bytemuck::cast_slice(table.raw()));
            self.table_host.clone_from(table);
            if let Some(m) = &mut self.map_host {
                m.update(table);
                gpu.queue
                    .write_buffer(&self.map, 0, bytemuck::cast_slice(m.raw()));
            }
        }
    }
}

/// Group 3's bind group: parameters, levels, page table, residency map, pool buffers.
fn bind(
    gpu: &Gpu,
    bgl: &wgpu::BindGroupLayout,
    b: [&wgpu::Buffer; 4],
    pools: &[wgpu::Buffer],
) -> wgpu::BindGroup {
    use super::util::buf;
    let mut entries = vec![buf(0, b[0]), buf(1, b[1]), buf(2, b[2]), buf(4, b[3])];
    entries.extend(
        pools
            .iter()
            .enumerate()
            .map(|(k, p)| buf(pool_binding(k), p)),
    );
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("terrain pool"),
        layout: bgl,
        entries: &entries,
    })
}
