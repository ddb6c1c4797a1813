//! The compiler's source DEMs: loaded through the terrain loaders (voids kept as such, and a
//! copy with them filled as the loaders fill them), checked, ordered finest first, and sampled
//! bilinearly at a geographic position; or a procedural mosaic ([`Synth`]) whose samples are
//! computed on demand, never held.

use crate::terrain::procedural::ridged_fbm;
use crate::terrain::{geotiff, hgt, SampleGrid};
use crate::{fileio, Error, Result};
use std::path::{Path, PathBuf};

/// Sample positions closer than this (in source samples) to a sample are taken as that
/// sample: level grids and source grids meet at exact multiples that f64 arithmetic reaches
/// only within an ulp or two.
pub const SNAP: f64 = 1e-6;

/// One source DEM in geographic coordinates.
pub struct Source {
    pub path: PathBuf,
    /// File name, as stored in the header.
    pub name: String,
    /// Position on the command line (equal spacings: the earlier wins).
    pub order: usize,
    /// South-west sample and steps, degrees.
    pub lon0: f64,
    pub lat0: f64,
    pub dlon: f64,
    pub dlat: f64,
    pub width: usize,
    pub height: usize,
    /// The samples: row 0 south, NaN marks a void.
    pub data: SourceData,
    /// Where the source has voids: its samples with the voids filled by pull-push, as the
    /// terrain loaders fill them (`Heightfield::from_samples_with_voids`). A position inside
    /// the source where no source has data takes its height from these ([`Source::sample_filled`]).
    pub filled: Option<Vec<f32>>,
    /// Bytes of the file.
    pub file_len: u64,
}

/// Where a source's samples come from.
pub enum SourceData {
    /// Loaded from a file, row 0 south.
    Grid(Vec<f32>),
    /// Computed from their indices when asked.
    Synth(Synth),
}

/// A procedural source: ridged fBm over the sample grid, deterministic for a seed, a
/// function of the sample's position alone (so any tiling of it is seamless).
#[derive(Clone, Copy, Debug)]
pub struct Synth {
    pub seed: u32,
    /// Wavelength of the first octave, in samples.
    pub wavelength: f64,
    pub octaves: u32,
    /// Peak-to-valley height, metres.
    pub height: f64,
}

impl Synth {
    /// The height of sample `(i, j)`.
    pub fn at(&self, i: usize, j: usize) -> f32 {
        let f = 1.0 / self.wavelength;
        let r = ridged_fbm(i as f64 * f, j as f64 * f, self.octaves, self.seed);
        (r * 0.5 * self.height) as f32
    }
}

impl SourceData {
    /// Sample `(i, j)` of a source `width` samples wide.
    pub fn at(&self, width: usize, i: usize, j: usize) -> f32 {
        match self {
            SourceData::Grid(v) => v[j * width + i],
            SourceData::Synth(s) => s.at(i, j),
        }
    }
}

fn snap(x: f64) -> f64 {
    let r = x.round();
    if (x - r).abs() < SNAP {
        r
    } else {
        x
    }
}

