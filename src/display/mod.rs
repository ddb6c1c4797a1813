//! Curved-screen display model (TOML files in `distortion/`): screen surface, projectors, eye
//! point and channels. No GPU types; the per-frame ray table is computed from it by
//! `cpu::distortion` (reference) and by the GPU ray-generation pass.
//!
//! Display frame: metres, x right, y forward, z up, fixed to the vehicle (cockpit). A direction
//! in it maps to the world through the camera's attitude: x → camera right, y → camera forward,
//! z → camera up.

pub mod blend;
pub mod dome_master;
pub mod pattern;
pub mod screen_points;
mod validate;
pub mod warp;

use crate::geom::attitude_basis;
use crate::{Error, Result};
use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A display configuration file.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DisplayConfig {
    pub screen: Screen,
    pub eye: Eye,
    #[serde(rename = "channel")]
    pub channels: Vec<Channel>,
    /// Directory relative warp files start from (the config file's).
    #[serde(skip)]
    pub base_dir: std::path::PathBuf,
}

/// The projection surface.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Screen {
    /// Sphere (dome) of `radius` around `centre`; points below `min_elevation` degrees (seen from
    /// the centre) are not screen (truncated dome).
    Dome {
        centre: [f64; 3],
        radius: f64,
        #[serde(default = "minus_ninety")]
        min_elevation: f64,
    },
    /// Vertical-axis cylinder of `radius` around `centre`, from `bottom` to `top` (z, metres).
    Cylinder {
        centre: [f64; 3],
        radius: f64,
        bottom: f64,
        top: f64,
    },
    /// Plane through `point` with unit `normal`.
    Flat { point: [f64; 3], normal: [f64; 3] },
    /// Spherical-mirror projection (Bourke; `kind = "mirror-dome"`): every projector ray is reflected by a convex
    /// mirror sphere (`mirror_centre`, `mirror_radius`) onto a dome (`centre`, `radius`,
    /// `min_elevation` as for `dome`). Projector rays that miss the mirror show nothing; the
    /// eye sees the dome directly (the mirror hides the dome behind it).
    #[serde(rename = "mirror-dome")]
    MirrorDome {
        centre: [f64; 3],
        radius: f64,
        #[serde(default = "minus_ninety")]
        min_elevation: f64,
        mirror_centre: [f64; 3],
        mirror_radius: f64,
    },
}

fn minus_ninety() -> f64 {
    -90.0
}

/// The design eye point (static, or moved per frame by the caller).
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Eye {
    pub position: [f64; 3],
}

/// One projector channel.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Channel {
    #[serde(default)]
    pub name: String,
    pub projector: Projector,
    /// Soft edges where this projector's image overlaps its neighbours'.
    #[serde(default)]
    pub blend: Option<blend::Blend>,
    /// This channel's view offset in the vehicle.
    #[serde(default)]
    pub view: Option<ViewOffset>,
    /// A measured warp instead of the projector model's geometry: an MPCDI-style 3-D PFM
    /// holding each projector pixel's screen point (display frame, metres; NaN = no screen),
    /// relative to the config file, at the projector's resolution.
    #[serde(default)]
    pub warp: Option<std::path::PathBuf>,
    /// Row order of `warp`: "bottom-to-top" (default, as netpbm) or "top-to-bottom".
    #[serde(default)]
    pub warp_rows: Option<String>,
}

/// `view = { heading, pitch, roll }` (degrees, as for the camera): turns what a channel shows
/// relative to the vehicle, e.g. to aim a channel of a fixed screen elsewhere for testing, or
/// to correct a display frame that is not aligned with the vehicle's axes. World direction =
/// vehicle attitude · offset · display direction.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ViewOffset {
    pub heading: f64,
    pub pitch: f64,
    pub roll: f64,
}

impl ViewOffset {
    /// The rotation of display directions.
    pub fn matrix(&self) -> glam::DMat3 {
        crate::geom::attitude_matrix(self.heading, self.pitch, self.roll)
    }
}

/// Projector pose, resolution and lens.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Projector {
    pub position: [f64; 3],
    #[serde(default)]
    pub heading: f64,
    #[serde(default)]
    pub pitch: f64,
    #[serde(default)]
    pub roll: f64,
    pub width: u32,
    pub height: u32,
    pub lens: Lens,
    /// Measured lens distortion on top of the ideal lens.
    #[serde(default)]
    pub distortion: Option<LensDistortion>,
}

