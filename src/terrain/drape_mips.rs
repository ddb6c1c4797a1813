//! Mip levels of a drape image for footprint-filtered texturing (with `render.antialias`): each
//! level the 2x2 box mean of the one below in linear light (sRGB decoded, averaged, encoded),
//! odd sizes rounded up with the last row or column repeated, down to 1x1.

use super::geotiff::Drape;
use crate::colour::{linear_to_srgb8 as to_srgb8, srgb_to_linear as to_linear};
use rayon::prelude::*;

/// One level: `width` x `height` RGBA8 (sRGB) texels, row 0 south like the drape.
#[derive(Clone, Debug, PartialEq)]
pub struct MipLevel {
    pub width: usize,
    pub height: usize,
    pub rgba: Vec<u8>,
}

/// How many levels [`mip_levels`] makes for `d`, without making them.
pub fn level_count(d: &Drape, max_levels: usize) -> usize {
    let (mut w, mut h, mut n) = (d.width, d.height, 1);
    while n < max_levels && (w > 1 || h > 1) {
        (w, h, n) = (w.div_ceil(2), h.div_ceil(2), n + 1);
    }
    n
}

/// The drape's levels, the drape itself first, at most `max_levels`.
pub fn mip_levels(d: &Drape, max_levels: usize) -> Vec<MipLevel> {
    let linear: [f64; 256] = std::array::from_fn(|v| to_linear(v as u8));
    let mut out = vec![MipLevel {
        width: d.width,
        height: d.height,
        rgba: d.rgba.clone(),
    }];
    while out.len() < max_levels {
        let l = out.last().expect("level 0");
        if l.width <= 1 && l.height <= 1 {
            break;
        }
        let (w, h) = (l.width.div_ceil(2), l.height.div_ceil(2));
        let mut rgba = vec![0u8; w * h * 4];
        // Rows in parallel; sRGB decoded through a table (exact: 8-bit inputs).
        rgba.par_chunks_mut(w * 4).enumerate().for_each(|(y, row)| {
            for x in 0..w {
                for c in 0..4 {
                    let mut sum = 0.0;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (sx, sy) = (
                            (2 * x + dx).min(l.width - 1),
                            (2 * y + dy).min(l.height - 1),
                        );
                        let v = l.rgba[(sy * l.width + sx) * 4 + c];
                        sum += if c == 3 {
                            f64::from(v) / 255.0
                        } else {
                            linear[usize::from(v)]
                        };
                    }
                    let mean = sum / 4.0;
                    row[x * 4 + c] = if c == 3 {
                        (mean * 255.0).round() as u8
                    } else {
                        to_srgb8(mean)
                    };
                }
            }
        });
        out.push(MipLevel {
            width: w,
            height: h,
            rgba,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_halve_to_one_texel_and_average_in_linear_light() {
        // 3x2: black and white columns; the 2x1 level averages a black and a white column
        // (linear 0.5 → sRGB 188), the last column alone stays white.
        let px = |v: u8| [v, v, v, 255];
        let row = [px(0), px(255), px(255)].concat();
        let d = Drape {
            width: 3,
            height: 2,
            rgba: [row.clone(), row].concat(),
            geo: None,
        };
        let levels = mip_levels(&d, 16);
        let sizes: Vec<_> = levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, vec![(3, 2), (2, 1), (1, 1)]);
        assert_eq!(&levels[1].rgba[..4], &[188, 188, 188, 255]);
        assert_eq!(&levels[1].rgba[4..8], &[255, 255, 255, 255]);
        assert_eq!(mip_levels(&d, 2).len(), 2);
        assert_eq!(level_count(&d, 16), 3);
        assert_eq!(level_count(&d, 2), 2);
    }
}
