//! `[[volumes]]` in a scene file and the placed [`Volume`] both renderers use.

use super::procedural::ProceduralVolume;
use super::transfer::{TfPoint, TransferFunction, TransferTable};
use super::{BrickGrid, DensityGrid, VolumeTexture};
use crate::error::check_finite;
use crate::geom::{checked_attitude, place, Ground};
use crate::{Error, Result};
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One density volume.
///
/// The volume is a box of `dims · voxel_size` metres; `position` is the world position of
/// the centre of its bottom face (or `geodetic` its latitude, longitude and altitude; with
/// `above_terrain`, that many metres above the terrain below), turned by heading/pitch/roll
/// like the camera.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct VolumeDesc {
    pub name: Option<String>,
    /// `.nrrd` / `.nhdr`, or a raw volume's `.toml` header, relative to the scene file.
    pub source: Option<std::path::PathBuf>,
    pub procedural: Option<ProceduralVolume>,
    /// Data values mapped onto densities 0 and 255 (default: the type's range for 8-bit data,
    /// else the data's min..max; procedural fields are 0..1).
    pub range: Option<[f64; 2]>,
    /// Metres per voxel (default: the file's spacing; procedural: 1).
    pub voxel_size: Option<[f64; 3]>,
    pub position: Option<[f64; 3]>,
    /// Or `[latitude, longitude, altitude]` (WGS84 degrees, metres above mean sea level).
    pub geodetic: Option<[f64; 3]>,
    pub above_terrain: Option<f64>,
    #[serde(default)]
    pub heading: f64,
    #[serde(default)]
    pub pitch: f64,
    #[serde(default)]
    pub roll: f64,
    /// A preset name (see [`super::transfer::PRESETS`]).
    pub transfer: Option<String>,
    /// Or explicit control points, sorted by value.
    pub transfer_points: Option<Vec<TfPoint>>,
    /// Metres over which a point's opacity is reached (default: one voxel).
    pub opacity_unit: Option<f64>,
    #[serde(default)]
    pub render: VolumeSettings,
    #[serde(default)]
    pub material: VolumeMaterial,
    /// Bounding shell: rays start where they enter this ellipsoid (volume frame, metres from
    /// the box centre) and stop where they leave it.
    pub shell: Option<Shell>,
}

/// `render = { step = 0.5, jitter = false, skip = true, early_termination = true, mipmaps = true }`
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct VolumeSettings {
    /// Sample spacing along the ray in voxels (of the smallest spacing).
    pub step: f64,
    /// Offset each pixel's samples by a hash of its position (against wood-grain artefacts).
    pub jitter: bool,
    /// Empty-space skipping over the brick grid.
    pub skip: bool,
    /// Stop when the transmittance drops below `epsilon`.
    pub early_termination: bool,
    /// Default 1e-4: what is left behind (at most ε of the radiance) stays below half a level
    /// of 8-bit sRGB even in the darkest tones, where the encoding's slope is 12.92.
    pub epsilon: f64,
    /// Sample coarser mip levels where the pixel footprint covers several voxels.
    pub mipmaps: bool,
    /// Self-shadowing: light each sample with the sun's transmittance through the volume
    /// itself (see [`super::shadow`]; computed when the scene's sun is known).
    pub shadows: bool,
}

impl Default for VolumeSettings {
    fn default() -> Self {
        VolumeSettings {
            step: 0.5,
            jitter: false,
            skip: true,
            early_termination: true,
            epsilon: 1e-4,
            mipmaps: true,
            shadows: true,
        }
    }
}

/// Sample lighting: the paper's `C = (Qa·Ca + Qd·Cd + Qs·Cs) / (Qa + Qd + Qs)` with the
/// classified colour as surface colour and the density gradient as normal.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct VolumeMaterial {
    pub ambient: f64,
    pub diffuse: f64,
    pub specular: f64,
    pub shininess: f64,
}

impl Default for VolumeMaterial {
    fn default() -> Self {
        VolumeMaterial {
            ambient: 0.45,
            diffuse: 0.55,
            specular: 0.15,
            shininess: 16.0,
        }
    }
}

/// `shell = { radii = [rx, ry, rz], centre = [x, y, z] }`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Shell {
    pub radii: [f64; 3],
    #[serde(default)]
    pub centre: [f64; 3],
}