/// `distortion = { k1, k2, k3, p1, p2 }`: Brown–Conrady radial (k) and tangential (p)
/// coefficients of a measured projector lens, in the lens's normalised image coordinates
/// (perspective: `(u − cx)/f`; f-theta: offset from the centre over the fisheye radius). The
/// ideal point `q` is imaged at `D(q) = q·(1 + k1 r² + k2 r⁴ + k3 r⁶) + (2 p1 x y + p2 (r² + 2x²),
/// p1 (r² + 2y²) + 2 p2 x y)`. Screen points (and so the per-frame table) use the inverse.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct LensDistortion {
    pub k1: f64,
    pub k2: f64,
    pub k3: f64,
    pub p1: f64,
    pub p2: f64,
}

impl LensDistortion {
    /// Where the ideal normalised point `q` is imaged.
    pub fn apply(&self, q: [f64; 2]) -> [f64; 2] {
        let [x, y] = q;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        [
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        ]
    }

    /// `Ok` when the radial mapping `g(r) = r·(1 + k1 r² + k2 r⁴ + k3 r⁶)` keeps increasing
    /// (g′ > 0) over every ideal radius the projector's image needs: from 0 until `g` reaches
    /// the normalised radius of the farthest image corner (for an f-theta lens at most the
    /// fisheye circle, ideal radius 1, beyond which pixels are outside the field). A fold
    /// there would image two directions at one pixel. `field` names the table in the error.
    pub fn check_radial_monotonic(&self, field: &str, p: &Projector) -> Result<()> {
        let (w, h) = (p.width as f64, p.height as f64);
        let (centre, norm, field_radius) = match p.lens {
            Lens::Perspective { fov, shift } => {
                let f = 0.5 * w / (0.5 * fov.to_radians()).tan();
                (
                    [0.5 * w + shift[0] * w, 0.5 * h + shift[1] * h],
                    f,
                    f64::INFINITY,
                )
            }
            Lens::Ftheta { .. } => ([0.5 * w, 0.5 * h], 0.5 * w.min(h), 1.0),
        };
        let corner = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
            .iter()
            .map(|&(u, v)| ((u - centre[0]) / norm).hypot((v - centre[1]) / norm))
            .fold(0.0, f64::max);
        if !corner.is_finite() {
            return Ok(()); // the lens values are refused by their own checks
        }
        let g = |r: f64| {
            let r2 = r * r;
            r * (1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3)))
        };
        let dg = |r: f64| {
            let r2 = r * r;
            1.0 + r2 * (3.0 * self.k1 + r2 * (5.0 * self.k2 + r2 * 7.0 * self.k3))
        };
        // Walk the ideal radius in small steps; g' is a cubic in r², so a fold shows as g' ≤ 0.
        let step = corner.min(field_radius) / 4096.0;
        let mut r = 0.0;
        for _ in 0..1_000_000 {
            if g(r) >= corner || r >= field_radius {
                return Ok(());
            }
            if dg(r) <= 0.0 {
                return Err(Error::invalid(
                    field,
                    format!(
                        "the radial distortion folds over inside the image, so it does not invert \
                         there: r·(1 + k1 r² + k2 r⁴ + k3 r⁶) stops increasing at normalised radius \
                         {r:.4} (imaged at {:.4}) but the image corners reach {corner:.4}; check the \
                         coefficients' signs and units (normalised coordinates, not pixels), \
                         e.g. a smaller |k1|",
                        g(r)
                    ),
                ));
            }
            r += step;
        }
        Ok(())
    }

    /// The ideal point imaged at `a` (Newton's method, numeric Jacobian); `None` if it does not
    /// converge (the distortion folds over there).
    pub fn invert(&self, a: [f64; 2]) -> Option<[f64; 2]> {
        let mut q = a;
        for _ in 0..50 {
            let d = self.apply(q);
            let e = [d[0] - a[0], d[1] - a[1]];
            if e[0].hypot(e[1]) < 1e-14 {
                return Some(q);
            }
            let h = 1e-7;
            let dx = self.apply([q[0] + h, q[1]]);
            let dy = self.apply([q[0], q[1] + h]);
            let (j00, j10) = ((dx[0] - d[0]) / h, (dx[1] - d[1]) / h);
            let (j01, j11) = ((dy[0] - d[0]) / h, (dy[1] - d[1]) / h);
            let det = j00 * j11 - j01 * j10;
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            q = [
                q[0] - (j11 * e[0] - j01 * e[1]) / det,
                q[1] - (-j10 * e[0] + j00 * e[1]) / det,
            ];
        }
        let d = self.apply(q);
        ((d[0] - a[0]).hypot(d[1] - a[1]) < 1e-10).then_some(q)
    }
}

