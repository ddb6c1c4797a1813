//! `[[voxels]]` in a scene file: a voxel model file (`.vox` or segment `.rvs`) placed in the
//! world. Unknown keys are errors.
//!
//! ```toml
//! [[voxels]]
//! name = "tree"
//! file = "tree.vox"          # relative to the scene file
//! position = [x, y, z]       # world position of the model's bottom centre
//! # geodetic = [lat, lon, alt] # or: its latitude, longitude, metres above sea level
//! above_terrain = 0.0        # z = terrain height below + this
//! voxel_size = 0.05          # metres per voxel
//! heading = 0.0              # degrees, pitch and roll as for the camera
//! fps = 8.0                  # animation frames per second (files with several frames)
//! frame = 0                  # or: always show this frame
//! ```

use super::VoxelModel;
use crate::geom::{checked_attitude, place, Ground};
use crate::{Error, Result};
use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// Most voxel models one scene may place.
pub const MAX_INSTANCES: usize = 64;

/// One `[[voxels]]` table.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct VoxelDesc {
    pub name: Option<String>,
    pub file: std::path::PathBuf,
    /// World position of the model's bottom centre.
    pub position: Option<[f64; 3]>,
    /// Or its `[latitude, longitude, altitude]` (WGS84 degrees, metres above mean sea level).
    pub geodetic: Option<[f64; 3]>,
    pub above_terrain: Option<f64>,
    #[serde(default = "default_size")]
    pub voxel_size: f64,
    #[serde(default)]
    pub heading: f64,
    #[serde(default)]
    pub pitch: f64,
    #[serde(default)]
    pub roll: f64,
    #[serde(default = "default_fps")]
    pub fps: f64,
    pub frame: Option<u32>,
}

fn default_size() -> f64 {
    0.1
}
fn default_fps() -> f64 {
    10.0
}

/// A placed voxel model: `world = position + rotation · ((p − anchor) · voxel_size)` for a point
/// `p` in voxel units, where `anchor` is the model's bottom centre `(dx/2, dy/2, 0)`.
#[derive(Clone, Debug)]
pub struct VoxelInstance {
    pub name: String,
    /// Animation frames (all the same size).
    pub frames: Vec<Arc<VoxelModel>>,
    /// Columns: the model's x, y, z axes in the world.
    pub rotation: DMat3,
    pub position: DVec3,
    pub voxel_size: f64,
    pub fps: f64,
    pub fixed_frame: Option<u32>,
}

impl VoxelInstance {
    /// An instance of `frames` at `position` (bottom centre), rotated, `voxel_size` m per voxel.
    pub fn new(
        name: &str,
        frames: Vec<Arc<VoxelModel>>,
        rotation: DMat3,
        position: DVec3,
        voxel_size: f64,
    ) -> VoxelInstance {
        VoxelInstance {
            name: name.to_string(),
            frames,
            rotation,
            position,
            voxel_size,
            fps: 10.0,
            fixed_frame: None,
        }
    }

    pub fn dims(&self) -> [u32; 3] {
        self.frames[0].dims
    }

    /// The model's bottom centre in voxel units.
    pub fn anchor(&self) -> DVec3 {
        let d = self.dims();
        DVec3::new(d[0] as f64 * 0.5, d[1] as f64 * 0.5, 0.0)
    }

    /// The model moved rigidly by `offset` (world metres).
    pub fn translated(&self, offset: DVec3) -> VoxelInstance {
        VoxelInstance {
            position: self.position + offset,
            ..self.clone()
        }
    }

