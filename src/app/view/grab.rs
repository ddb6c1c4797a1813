//! `relief view --grab`: the swap-chain image read back through a copy, and on X11 the
//! window's pixels as the X server holds them, both written as PNG.

use crate::app::output::write_png;
use crate::gpu::Gpu;
use crate::{Error, Result};
use std::path::Path;
use std::sync::mpsc;
use std::time::Duration;
use winit::window::Window;

/// A buffer the swap-chain texture `tex` is copied into by `enc`; returns it with its row pitch.
pub fn copy_surface(
    gpu: &Gpu,
    enc: &mut wgpu::CommandEncoder,
    tex: &wgpu::Texture,
) -> (wgpu::Buffer, u32) {
    let (sw, sh) = (tex.width(), tex.height());
    let row = (sw * 4).div_ceil(256) * 256;
    let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("surface readback"),
        size: row as u64 * sh as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    enc.copy_texture_to_buffer(
        tex.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(sh),
            },
        },
        tex.size(),
    );
    (buf, row)
}

/// What `--grab` writes at frame `n` for a window presented at `size`: `surface_NNNN.png`
/// from the copy made by [`copy_surface`] (when the surface allowed it) and `x11_NNNN.png`,
/// `suffix` naming the channel when there are several windows.
#[allow(clippy::too_many_arguments)]
pub fn write_grabs(
    gpu: &Gpu,
    window: &Window,
    copy: Option<(wgpu::Buffer, u32)>,
    format: wgpu::TextureFormat,
    dir: &Path,
    n: u64,
    suffix: &str,
    (sw, sh): (u32, u32),
) -> Result<()> {
    match copy {
        Some((buf, row)) => {
            let rgba = read_surface(gpu, &buf, row, sw, sh, format)?;
            let p = dir.join(format!("surface_{n:04}{suffix}.png"));
            write_png(&p, sw, sh, &rgba)?;
            log::info!("frame {n}: swap-chain image read back to {}", p.display());
        }
        None => {
            log::warn!("the surface does not allow COPY_SRC: no swap-chain readback")
        }
    }
    grab_x11(window, dir, n, suffix, sw, sh);
    Ok(())
}

/// Maps a swap-chain readback and returns RGBA8 rows (BGRA formats swizzled).
pub fn read_surface(
    gpu: &Gpu,
    buf: &wgpu::Buffer,
    row: u32,
    w: u32,
    h: u32,
    format: wgpu::TextureFormat,
) -> Result<Vec<u8>> {
    let (tx, rx) = mpsc::channel();
    buf.slice(..)
        .map_async(wgpu::MapMode::Read, move |r| drop(tx.send(r)));
    gpu.wait()?;
    rx.recv()
        .map_err(|_| Error::Gpu("surface readback callback never ran".into()))?
        .map_err(|e| Error::Gpu(format!("mapping the surface readback: {e}")))?;
    let bgra = matches!(
        format,
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    );
    let mut out = Vec::with_capacity((w * h * 4) as usize);
    {
        let view = buf
            .get_mapped_range(..)
            .map_err(|e| Error::Gpu(format!("surface readback range: {e}")))?;
        for r in 0..h as usize {
            for px in view[r * row as usize..][..w as usize * 4].chunks_exact(4) {
                if bgra {
                    out.extend_from_slice(&[px[2], px[1], px[0], px[3]]);
                } else {
                    out.extend_from_slice(px);
                }
            }
        }
    }
    buf.unmap();
    Ok(out)
}

/// Reads the window back from the X server once the presented image has settled (two equal
/// reads in a row); writes `x11_NNNN.png`. Logs why when it cannot.
#[allow(unused_variables)]
pub fn grab_x11(window: &Window, dir: &Path, n: u64, suffix: &str, w: u32, h: u32) {
    #[cfg(target_os = "linux")]
    {
        use winit::raw_window_handle::{HasWindowHandle, RawWindowHandle};
        let id = match window.window_handle().map(|h| h.as_raw()) {
            Ok(RawWindowHandle::Xlib(x)) => x.window,
            Ok(RawWindowHandle::Xcb(x)) => x.window.get() as u64,
            _ => {
                log::warn!("not an X11 window: no X server readback");
                return;
            }
        };
        let mut last: Option<Vec<u8>> = None;
        for _ in 0..40 {
            std::thread::sleep(Duration::from_millis(50));
            match super::x11::grab_window(id, w, h) {
                Ok(px) => {
                    if last.as_ref() == Some(&px) {
                        break;
                    }
                    last = Some(px);
                }
                Err(e) => {
                    log::warn!("{e}");
                    return;
                }
            }
        }
        if let Some(px) = last {
            let p = dir.join(format!("x11_{n:04}{suffix}.png"));
            match write_png(&p, w, h, &px) {
                Ok(()) => log::info!("frame {n}: X server's window pixels to {}", p.display()),
                Err(e) => log::warn!("{e}"),
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    log::warn!("X server readback exists on Linux only");
}
