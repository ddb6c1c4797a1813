//! The parts every benchmark report has: who ran what ([`RunInfo`]), and the figures in one
//! shape ([`Table`]): rows of named figures (the measured configurations), headline figures
//! and notes.

use crate::gpu::Gpu;
use serde::{Serialize, Serializer};
use std::path::Path;

/// The adapter, scene, size and frame count of a run.
#[derive(Clone, Debug, Serialize)]
pub struct RunInfo {
    pub adapter: String,
    pub backend: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    /// Timed frames per configuration.
    pub frames: u32,
}

impl RunInfo {
    /// A run on `gpu`'s adapter of `scene` at `size`, `frames` timed frames.
    pub fn new(gpu: &Gpu, scene: &Path, size: (u32, u32), frames: u32) -> RunInfo {
        RunInfo {
            adapter: gpu.info.name.clone(),
            backend: format!("{:?}", gpu.info.backend),
            scene: scene.display().to_string(),
            width: size.0,
            height: size.1,
            frames,
        }
    }
}

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
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
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

/// A mode's figures in the shape every report shares.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Table {
    /// The measured configurations, the same figures in each.
    pub rows: Vec<Row>,
    /// Headline figures (ratios, totals).
    pub summary: Figures,
    /// What is not a figure.
    pub notes: Vec<String>,
}
