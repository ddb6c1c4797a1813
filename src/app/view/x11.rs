//! Reads a window's pixels back from the X server (`XGetImage` on its own connection): what
//! the display actually shows, as opposed to the swap-chain image the application drew.

use crate::{Error, Result};
use std::sync::atomic::{AtomicI32, Ordering};
use x11_dl::xlib;

static LAST_ERROR: AtomicI32 = AtomicI32::new(0);

unsafe extern "C" fn on_error(_d: *mut xlib::Display, e: *mut xlib::XErrorEvent) -> i32 {
    LAST_ERROR.store(i32::from((*e).error_code).max(1), Ordering::SeqCst);
    0
}

/// RGBA8 pixels (row 0 at the top) of the `width` x `height` top-left area of X window `window`.
pub fn grab_window(window: u64, width: u32, height: u32) -> Result<Vec<u8>> {
    let err = |m: String| Error::Gpu(format!("X11 window grab: {m}"));
    let x = xlib::Xlib::open().map_err(|e| err(format!("cannot load libX11: {e}")))?;
    // SAFETY: plain Xlib calls on a connection opened and closed here; the image is checked
    // for null and its size and format before its data are read, and destroyed once.
    unsafe {
        let dpy = (x.XOpenDisplay)(std::ptr::null());
        if dpy.is_null() {
            return Err(err("cannot open the display named by DISPLAY".into()));
        }
        let old = (x.XSetErrorHandler)(Some(on_error));
        LAST_ERROR.store(0, Ordering::SeqCst);
        let img = (x.XGetImage)(
            dpy,
            window as std::os::raw::c_ulong,
            0,
            0,
            width,
            height,
            !0,
            xlib::ZPixmap,
        );
        (x.XSync)(dpy, 0);
        let code = LAST_ERROR.load(Ordering::SeqCst);
        let result = if img.is_null() || code != 0 {
            Err(err(format!(
                "XGetImage failed (X error code {code}); is the window mapped?"
            )))
        } else {
            let im = &*img;
            let ok = im.width as u32 == width
                && im.height as u32 == height
                && im.bits_per_pixel == 32
                && im.red_mask == 0xff0000
                && im.green_mask == 0xff00
                && im.blue_mask == 0xff
                && im.byte_order == xlib::LSBFirst;
            if !ok {
                Err(err(format!(
                    "unsupported image: {}x{}, {} bits per pixel, masks {:x}/{:x}/{:x}",
                    im.width,
                    im.height,
                    im.bits_per_pixel,
                    im.red_mask,
                    im.green_mask,
                    im.blue_mask
                )))
            } else {
                let stride = im.bytes_per_line as usize;
                let data =
                    std::slice::from_raw_parts(im.data as *const u8, stride * height as usize);
                let mut out = Vec::with_capacity((width * height * 4) as usize);
                for row in data.chunks_exact(stride) {
                    for px in row[..width as usize * 4].chunks_exact(4) {
                        out.extend_from_slice(&[px[2], px[1], px[0], 255]);
                    }
                }
                Ok(out)
            }
        };
        if !img.is_null() {
            (x.XDestroyImage)(img);
        }
        (x.XSetErrorHandler)(old);
        (x.XCloseDisplay)(dpy);
        result
    }
}