/// A density volume placed in the world, classified and ready to sample.
#[derive(Clone, Debug)]
pub struct Volume {
    pub name: String,
    pub grid: DensityGrid,
    pub texture: VolumeTexture,
    pub bricks: BrickGrid,
    pub transfer: TransferFunction,
    pub table: TransferTable,
    /// One word per brick (see [`BrickGrid::occupancy`]).
    pub occupancy: Vec<u32>,
    /// World position of the box corner at voxel (0, 0, 0)'s outer corner.
    pub corner: DVec3,
    /// Columns: the volume's x, y, z axes in the world.
    pub rotation: DMat3,
    pub settings: VolumeSettings,
    pub material: VolumeMaterial,
    /// Ellipsoid shell in the volume frame (metres from the corner): centre, radii.
    pub shell: Option<(DVec3, DVec3)>,
    /// Self-shadowing ([`Volume::set_sun`]), or `None` (lit without it).
    pub sun_shadow: Option<super::shadow::SunShadow>,
}

impl VolumeDesc {
    /// Loads the data and places it; `ground` gives the terrain height below a point (for
    /// `above_terrain`) and places `geodetic` positions. Errors name the volume.
    pub fn build(&self, index: usize, base_dir: &Path, ground: &dyn Ground) -> Result<Volume> {
        let name = self
            .name
            .clone()
            .unwrap_or_else(|| format!("volumes[{index}]"));
        let field = |f: &str| format!("volume {name:?}: {f}");
        let rotation = checked_attitude(&field, self.heading, self.pitch, self.roll)?;
        self.check_settings(&field)?;
        let grid = self.load_grid(base_dir, &field)?;
        let transfer = self.transfer_function(&field)?;
        let ext = DVec3::from(grid.extent());
        let corner = self.corner(ext, rotation, ground, &field)?;
        let shell = self.shell_box(ext, &field)?;
        Ok(Volume::new(
            name,
            grid,
            transfer,
            corner,
            rotation,
            self.render,
            self.material,
            shell,
        ))
    }

    /// The data range, the render settings and the material in range.
    fn check_settings(&self, field: &dyn Fn(&str) -> String) -> Result<()> {
        if let Some(r) = self.range {
            check_finite(&field("range"), &r)?;
            if r[1] <= r[0] {
                return Err(Error::invalid(
                    field("range"),
                    format!("{r:?} must increase"),
                ));
            }
        }
        let s = &self.render;
        if !s.step.is_finite() || !(0.05..=8.0).contains(&s.step) {
            return Err(Error::invalid(
                field("render.step"),
                format!("must be 0.05..=8 voxels, got {}", s.step),
            ));
        }
        if !s.epsilon.is_finite() || !(0.0..0.5).contains(&s.epsilon) {
            return Err(Error::invalid(
                field("render.epsilon"),
                format!("must be in 0..0.5, got {}", s.epsilon),
            ));
        }
        let m = &self.material;
        let q = [m.ambient, m.diffuse, m.specular];
        if q.iter().any(|v| !v.is_finite() || *v < 0.0) || q.iter().sum::<f64>() <= 0.0 {
            return Err(Error::invalid(
                field("material"),
                format!("ambient/diffuse/specular must be ≥ 0 and not all 0, got {q:?}"),
            ));
        }
        if !m.shininess.is_finite() || !(0.0..=1e4).contains(&m.shininess) {
            return Err(Error::invalid(
                field("material.shininess"),
                format!("must be in 0..=10000, got {}", m.shininess),
            ));
        }
        Ok(())
    }

    /// The density grid: loaded from `source` (relative to `base_dir`) or generated from
    /// `procedural`, with `voxel_size` overriding its spacing.
    fn load_grid(&self, base_dir: &Path, field: &dyn Fn(&str) -> String) -> Result<DensityGrid> {
        let mut grid = match (&self.source, &self.procedural) {
            (Some(_), Some(_)) | (None, None) => {
                return Err(Error::invalid(
                    field("source"),
                    "set exactly one of `source = \"file.nrrd|.toml\"` and `procedural = {..}`",
                ))
            }
            (Some(src), None) => {
                let p = base_dir.join(src);
                match p.extension().and_then(|e| e.to_str()) {
                    Some("nrrd") | Some("nhdr") => super::nrrd::load(&p, self.range)?,
                    Some("toml") => super::raw::load(&p, self.range)?,
                    _ => {
                        return Err(Error::invalid(
                            field("source"),
                            format!(
                                "{}: use a .nrrd/.nhdr file or a raw volume's .toml header",
                                p.display()
                            ),
                        ))
                    }
                }
            }
            (None, Some(pv)) => pv.generate(&field("procedural"), [1.0; 3])?,
        };
        if let Some(v) = self.voxel_size {
            if v.iter().any(|x| !x.is_finite() || *x <= 0.0) {
                return Err(Error::invalid(
                    field("voxel_size"),
                    format!("must be positive metres, got {v:?}"),
                ));
            }
            grid.spacing = v;
        }
        Ok(grid)
    }

