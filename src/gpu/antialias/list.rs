//! The list of marked pixels (`gpu::antialias`): the edge mask read back, sorted by sample
//! count and tile by tile along a Hilbert curve (on CPU adapters; GPUs build the same list
//! themselves, `gpu_list`), and cut into batches of the atlas from its parts' lengths.

/// The marked pixels of a frame, packed x | y << 16: those with 16 samples first, then those
/// with 8, then those with 4, each part tile by tile (8x8 tiles along a Hilbert curve,
/// [`tile_order`]; row by row inside a tile), so that pixels close in the list are close on
/// the screen (the atlas's tiles and free-form bins then hold neighbouring rays, with narrow
/// cones).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Marked {
    pub pixels: Vec<u32>,
    /// Pixels with 16, 8 and 4 samples.
    pub counts: [u32; 3],
}

/// The sample counts of [`Marked`]'s parts, in list order.
const PARTS: [u32; 3] = [16, 8, 4];

/// Sub-pixel rays cast for `counts` pixels with 16, 8 and 4 samples.
pub(crate) fn sample_rays(counts: [u64; 3]) -> u64 {
    (counts.iter().zip(PARTS))
        .map(|(&c, n)| c * u64::from(n))
        .sum()
}

/// The 8x8 tiles of a `w` x `h` screen (packed x | y << 16) along a Hilbert curve: the order
/// [`Marked`] lists each part's pixels in, tile by tile, so that any run of consecutive
/// pixels (an atlas tile's 4 groups, a free-form bin's 16) lies in few neighbouring tiles.
pub(crate) fn tile_order(w: u32, h: u32) -> Vec<u32> {
    let tiles = [w.div_ceil(8), h.div_ceil(8)];
    let side = tiles[0].max(tiles[1]).next_power_of_two();
    (0..side * side)
        .map(|d| hilbert_point(side, d))
        .filter(|&(tx, ty)| tx < tiles[0] && ty < tiles[1])
        .map(|(tx, ty)| tx | (ty << 16))
        .collect()
}

/// Point `d` along the Hilbert curve through a `side` x `side` grid (`side` a power of two):
/// consecutive points are neighbours, and every aligned square of 4^k points is visited in
/// one run.
fn hilbert_point(side: u32, d: u32) -> (u32, u32) {
    let (mut x, mut y, mut t) = (0, 0, d);
    let mut s = 1;
    while s < side {
        let rx = 1 & (t / 2);
        let ry = 1 & (t ^ rx);
        if ry == 0 {
            if rx == 1 {
                (x, y) = (s - 1 - x, s - 1 - y);
            }
            (x, y) = (y, x);
        }
        (x, y) = (x + s * rx, y + s * ry);
        t /= 4;
        s *= 2;
    }
    (x, y)
}

impl Marked {
    /// From the edge pass's mask (`w` x `h`, each byte the pixel's sample count or 0).
    #[cfg(test)]
    pub fn from_mask(mask: &[u8], w: u32, h: u32) -> Marked {
        Marked::from_mask_in(mask, w, h, &tile_order(w, h))
    }

    /// The list from the edge pass's mask (`w` x `h`, each byte the pixel's sample count or
    /// 0), the screen's tiles taken in the order `tiles` ([`tile_order`], made once per size).
    pub fn from_mask_in(mask: &[u8], w: u32, h: u32, tiles: &[u32]) -> Marked {
        let mut parts: [Vec<u32>; 3] = Default::default();
        for &t in tiles {
            let (tx, ty) = (t & 0xffff, t >> 16);
            let (x0, x1) = (tx * 8, (tx * 8 + 8).min(w));
            for y in ty * 8..(ty * 8 + 8).min(h) {
                let row = &mask[(y * w + x0) as usize..(y * w + x1) as usize];
                // Most of a frame is unmarked (3.5% of the alps's pixels are marked): a tile's
                // row of eight zeros is one load.
                let empty = match <[u8; 8]>::try_from(row) {
                    Ok(bytes) => u64::from_ne_bytes(bytes) == 0,
                    Err(_) => row.iter().all(|&n| n == 0),
                };
                if empty {
                    continue;
                }
                for (x, &n) in (x0..).zip(row) {
                    let part = match n {
                        16 => 0,
                        8 => 1,
                        4 => 2,
                        _ => continue,
                    };
                    parts[part].push(x | (y << 16));
                }
            }
        }
        let counts = parts.each_ref().map(|p| p.len() as u32);
        Marked {
            pixels: parts.concat(),
            counts,
        }
    }
}

