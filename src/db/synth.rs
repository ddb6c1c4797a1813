//! Synthetic mosaics: a database compiled from a procedural source (`relief db synth`), for
//! tests and benchmarks at any size without source files.
//!
//! The mosaic is `tiles_x × tiles_y` source tiles of `samples²` samples sharing their edges,
//! as SRTM tiles do (by default each covers one degree: `(samples − 1)` samples per degree), from
//! `(lat, lon)` at its south-west corner. Heights are ridged fBm of the sample's indices in the
//! mosaic, computed by the compiler at each position it asks for, so no sample array is ever
//! held and any tiling is seamless; the same options give the same file, byte for byte.

use super::build::{build_sources, BuildOptions, BuildReport};
use super::source::{Source, SourceData, Synth};
use crate::{fileio, Error, Result};
use std::path::{Path, PathBuf};

/// Options of `relief db synth`.
#[derive(Clone, Copy, Debug)]
pub struct SynthOptions {
    /// Source tiles in longitude and latitude.
    pub tiles: [u32; 2],
    /// Samples per source tile side (neighbours share their edge samples).
    pub samples: u32,
    /// South-west corner, degrees.
    pub lat: f64,
    pub lon: f64,
    /// Sample step in arc-seconds; default one degree per source tile.
    pub arcsec: Option<f64>,
    pub seed: u32,
    /// Peak-to-valley height, metres.
    pub height: f64,
    /// Wavelength of the first octave, metres.
    pub wavelength_m: f64,
    /// Database tile cells.
    pub tile: u32,
}

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            tiles: [16, 16],
            samples: 257,
            lat: 46.0,
            lon: 7.0,
            arcsec: None,
            seed: 1,
            height: 3000.0,
            wavelength_m: 20_000.0,
            tile: super::format::DEFAULT_TILE,
        }
    }
}

/// Metres per arc-second of latitude (mean).
const METRES_PER_ARCSEC: f64 = 30.87;

impl SynthOptions {
    /// The sample step in degrees.
    pub fn step(&self) -> f64 {
        self.arcsec
            .map_or(1.0 / (self.samples.max(2) - 1) as f64, |a| a / 3600.0)
    }

    /// Samples of the whole mosaic along longitude and latitude.
    pub fn size(&self) -> [u64; 2] {
        let s = self.samples as u64 - 1;
        [self.tiles[0] as u64 * s + 1, self.tiles[1] as u64 * s + 1]
    }

    fn check(&self) -> Result<()> {
        let bad = |field: &str, msg: String| Err(Error::invalid(field, msg));
        if !(1..=4096).contains(&self.tiles[0]) || !(1..=4096).contains(&self.tiles[1]) {
            return bad(
                "--tiles",
                format!(
                    "{}x{} tiles: give 1..=4096 each way",
                    self.tiles[0], self.tiles[1]
                ),
            );
        }
        if !(2..=100_001).contains(&self.samples) {
            return bad(
                "--samples",
                format!("{} samples a side: give 2..=100001", self.samples),
            );
        }
        if let Some(a) = self.arcsec {
            if !(a.is_finite() && (0.01..=3600.0).contains(&a)) {
                return bad(
                    "--arcsec",
                    format!("{a}: give a step of 0.01..=3600 arc-seconds"),
                );
            }
        }
        for (field, v) in [("--height", self.height), ("wavelength", self.wavelength_m)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, format!("{v}: must be a positive number"));
            }
        }
        let step = self.step();
        let [w, h] = self.size();
        let (lon1, lat1) = (
            self.lon + (w - 1) as f64 * step,
            self.lat + (h - 1) as f64 * step,
        );
        let ok = |v: f64, lo: f64, hi: f64| v.is_finite() && v >= lo - 1e-9 && v <= hi + 1e-9;
        if !(ok(self.lon, -180.0, 180.0)
            && ok(lon1, -180.0, 180.0)
            && ok(self.lat, -90.0, 90.0)
            && ok(lat1, -90.0, 90.0))
        {
            return bad(
                "--lat/--lon",
                format!(
                    "the mosaic would span longitude {}..{lon1}, latitude {}..{lat1}: it must lie within -180..180, -90..90",
                    self.lon, self.lat
                ),
            );
        }
        Ok(())
    }

    /// The procedural source.
    pub fn source(&self) -> Result<Source> {
        self.check()?;
        let step = self.step();
        let wavelength = (self.wavelength_m / (step * 3600.0 * METRES_PER_ARCSEC)).max(2.0);
        // Octaves down to a wavelength of about two samples.
        let octaves = ((wavelength / 2.0).log2().floor() as u32 + 1).clamp(1, 16);
        let [w, h] = self.size();
        Ok(Source {
            path: PathBuf::from("synth"),
            name: format!(
                "synth seed {}: {}x{} tiles of {}² samples, {:.4}″",
                self.seed,
                self.tiles[0],
                self.tiles[1],
                self.samples,
                step * 3600.0
            ),
            order: 0,
            lon0: self.lon,
            lat0: self.lat,
            dlon: step,
            dlat: step,
            width: w as usize,
            height: h as usize,
            data: SourceData::Synth(Synth {
                seed: self.seed,
                wavelength,
                octaves,
                height: self.height,
            }),
            filled: None,
            file_len: 0,
        })
    }
}

/// Writes the synthetic mosaic `opts` as the database `out` (atomically, as `db build`).
pub fn synth(
    out: &Path,
    opts: &SynthOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<BuildReport> {
    let src = opts.source()?;
    fileio::check_writable_target(out)?;
    build_sources(out, &[src], &BuildOptions { tile: opts.tile }, progress)
}
