//! GPU time per frame of the window loop from timestamp queries: an empty pass writes a
//! timestamp before and after the frame's work, and a small ring of buffers reads them back
//! without waiting.

use crate::gpu::Gpu;
use std::sync::{Arc, Mutex};

/// GPU time per frame from timestamp queries (two per frame, a small ring of readbacks).
pub struct GpuTimer {
    queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    slots: Vec<TimerSlot>,
    period_ns: f64,
}

struct TimerSlot {
    buffer: wgpu::Buffer,
    /// Frame whose times the buffer holds (or will once mapped).
    frame: Option<u64>,
    mapped: Arc<Mutex<Option<std::result::Result<(), wgpu::BufferAsyncError>>>>,
}

/// Frames whose timestamps can be in flight at once.
pub const TIMER_SLOTS: u64 = 4;

impl GpuTimer {
    pub fn new(gpu: &Gpu) -> GpuTimer {
        let queries = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("frame timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 2 * TIMER_SLOTS as u32,
        });
        let resolve = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timestamp resolve"),
            size: 256 * TIMER_SLOTS,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let slots = (0..TIMER_SLOTS)
            .map(|_| TimerSlot {
                buffer: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("timestamp readback"),
                    size: 16,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                }),
                frame: None,
                mapped: Arc::new(Mutex::new(None)),
            })
            .collect();
        GpuTimer {
            queries,
            resolve,
            slots,
            period_ns: gpu.queue.get_timestamp_period() as f64,
        }
    }

    /// Query index pair for `frame`, or `None` while that slot's last readback is pending.
    pub fn slot(&self, frame: u64) -> Option<u32> {
        let s = (frame % TIMER_SLOTS) as usize;
        self.slots[s].frame.is_none().then_some(s as u32)
    }

    /// An empty pass that writes timestamp `index`.
    pub fn stamp(&self, enc: &mut wgpu::CommandEncoder, index: u32) {
        enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("timestamp"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: &self.queries,
                beginning_of_pass_write_index: Some(index),
                end_of_pass_write_index: None,
            }),
        });
    }

    /// Resolves slot `slot`'s two timestamps and copies them to its readback buffer.
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder, slot: u32) {
        let q = 2 * slot;
        enc.resolve_query_set(&self.queries, q..q + 2, &self.resolve, 256 * slot as u64);
        enc.copy_buffer_to_buffer(
            &self.resolve,
            256 * slot as u64,
            &self.slots[slot as usize].buffer,
            0,
            16,
        );
    }

    /// Maps slot `slot`'s readback buffer; its times belong to `frame`.
    pub fn start_readback(&mut self, slot: u32, frame: u64) {
        let s = &mut self.slots[slot as usize];
        s.frame = Some(frame);
        let cell = s.mapped.clone();
        s.buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            *cell.lock().unwrap() = Some(r)
        });
    }

    /// (frame, GPU milliseconds) of every readback that has arrived.
    pub fn collect(&mut self) -> Vec<(u64, f64)> {
        let mut out = Vec::new();
        for s in &mut self.slots {
            let Some(frame) = s.frame else { continue };
            let Some(r) = s.mapped.lock().unwrap().take() else {
                continue;
            };
            if r.is_ok() {
                if let Ok(view) = s.buffer.get_mapped_range(..) {
                    let t: &[u64] = bytemuck::cast_slice(&view[..16]);
                    if t[1] >= t[0] && t[0] != 0 {
                        out.push((frame, (t[1] - t[0]) as f64 * self.period_ns * 1e-6));
                    }
                }
                s.buffer.unmap();
            }
            s.frame = None;
        }
        out
    }
}
