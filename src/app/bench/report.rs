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
//! mode's whole result ([`Details`]).

use super::antialias::AntialiasBench;
use super::cigi::CigiBench;
use super::clouds::CloudsBench;
use super::db::DbBench;
use super::display::DisplayBench;
use super::freeforms::FreeFormBench;
use super::primary::PrimaryTiming;
use super::soak::SoakBench;
use super::table::{RunInfo, Table};
use super::terrain::TerrainBench;
use super::volume::VolumeBench;
use super::voxels::VoxelBench;
use crate::{Error, Result};
use serde::Serialize;
use std::fmt;

/// A mode's whole result.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum Details {
    Terrain(TerrainBench),
    Primary(PrimaryTiming),
    FreeForms(FreeFormBench),
    Volume(VolumeBench),
    Voxels(VoxelBench),
    Display(DisplayBench),
    Soak(SoakBench),
    Db(DbBench),
    Cigi(CigiBench),
    Antialias(AntialiasBench),
    Clouds(CloudsBench),
}

impl Details {
    /// The mode's name (the report's `bench`).
    pub fn mode(&self) -> &'static str {
        match self {
            Details::Terrain(_) => "terrain",
            Details::Primary(_) => "primary",
            Details::FreeForms(_) => "freeforms",
            Details::Volume(_) => "volume",
            Details::Voxels(_) => "voxels",
            Details::Display(_) => "display",
            Details::Soak(_) => "soak",
            Details::Db(_) => "db",
            Details::Cigi(_) => "cigi",
            Details::Antialias(_) => "antialias",
            Details::Clouds(_) => "clouds",
        }
    }

    /// The result in the shape every report shares.
    pub fn table(&self) -> Table {
        match self {
            Details::Terrain(d) => d.table(),
            Details::Primary(d) => d.table(),
            Details::FreeForms(d) => d.table(),
            Details::Volume(d) => d.table(),
            Details::Voxels(d) => d.table(),
            Details::Display(d) => d.table(),
            Details::Soak(d) => d.table(),
            Details::Db(d) => d.table(),
            Details::Cigi(d) => d.table(),
            Details::Antialias(d) => d.table(),
            Details::Clouds(d) => d.table(),
        }
    }
}

/// What every benchmark mode reports.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// The mode: `terrain`, `primary`, `freeforms`, `volume`, `voxels`, `display`, `soak`, `db` or `cigi`.
    pub bench: &'static str,
    #[serde(flatten)]
    pub run: RunInfo,
    #[serde(flatten)]
    pub table: Table,
    /// The mode's own result in full.
    pub details: Details,
}

impl BenchReport {
    /// The report of a run with result `details`.
    pub fn new(run: RunInfo, details: Details) -> BenchReport {
        BenchReport {
            bench: details.mode(),
            run,
            table: details.table(),
            details,
        }
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
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{v:.decimals$}")
    }
}

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.run;
        writeln!(
            f,
            "relief bench {}: {} at {}x{}, {} frames; adapter {} ({})",
            self.bench, r.scene, r.width, r.height, r.frames, r.adapter, r.backend
        )?;
        let t = &self.table;
        if let Some(first) = t.rows.first() {
            let columns: Vec<&str> = first.figures.0.iter().map(|(k, _)| k.as_str()).collect();
            let cells: Vec<Vec<String>> = (t.rows.iter())
                .map(|r| r.figures.0.iter().map(|(_, v)| number(*v)).collect())
                .collect();
            let name_w = t.rows.iter().map(|r| r.name.len()).fold(13, usize::max);
            let widths: Vec<usize> = (columns.iter().enumerate())
                .map(|(i, c)| {
                    let cells = cells.iter().filter_map(|r| r.get(i));
                    cells.map(String::len).fold(c.len(), usize::max)
                })
                .collect();
            write!(f, "{:<name_w$}", "configuration")?;
            for (c, w) in columns.iter().zip(&widths) {
                write!(f, "  {c:>w$}")?;
            }
            writeln!(f)?;
            for (row, values) in t.rows.iter().zip(&cells) {
                write!(f, "{:<name_w$}", row.name)?;
                for (v, w) in values.iter().zip(&widths) {
                    write!(f, "  {v:>w$}")?;
                }
                writeln!(f)?;
            }
        }
        for (k, v) in &t.summary.0 {
            writeln!(f, "{k}: {}", number(*v))?;
        }
        for n in &t.notes {
            writeln!(f, "{n}")?;
        }
        Ok(())
    }
}