    /// World point → voxel units.
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.rotation.transpose() * (p - self.position) / self.voxel_size + self.anchor()
    }

    /// World direction → voxel units per metre (ray distances stay in metres).
    pub fn dir_to_local(&self, d: DVec3) -> DVec3 {
        self.rotation.transpose() * d / self.voxel_size
    }

    /// Voxel-unit direction → world unit vector.
    pub fn dir_to_world(&self, d: DVec3) -> DVec3 {
        (self.rotation * d).normalize()
    }

    /// The frame shown at `time` seconds.
    pub fn frame_at(&self, time: f64) -> usize {
        let n = self.frames.len();
        match self.fixed_frame {
            Some(f) => (f as usize).min(n - 1),
            None if n > 1 && time.is_finite() && time > 0.0 => {
                ((time * self.fps).floor() as u64 % n as u64) as usize
            }
            None => 0,
        }
    }

    /// World corners of the model box (all frames share its size).
    pub fn box_corners(&self) -> [DVec3; 8] {
        let d = self.dims();
        self.local_box_corners([
            DVec3::ZERO,
            DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64),
        ])
    }

    /// World corners of the box `[lo, hi]` given in voxel units.
    pub fn local_box_corners(&self, [lo, hi]: [DVec3; 2]) -> [DVec3; 8] {
        std::array::from_fn(|k| {
            let c = DVec3::new(
                if k & 1 != 0 { hi.x } else { lo.x },
                if k & 2 != 0 { hi.y } else { lo.y },
                if k & 4 != 0 { hi.z } else { lo.z },
            );
            self.position + self.rotation * (c - self.anchor()) * self.voxel_size
        })
    }

    /// Bounding boxes (voxel units, `[lo, hi]`) of the occupied voxels of every frame in
    /// `slabs` equal ranges of z, empty ones left out: a tighter hull than the model box (a
    /// tree's trunk and crown), for the voxel passes' screen rectangles.
    pub fn occupied_slabs(&self, slabs: u32) -> Vec<[DVec3; 2]> {
        let d = self.dims();
        let slabs = slabs.clamp(1, d[2]);
        let mut boxes = vec![[DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)]; slabs as usize];
        for v in self.frames.iter().flat_map(|f| &f.voxels) {
            let b = &mut boxes[(v.pos[2] as u64 * slabs as u64 / d[2] as u64) as usize];
            let p = DVec3::new(v.pos[0] as f64, v.pos[1] as f64, v.pos[2] as f64);
            b[0] = b[0].min(p);
            b[1] = b[1].max(p + 1.0);
        }
        boxes.retain(|b| b[0].x <= b[1].x);
        boxes
    }

    /// World-space bounding sphere (centre, radius).
    pub fn bounding_sphere(&self) -> (DVec3, f64) {
        let d = self.dims();
        let half = DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64) * 0.5;
        let c = self.rotation * (half - self.anchor()) * self.voxel_size + self.position;
        (c, half.length() * self.voxel_size)
    }
}

/// Loads a model file's frames: `.vox` (with its scene graph) or a segment file.
pub fn load_frames(path: &Path) -> Result<Vec<VoxelModel>> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("vox") => super::vox::VoxFile::load(path)?.frames(),
        Some("rvs") => Ok(vec![super::segment::read(path)?]),
        _ => Err(Error::format(
            path,
            "unknown voxel model type: use a MagicaVoxel .vox or a relief segment .rvs file",
        )),
    }
}

impl VoxelDesc {
    /// Loads and places the model (`index` and name in errors); `ground` gives the terrain
    /// height below a world point and places `geodetic` positions.
    pub fn build(
        &self,
        index: usize,
        base_dir: &Path,
        ground: &dyn Ground,
    ) -> Result<VoxelInstance> {
        let name = self
            .name
            .clone()
            .unwrap_or_else(|| format!("voxels {index}"));
        let field = format!("voxels[{index}] ({name})");
        let at = |k: &str| format!("{field}.{k}");
        let rotation = checked_attitude(&at, self.heading, self.pitch, self.roll)?;
        if !self.voxel_size.is_finite() || !(1e-4..=1e3).contains(&self.voxel_size) {
            return Err(Error::invalid(
                format!("{field}.voxel_size"),
                format!("must be 0.0001..=1000 metres, got {}", self.voxel_size),
            ));
        }
        if !self.fps.is_finite() || !(0.0..=1000.0).contains(&self.fps) {
            return Err(Error::invalid(
                format!("{field}.fps"),
                format!("must be 0..=1000, got {}", self.fps),
            ));
        }
        let position = place(
            &at,
            self.position,
            self.geodetic,
            self.above_terrain,
            ground,
        )?;
        let path = base_dir.join(&self.file);
        let frames = load_frames(&path)?;
        if let Some(f) = self.frame {
            if f as usize >= frames.len() {
                return Err(Error::invalid(
                    format!("{field}.frame"),
                    format!(
                        "{} has {} frame(s), asked for {f}",
                        path.display(),
                        frames.len()
                    ),
                ));
            }
        }
        let mut inst = VoxelInstance::new(
            &name,
            frames.into_iter().map(Arc::new).collect(),
            rotation,
            position,
            self.voxel_size,
        );
        inst.fps = self.fps;
        inst.fixed_frame = self.frame;
        Ok(inst)
    }
}

/// Builds every `[[voxels]]` table of a scene.
pub fn build_all(
    descs: &[VoxelDesc],
    base_dir: &Path,
    terrain: &crate::terrain::Terrain,
) -> Result<Vec<VoxelInstance>> {
    if descs.len() > MAX_INSTANCES {
        return Err(Error::invalid(
            "voxels",
            format!(
                "{} voxel models; at most {MAX_INSTANCES} are supported",
                descs.len()
            ),
        ));
    }
    descs
        .iter()
        .enumerate()
        .map(|(i, d)| d.build(i, base_dir, terrain))
        .collect()
}
