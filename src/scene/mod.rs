//! The scene file (TOML): terrain, sun, sky, fog, camera, output size and an optional camera
//! path. Unknown keys are errors that name the key. No GPU types live here.

pub mod antialias;
mod camera;
pub mod cigi;
pub mod clouds;
pub mod daylight;
pub mod lunar;
pub mod solar;

pub use antialias::AntialiasOption;
pub use camera::{Camera, CameraPath, Keyframe, Pose};
pub use daylight::Daylight;

use crate::error::check_finite;
pub use crate::terrain::desc::{HeightSource, TerrainDesc};
use crate::terrain::Terrain;
use crate::{Error, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole scene file.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    pub terrain: TerrainDesc,
    #[serde(default)]
    pub sun: Sun,
    #[serde(default)]
    pub sky: Sky,
    /// The moon (`[moon]`), where it shines: at night (the sun a degree or more below the
    /// horizon) it lights the scene instead of the sun ([`daylight`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub moon: Option<Moon>,
    #[serde(default)]
    pub fog: Fog,
    /// Cloud layers (`[[clouds]]`), at most [`clouds::MAX_CLOUD_LAYERS`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub clouds: Vec<clouds::CloudLayer>,
    pub camera: CameraDesc,
    #[serde(default)]
    pub output: Output,
    /// Optional camera path; frame `n` is at time `n / fps`.
    #[serde(default)]
    pub path: Option<CameraPath>,
    #[serde(default)]
    pub render: RenderOptions,
    /// Quadric free forms (`[[objects]]`).
    #[serde(default)]
    pub objects: Vec<crate::freeform::FreeFormDesc>,
    /// CIGI entity templates (`[cigi]`).
    #[serde(default, skip_serializing_if = "cigi::CigiDesc::is_empty")]
    pub cigi: cigi::CigiDesc,
    /// Density volumes (`[[volumes]]`).
    #[serde(default)]
    pub volumes: Vec<crate::volume::VolumeDesc>,
    /// Coloured voxel models (`[[voxels]]`).
    #[serde(default)]
    pub voxels: Vec<crate::voxel::VoxelDesc>,
}

/// `[sun]`: direction and colour of the sun.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sun {
    /// Degrees clockwise from north (+y).
    pub azimuth: f64,
    /// Degrees above the horizon.
    pub elevation: f64,
    /// Linear RGB colour.
    pub colour: [f32; 3],
    /// Irradiance scale.
    pub intensity: f32,
}

impl Default for Sun {
    fn default() -> Self {
        Sun {
            azimuth: 135.0,
            elevation: 30.0,
            colour: [1.0, 0.95, 0.85],
            intensity: 2.6,
        }
    }
}

impl Sun {
    /// Unit vector towards the sun in the world frame.
    pub fn direction(&self) -> DVec3 {
        let (a, e) = (self.azimuth.to_radians(), self.elevation.to_radians());
        DVec3::new(a.sin() * e.cos(), a.cos() * e.cos(), e.sin())
    }
}

/// `[moon]`: where the moon is and how much of it is lit.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Moon {
    /// Degrees clockwise from north (+y).
    pub azimuth: f64,
    /// Degrees above the horizon.
    pub elevation: f64,
    /// Illuminated fraction of its disc, 0 (new) to 1 (full).
    #[serde(default = "full")]
    pub illuminated: f64,
}

fn full() -> f64 {
    1.0
}

impl Moon {
    /// Unit vector towards the moon in the world frame.
    pub fn direction(&self) -> DVec3 {
        Sun {
            azimuth: self.azimuth,
            elevation: self.elevation,
            ..Sun::default()
        }
        .direction()
    }
}

/// `[sky]`: sky gradient and ambient light.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sky {
    /// Linear RGB at the zenith.
    pub zenith: [f32; 3],
    /// Linear RGB at the horizon.
    pub horizon: [f32; 3],
    /// Sky (ambient) light on the terrain.
    pub ambient: f32,
    /// Whether a sun below 10° dims and reddens the sun and sky (dusk, twilight and night;
    /// [`daylight`]); these colours are full day's.
    pub twilight: bool,
}

impl Default for Sky {
    fn default() -> Self {
        Sky {
            zenith: [0.10, 0.22, 0.55],
            horizon: [0.62, 0.74, 0.88],
            ambient: 0.55,
            twilight: true,
        }
    }
}

/// `[fog]`: aerial perspective.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Fog {
    /// Meteorological visibility in metres (Koschmieder: extinction 3.912 / visibility, a 2%
    /// contrast threshold); 0 disables fog.
    pub visibility: f64,
    /// Linear RGB of the haze; defaults to the sky's horizon colour.
    pub colour: Option<[f32; 3]>,
    /// Scale height of the haze in metres (denser low down); 0 = uniform.
    pub scale_height: f64,
}