impl Source {
    /// Loads `path` (`.hgt` or GeoTIFF in degrees); the sample grid must be geographic.
    pub fn load(path: &Path, order: usize) -> Result<Source> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let grid: SampleGrid = match ext.as_str() {
            "hgt" => hgt::load_samples(path)?,
            "tif" | "tiff" => geotiff::load_height_samples(path, None)?,
            _ => {
                return Err(Error::format(
                    path,
                    format!("`.{ext}` is not a database source: give SRTM .hgt tiles or GeoTIFFs in geographic coordinates (degrees)"),
                ))
            }
        };
        let Some(geo) = grid.geo else {
            return Err(Error::format(
                path,
                "has no geographic georeference (longitude/latitude degrees): a database is compiled from .hgt tiles and GeoTIFFs in degrees (EPSG:4326); reproject it first (e.g. gdalwarp -t_srs EPSG:4326)",
            ));
        };
        let (w, h) = (grid.width, grid.height);
        let (lon1, lat1) = (
            geo.lon0 + (w - 1) as f64 * geo.dlon,
            geo.lat0 + (h - 1) as f64 * geo.dlat,
        );
        let tol = 1e-9;
        let inside = geo.lon0 >= -180.0 - tol
            && lon1 <= 180.0 + tol
            && geo.lat0 >= -90.0 - tol
            && lat1 <= 90.0 + tol;
        if !(inside && geo.dlon > 0.0 && geo.dlat > 0.0 && geo.dlat >= 1e-7 && geo.dlon >= 1e-7) {
            return Err(Error::format(
                path,
                format!(
                    "its samples span longitude {}..{lon1}, latitude {}..{lat1} in steps of {}° x {}°: a source must lie within -180..180, -90..90 with steps of at least 1e-7° (rasters that wrap around the antimeridian are not supported)",
                    geo.lon0, geo.lat0, geo.dlon, geo.dlat
                ),
            ));
        }
        let file_len = fileio::file_len(path)?;
        let voids = grid.samples.iter().filter(|s| s.is_none()).count();
        let filled = if voids > 0 && voids < grid.samples.len() {
            // Pull-push holds (sum, weight) pairs of f64 over the levels above the samples
            // (16 bytes for a third of them), and the filled copy (4 bytes a sample).
            fileio::check_alloc(
                format!(
                    "{} ({w}x{h} samples, {voids} voids to fill)",
                    path.display()
                ),
                (w * h) as u64 * 10,
            )?;
            log::warn!(
                "{}: filled {voids} void/no-data samples of {} (pull-push) where no other source has data",
                path.display(),
                w * h
            );
            Some(crate::terrain::heightfield::fill_voids(w, h, &grid.samples))
        } else {
            None
        };
        let data = SourceData::Grid(
            grid.samples
                .into_iter()
                .map(|s| s.unwrap_or(f32::NAN))
                .collect(),
        );
        Ok(Source {
            path: path.to_path_buf(),
            name: path.file_name().map_or_else(
                || path.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            ),
            order,
            lon0: geo.lon0,
            lat0: geo.lat0,
            dlon: geo.dlon,
            dlat: geo.dlat,
            width: w,
            height: h,
            data,
            filled,
            file_len,
        })
    }

    /// Longitude of the easternmost sample column.
    pub fn lon1(&self) -> f64 {
        self.lon0 + (self.width - 1) as f64 * self.dlon
    }
    /// Latitude of the northernmost sample row.
    pub fn lat1(&self) -> f64 {
        self.lat0 + (self.height - 1) as f64 * self.dlat
    }

    /// Whether its closed sample extent meets the box `[lon_a, lon_b] x [lat_a, lat_b]`.
    pub fn touches(&self, lon_a: f64, lat_a: f64, lon_b: f64, lat_b: f64) -> bool {
        let eps_x = SNAP * self.dlon;
        let eps_y = SNAP * self.dlat;
        self.lon0 <= lon_b + eps_x
            && self.lon1() >= lon_a - eps_x
            && self.lat0 <= lat_b + eps_y
            && self.lat1() >= lat_a - eps_y
    }

    /// The bilinear height at (lon, lat), exact at the source's own sample positions; `None`
    /// outside its samples or where a sample with weight in the result is void.
    pub fn sample(&self, lon: f64, lat: f64) -> Option<f32> {
        self.sample_with(lon, lat, |i, j| self.data.at(self.width, i, j))
    }

    /// [`Source::sample`] with the source's voids filled: `None` outside its samples, or
    /// where it has no voids (there [`Source::sample`] has answered).
    pub fn sample_filled(&self, lon: f64, lat: f64) -> Option<f32> {
        let filled = self.filled.as_ref()?;
        self.sample_with(lon, lat, |i, j| filled[j * self.width + i])
    }

    fn sample_with(&self, lon: f64, lat: f64, at: impl Fn(usize, usize) -> f32) -> Option<f32> {
        let fx = snap((lon - self.lon0) / self.dlon);
        let fy = snap((lat - self.lat0) / self.dlat);
        let (wx, wy) = ((self.width - 1) as f64, (self.height - 1) as f64);
        if !(fx >= 0.0 && fy >= 0.0 && fx <= wx && fy <= wy) {
            return None;
        }
        let i = (fx.floor() as usize).min(self.width - 2);
        let j = (fy.floor() as usize).min(self.height - 2);
        let (u, v) = (fx - i as f64, fy - j as f64);
        let mut sum = 0.0f64;
        for (di, dj, wgt) in [
            (0, 0, (1.0 - u) * (1.0 - v)),
            (1, 0, u * (1.0 - v)),
            (0, 1, (1.0 - u) * v),
            (1, 1, u * v),
        ] {
            if wgt == 0.0 {
                continue;
            }
            let h = at(i + di, j + dj);
            if h.is_nan() {
                return None;
            }
            sum += wgt * h as f64;
        }
        Some(sum as f32)
    }
}

/// Whether two spacings are the same resolution.
pub fn same_spacing(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.max(b)
}

/// Sorts the sources finest first (by latitude step; equal steps keep the command line's
/// order) and warns about sources of equal resolution that overlap by more than a shared
/// edge: there the one given first wins, and the warning names both, the overlap and how much
/// they disagree in it.
pub fn order_and_check_overlaps(sources: &mut [Source]) {
    sources.sort_by(|a, b| {
        if same_spacing(a.dlat, b.dlat) {
            a.order.cmp(&b.order)
        } else {
            a.dlat.total_cmp(&b.dlat)
        }
    });
    for (k, a) in sources.iter().enumerate() {
        for b in &sources[k + 1..] {
            if !(same_spacing(a.dlat, b.dlat) && same_spacing(a.dlon, b.dlon)) {
                continue;
            }
            let (lo_x, hi_x) = (a.lon0.max(b.lon0), a.lon1().min(b.lon1()));
            let (lo_y, hi_y) = (a.lat0.max(b.lat0), a.lat1().min(b.lat1()));
            let (ex, ey) = (0.5 * a.dlon, 0.5 * a.dlat);
            if hi_x - lo_x <= ex || hi_y - lo_y <= ey {
                continue;
            }
            let (mut worst, mut shared) = (0.0f64, 0usize);
            let (first, second) = if a.order < b.order { (a, b) } else { (b, a) };
            for j in 0..first.height {
                let lat = first.lat0 + j as f64 * first.dlat;
                if lat < lo_y - ey || lat > hi_y + ey {
                    continue;
                }
                for i in 0..first.width {
                    let lon = first.lon0 + i as f64 * first.dlon;
                    if lon < lo_x - ex || lon > hi_x + ex {
                        continue;
                    }
                    let h = first.data.at(first.width, i, j);
                    if let (false, Some(g)) = (h.is_nan(), second.sample(lon, lat)) {
                        worst = worst.max((h as f64 - g as f64).abs());
                        shared += 1;
                    }
                }
            }
            log::warn!(
                "{} and {} have the same resolution and overlap over longitude {lo_x:.6}..{hi_x:.6}, latitude {lo_y:.6}..{hi_y:.6} ({shared} shared samples, differing by up to {worst} m): {} wins there, as it is given first",
                first.name,
                second.name,
                first.name
            );
        }
    }
}