/// Projector lens.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Lens {
    /// Pinhole with horizontal field of view (degrees) and lens shift (fractions of the image
    /// width and height; +x right, +y down).
    Perspective {
        fov: f64,
        #[serde(default)]
        shift: [f64; 2],
    },
    /// Equidistant fisheye: the angle from the axis grows linearly with the distance from the
    /// image centre, reaching `fov / 2` at the inscribed circle's edge (radius min(w, h) / 2).
    Ftheta { fov: f64 },
}

impl Projector {
    /// Unit direction, in the display frame, of the projector's ray through image point (u, v)
    /// (pixel centres at +0.5); `None` outside the lens's field.
    pub fn ray(&self, u: f64, v: f64) -> Option<DVec3> {
        let (w, h) = (self.width as f64, self.height as f64);
        let local = match self.lens {
            Lens::Perspective { fov, shift } => {
                let f = 0.5 * w / (0.5 * fov.to_radians()).tan();
                let (cx, cy) = (0.5 * w + shift[0] * w, 0.5 * h + shift[1] * h);
                let [x, y] = self.undistort([(u - cx) / f, (v - cy) / f])?;
                DVec3::new(x, y, 1.0).normalize()
            }
            Lens::Ftheta { fov } => {
                let rmax = 0.5 * w.min(h);
                let [qx, qy] = self.undistort([(u - 0.5 * w) / rmax, (v - 0.5 * h) / rmax])?;
                let (du, dv) = (qx * rmax, qy * rmax);
                let r = (du * du + dv * dv).sqrt();
                let theta = r / rmax * 0.5 * fov.to_radians();
                if r > rmax {
                    return None;
                }
                if r == 0.0 {
                    DVec3::Z
                } else {
                    DVec3::new(theta.sin() * du / r, theta.sin() * dv / r, theta.cos())
                }
            }
        };
        let (right, down, fwd) = attitude_basis(self.heading, self.pitch, self.roll);
        Some(DMat3::from_cols(right, down, fwd) * local)
    }

    /// Ideal normalised point of an imaged one (identity without distortion).
    fn undistort(&self, a: [f64; 2]) -> Option<[f64; 2]> {
        match &self.distortion {
            Some(d) => d.invert(a),
            None => Some(a),
        }
    }

    /// Imaged normalised point of an ideal one (identity without distortion).
    fn distort(&self, q: [f64; 2]) -> [f64; 2] {
        self.distortion.map_or(q, |d| d.apply(q))
    }
}

impl Projector {
    /// Image point (u, v) (pixel centres at +0.5) whose ray has unit-or-not direction `dir`
    /// (display frame): the inverse of [`Projector::ray`]; `None` behind the lens or outside
    /// its field.
    pub fn pixel(&self, dir: DVec3) -> Option<(f64, f64)> {
        let (w, h) = (self.width as f64, self.height as f64);
        let (right, down, fwd) = attitude_basis(self.heading, self.pitch, self.roll);
        let l = DVec3::new(dir.dot(right), dir.dot(down), dir.dot(fwd)).normalize();
        match self.lens {
            Lens::Perspective { fov, shift } => {
                if l.z <= 1e-9 {
                    return None;
                }
                let f = 0.5 * w / (0.5 * fov.to_radians()).tan();
                let (cx, cy) = (0.5 * w + shift[0] * w, 0.5 * h + shift[1] * h);
                let [x, y] = self.distort([l.x / l.z, l.y / l.z]);
                Some((cx + f * x, cy + f * y))
            }
            Lens::Ftheta { fov } => {
                let theta = l.z.clamp(-1.0, 1.0).acos();
                let rmax = 0.5 * w.min(h);
                let r = theta / (0.5 * fov.to_radians()) * rmax;
                if r > rmax {
                    return None;
                }
                let rho = l.x.hypot(l.y);
                let q = if rho < 1e-15 {
                    [0.0, 0.0]
                } else {
                    [r / rmax * l.x / rho, r / rmax * l.y / rho]
                };
                let [x, y] = self.distort(q);
                Some((0.5 * w + x * rmax, 0.5 * h + y * rmax))
            }
        }
    }
}

