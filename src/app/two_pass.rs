//! Two-pass warping, the mode `relief render --display --two-pass` uses and `relief warp
//! verify` compares against: a pinhole image around the channel (or a cube when the channel
//! spans more than 65° from its axis) rendered at about the table's pixel density, then warped
//! into the projector image through the table with bilinear filtering, as conventional warping
//! software does. Also the virtual views both build on: view bases and per-pixel view points.

use super::sampling::{quantise, sample_rgba8};
use crate::display::screen_points::ScreenPoints;
use crate::gpu::{FrameOutput, Gpu, RenderSettings, TerrainRenderer};
use crate::scene::{Camera, Pose, SceneDesc};
use crate::terrain::Terrain;
use crate::{Error, Result};
use glam::DVec3;
use rayon::prelude::*;

/// Right, down, forward basis of a view looking along `fwd` (image up = display +z, or
/// display +y when looking nearly straight up or down).
pub fn view_basis(fwd: DVec3) -> (DVec3, DVec3, DVec3) {
    let fwd = fwd.normalize();
    let up = if fwd.z.abs() < 0.9 {
        DVec3::Z
    } else {
        DVec3::Y
    };
    let right = fwd.cross(up).normalize();
    let down = fwd.cross(right);
    (right, down, fwd)
}

/// One planar image of the two-pass intermediate: a pinhole view along `fwd` covering
/// `tan_x`, `tan_y` (half extents of the image plane at unit distance).
#[derive(Clone, Copy, Debug)]
pub struct Face {
    pub right: DVec3,
    pub down: DVec3,
    pub fwd: DVec3,
    pub tan_x: f64,
    pub tan_y: f64,
    pub width: u32,
    pub height: u32,
}

impl Face {
    /// Unit direction through image point (x, y) (pixel centres at +0.5).
    pub fn dir(&self, x: f64, y: f64) -> DVec3 {
        let a = (x / self.width as f64 * 2.0 - 1.0) * self.tan_x;
        let b = (y / self.height as f64 * 2.0 - 1.0) * self.tan_y;
        (self.fwd + self.right * a + self.down * b).normalize()
    }

    /// Image point of direction `d`, `None` outside the image.
    pub fn coord(&self, d: DVec3) -> Option<(f64, f64)> {
        let z = d.dot(self.fwd);
        if z <= 1e-9 {
            return None;
        }
        let a = d.dot(self.right) / z / self.tan_x;
        let b = d.dot(self.down) / z / self.tan_y;
        (a.abs() <= 1.0 && b.abs() <= 1.0).then_some((
            (a + 1.0) * 0.5 * self.width as f64,
            (b + 1.0) * 0.5 * self.height as f64,
        ))
    }

    /// The face's pixels as virtual screen points (unit directions from an eye at the origin).
    pub fn points(&self) -> ScreenPoints {
        view_points(self.width, self.height, |x, y| Some(self.dir(x, y)))
    }
}

/// Virtual "screen points" of a view seen from the origin: per pixel centre the direction
/// `dir(x, y)`; rendering them with the eye at the origin casts exactly those directions.
pub fn view_points(
    width: u32,
    height: u32,
    dir: impl Fn(f64, f64) -> Option<DVec3> + Sync,
) -> ScreenPoints {
    let points = (0..width * height)
        .into_par_iter()
        .map(|k| dir((k % width) as f64 + 0.5, (k / width) as f64 + 0.5))
        .collect();
    ScreenPoints {
        width,
        height,
        points,
    }
}

