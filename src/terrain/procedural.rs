//! Procedural terrain: ridged fractional Brownian motion over gradient noise.
//! Deterministic for a given seed on every machine (integer hashing, f64 arithmetic).

use super::heightfield::Heightfield;
use crate::{Error, Result};
use rayon::prelude::*;

/// Parameters of a ridged-fBm terrain.
#[derive(Clone, Copy, Debug, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct RidgedFbm {
    /// Samples per side.
    pub size: usize,
    /// Metres between samples.
    #[serde(default = "default_cell")]
    pub cell_size: f64,
    /// Peak-to-valley height in metres.
    #[serde(default = "default_height")]
    pub height: f64,
    /// Number of octaves.
    #[serde(default = "default_octaves")]
    pub octaves: u32,
    /// Wavelength of the first octave, in samples.
    #[serde(default = "default_wavelength")]
    pub wavelength: f64,
    /// Random seed.
    #[serde(default)]
    pub seed: u32,
}

fn default_cell() -> f64 {
    30.0
}
fn default_height() -> f64 {
    2000.0
}
fn default_octaves() -> u32 {
    8
}
fn default_wavelength() -> f64 {
    256.0
}

fn hash(x: i64, y: i64, seed: u32) -> u32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ seed.wrapping_mul(0xcb1a_b31f);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297a_2d39);
    h ^ (h >> 15)
}

fn gradient_noise(x: f64, y: f64, seed: u32) -> f64 {
    let (xi, yi) = (x.floor(), y.floor());
    let (fx, fy) = (x - xi, y - yi);
    let (xi, yi) = (xi as i64, yi as i64);
    let grad = |i: i64, j: i64, dx: f64, dy: f64| {
        let a = hash(i, j, seed) as f64 * (std::f64::consts::TAU / 4_294_967_296.0);
        a.cos() * dx + a.sin() * dy
    };
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (u, v) = (fade(fx), fade(fy));
    let n00 = grad(xi, yi, fx, fy);
    let n10 = grad(xi + 1, yi, fx - 1.0, fy);
    let n01 = grad(xi, yi + 1, fx, fy - 1.0);
    let n11 = grad(xi + 1, yi + 1, fx - 1.0, fy - 1.0);
    let a = n00 + (n10 - n00) * u;
    let b = n01 + (n11 - n01) * u;
    (a + (b - a) * v) * std::f64::consts::SQRT_2
}

/// Ridged fBm at `(x, y)` in units of the first octave's wavelength: `octaves` octaves of
/// gradient noise, each twice the frequency and half the amplitude of the one before, folded
/// into ridges and weighted by the octave below. Deterministic (integer hashing, f64), in
/// about 0..2.
pub fn ridged_fbm(x: f64, y: f64, octaves: u32, seed: u32) -> f64 {
    let (mut freq, mut amp, mut sum, mut weight) = (1.0, 1.0, 0.0, 1.0);
    for o in 0..octaves {
        let r = 1.0 - gradient_noise(x * freq, y * freq, seed.wrapping_add(o)).abs();
        let r = r * r * weight;
        weight = (r * 2.0).clamp(0.0, 1.0);
        sum += r * amp;
        freq *= 2.0;
        amp *= 0.5;
    }
    sum
}

impl RidgedFbm {
    /// Generates the height field.
    pub fn generate(&self) -> Result<Heightfield> {
        if !(2..=super::heightfield::MAX_SIDE).contains(&self.size) {
            return Err(Error::invalid(
                "terrain.procedural.size",
                format!(
                    "must be 2..={} samples, got {}",
                    super::heightfield::MAX_SIDE,
                    self.size
                ),
            ));
        }
        if !(1..=16).contains(&self.octaves) {
            return Err(Error::invalid(
                "terrain.procedural.octaves",
                format!("must be 1..=16, got {}", self.octaves),
            ));
        }
        for (name, v) in [
            ("cell_size", self.cell_size),
            ("height", self.height),
            ("wavelength", self.wavelength),
        ] {
            if !v.is_finite() || v <= 0.0 {
                return Err(Error::invalid(
                    format!("terrain.procedural.{name}"),
                    format!("must be a positive number, got {v}"),
                ));
            }
        }
        let n = self.size;
        let heights: Vec<f32> = (0..n * n)
            .into_par_iter()
            .map(|k| {
                let (i, j) = ((k % n) as f64, (k / n) as f64);
                let f = 1.0 / self.wavelength;
                (ridged_fbm(i * f, j * f, self.octaves, self.seed) * 0.5 * self.height) as f32
            })
            .collect();
        Heightfield::from_samples_with_voids(
            "terrain.procedural",
            n,
            n,
            heights.into_iter().map(Some).collect(),
            [self.cell_size, self.cell_size],
            None,
        )
    }
}
