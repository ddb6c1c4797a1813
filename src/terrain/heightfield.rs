//! The regular height grid every loader produces.

use crate::{Error, Result};

/// Geographic reference of a grid: longitude/latitude of sample (0, 0) and the step per sample.
/// Samples are point values (pixel centres for area rasters).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GeoRef {
    /// Longitude of sample (0, 0), degrees east.
    pub lon0: f64,
    /// Latitude of sample (0, 0), degrees north (row 0 is the southern edge).
    pub lat0: f64,
    /// Degrees of longitude per sample step along +x.
    pub dlon: f64,
    /// Degrees of latitude per sample step along +y (positive: +y is north).
    pub dlat: f64,
}

/// Largest height magnitude (metres, before the vertical scale) a terrain may have.
pub const MAX_ABS_HEIGHT: f64 = 1.0e7;

/// Largest number of samples along one side a terrain may have: the procedural generator's
/// limit and the GPU's 2-D texture size; a database window is chosen to fit it.
pub const MAX_SIDE: usize = 16384;

/// The samples of a height file as it holds them, before voids are filled: what
/// [`Heightfield::from_samples_with_voids`] takes, kept apart for the database compiler,
/// which needs to know which samples are void (a void does not cover its position).
#[derive(Clone, Debug)]
pub struct SampleGrid {
    /// The file, for errors and warnings.
    pub what: String,
    /// Samples along x.
    pub width: usize,
    /// Samples along y.
    pub height: usize,
    /// `width * height` samples, row 0 = south; `None` marks a void / no-data sample.
    pub samples: Vec<Option<f32>>,
    /// Metres between neighbouring samples along x and y.
    pub spacing: [f64; 2],
    /// Geographic reference, where the file has one.
    pub geo: Option<GeoRef>,
}

impl SampleGrid {
    /// The height field: voids filled (and counted in a warning).
    pub fn into_heightfield(self) -> Result<Heightfield> {
        Heightfield::from_samples_with_voids(
            &self.what,
            self.width,
            self.height,
            self.samples,
            self.spacing,
            self.geo,
        )
    }
}

impl GeoRef {
    /// Metres between samples along x and y for a grid of `rows` rows: the degree steps
    /// converted at the grid's centre latitude (as the `.hgt` loader does).
    pub fn metric_spacing(&self, rows: usize) -> [f64; 2] {
        let centre_lat = self.lat0 + 0.5 * (rows.max(1) - 1) as f64 * self.dlat;
        let (mx, my) = metres_per_degree(centre_lat);
        [self.dlon * mx, self.dlat * my]
    }
}

/// A regular grid of heights in metres.
///
/// Sample `(i, j)` is at grid position `(i, j)`: `i` runs east (columns), `j` runs north
/// (row 0 is the southern edge, so rows are flipped from the usual north-up raster order).
#[derive(Clone, Debug)]
pub struct Heightfield {
    /// Samples along x.
    pub width: usize,
    /// Samples along y.
    pub height: usize,
    /// `width * height` heights in metres, row-major, row 0 = south.
    pub heights: Vec<f32>,
    /// Metres between neighbouring samples along x and y.
    pub spacing: [f64; 2],
    /// Geographic reference, where the source has one.
    pub geo: Option<GeoRef>,
    /// Number of void / no-data samples that were filled.
    pub voids_filled: usize,
}

impl Heightfield {
    /// Height of sample `(i, j)`.
    #[inline]
    pub fn at(&self, i: usize, j: usize) -> f32 {
        self.heights[j * self.width + i]
    }