impl Default for Fog {
    fn default() -> Self {
        Fog {
            visibility: 80_000.0,
            colour: None,
            scale_height: 0.0,
        }
    }
}

/// `[camera]`: the pose and field of view (the static camera, or the default for a path).
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// World position in metres (this or `geodetic`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<[f64; 3]>,
    /// `[latitude, longitude, altitude]`: degrees, metres above MSL, instead of `position`
    /// (a georeferenced terrain; the point must be over it). Heading stays from grid +y,
    /// which is true north on such a terrain.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geodetic: Option<[f64; 3]>,
    /// If set, the position's z is replaced by the terrain height below plus this many metres.
    pub above_terrain: Option<f64>,
    /// Degrees clockwise from north (+y).
    #[serde(default)]
    pub heading: f64,
    /// Degrees, nose up positive.
    #[serde(default)]
    pub pitch: f64,
    /// Degrees, right wing down positive.
    #[serde(default)]
    pub roll: f64,
    /// Horizontal field of view in degrees.
    #[serde(default = "camera::default_fov")]
    pub fov: f64,
}

/// `[output]`: image size.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Output {
    pub width: u32,
    pub height: u32,
}

impl Default for Output {
    fn default() -> Self {
        Output {
            width: 1280,
            height: 720,
        }
    }
}

/// `[render]`: quality and algorithm switches.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderOptions {
    /// Terrain self-shadowing by a second ray through the pyramid.
    pub shadows: bool,
    /// Screen-tile pre-pass: a cone per 8x8 tile through the pyramid finds where its rays may start.
    pub tile_prepass: bool,
    /// Safety bound on traversal steps per ray.
    pub max_steps: u32,
    /// Footprint level of detail of the primary rays (`false`, `true` or a scale factor).
    pub lod: Lod,
    /// Edge anti-aliasing: `"off"`, `"edges"`, 4, 8, 16 or `"reference"`.
    pub antialias: AntialiasOption,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            shadows: true,
            tile_prepass: true,
            max_steps: 4096,
            lod: Lod::Switch(false),
            antialias: AntialiasOption::Off,
        }
    }
}

/// `[render] lod`: footprint level of detail (docs/database.md#footprint-level-of-detail).
/// `false`: off, every ray descends to the finest patch (exact); `true`: on at scale 1; a
/// number: on at that scale (a cell may stand in for its samples while its side is at most
/// scale × the pixel cone's diameter).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum Lod {
    Switch(bool),
    Scale(f64),
}

impl Lod {
    /// The scale `true` stands for.
    pub const DEFAULT_SCALE: f64 = 1.0;
    /// Largest accepted scale (a cell 64 footprints wide is no level of detail).
    pub const MAX_SCALE: f64 = 64.0;

    /// The scale factor, `None` when off.
    pub fn scale(self) -> Option<f64> {
        match self {
            Lod::Switch(false) => None,
            Lod::Switch(true) => Some(Self::DEFAULT_SCALE),
            Lod::Scale(s) => Some(s),
        }
    }

    /// `on`, `off`, `true`, `false` or a scale factor (the CLI's `--lod`), validated.
    pub fn parse(s: &str) -> std::result::Result<Lod, String> {
        let lod = match s.trim() {
            "on" | "true" => Lod::Switch(true),
            "off" | "false" => Lod::Switch(false),
            x => Lod::Scale(
                x.parse()
                    .map_err(|_| format!("`{s}` is not on, off or a scale factor"))?,
            ),
        };
        lod.check()?;
        Ok(lod)
    }

    /// A scale must be finite, above 0 and at most [`Lod::MAX_SCALE`].
    pub fn check(self) -> std::result::Result<(), String> {
        match self {
            Lod::Scale(s) if !(s > 0.0 && s <= Self::MAX_SCALE) => Err(format!(
                "must be true, false or a scale in (0, {}], got {s}",
                Self::MAX_SCALE
            )),
            _ => Ok(()),
        }
    }
}

/// A scene file together with the directory its relative paths start from.
#[derive(Clone, Debug)]
pub struct Scene {
    pub desc: SceneDesc,
    pub base_dir: PathBuf,
    pub path: PathBuf,
}

