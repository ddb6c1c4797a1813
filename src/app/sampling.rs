//! Bilinear sampling of RGBA8 images on the CPU (the warps and the closed-loop check read
//! rendered images through it) and the quantisation back to RGBA8.

/// Bilinear sample of an RGBA8 image at image point (x, y) (pixel centres at +0.5), edges
/// clamped; values 0..1.
pub fn sample_rgba8(rgba: &[u8], width: u32, height: u32, x: f64, y: f64) -> [f64; 3] {
    let (w, h) = (width as i64, height as i64);
    let (fx, fy) = (x - 0.5, y - 0.5);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (ax, ay) = (fx - x0, fy - y0);
    let px = |i: i64, j: i64| -> [f64; 3] {
        let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
        let k = ((j * w + i) * 4) as usize;
        [
            rgba[k] as f64 / 255.0,
            rgba[k + 1] as f64 / 255.0,
            rgba[k + 2] as f64 / 255.0,
        ]
    };
    let (x0, y0) = (x0 as i64, y0 as i64);
    let (a, b, c, d) = (
        px(x0, y0),
        px(x0 + 1, y0),
        px(x0, y0 + 1),
        px(x0 + 1, y0 + 1),
    );
    std::array::from_fn(|i| {
        (a[i] * (1.0 - ax) + b[i] * ax) * (1.0 - ay) + (c[i] * (1.0 - ax) + d[i] * ax) * ay
    })
}

/// An RGB colour (0..1, clamped) as an opaque RGBA8 pixel.
pub fn quantise(c: [f64; 3]) -> [u8; 4] {
    let q = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c[0]), q(c[1]), q(c[2]), 255]
}