    /// The transfer function: a preset or explicit points, with the opacity unit.
    fn transfer_function(&self, field: &dyn Fn(&str) -> String) -> Result<TransferFunction> {
        let transfer = match (&self.transfer, &self.transfer_points) {
            (Some(_), Some(_)) | (None, None) => {
                return Err(Error::invalid(
                    field("transfer"),
                    "set exactly one of `transfer = \"preset\"` and `transfer_points = [..]`",
                ))
            }
            (Some(p), None) => TransferFunction::preset(p)
                .map_err(|e| Error::invalid(field("transfer"), e.to_string()))?,
            (None, Some(pts)) => TransferFunction {
                points: pts.clone(),
                unit: None,
            },
        };
        let transfer = TransferFunction {
            unit: self.opacity_unit,
            ..transfer
        };
        transfer.validate(&field("transfer_points"))?;
        Ok(transfer)
    }

    /// World position of the box corner at voxel (0, 0, 0) for a box of `ext` metres turned
    /// by `rotation`: from `position` (the bottom face's centre), lifted `above_terrain`.
    fn corner(
        &self,
        ext: DVec3,
        rotation: DMat3,
        ground: &dyn Ground,
        field: &dyn Fn(&str) -> String,
    ) -> Result<DVec3> {
        let pos = place(
            field,
            self.position,
            self.geodetic,
            self.above_terrain,
            ground,
        )?;
        Ok(pos - rotation * DVec3::new(ext.x / 2.0, ext.y / 2.0, 0.0))
    }

    /// The bounding shell in the volume frame (metres from the corner of a box of `ext`
    /// metres): centre, radii.
    fn shell_box(
        &self,
        ext: DVec3,
        field: &dyn Fn(&str) -> String,
    ) -> Result<Option<(DVec3, DVec3)>> {
        Ok(match self.shell {
            None => None,
            Some(sh) => {
                check_finite(&field("shell.centre"), &sh.centre)?;
                if sh.radii.iter().any(|r| !r.is_finite() || *r <= 0.0) {
                    return Err(Error::invalid(
                        field("shell.radii"),
                        format!("must be positive metres, got {:?}", sh.radii),
                    ));
                }
                Some((ext / 2.0 + DVec3::from(sh.centre), DVec3::from(sh.radii)))
            }
        })
    }
}

impl Volume {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        name: String,
        grid: DensityGrid,
        transfer: TransferFunction,
        corner: DVec3,
        rotation: DMat3,
        settings: VolumeSettings,
        material: VolumeMaterial,
        shell: Option<(DVec3, DVec3)>,
    ) -> Volume {
        // Slice masks are sampled nearest at level 0 only.
        let settings = if grid.slices > 0 {
            VolumeSettings {
                mipmaps: false,
                ..settings
            }
        } else {
            settings
        };
        let texture = VolumeTexture::from_grid(&grid);
        let bricks = BrickGrid::new(&grid);
        let mut v = Volume {
            name,
            grid,
            texture,
            bricks,
            table: TransferTable { entries: vec![] },
            occupancy: vec![],
            transfer: transfer.clone(),
            corner,
            rotation,
            settings,
            material,
            shell,
            sun_shadow: None,
        };
        v.set_transfer(transfer);
        v
    }

    /// Computes the self-shadowing for the unit world direction towards the sun `sun_world`
    /// (a density volume with `render.shadows`; slice masks are not lit).
    pub fn set_sun(&mut self, sun_world: DVec3) {
        self.sun_shadow = (self.settings.shadows && self.grid.slices == 0).then(|| {
            let s = (self.rotation.transpose() * sun_world).normalize();
            super::shadow::sun_transmittance(&self.grid, &self.table, s)
        });
    }

    /// The sun's transmittance for a sample at `p` (volume frame, metres from the corner),
    /// read [`super::shadow::OFFSET_VOXELS`] voxels towards the sun so that a surface facing
    /// the sun does not shadow itself; 1 without self-shadowing. Includes the other volumes'
    /// shadows once [`shadow_each_other`] has run.
    pub fn sun_transmittance(&self, p: DVec3) -> f64 {
        match &self.sun_shadow {
            Some(sh) => {
                let q =
                    (p + sh.sun * (super::shadow::OFFSET_VOXELS * self.voxel())) / self.extent();
                super::shadow::sample(sh.lit_data(), sh.dims, [q.x, q.y, q.z])
            }
            None => 1.0,
        }
    }

    /// The sun's transmittance through this volume for an opaque surface point `p` (world):
    /// read from the self-shadowing grid where the ray from `p` towards the sun enters the
    /// box (at `p` itself when `p` lies inside), without the sample offset (the surface is not
    /// part of the volume); 1 when the ray misses the box or the volume casts no shadow
    /// (`render.shadows = false`, slice masks). WGSL `volume_sun.wgsl` does the same per pixel.
    pub fn transmittance_to_sun(&self, p: DVec3) -> f64 {
        let Some(sh) = &self.sun_shadow else {
            return 1.0;
        };
        let q = self.to_local(p);
        let ext = self.extent();
        let (mut lo, mut hi) = (0.0f64, f64::INFINITY);
        for k in 0..3 {
            if sh.sun[k].abs() > 1e-30 {
                let (a, b) = ((0.0 - q[k]) / sh.sun[k], (ext[k] - q[k]) / sh.sun[k]);
                lo = lo.max(a.min(b));
                hi = hi.min(a.max(b));
            } else if q[k] < 0.0 || q[k] > ext[k] {
                return 1.0;
            }
        }
        if hi <= lo {
            return 1.0;
        }
        let u = (q + sh.sun * lo) / ext;
        super::shadow::sample(&sh.data, sh.dims, [u.x, u.y, u.z])
    }

    /// Metres of the smallest voxel side.
    pub fn voxel(&self) -> f64 {
        self.grid
            .spacing
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
    }

    /// Reclassifies: a new transfer table and brick occupancy.
    pub fn set_transfer(&mut self, tf: TransferFunction) {
        let g = &self.grid;
        self.table = tf.table(|d| g.value_of(d), self.voxel());
        self.occupancy = self.bricks.occupancy(
            &self.table,
            self.settings.mipmaps && self.texture.levels.len() > 1,
            g.slices,
        );
        self.transfer = tf;
        if let Some(sh) = &self.sun_shadow {
            let sun = sh.sun;
            self.sun_shadow = Some(super::shadow::sun_transmittance(
                &self.grid,
                &self.table,
                sun,
            ));
        }
    }

    /// Size of the box in metres (volume frame).
    pub fn extent(&self) -> DVec3 {
        DVec3::from(self.grid.extent())
    }

    /// World position of the box centre.
    pub fn world_centre(&self) -> DVec3 {
        self.corner + self.rotation * (0.5 * self.extent())
    }

    /// World position of the bottom face's centre: the point `position` / `geodetic` place
    /// (the anchor the curved earth lowers the volume by).
    pub fn anchor(&self) -> DVec3 {
        let e = self.extent();
        self.corner + self.rotation * DVec3::new(0.5 * e.x, 0.5 * e.y, 0.0)
    }

    /// The volume moved rigidly by `offset` (world metres).
    pub fn translated(&self, offset: DVec3) -> Volume {
        Volume {
            corner: self.corner + offset,
            ..self.clone()
        }
    }

    /// A world point in the volume frame (metres from the corner).
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.rotation.transpose() * (p - self.corner)
    }

    /// Fraction of voxels the transfer function hides.
    pub fn hidden_fraction(&self) -> f64 {
        let g = &self.grid;
        self.transfer.hidden_fraction(&g.data, |d| g.value_of(d))
    }
}