impl Scene {
    /// Reads and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = crate::fileio::read_to_string(path, crate::fileio::MAX_CONFIG_BYTES)?;
        Self::parse(&text, path)
    }

    /// Parses scene text; `path` names the file in errors and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Scene> {
        let desc: SceneDesc = toml::from_str(text).map_err(|e| {
            Error::format(
                path,
                format!("scene error: {}", crate::fileio::toml_error(text, &e)),
            )
        })?;
        desc.validate()?;
        let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(Scene {
            desc,
            base_dir,
            path: path.to_path_buf(),
        })
    }

    /// Loads the terrain the scene names; checks that `camera.above_terrain` (if set) has
    /// ground below the camera.
    pub fn load_terrain(&self) -> Result<Terrain> {
        self.load_terrain_as(false)
    }

    /// [`Self::load_terrain`]; `paged`: as the paged renderer takes it, a database window
    /// hollow ([`Terrain::from_desc_paged`]).
    pub fn load_terrain_as(&self, paged: bool) -> Result<Terrain> {
        let (desc, dir) = (&self.desc.terrain, &self.base_dir);
        let terrain = if paged {
            Terrain::from_desc_paged(desc, dir)?
        } else {
            Terrain::from_desc(desc, dir)?
        };
        self.camera_position(&terrain)?;
        self.check_above_terrain(&terrain)?;
        Ok(terrain)
    }

    /// The static camera's world position: `camera.position`, or `camera.geodetic` mapped
    /// by [`Terrain::geodetic_to_world`] (an error naming `camera.geodetic` when the terrain
    /// has no geographic reference or the point is off it).
    pub fn camera_position(&self, terrain: &Terrain) -> Result<DVec3> {
        let c = &self.desc.camera;
        match (c.position, c.geodetic) {
            (Some(p), None) => Ok(DVec3::from(p)),
            (None, Some(g)) => terrain.geodetic_to_world("camera.geodetic", g),
            _ => Err(camera_position_error()),
        }
    }

    /// `Err` naming `camera.above_terrain` when it is set but the camera position is not over
    /// the height grid (there is no ground to be above).
    pub fn check_above_terrain(&self, terrain: &Terrain) -> Result<()> {
        let c = &self.desc.camera;
        if c.above_terrain.is_none() {
            return Ok(());
        }
        let p = self.camera_position(terrain)?;
        if terrain.point_below(p).is_some() {
            return Ok(());
        }
        let [cw, ch] = terrain.cells();
        let fr = &terrain.frame;
        let corner = |i: usize, j: usize| {
            let w = fr.grid_to_world(DVec3::new(i as f64, j as f64, 0.0));
            format!("({:.1}, {:.1})", w.x, w.y)
        };
        Err(Error::invalid(
            "camera.above_terrain",
            format!(
                "camera.position ({}, {}) is outside the height grid, whose corners are {}, {}, {}, {} \
                 (world x, y): move the camera over the grid or drop above_terrain",
                p.x,
                p.y,
                corner(0, 0),
                corner(cw, 0),
                corner(cw, ch),
                corner(0, ch)
            ),
        ))
    }

    /// Builds the scene's free forms (`above_terrain` needs the terrain).
    pub fn free_forms(&self, terrain: &Terrain) -> Result<Vec<crate::freeform::FreeForm>> {
        if self.desc.objects.len() > crate::freeform::MAX_OBJECTS {
            return Err(Error::invalid(
                "objects",
                format!(
                    "{} objects; at most {} are supported",
                    self.desc.objects.len(),
                    crate::freeform::MAX_OBJECTS
                ),
            ));
        }
        self.desc
            .objects
            .iter()
            .enumerate()
            .map(|(i, o)| o.build(i, terrain))
            .collect()
    }

    /// Loads and places the scene's density volumes (`above_terrain` needs the terrain).
    pub fn volumes(&self, terrain: &Terrain) -> Result<Vec<crate::volume::Volume>> {
        let mut volumes = self
            .desc
            .volumes
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let mut v = v.build(i, &self.base_dir, terrain)?;
                v.set_sun(self.desc.daylight().light);
                Ok(v)
            })
            .collect::<Result<Vec<_>>>()?;
        crate::volume::desc::shadow_each_other(&mut volumes.iter_mut().collect::<Vec<_>>());
        Ok(volumes)
    }

    /// Loads and places the scene's voxel models (`above_terrain` needs the terrain).
    pub fn voxel_models(&self, terrain: &Terrain) -> Result<Vec<crate::voxel::VoxelInstance>> {
        crate::voxel::desc::build_all(&self.desc.voxels, &self.base_dir, terrain)
    }

    /// The camera for frame `frame` (the path if there is one, else the static camera).
    pub fn camera(&self, frame: u32, terrain: &Terrain) -> Camera {
        let d = &self.desc;
        let pose = match &d.path {
            Some(p) => p.pose_at(frame as f64 / p.fps),
            None => Pose {
                // Checked by `load_terrain`; the origin only for a terrain it did not load.
                position: self.camera_position(terrain).unwrap_or(DVec3::ZERO),
                heading: d.camera.heading,
                pitch: d.camera.pitch,
                roll: d.camera.roll,
                fov: d.camera.fov,
            },
        };
        let mut pose = pose;
        if let Some(agl) = d.camera.above_terrain.filter(|_| d.path.is_none()) {
            if let Some(h) = terrain.point_below(pose.position) {
                pose.position = h + terrain.frame.normal * agl;
            }
        }
        Camera::new(pose, d.output.width, d.output.height)
    }
}