/// Atlas groups a list of `counts` pixels with 16, 8 and 4 samples fills (a pixel with 8
/// samples shares one with another, one with 4 with three others).
fn groups([a, b, c]: [u32; 3]) -> u32 {
    a + b.div_ceil(2) + c.div_ceil(4)
}

/// The place in a list of `counts` of group `g`'s first pixel (the list's length for
/// [`groups`]).
fn first_pixel([a, b, c]: [u32; 3], g: u32) -> u32 {
    let g4 = a + b.div_ceil(2);
    if g <= a {
        g
    } else if g <= g4 {
        (a + (g - a) * 2).min(a + b)
    } else {
        (a + b + (g - g4) * 4).min(a + b + c)
    }
}

/// The batches of a list of `counts` pixels with 16, 8 and 4 samples in atlases of
/// `per_batch` groups.
pub(crate) fn batches(counts: [u32; 3], per_batch: u32) -> Vec<Batch> {
    let all = groups(counts);
    (0..all)
        .step_by(per_batch.max(1) as usize)
        .map(|g| {
            let end = (g + per_batch).min(all);
            let first = first_pixel(counts, g);
            Batch {
                counts,
                group: g,
                groups: end - g,
                first,
                count: first_pixel(counts, end) - first,
            }
        })
        .collect()
}

/// One atlas's share of a [`Marked`] list: groups `group..group + groups`, pixels
/// `first..first + count`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Batch {
    pub counts: [u32; 3],
    pub group: u32,
    pub groups: u32,
    pub first: u32,
    pub count: u32,
}

#[cfg(test)]
mod tests {
    use super::{Batch, Marked};