    /// (min, max) of all samples.
    pub fn range(&self) -> (f32, f32) {
        self.heights
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                (lo.min(h), hi.max(h))
            })
    }

    /// Builds a field from raw samples where `None` marks a void; voids are filled and counted.
    /// `what` names the source in errors and the warning.
    pub fn from_samples_with_voids(
        what: &str,
        width: usize,
        height: usize,
        samples: Vec<Option<f32>>,
        spacing: [f64; 2],
        geo: Option<GeoRef>,
    ) -> Result<Self> {
        if width < 2 || height < 2 {
            return Err(Error::invalid(
                what,
                format!("a height field needs at least 2x2 samples, got {width}x{height}"),
            ));
        }
        if samples.len() != width * height {
            return Err(Error::invalid(
                what,
                format!("expected {} samples, got {}", width * height, samples.len()),
            ));
        }
        for (k, s) in spacing.iter().enumerate() {
            if !s.is_finite() || *s <= 0.0 {
                return Err(Error::invalid(
                    what,
                    format!(
                        "sample spacing along {} must be a positive number of metres, got {s}",
                        ["x", "y"][k]
                    ),
                ));
            }
        }
        let voids = samples.iter().filter(|s| s.is_none()).count();
        if voids == samples.len() {
            return Err(Error::invalid(
                what,
                "contains no valid height sample (every value is void, no-data or not finite)",
            ));
        }
        let heights = if voids > 0 {
            log::warn!(
                "{what}: filled {voids} void/no-data samples of {}",
                samples.len()
            );
            fill_voids(width, height, &samples)
        } else {
            samples.into_iter().map(|s| s.unwrap_or(0.0)).collect()
        };
        Ok(Heightfield {
            width,
            height,
            heights,
            spacing,
            geo,
            voids_filled: voids,
        })
    }
}

/// Pull-push hole filling: valid samples are averaged down a pyramid, holes take the
/// interpolated coarser value. Large voids get smooth fills; valid samples are untouched.
/// The database compiler fills its sources' voids with it too (`db::source`), so a database
/// holds the heights the loaders give the same file.
pub(crate) fn fill_voids(width: usize, height: usize, samples: &[Option<f32>]) -> Vec<f32> {
    // Level 0 is the samples themselves; levels 1.. hold (value*weight, weight) per cell, a
    // third of the samples' count in all (the database compiler fills whole sources).
    type Level = (usize, usize, Vec<(f64, f64)>);
    let at0 = |k: usize| samples[k].map_or((0.0, 0.0), |v| (v as f64, 1.0));
    let mut levels: Vec<Level> = Vec::new();
    let (mut w, mut h) = (width, height);
    while w > 1 || h > 1 {
        let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
        let mut next = vec![(0.0, 0.0); nw * nh];
        for j in 0..h {
            for i in 0..w {
                let (s, wt) = match levels.last() {
                    None => at0(j * w + i),
                    Some((_, _, data)) => data[j * w + i],
                };
                let c = &mut next[(j / 2) * nw + i / 2];
                c.0 += s;
                c.1 += wt;
            }
        }
        levels.push((nw, nh, next));
        (w, h) = (nw, nh);
    }
    // Push: fill every empty cell from its parent (bilinear would be smoother; nearest parent
    // with repeated smoothing at each level is enough for voids, which are rare and flagged).
    let push = |c: (f64, f64), p: (f64, f64)| {
        if c.1 == 0.0 {
            (p.0 / p.1.max(1e-300), 1.0)
        } else {
            (c.0 / c.1, 1.0)
        }
    };
    for l in (0..levels.len().saturating_sub(1)).rev() {
        let (finer, coarser) = levels.split_at_mut(l + 1);
        let (pw, parent) = (coarser[0].0, &coarser[0].2);
        let (w, h, data) = &mut finer[l];
        for j in 0..*h {
            for i in 0..*w {
                let c = &mut data[j * *w + i];
                *c = push(*c, parent[(j / 2) * pw + i / 2]);
            }
        }
    }
    let Some((pw, _, parent)) = levels.first() else {
        return (0..samples.len()).map(|k| at0(k).0 as f32).collect();
    };
    (0..samples.len())
        .map(|k| {
            let (i, j) = (k % width, k / width);
            push(at0(k), parent[(j / 2) * pw + i / 2]).0 as f32
        })
        .collect()
}

/// Metres per degree of longitude and latitude at latitude `lat_deg` (WGS84 series).
pub fn metres_per_degree(lat_deg: f64) -> (f64, f64) {
    let p = lat_deg.to_radians();
    let lat =
        111_132.92 - 559.82 * (2.0 * p).cos() + 1.175 * (4.0 * p).cos() - 0.0023 * (6.0 * p).cos();
    let lon = 111_412.84 * p.cos() - 93.5 * (3.0 * p).cos() + 0.118 * (5.0 * p).cos();
    (lon, lat)
}