impl SceneDesc {
    /// Checks ranges and consistency; errors name the field.
    pub fn validate(&self) -> Result<()> {
        self.cigi.validate(&self.objects, &self.voxels)?;
        let c = &self.camera;
        if c.position.is_some() == c.geodetic.is_some() {
            return Err(camera_position_error());
        }
        if let Some(p) = &c.position {
            check_finite("camera.position", p)?;
        }
        if let Some(g) = &c.geodetic {
            check_finite("camera.geodetic", g)?;
        }
        check_finite("camera.heading/pitch/roll", &[c.heading, c.pitch, c.roll])?;
        camera::check_fov("camera.fov", c.fov)?;
        if let Some(a) = c.above_terrain {
            check_finite("camera.above_terrain", &[a])?;
            if self.path.is_some() {
                return Err(Error::invalid(
                    "camera.above_terrain",
                    "applies to the static camera only, and this scene has a [path]: \
                     give the keyframes' positions their heights, or drop above_terrain",
                ));
            }
        }
        let o = &self.output;
        if !(1..=16384).contains(&o.width) || !(1..=16384).contains(&o.height) {
            return Err(Error::invalid(
                "output.width/height",
                format!("must be 1..=16384 pixels, got {}x{}", o.width, o.height),
            ));
        }
        if let Some(m) = &self.moon {
            check_finite("moon.azimuth/elevation", &[m.azimuth, m.elevation])?;
            if !(-90.0..=90.0).contains(&m.elevation) || !(0.0..=1.0).contains(&m.illuminated) {
                return Err(Error::invalid(
                    "moon",
                    format!(
                        "elevation must be in -90..=90 degrees and illuminated in 0..=1, got {} and {}",
                        m.elevation, m.illuminated
                    ),
                ));
            }
        }
        let s = &self.sun;
        check_finite("sun.azimuth/elevation", &[s.azimuth, s.elevation])?;
        if !(-90.0..=90.0).contains(&s.elevation) {
            return Err(Error::invalid(
                "sun.elevation",
                format!("must be in -90..=90 degrees, got {}", s.elevation),
            ));
        }
        let colours = [
            ("sun.colour", s.colour),
            ("sky.zenith", self.sky.zenith),
            ("sky.horizon", self.sky.horizon),
        ];
        for (name, col) in colours.iter().chain(
            self.fog
                .colour
                .iter()
                .map(|c| ("fog.colour", *c))
                .collect::<Vec<_>>()
                .iter(),
        ) {
            if col.iter().any(|v| !v.is_finite() || *v < 0.0 || *v > 100.0) {
                return Err(Error::invalid(
                    *name,
                    format!("must be linear RGB in 0..=100, got {col:?}"),
                ));
            }
        }
        for (name, v) in [
            ("sun.intensity", s.intensity),
            ("sky.ambient", self.sky.ambient),
        ] {
            if !v.is_finite() || !(0.0..=100.0).contains(&v) {
                return Err(Error::invalid(name, format!("must be in 0..=100, got {v}")));
            }
        }
        let f = &self.fog;
        if !f.visibility.is_finite() || f.visibility < 0.0 {
            return Err(Error::invalid(
                "fog.visibility",
                format!("must be ≥ 0 metres (0 = no fog), got {}", f.visibility),
            ));
        }
        if !f.scale_height.is_finite() || f.scale_height < 0.0 {
            return Err(Error::invalid(
                "fog.scale_height",
                format!("must be ≥ 0 metres, got {}", f.scale_height),
            ));
        }
        clouds::validate(&self.clouds)?;
        let r = &self.render;
        if !(16..=1 << 20).contains(&r.max_steps) {
            return Err(Error::invalid(
                "render.max_steps",
                format!("must be 16..=1048576, got {}", r.max_steps),
            ));
        }
        r.lod.check().map_err(|e| Error::invalid("render.lod", e))?;
        let t = &self.terrain;
        t.height_source()?;
        check_finite("terrain.origin", &t.origin)?;
        t.axes()?;
        if let Some(cs) = t.cell_size {
            if cs.iter().any(|v| !v.is_finite() || *v <= 0.0) {
                return Err(Error::invalid(
                    "terrain.cell_size",
                    format!("must be positive metres, got {cs:?}"),
                ));
            }
        }
        check_finite("terrain.png_scale/png_offset", &[t.png_scale, t.png_offset])?;
        if let Some(p) = &self.path {
            p.validate()?;
        }
        Ok(())
    }
}

fn camera_position_error() -> Error {
    Error::invalid(
        "camera.position",
        "give the camera either `position = [x, y, z]` (metres) or `geodetic = [latitude, longitude, altitude]`, exactly one of them",
    )
}