/// First intersection of a ray with a sphere from outside; `None` if it misses, starts
/// inside or the sphere is behind.
fn sphere_entry(origin: DVec3, dir: DVec3, centre: DVec3, radius: f64) -> Option<f64> {
    let oc = origin - centre;
    let c = oc.length_squared() - radius * radius;
    if c <= 0.0 {
        return None;
    }
    let b = dir.dot(oc);
    let disc = b * b - c;
    if disc < 0.0 || b >= 0.0 {
        return None;
    }
    // Stable smaller root: c / (-b + sqrt(disc)).
    Some(c / (-b + disc.sqrt()))
}

impl Screen {
    /// The screen point the eye sees along unit `dir` from `eye` (for a mirror dome: the dome,
    /// unless the mirror is in the way); `None` where the eye sees no screen.
    pub fn seen_from(&self, eye: DVec3, dir: DVec3) -> Option<DVec3> {
        match *self {
            Screen::MirrorDome {
                centre,
                radius,
                min_elevation,
                mirror_centre,
                mirror_radius,
            } => {
                if sphere_entry(eye, dir, DVec3::from(mirror_centre), mirror_radius).is_some() {
                    return None;
                }
                Screen::Dome {
                    centre,
                    radius,
                    min_elevation,
                }
                .intersect(eye, dir)
            }
            _ => self.intersect(eye, dir),
        }
    }

    /// The mirror point that reflects light from `from` to `to` (both outside the mirror
    /// sphere) for a mirror dome; `None` for other screens or when that point is not visible
    /// from both. Solves Alhazen's problem in the plane through the mirror centre, `from` and
    /// `to`: bisection on the arc between them for equal angles of incidence and reflection.
    pub fn mirror_point(&self, from: DVec3, to: DVec3) -> Option<DVec3> {
        let Screen::MirrorDome {
            mirror_centre,
            mirror_radius,
            ..
        } = *self
        else {
            return None;
        };
        let c = DVec3::from(mirror_centre);
        let e1 = (from - c).try_normalize()?;
        let w = to - c;
        let e2 = (w - w.dot(e1) * e1)
            .try_normalize()
            .unwrap_or_else(|| e1.any_orthonormal_vector());
        let phi_to = w.dot(e2).atan2(w.dot(e1));
        let angle = |a: DVec3, b: DVec3| a.cross(b).length().atan2(a.dot(b));
        let at = |phi: f64| c + (e1 * phi.cos() + e2 * phi.sin()) * mirror_radius;
        // f < 0 at phi = 0 (facing `from`), f > 0 at phi_to (facing `to`).
        let f = |phi: f64| {
            let m = at(phi);
            let n = m - c;
            angle(n, from - m) - angle(n, to - m)
        };
        let (mut lo, mut hi) = (0.0, phi_to);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if f(mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let m = at(0.5 * (lo + hi));
        let n = m - c;
        (n.dot(from - m) > 0.0 && n.dot(to - m) > 0.0).then_some(m)
    }

    /// First intersection in front of `origin` along unit `dir` (the screen point lit by a
    /// projector ray); `None` if the ray misses the screen.
    pub fn intersect(&self, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        match *self {
            Screen::Dome {
                centre,
                radius,
                min_elevation,
            } => {
                let c = DVec3::from(centre);
                let oc = origin - c;
                let b = dir.dot(oc);
                let disc = b * b - (oc.length_squared() - radius * radius);
                if disc < 0.0 {
                    return None;
                }
                let t = -b + disc.sqrt();
                if t <= 0.0 {
                    return None;
                }
                let p = origin + dir * t;
                let elev = ((p - c).z / radius).clamp(-1.0, 1.0).asin().to_degrees();
                (elev >= min_elevation).then_some(p)
            }
            Screen::Cylinder {
                centre,
                radius,
                bottom,
                top,
            } => {
                let c = DVec3::from(centre);
                let (o2, d2) = ((origin - c).truncate(), dir.truncate());
                let a = d2.length_squared();
                if a < 1e-18 {
                    return None;
                }
                let b = d2.dot(o2);
                let disc = b * b - a * (o2.length_squared() - radius * radius);
                if disc < 0.0 {
                    return None;
                }
                let t = (-b + disc.sqrt()) / a;
                if t <= 0.0 {
                    return None;
                }
                let p = origin + dir * t;
                (p.z >= bottom && p.z <= top).then_some(p)
            }
            Screen::Flat { point, normal } => {
                let n = DVec3::from(normal);
                let denom = dir.dot(n);
                if denom.abs() < 1e-12 {
                    return None;
                }
                let t = (DVec3::from(point) - origin).dot(n) / denom;
                (t > 0.0).then(|| origin + dir * t)
            }
            Screen::MirrorDome {
                centre,
                radius,
                min_elevation,
                mirror_centre,
                mirror_radius,
            } => {
                let mc = DVec3::from(mirror_centre);
                let t = sphere_entry(origin, dir, mc, mirror_radius)?;
                let m = origin + dir * t;
                let n = (m - mc) / mirror_radius;
                let reflected = (dir - 2.0 * dir.dot(n) * n).normalize();
                Screen::Dome {
                    centre,
                    radius,
                    min_elevation,
                }
                .intersect(m, reflected)
            }
        }
    }
}

impl DisplayConfig {
    /// Reads and validates a display configuration.
    pub fn load(path: &Path) -> Result<DisplayConfig> {
        let text = crate::fileio::read_to_string(path, crate::fileio::MAX_CONFIG_BYTES)?;
        let cfg: DisplayConfig = toml::from_str(&text).map_err(|e| {
            Error::format(
                path,
                format!(
                    "display config error: {}",
                    crate::fileio::toml_error(&text, &e)
                ),
            )
        })?;
        cfg.validate()
            .map_err(|e| Error::format(path, e.to_string()))?;
        let mut cfg = cfg;
        cfg.base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(cfg)
    }

