//! Transfer functions: piecewise-linear colour and opacity per data value.
//!
//! Opacity is given per unit length: a point's `opacity` is what a slab `unit` metres thick
//! absorbs. The table stores the extinction `σ = −ln(1 − opacity) / unit` per metre, so a
//! sample standing for a ray segment of length `ℓ` has `Ω = 1 − exp(−σ·ℓ)` whatever the step:
//! the opacity is corrected for the actual step length.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Entries in the table both renderers interpolate (WGSL `VOL_TABLE`).
pub const TABLE_SIZE: usize = 256;
/// Opacities are clamped below 1 so that σ stays finite.
const MAX_OPACITY: f64 = 0.999_999;

/// One control point: at data value `value`, linear RGB `colour` and `opacity` per `unit`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TfPoint {
    pub value: f64,
    pub colour: [f64; 3],
    pub opacity: f64,
}

/// A transfer function: control points sorted by value (colour and opacity are held
/// constant beyond the ends) and the length over which a point's opacity is reached.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferFunction {
    pub points: Vec<TfPoint>,
    /// Metres; `None` means one voxel (the smallest spacing) of the volume it classifies.
    pub unit: Option<f64>,
}

/// Built-in transfer functions (`transfer = "name"`).
pub const PRESETS: &[&str] = &["brain", "brain-white", "grey", "cloud", "smoke", "slices"];

fn p(value: f64, colour: [f64; 3], opacity: f64) -> TfPoint {
    TfPoint {
        value,
        colour,
        opacity,
    }
}

impl TransferFunction {
    /// A named preset; the error lists the names.
    pub fn preset(name: &str) -> Result<TransferFunction> {
        let points = match name {
            // MNI T1 (0..255): background and CSF clear, grey matter a faint rose haze,
            // white matter near-opaque ivory.
            "brain" => vec![
                p(0.0, [0.0, 0.0, 0.0], 0.0),
                p(60.0, [0.0, 0.0, 0.0], 0.0),
                p(100.0, [0.75, 0.35, 0.3], 0.02),
                p(150.0, [0.85, 0.55, 0.45], 0.08),
                p(175.0, [0.95, 0.9, 0.8], 0.6),
                p(255.0, [1.0, 0.97, 0.9], 0.9),
            ],
            // White matter only (hides about 87% of the MNI template's voxels).
            "brain-white" => vec![
                p(0.0, [0.0, 0.0, 0.0], 0.0),
                p(165.0, [0.0, 0.0, 0.0], 0.0),
                p(180.0, [0.9, 0.85, 0.7], 0.5),
                p(255.0, [1.0, 0.95, 0.85], 0.95),
            ],
            // Linear ramp over 0..255.
            "grey" => vec![p(0.0, [0.0; 3], 0.0), p(255.0, [1.0; 3], 0.5)],
            // Clouds on 0..1 densities: clear below 0.25, white and dense above.
            "cloud" => vec![
                p(0.0, [1.0; 3], 0.0),
                p(0.25, [1.0; 3], 0.0),
                p(0.6, [0.97, 0.97, 1.0], 0.3),
                p(1.0, [1.0; 3], 0.8),
            ],
            // Smoke on 0..1 densities: grey, thin.
            "smoke" => vec![
                p(0.0, [0.3; 3], 0.0),
                p(0.1, [0.3; 3], 0.0),
                p(1.0, [0.15, 0.14, 0.13], 0.4),
            ],
            // Slice masks (procedural function4d): slice i at value i, a rainbow from red to
            // violet, each slice absorbing 20% per voxel.
            "slices" => (0..8)
                .map(|i| {
                    let h = i as f64 / 8.0 * 5.0;
                    let c = |k: f64| {
                        let x = (h + k) % 6.0;
                        1.0 - x.min(4.0 - x).clamp(0.0, 1.0)
                    };
                    p(i as f64, [c(5.0), c(3.0), c(1.0)], 0.2)
                })
                .collect(),
            _ => {
                return Err(Error::invalid(
                    "transfer",
                    format!("unknown preset {name:?}; presets: {}", PRESETS.join(", ")),
                ))
            }
        };
        Ok(TransferFunction { points, unit: None })
    }