/// Median angle between horizontally and vertically neighbouring table directions (radians).
pub fn median_pitch(width: u32, dirs: &[Option<DVec3>]) -> f64 {
    let w = width as usize;
    let mut a: Vec<f64> = (0..dirs.len())
        .filter_map(|k| {
            let d = dirs[k]?;
            let r = (k % w + 1 < w).then(|| dirs[k + 1]).flatten();
            let b = dirs.get(k + w).copied().flatten();
            let v: Vec<f64> = [r, b]
                .iter()
                .flatten()
                .map(|n| d.angle_between(*n))
                .collect();
            (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
        })
        .collect();
    if a.is_empty() {
        return 0.0;
    }
    a.sort_by(f64::total_cmp);
    a[a.len() / 2]
}

/// The intermediate images of two-pass warping for a channel whose table holds `dirs`
/// (display frame): one pinhole image around the channel's axis when every ray lies within
/// 65° of it, a cube otherwise; centre pixel pitch = the table's median pitch.
pub fn two_pass_faces(width: u32, dirs: &[Option<DVec3>]) -> Result<Vec<Face>> {
    let lit: Vec<DVec3> = dirs.iter().flatten().copied().collect();
    let pitch = median_pitch(width, dirs);
    if lit.is_empty() || pitch <= 0.0 {
        return Err(Error::invalid("two-pass", "the channel shows no screen"));
    }
    let sum: DVec3 = lit.iter().sum();
    let axis = sum.try_normalize().unwrap_or(DVec3::Y);
    let max_angle = lit
        .iter()
        .map(|d| d.angle_between(axis))
        .fold(0.0, f64::max);
    let cap = |n: f64| -> Result<u32> {
        if n > 4096.0 {
            Err(Error::Limit {
                what: "two-pass intermediate image".into(),
                msg: format!("{n:.0} pixels wide at the table's density; the limit is 4096"),
            })
        } else {
            Ok(n.max(2.0) as u32)
        }
    };
    if max_angle < 65f64.to_radians() {
        let (right, down, fwd) = view_basis(axis);
        let (mut tx, mut ty) = (0.0f64, 0.0f64);
        for d in &lit {
            let z = d.dot(fwd);
            tx = tx.max((d.dot(right) / z).abs());
            ty = ty.max((d.dot(down) / z).abs());
        }
        // Two pixels of guard band around the channel.
        let (tx, ty) = (tx + 2.0 * pitch, ty + 2.0 * pitch);
        return Ok(vec![Face {
            right,
            down,
            fwd,
            tan_x: tx,
            tan_y: ty,
            width: cap((2.0 * tx / pitch).ceil())?,
            height: cap((2.0 * ty / pitch).ceil())?,
        }]);
    }
    let n = cap((2.0 / pitch).ceil())?;
    let t = 1.0 + 4.0 / n as f64;
    let size = n + 4;
    Ok([
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::NEG_Y,
        DVec3::Z,
        DVec3::NEG_Z,
    ]
    .iter()
    .map(|&f| {
        let (right, down, fwd) = view_basis(f);
        Face {
            right,
            down,
            fwd,
            tan_x: t,
            tan_y: t,
            width: size,
            height: size,
        }
    })
    .collect())
}

/// Warps rendered faces into a projector image: per pixel with a display-frame direction, the
/// bilinear sample of the face that holds it (the face it is most central in); black where the
/// pixel shows no screen.
pub fn warp_faces(faces: &[(Face, Vec<u8>)], dirs: &[Option<DVec3>]) -> Vec<u8> {
    dirs.par_iter()
        .flat_map_iter(|d| {
            let px = d
                .and_then(|d| {
                    let (f, img) = faces
                        .iter()
                        .max_by(|a, b| d.dot(a.0.fwd).total_cmp(&d.dot(b.0.fwd)))?;
                    let (x, y) = f.coord(d)?;
                    Some(quantise(sample_rgba8(img, f.width, f.height, x, y)))
                })
                .unwrap_or([0, 0, 0, 255]);
            px.into_iter()
        })
        .collect()
}

/// Two-pass rendering of a scene for one projector: renders each intermediate face (pinhole
/// views from the eye, rotated by the camera's attitude like the table) and warps them into
/// the projector image through the display-frame directions `dirs` with bilinear filtering.
/// Depth is the nearest face pixel's (approximate near silhouettes); the per-pixel statistics
/// are zero. Leaves the renderer in table mode for the last face: call `set_display` again
/// for direct frames.
#[allow(clippy::too_many_arguments)]
pub fn render_two_pass(
    gpu: &Gpu,
    renderer: &mut TerrainRenderer,
    terrain: &Terrain,
    scene: &SceneDesc,
    pose: Pose,
    settings: &RenderSettings,
    faces: &[Face],
    dirs: &[Option<DVec3>],
    width: u32,
    height: u32,
) -> Result<FrameOutput> {
    let mut rendered = Vec::new();
    let mut depths = Vec::new();
    let mut times = crate::gpu::PassTimes::default();
    for f in faces {
        renderer.set_display(gpu, &f.points(), DVec3::ZERO)?;
        let cam = Camera::new(pose, f.width, f.height);
        let out = renderer.capture(gpu, terrain, scene, &cam, settings)?;
        let t = out.times;
        times.raygen_ms += t.raygen_ms;
        times.tile_ms += t.tile_ms;
        times.cast_ms += t.cast_ms;
        times.objects_ms += t.objects_ms;
        times.voxels_ms += t.voxels_ms;
        times.voxel_shadow_ms += t.voxel_shadow_ms;
        times.object_shadow_ms += t.object_shadow_ms;
        times.shade_ms += t.shade_ms;
        times.volume_shadow_ms += t.volume_shadow_ms;
        times.volume_ms += t.volume_ms;
        times.readback_ms += t.readback_ms;
        times.antialias_ms += t.antialias_ms;
        for (sum, n) in times.antialias_counts.iter_mut().zip(t.antialias_counts) {
            *sum += n;
        }
        rendered.push((*f, out.rgba));
        depths.push(out.depth);
    }
    let start = std::time::Instant::now();
    let rgba = warp_faces(&rendered, dirs);
    let depth = dirs
        .par_iter()
        .map(|d| {
            d.and_then(|d| {
                let (i, (f, _)) = rendered
                    .iter()
                    .enumerate()
                    .max_by(|a, b| d.dot(a.1 .0.fwd).total_cmp(&d.dot(b.1 .0.fwd)))?;
                let (x, y) = f.coord(d)?;
                let (px, py) = ((x as u32).min(f.width - 1), (y as u32).min(f.height - 1));
                Some(depths[i][(py * f.width + px) as usize])
            })
            .unwrap_or(f32::INFINITY)
        })
        .collect();
    times.readback_ms += start.elapsed().as_secs_f64() * 1e3;
    let n = (width * height) as usize;
    Ok(FrameOutput {
        width,
        height,
        rgba,
        depth,
        steps: vec![0; n],
        patch_tests: vec![0; n],
        shadow_steps: vec![0; n],
        flags: dirs
            .iter()
            .map(|d| if d.is_some() { 0 } else { 8 })
            .collect(),
        objects: vec![0; n],
        volume_samples: Vec::new(),
        volume_segments: Vec::new(),
        volume_sun: Vec::new(),
        times,
    })
}

/// A projector channel set up for two-pass rendering: the intermediate faces and the
/// display-frame direction of each projector pixel (rotated by the channel's view offset).
pub struct TwoPass {
    pub faces: Vec<Face>,
    pub dirs: Vec<Option<DVec3>>,
}

impl TwoPass {
    /// The faces for the channel whose pixels show screen points `points` (the table's width)
    /// seen from `eye`, with the channel's view offset `view`.
    pub fn new(points: &ScreenPoints, eye: DVec3, view: Option<glam::DMat3>) -> Result<TwoPass> {
        let dirs: Vec<_> = points
            .points
            .iter()
            .map(|s| s.and_then(|s| (s - eye).try_normalize()))
            .map(|d| d.map(|d| view.map_or(d, |v| v * d)))
            .collect();
        let faces = two_pass_faces(points.width, &dirs)?;
        Ok(TwoPass { faces, dirs })
    }

    /// What a frame's metadata says about the mode.
    pub fn describe(&self) -> String {
        format!(
            "two-pass: {} pinhole image(s) of {}x{} from the eye, warped bilinearly through the table",
            self.faces.len(),
            self.faces[0].width,
            self.faces[0].height
        )
    }
}
