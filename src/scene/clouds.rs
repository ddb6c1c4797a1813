//! `[[clouds]]`: stratiform cloud layers (decks) over the whole terrain, the layers a host
//! gives over CIGI's Weather Control (layer IDs 1–3). The optics are in [`crate::cpu::clouds`],
//! the shader in `gpu/shaders/clouds.wgsl`.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// The most cloud layers a scene (or a host) may give.
pub const MAX_CLOUD_LAYERS: usize = 3;

/// One cloud layer: a slab between two heights above mean sea level, covered in part by
/// cloud cells of a 2-D noise pattern fixed to the ground.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CloudLayer {
    /// Height of the cloud base above mean sea level (m).
    pub base: f64,
    /// From base to tops (m).
    pub thickness: f64,
    /// Fraction of the sky the layer covers, 0..=1 (1: overcast).
    #[serde(default = "overcast")]
    pub coverage: f64,
    /// Visibility inside the cloud (m): its extinction is 3.912 / visibility (Koschmieder).
    #[serde(default = "in_cloud_visibility")]
    pub visibility: f64,
    /// Size of a cloud cell (m): the period of the pattern's coarsest octave.
    #[serde(default = "cell_size")]
    pub feature: f64,
    /// Seed of the cloud pattern (layers with the same seed and feature look alike).
    #[serde(default)]
    pub seed: u32,
    /// How domed the cells are, 0..=1: 0 flat tops at the layer's top (stratus), 1 tops
    /// rising from a third of the thickness at a cell's edge (cumulus).
    #[serde(default = "domed")]
    pub relief: f64,
}

fn domed() -> f64 {
    1.0
}

fn overcast() -> f64 {
    1.0
}

fn in_cloud_visibility() -> f64 {
    60.0
}

fn cell_size() -> f64 {
    2500.0
}

impl CloudLayer {
    /// Height of the tops above mean sea level (m).
    pub fn top(&self) -> f64 {
        self.base + self.thickness
    }
}

/// Checks each layer's values and that the layers neither overlap nor number more than
/// [`MAX_CLOUD_LAYERS`]; errors name the layer and the field.
pub fn validate(layers: &[CloudLayer]) -> Result<()> {
    if layers.len() > MAX_CLOUD_LAYERS {
        return Err(Error::invalid(
            "clouds",
            format!(
                "{} layers given, at most {MAX_CLOUD_LAYERS} are drawn: merge or drop some",
                layers.len()
            ),
        ));
    }
    for (i, l) in layers.iter().enumerate() {
        let field = |name: &str| format!("clouds[{i}].{name}");
        let checks = [
            (
                "base",
                l.base,
                -1000.0,
                30_000.0,
                "metres above mean sea level",
            ),
            ("thickness", l.thickness, 1.0, 20_000.0, "metres"),
            (
                "coverage",
                l.coverage,
                0.0,
                1.0,
                "(a fraction: 0.5 covers half the sky)",
            ),
            (
                "visibility",
                l.visibility,
                1.0,
                100_000.0,
                "metres inside the cloud",
            ),
            (
                "feature",
                l.feature,
                50.0,
                1.0e6,
                "metres (the size of a cloud cell)",
            ),
            (
                "relief",
                l.relief,
                0.0,
                1.0,
                "(0: flat tops, 1: domed cells)",
            ),
        ];
        for (name, v, lo, hi, unit) in checks {
            if !v.is_finite() || !(lo..=hi).contains(&v) {
                return Err(Error::invalid(
                    field(name),
                    format!("must be in {lo}..={hi} {unit}, got {v}"),
                ));
            }
        }
        if l.seed >= 1 << 24 {
            // The GPU holds it as an f32.
            return Err(Error::invalid(
                field("seed"),
                format!("must be below 16777216, got {}", l.seed),
            ));
        }
        for (j, o) in layers.iter().enumerate().take(i) {
            if l.base < o.top() && o.base < l.top() {
                return Err(Error::invalid(
                    field("base"),
                    format!(
                        "the layer from {} to {} m overlaps clouds[{j}] ({} to {} m): give each layer its own heights",
                        l.base,
                        l.top(),
                        o.base,
                        o.top()
                    ),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn deck(base: f64, thickness: f64) -> CloudLayer {
        CloudLayer {
            base,
            thickness,
            coverage: 0.5,
            visibility: 60.0,
            feature: 2500.0,
            seed: 0,
            relief: 1.0,
        }
    }

    #[test]
    fn bad_layers_are_refused_by_name() {
        assert!(validate(&[deck(1000.0, 300.0), deck(2000.0, 500.0)]).is_ok());
        let msg = |l: &[CloudLayer]| validate(l).unwrap_err().to_string();
        assert!(msg(&[deck(1000.0, 300.0), deck(1200.0, 500.0)]).contains("clouds[1].base"));
        assert!(msg(&[deck(f64::NAN, 300.0)]).contains("clouds[0].base"));
        assert!(msg(&[deck(1000.0, 0.0)]).contains("clouds[0].thickness"));
        let mut l = deck(1000.0, 300.0);
        l.coverage = 1.5;
        assert!(msg(&[l]).contains("clouds[0].coverage"));
        l.coverage = 0.5;
        l.visibility = 0.0;
        assert!(msg(&[l]).contains("clouds[0].visibility"));
        l.visibility = 60.0;
        l.feature = f64::INFINITY;
        assert!(msg(&[l]).contains("clouds[0].feature"));
        l.feature = 2500.0;
        l.seed = 1 << 24;
        assert!(msg(&[l]).contains("clouds[0].seed"));
        l.seed = 0;
        l.relief = -0.1;
        assert!(msg(&[l]).contains("clouds[0].relief"));
        let four: Vec<_> = (0..4).map(|k| deck(1000.0 * k as f64, 300.0)).collect();
        assert!(msg(&four).contains("at most 3"));
    }
}