    /// A 16x8 mask: pixel (x, y) gets the count `f(x, y)` (0: unmarked).
    fn mask(f: impl Fn(u32, u32) -> u8) -> Vec<u8> {
        (0..8)
            .flat_map(|y| (0..16).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect()
    }

    #[test]
    fn the_list_holds_the_16s_then_the_8s_then_the_4s_each_tile_by_tile() {
        // Column x gets 16 samples for x = 1, 9; 8 for x = 2, 3, 10; 4 for x = 12..15.
        let m = Marked::from_mask(
            &mask(|x, _| match x {
                1 | 9 => 16,
                2 | 3 | 10 => 8,
                12..=15 => 4,
                _ => 0,
            }),
            16,
            8,
        );
        assert_eq!(m.counts, [16, 24, 32]);
        let xy = |p: u32| (p & 0xffff, p >> 16);
        let parts = [&m.pixels[..16], &m.pixels[16..40], &m.pixels[40..]];
        assert!(parts[0].iter().all(|&p| [1, 9].contains(&xy(p).0)));
        assert!(parts[1].iter().all(|&p| [2, 3, 10].contains(&xy(p).0)));
        assert!(parts[2].iter().all(|&p| xy(p).0 >= 12));
        // Tile by tile (8x8): the left tile's 16s, row by row, before the right tile's.
        let first: Vec<_> = parts[0].iter().map(|&p| xy(p)).collect();
        assert_eq!(&first[..3], &[(1, 0), (1, 1), (1, 2)]);
        assert_eq!(first[8], (9, 0));
        assert_eq!(
            super::sample_rays(m.counts.map(u64::from)),
            16 * 16 + 8 * 24 + 4 * 32
        );
        // Other bytes are no count.
        assert_eq!(Marked::from_mask(&mask(|_, _| 3), 16, 8), Marked::default());
    }

    #[test]
    fn the_tiles_follow_a_hilbert_curve_over_the_screen() {
        // A square power-of-two screen of tiles: every tile once, each a neighbour of the last.
        let order = super::tile_order(64, 64);
        let xy = |t: u32| ((t & 0xffff) as i64, (t >> 16) as i64);
        let mut seen = std::collections::HashSet::new();
        assert!(order.iter().all(|&t| seen.insert(t)));
        assert_eq!(seen.len(), 64);
        for w in order.windows(2) {
            let ((ax, ay), (bx, by)) = (xy(w[0]), xy(w[1]));
            assert_eq!(
                (ax - bx).abs() + (ay - by).abs(),
                1,
                "{:?} then {:?}",
                xy(w[0]),
                xy(w[1])
            );
        }
        // Every aligned 2x2 block of tiles is one run of four.
        for run in order.chunks(4) {
            let first = xy(run[0]);
            assert!(run
                .iter()
                .all(|&t| xy(t).0 / 2 == first.0 / 2 && xy(t).1 / 2 == first.1 / 2));
        }
        // Any screen: every tile once, partial tiles at the edges included (1280x720: 160x90).
        for (w, h) in [(1280, 720), (100, 37), (8, 8), (1, 1)] {
            let order = super::tile_order(w, h);
            let tiles = (w.div_ceil(8) * h.div_ceil(8)) as usize;
            let unique: std::collections::HashSet<_> = order.iter().collect();
            assert_eq!((order.len(), unique.len()), (tiles, tiles), "{w}x{h}");
            assert!(order
                .iter()
                .all(|&t| (t & 0xffff) < w.div_ceil(8) && (t >> 16) < h.div_ceil(8)));
        }
    }

    #[test]
    fn groups_and_batches_cover_every_pixel_once() {
        let counts = [3, 5, 7];
        // 3 groups of one 16, 3 of two 8s (the last half empty), 2 of four 4s.
        assert_eq!(super::groups(counts), 8);
        let firsts: Vec<u32> = (0..=8).map(|g| super::first_pixel(counts, g)).collect();
        assert_eq!(firsts, [0, 1, 2, 3, 5, 7, 8, 12, 15]);
        for per in 1..=9 {
            let b = super::batches(counts, per);
            assert_eq!(b.iter().map(|b| b.groups).sum::<u32>(), 8);
            assert!(b.iter().all(|b| b.groups <= per && b.counts == counts));
            let mut next = (0, 0);
            for Batch {
                group,
                groups,
                first,
                count,
                ..
            } in b
            {
                assert_eq!((group, first), next, "batches follow one another");
                next = (group + groups, first + count);
            }
            assert_eq!(next, (8, 15));
        }
        assert!(super::batches([0; 3], 4).is_empty());
    }

    /// The list made with rows of zeros skipped eight pixels at a time is the one made pixel
    /// by pixel, also where tiles are cut by the screen's edges (21x13) and where a mask byte
    /// is none of 16, 8 and 4.
    #[test]
    fn skipping_unmarked_rows_changes_no_list() {
        let (w, h) = (21u32, 13u32);
        let mut seed = 7u32;
        for density in [0u32, 3, 30, 100] {
            let m: Vec<u8> = (0..w * h)
                .map(|_| {
                    seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    let r = seed >> 8;
                    if r % 100 < density {
                        [16u8, 8, 4, 3][(r / 100 % 4) as usize]
                    } else {
                        0
                    }
                })
                .collect();
            let tiles = super::tile_order(w, h);
            let mut parts: [Vec<u32>; 3] = Default::default();
            for &t in &tiles {
                let (tx, ty) = (t & 0xffff, t >> 16);
                for y in ty * 8..(ty * 8 + 8).min(h) {
                    for x in tx * 8..(tx * 8 + 8).min(w) {
                        let n = u32::from(m[(y * w + x) as usize]);
                        if let Some(p) = super::PARTS.iter().position(|&k| k == n) {
                            parts[p].push(x | (y << 16));
                        }
                    }
                }
            }
            let want = Marked {
                counts: parts.each_ref().map(|p| p.len() as u32),
                pixels: parts.concat(),
            };
            assert_eq!(Marked::from_mask(&m, w, h), want, "density {density}%");
            assert_eq!(want.pixels.is_empty(), density == 0);
        }
    }
}