    /// Checks the points (finite, sorted, colours ≥ 0, opacity in 0..=1); `field` names the
    /// table in errors.
    pub fn validate(&self, field: &str) -> Result<()> {
        if self.points.is_empty() {
            return Err(Error::invalid(field, "needs at least one point"));
        }
        for (i, q) in self.points.iter().enumerate() {
            let bad = |msg: String| Err(Error::invalid(format!("{field}[{i}]"), msg));
            if !q.value.is_finite() {
                return bad(format!("value must be finite, got {}", q.value));
            }
            if q.colour
                .iter()
                .any(|c| !c.is_finite() || *c < 0.0 || *c > 100.0)
            {
                return bad(format!(
                    "colour must be linear RGB in 0..=100, got {:?}",
                    q.colour
                ));
            }
            if !(0.0..=1.0).contains(&q.opacity) {
                return bad(format!("opacity must be in 0..=1, got {}", q.opacity));
            }
            if i > 0 && q.value < self.points[i - 1].value {
                return bad("points must be sorted by value".into());
            }
        }
        if let Some(u) = self.unit {
            if !u.is_finite() || u <= 0.0 {
                return Err(Error::invalid(
                    format!("{field} unit"),
                    format!("must be positive metres, got {u}"),
                ));
            }
        }
        Ok(())
    }

    /// Colour and opacity at data value `v`.
    pub fn eval(&self, v: f64) -> ([f64; 3], f64) {
        let pts = &self.points;
        let last = pts[pts.len() - 1];
        if v <= pts[0].value {
            return (pts[0].colour, pts[0].opacity);
        }
        if v >= last.value {
            return (last.colour, last.opacity);
        }
        let k = pts.partition_point(|q| q.value <= v);
        let (a, b) = (pts[k - 1], pts[k]);
        let f = if b.value > a.value {
            (v - a.value) / (b.value - a.value)
        } else {
            1.0
        };
        (
            std::array::from_fn(|i| a.colour[i] + (b.colour[i] - a.colour[i]) * f),
            a.opacity + (b.opacity - a.opacity) * f,
        )
    }

    /// The 256-entry table over 8-bit densities: entry `i` classifies data value
    /// `value_of(i)`; `default_unit` (metres) applies when the function has no `unit`.
    pub fn table(&self, value_of: impl Fn(f64) -> f64, default_unit: f64) -> TransferTable {
        let unit = self.unit.unwrap_or(default_unit);
        let entries = (0..TABLE_SIZE)
            .map(|i| {
                let (c, a) = self.eval(value_of(i as f64));
                let sigma = -(1.0 - a.min(MAX_OPACITY)).ln() / unit;
                [c[0] as f32, c[1] as f32, c[2] as f32, sigma as f32]
            })
            .collect();
        TransferTable { entries }
    }

    /// Fraction of `data`'s voxels the function gives no opacity to.
    pub fn hidden_fraction(&self, data: &[u8], value_of: impl Fn(f64) -> f64) -> f64 {
        let mut hist = [0usize; 256];
        for &d in data {
            hist[d as usize] += 1;
        }
        let hidden: usize = (0..256)
            .filter(|&i| self.eval(value_of(i as f64)).1 <= 0.0)
            .map(|i| hist[i])
            .sum();
        hidden as f64 / data.len().max(1) as f64
    }
}

/// The classified table: per 8-bit density, linear RGB and extinction σ per metre.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferTable {
    pub entries: Vec<[f32; 4]>,
}

impl TransferTable {
    /// Colour and σ at a filtered density `d` in 0..1, interpolating between entries exactly
    /// as the shader does (f32 table, f64 arithmetic).
    pub fn lookup(&self, d: f64) -> [f64; 4] {
        let x = (d * 255.0).clamp(0.0, 255.0);
        let i0 = (x.floor() as usize).min(TABLE_SIZE - 1);
        let i1 = (i0 + 1).min(TABLE_SIZE - 1);
        let f = x - i0 as f64;
        let (a, b) = (self.entries[i0], self.entries[i1]);
        std::array::from_fn(|k| a[k] as f64 + (b[k] as f64 - a[k] as f64) * f)
    }

    /// Whether some density in `lo..=hi` (8-bit) has opacity. Interpolation between entries
    /// stays within them, so checking the entries is exact.
    pub fn any_opaque(&self, lo: u8, hi: u8) -> bool {
        self.entries[lo as usize..=hi as usize]
            .iter()
            .any(|e| e[3] > 0.0)
    }
}
