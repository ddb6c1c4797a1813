//! The report of every `relief bench` mode: one JSON schema (`--json`) and one printed form.
//!
//! ```json
//! { "bench": "terrain", "adapter": "...", "backend": "Vulkan", "scene": "terrains/alps.toml",
//!   "width": 1280, "height": 720, "frames": 10,
//!   "rows": [ { "name": "pyramid+tiles", "primary_ms": 1.9, ... }, ... ],
//!   "summary": { "speedup_vs_march": 3.1, ... },
//!   "notes": [ "..." ],
//!   "details": { ...the mode's own figures, in full... } }
//! ```
//!
//! `rows` are the measured configurations (the same figures in every row, a table when
//! printed), `summary` the headline figures, `notes` what is not a number, `details` the
//! mode's whole result ([`super::terrain::TerrainBench`], [`super::soak::SoakBench`], …).

use crate::gpu::Gpu;
use crate::{Error, Result};
use serde::{Serialize, Serializer};
use std::fmt;
use std::path::Path;

/// Named figures in a fixed order (a JSON object in that order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Figures(pub Vec<(String, f64)>);

impl Figures {
    /// `self` with `name` = `value` appended.
    pub fn with(mut self, name: &str, value: f64) -> Figures {
        self.0.push((name.to_string(), value));
        self
    }

    /// The figure called `name`.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.0.iter().find(|(n, _)| n == name).map(|(_, v)| *v)
    }
}

impl Serialize for Figures {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_map(self.0.iter().map(|(k, v)| (k, v)))
    }
}

/// One measured configuration.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub name: String,
    #[serde(flatten)]
    pub figures: Figures,
}

impl Row {
    pub fn new(name: impl Into<String>, figures: Figures) -> Row {
        Row {
            name: name.into(),
            figures,
        }
    }
}

/// What every benchmark mode reports.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// The mode: `terrain`, `primary`, `freeforms`, `volume`, `voxels`, `display` or `soak`.
    pub bench: String,
    pub adapter: String,
    pub backend: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    /// Timed frames per configuration.
    pub frames: u32,
    /// The measured configurations, the same figures in each.
    pub rows: Vec<Row>,
    /// Headline figures (ratios, totals).
    pub summary: Figures,
    /// What is not a figure.
    pub notes: Vec<String>,
    /// The mode's own result in full.
    pub details: serde_json::Value,
}

impl BenchReport {
    /// A report of mode `bench` on `gpu`'s adapter with the mode's whole result `details`;
    /// rows, summary and notes empty.
    pub fn new(
        bench: &str,
        gpu: &Gpu,
        scene: &Path,
        size: (u32, u32),
        frames: u32,
        details: &impl Serialize,
    ) -> Result<BenchReport> {
        let details = serde_json::to_value(details)
            .map_err(|e| Error::invalid(format!("bench {bench}"), format!("report: {e}")))?;
        Ok(BenchReport {
            bench: bench.to_string(),
            adapter: gpu.info.name.clone(),
            backend: format!("{:?}", gpu.info.backend),
            scene: scene.display().to_string(),
            width: size.0,
            height: size.1,
            frames,
            rows: Vec::new(),
            summary: Figures::default(),
            notes: Vec::new(),
            details,
        })
    }

    /// The report as one pretty-printed JSON object.
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string_pretty(self)
            .map_err(|e| Error::invalid(format!("bench {}", self.bench), format!("JSON: {e}")))
    }
}

/// A figure as printed: whole numbers as they are, others to 4 significant digits, very large
/// and very small ones in exponent form; `-` for none (NaN).
pub fn number(v: f64) -> String {
    let a = v.abs();
    if v.is_nan() {
        "-".into()
    } else if v.fract() == 0.0 && a < 1e9 {
        format!("{v:.0}")
    } else if !v.is_finite() || a >= 1e5 || a < 1e-3 {
        format!("{v:.3e}")
    } else {
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{v:.decimals$}")
    }
}

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "relief bench {}: {} at {}x{}, {} frames; adapter {} ({})",
            self.bench,
            self.scene,
            self.width,
            self.height,
            self.frames,
            self.adapter,
            self.backend
        )?;
        if let Some(first) = self.rows.first() {
            let columns: Vec<&str> = first.figures.0.iter().map(|(k, _)| k.as_str()).collect();
            let cells: Vec<Vec<String>> = (self.rows.iter())
                .map(|r| r.figures.0.iter().map(|(_, v)| number(*v)).collect())
                .collect();
            let name_w = self
                .rows
                .iter()
                .map(|r| r.name.len())
                .max()
                .unwrap_or(0)
                .max(13);
            let widths: Vec<usize> = (columns.iter().enumerate())
                .map(|(i, c)| {
                    cells
                        .iter()
                        .filter_map(|r| r.get(i))
                        .map(String::len)
                        .fold(c.len(), usize::max)
                })
                .collect();
            write!(f, "{:<name_w$}", "configuration")?;
            for (c, w) in columns.iter().zip(&widths) {
                write!(f, "  {c:>w$}")?;
            }
            writeln!(f)?;
            for (r, row) in self.rows.iter().zip(&cells) {
                write!(f, "{:<name_w$}", r.name)?;
                for (v, w) in row.iter().zip(&widths) {
                    write!(f, "  {v:>w$}")?;
                }
                writeln!(f)?;
            }
        }
        for (k, v) in &self.summary.0 {
            writeln!(f, "{k}: {}", number(*v))?;
        }
        for n in &self.notes {
            writeln!(f, "{n}")?;
        }
        Ok(())
    }
}