    /// The screen point of every pixel of `channel`: from its measured `warp` file if it has
    /// one, else from the projector model ([`screen_points::screen_points`]).
    pub fn channel_points(&self, channel: usize) -> Result<screen_points::ScreenPoints> {
        let c = self.channels.get(channel).ok_or_else(|| {
            Error::invalid(
                "channel",
                format!(
                    "{} channel(s), asked for index {channel}",
                    self.channels.len()
                ),
            )
        })?;
        let p = &c.projector;
        // The table (an optional f64 point per pixel) and its f32 upload: 48 bytes a pixel
        // on the host, before any render target.
        crate::fileio::check_alloc(
            format_args!(
                "channel {channel} ({:?}): its {}x{} projector's ray table",
                c.name, p.width, p.height
            ),
            p.width as u64 * p.height as u64 * 48,
        )?;
        let Some(file) = &c.warp else {
            return Ok(screen_points::screen_points(&self.screen, p));
        };
        let path = self.base_dir.join(file);
        let order = match c.warp_rows.as_deref() {
            None | Some("bottom-to-top") => warp::RowOrder::BottomToTop,
            Some("top-to-bottom") => warp::RowOrder::TopToBottom,
            Some(o) => {
                return Err(Error::invalid(
                    format!("channel[{channel}].warp_rows"),
                    format!("{o:?}: use \"bottom-to-top\" or \"top-to-bottom\""),
                ))
            }
        };
        let pfm = warp::read_pfm(&path, order)?;
        if pfm.channels != 3 {
            return Err(Error::format(
                &path,
                format!(
                    "a {}-channel PFM: a channel's warp must be 3-D screen geometry (X, Y, Z per \
                     pixel); 2-D u,v warps map into content images, not onto a screen",
                    pfm.channels
                ),
            ));
        }
        // A 2-D u,v warp stored in three channels (MPCDI style): u, v in 0..1, the third 0
        // or not a number.
        let uv: Vec<&[f32]> = pfm
            .data
            .chunks_exact(3)
            .filter(|q| q[0].is_finite() && q[1].is_finite())
            .collect();
        if !uv.is_empty()
            && uv.iter().all(|q| {
                (q[2] == 0.0 || !q[2].is_finite())
                    && (0.0..=1.0).contains(&q[0])
                    && (0.0..=1.0).contains(&q[1])
            })
        {
            return Err(Error::format(
                &path,
                "looks like a 2-D u,v warp (third channel 0 or NaN, u and v in 0..1): a \
                 channel's warp must be 3-D screen geometry (X, Y, Z per pixel, metres)",
            ));
        }
        if (pfm.width, pfm.height) != (p.width, p.height) {
            return Err(Error::format(
                &path,
                format!(
                    "{}x{} warp for a {}x{} projector: export it at the projector's resolution",
                    pfm.width, pfm.height, p.width, p.height
                ),
            ));
        }
        let points = pfm
            .data
            .chunks_exact(3)
            .map(|q| {
                let v = DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64);
                v.is_finite().then_some(v)
            })
            .collect();
        Ok(screen_points::ScreenPoints {
            width: p.width,
            height: p.height,
            points,
        })
    }
}
