//! The GPU options of the command line (`--kernels`, `--trace-passes`), set once by `main`
//! before any command opens the adapter, and the adapter opened with them.

use crate::gpu::{Gpu, GpuOptions};
use crate::Result;
use std::sync::OnceLock;

static OPTIONS: OnceLock<GpuOptions> = OnceLock::new();

/// Sets the options every command opens the GPU with; the first call wins.
pub fn set(options: GpuOptions) {
    let _ = OPTIONS.set(options);
}

/// The options set by [`set`], or the defaults (kernels by adapter, no pass tracing).
pub fn get() -> GpuOptions {
    OPTIONS.get().copied().unwrap_or_default()
}

/// The adapter relief renders on (`WGPU_BACKEND`, `WGPU_ADAPTER_NAME`) with [`get`]'s options.
pub fn open() -> Result<Gpu> {
    Gpu::with_options(get())
}