/// Lets the volumes shadow each other: per shadow-casting volume, its grid times, at each cell
/// centre, the sun's transmittance through every other volume
/// ([`Volume::transmittance_to_sun`]; optical depths add, so the product is exact),
/// rounded to bytes into [`super::shadow::SunShadow::lit`]. Baked on the CPU when the volumes are loaded or
/// reclassified (the sun and the boxes do not move within a scene), so the volume pass pays
/// nothing for it. Returns per volume whether another one shadows it.
pub fn shadow_each_other(volumes: &mut [&mut Volume]) -> Vec<bool> {
    let start = std::time::Instant::now();
    let lits: Vec<Option<Vec<u8>>> = (0..volumes.len())
        .map(|i| {
            let v = &*volumes[i];
            let sh = v.sun_shadow.as_ref()?;
            let others: Vec<&Volume> = volumes
                .iter()
                .enumerate()
                .filter(|&(j, o)| j != i && o.sun_shadow.is_some())
                .map(|(_, o)| &**o)
                .collect();
            if others.is_empty() {
                return None;
            }
            let n = sh.dims.map(|d| d as usize);
            let cell = v.extent() / DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
            let lit: Vec<u8> = sh
                .data
                .par_iter()
                .enumerate()
                .map(|(k, &b)| {
                    let idx = DVec3::new(
                        (k % n[0]) as f64,
                        (k / n[0] % n[1]) as f64,
                        (k / (n[0] * n[1])) as f64,
                    );
                    let p = v.corner + v.rotation * ((idx + 0.5) * cell);
                    let t: f64 = others.iter().map(|o| o.transmittance_to_sun(p)).product();
                    (b as f64 * t).round() as u8
                })
                .collect();
            (lit != sh.data).then_some(lit)
        })
        .collect();
    let shadowed = lits
        .into_iter()
        .zip(volumes.iter_mut())
        .map(|(lit, v)| {
            let some = lit.is_some();
            if let Some(sh) = &mut v.sun_shadow {
                sh.lit = lit;
            }
            some
        })
        .collect();
    log::debug!(
        "volumes shadowing each other: {shadowed:?} in {:.1} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    shadowed
}
