//! Camera model and camera paths.
//!
//! Camera frame (as in OpenCV): x right, y down, z forward. Pixel `(px, py)` counts from the
//! top-left corner and its centre is at `(px + 0.5, py + 0.5)`; the pinhole ray through image
//! point `(u, v)` is `normalize(((u - cx) / fx, (v - cy) / fy, 1))` in the camera frame.

use crate::geom::attitude_basis;
use crate::{Error, Result};
use glam::{DMat3, DMat4, DVec3};
use serde::{Deserialize, Serialize};

pub(crate) fn check_fov(field: &str, fov: f64) -> Result<()> {
    if !fov.is_finite() || fov <= 0.0 || fov > 179.0 {
        return Err(Error::invalid(
            field,
            format!("horizontal field of view must be in (0, 179] degrees, got {fov}"),
        ));
    }
    Ok(())
}

/// Position, attitude (degrees) and horizontal field of view (degrees).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
pub struct Pose {
    pub position: DVec3,
    pub heading: f64,
    pub pitch: f64,
    pub roll: f64,
    pub fov: f64,
}

/// A pinhole camera for one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub pose: Pose,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    pub fn new(pose: Pose, width: u32, height: u32) -> Camera {
        Camera {
            pose,
            width,
            height,
        }
    }

    /// (right, down, forward) unit vectors in the world.
    /// Heading turns clockwise from north (+y), pitch raises the nose, roll lowers the right wing.
    pub fn basis(&self) -> (DVec3, DVec3, DVec3) {
        attitude_basis(self.pose.heading, self.pose.pitch, self.pose.roll)
    }

    /// World-from-camera rotation (columns: right, down, forward).
    pub fn rotation(&self) -> DMat3 {
        let (r, d, f) = self.basis();
        DMat3::from_cols(r, d, f)
    }

    /// World-from-camera affine matrix.
    pub fn world_from_camera(&self) -> DMat4 {
        let r = self.rotation();
        DMat4::from_cols(
            r.x_axis.extend(0.0),
            r.y_axis.extend(0.0),
            r.z_axis.extend(0.0),
            self.pose.position.extend(1.0),
        )
    }

    /// Intrinsics `(fx, fy, cx, cy)` in pixels (square pixels, principal point at the centre).
    pub fn intrinsics(&self) -> (f64, f64, f64, f64) {
        let fx = 0.5 * self.width as f64 / (0.5 * self.pose.fov.to_radians()).tan();
        (fx, fx, 0.5 * self.width as f64, 0.5 * self.height as f64)
    }

    /// Unit world ray direction through image point `(u, v)` (pixel centres at `+0.5`).
    pub fn ray_dir(&self, u: f64, v: f64) -> DVec3 {
        let (fx, fy, cx, cy) = self.intrinsics();
        (self.rotation() * DVec3::new((u - cx) / fx, (v - cy) / fy, 1.0)).normalize()
    }

    /// Unit world ray through the centre of pixel `(px, py)`.
    pub fn pixel_ray(&self, px: u32, py: u32) -> DVec3 {
        self.ray_dir(px as f64 + 0.5, py as f64 + 0.5)
    }

    /// Cone half-angle (radians) of pixel `(px, py)`: half the angle one pixel subtends at its
    /// centre, as the ray generation pass writes it to the ray table's w (`pinhole_ray`).
    pub fn pixel_cone(&self, px: u32, py: u32) -> f64 {
        let (fx, fy, cx, cy) = self.intrinsics();
        let (u, v) = ((px as f64 + 0.5 - cx) / fx, (py as f64 + 0.5 - cy) / fy);
        0.5 / (fx * (1.0 + u * u + v * v))
    }

    /// Projects a world point to image coordinates; `None` behind the camera.
    pub fn project(&self, p: DVec3) -> Option<(f64, f64)> {
        let c = self.rotation().transpose() * (p - self.pose.position);
        if c.z <= 1e-9 {
            return None;
        }
        let (fx, fy, cx, cy) = self.intrinsics();
        Some((cx + fx * c.x / c.z, cy + fy * c.y / c.z))
    }
}

/// One keyframe of a camera path.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Seconds from the path's start.
    pub time: f64,
    pub position: [f64; 3],
    #[serde(default)]
    pub heading: f64,
    #[serde(default)]
    pub pitch: f64,
    #[serde(default)]
    pub roll: f64,
    /// Horizontal field of view; defaults to 60°.
    #[serde(default = "default_fov")]
    pub fov: f64,
}

pub(crate) fn default_fov() -> f64 {
    60.0
}

/// `[path]`: keyframes interpolated over time (Catmull-Rom positions, linear angles with the
/// heading taking the short way round). Frame `n` is at `n / fps` seconds: reproducible.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPath {
    #[serde(default = "default_fps")]
    pub fps: f64,
    pub keyframes: Vec<Keyframe>,
}

fn default_fps() -> f64 {
    30.0
}

impl CameraPath {
    pub(crate) fn validate(&self) -> Result<()> {
        if !self.fps.is_finite() || self.fps <= 0.0 || self.fps > 10_000.0 {
            return Err(Error::invalid(
                "path.fps",
                format!("must be in (0, 10000], got {}", self.fps),
            ));
        }
        if self.keyframes.is_empty() {
            return Err(Error::invalid(
                "path.keyframes",
                "needs at least one keyframe",
            ));
        }
        for (i, k) in self.keyframes.iter().enumerate() {
            let f = format!("path.keyframes[{i}]");
            let vals = [
                k.time,
                k.position[0],
                k.position[1],
                k.position[2],
                k.heading,
                k.pitch,
                k.roll,
            ];
            if vals.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(f, "has a non-finite value"));
            }
            check_fov(&format!("path.keyframes[{i}].fov"), k.fov)?;
            if i > 0 && k.time <= self.keyframes[i - 1].time {
                return Err(Error::invalid(f, "times must increase strictly"));
            }
        }
        Ok(())
    }

    /// Pose at time `t` (clamped to the path's ends).
    pub fn pose_at(&self, t: f64) -> Pose {
        let k = &self.keyframes;
        let last = k.len() - 1;
        let pose_of = |k: &Keyframe| Pose {
            position: DVec3::from(k.position),
            heading: k.heading,
            pitch: k.pitch,
            roll: k.roll,
            fov: k.fov,
        };
        if t <= k[0].time || last == 0 {
            return pose_of(&k[0]);
        }
        if t >= k[last].time {
            return pose_of(&k[last]);
        }
        let i = k.partition_point(|kf| kf.time <= t) - 1;
        let (a, b) = (&k[i], &k[i + 1]);
        let s = (t - a.time) / (b.time - a.time);
        let p = |j: usize| DVec3::from(k[j].position);
        let (p0, p1, p2, p3) = (p(i.saturating_sub(1)), p(i), p(i + 1), p((i + 2).min(last)));
        // Uniform Catmull-Rom.
        let s2 = s * s;
        let s3 = s2 * s;
        let position = 0.5
            * ((2.0 * p1)
                + (-p0 + p2) * s
                + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * s2
                + (-p0 + 3.0 * p1 - 3.0 * p2 + p3) * s3);
        let dh = (b.heading - a.heading + 540.0).rem_euclid(360.0) - 180.0;
        Pose {
            position,
            heading: a.heading + dh * s,
            pitch: a.pitch + (b.pitch - a.pitch) * s,
            roll: a.roll + (b.roll - a.roll) * s,
            fov: a.fov + (b.fov - a.fov) * s,
        }
    }
}
