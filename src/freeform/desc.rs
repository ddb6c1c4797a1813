//! `[[objects]]` in a scene file: named shapes or raw coefficients, placement, bounds,
//! material and nested `[[objects.perturb]]` tables. Unknown keys are errors.

use super::{FreeForm, Material, Node, Quadric, MAX_DEPTH, MAX_NODES};
use crate::error::check_finite;
use crate::geom::{checked_attitude, place, Ground};
use crate::{Error, Result};
use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

/// One free form (at the top level) or one perturbation (inside `perturb`).
///
/// Shapes are written in their own frame, normalised so that `F` is -1 at the centre and 0 on
/// the surface: `sphere {radius}`, `ellipsoid {radii}`, `cylinder {radius, height}` (axis z,
/// from z = 0 up), `cone {radius, height}` (base at z = 0, apex at z = height),
/// `paraboloid {radius, height}` (dome, apex at z = height), `hyperboloid {radius, height,
/// flare}` (one sheet, waist `radius` at z = height/2, `flare` times wider at both ends),
/// `box {size}` (from z = 0 up), `plane` (solid below z = 0; needs `bounds`), or
/// `coefficients = [A, B, C, D, E, F, G, H, I, K]` (needs `bounds`).
///
/// A perturbation's `Q` is the negated shape (positive inside it), moved to `centre` and
/// rotated by heading/pitch/roll in the object frame (nested perturbations too), and adds
/// `weight · Q²` where `Q > 0`: positive weights carve, negative weights add material.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FreeFormDesc {
    /// Name used in errors and metadata (objects only).
    pub name: Option<String>,
    pub shape: Option<String>,
    pub coefficients: Option<[f64; 10]>,
    pub radius: Option<f64>,
    pub radii: Option<[f64; 3]>,
    pub height: Option<f64>,
    pub flare: Option<f64>,
    pub size: Option<[f64; 3]>,
    /// Objects: world position of the object origin.
    pub position: Option<[f64; 3]>,
    /// Objects: or the origin's `[latitude, longitude, altitude]` (WGS84 degrees, metres above
    /// mean sea level) on a georeferenced terrain.
    pub geodetic: Option<[f64; 3]>,
    /// Objects: if set, the position's z becomes the terrain height below plus this.
    pub above_terrain: Option<f64>,
    /// Perturbations: centre in the object frame.
    pub centre: Option<[f64; 3]>,
    /// Degrees: heading (clockwise about z from +y), pitch, roll, as for the camera.
    #[serde(default)]
    pub heading: f64,
    #[serde(default)]
    pub pitch: f64,
    #[serde(default)]
    pub roll: f64,
    /// Objects: bounding box `[[xmin, ymin, zmin], [xmax, ymax, zmax]]` in the object frame.
    pub bounds: Option<[[f64; 3]; 2]>,
    /// Perturbations: `R = weight · Q²` (default 1).
    pub weight: Option<f64>,
    /// Objects: surface appearance.
    pub material: Option<MaterialDesc>,
    #[serde(default)]
    pub perturb: Vec<FreeFormDesc>,
}

/// `material = { colour = [r, g, b], ambient, diffuse, specular, shininess }`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MaterialDesc {
    /// Linear RGB.
    pub colour: [f32; 3],
    pub ambient: f32,
    pub diffuse: f32,
    pub specular: f32,
    pub shininess: f32,
}

impl Default for MaterialDesc {
    fn default() -> Self {
        MaterialDesc {
            colour: [0.6, 0.6, 0.6],
            ambient: 0.35,
            diffuse: 0.65,
            specular: 0.15,
            shininess: 24.0,
        }
    }
}

/// The object's shape quadric in its own frame, and its natural bounds if it has them.
fn shape_quadric(d: &FreeFormDesc, field: &str) -> Result<(Quadric, Option<[DVec3; 2]>)> {
    let need = |v: Option<f64>, key: &str| -> Result<f64> {
        match v {
            Some(x) if x.is_finite() && x > 0.0 && x < 1e7 => Ok(x),
            Some(x) => Err(Error::invalid(
                format!("{field}.{key}"),
                format!("must be a positive finite length below 1e7 m, got {x}"),
            )),
            None => Err(Error::invalid(
                field,
                format!("shape {:?} needs `{key}`", d.shape.as_deref().unwrap_or("")),
            )),
        }
    };
    let v3 = |v: Option<[f64; 3]>, key: &str| -> Result<[f64; 3]> {
        let v = v.ok_or_else(|| {
            Error::invalid(
                field,
                format!("shape {:?} needs `{key}`", d.shape.as_deref().unwrap_or("")),
            )
        })?;
        for x in v {
            need(Some(x), key)?;
        }
        Ok(v)
    };
    let q = |c: [f64; 10]| Quadric(c);
    match (d.shape.as_deref(), d.coefficients) {
        (Some(_), Some(_)) => Err(Error::invalid(
            field,
            "set either `shape` or `coefficients`, not both",
        )),
        (None, None) => Err(Error::invalid(
            field,
            "set `shape = \"sphere|ellipsoid|cylinder|cone|paraboloid|hyperboloid|box|plane\"` or `coefficients = [A, B, C, D, E, F, G, H, I, K]`",
        )),
        (None, Some(c)) => {
            if c.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    format!("{field}.coefficients"),
                    format!("must be finite numbers, got {c:?}"),
                ));
            }
            let quad = Quadric(c);
            if quad.is_constant() {
                return Err(Error::invalid(
                    format!("{field}.coefficients"),
                    "degenerate quadric: A..I are all zero, so F is a constant with no surface",
                ));
            }
            Ok((quad, None))
        }
        (Some(shape), None) => {
            let b = |lo: [f64; 3], hi: [f64; 3]| Some([DVec3::from(lo), DVec3::from(hi)]);
            Ok(match shape {
                "sphere" => {
                    let r = need(d.radius, "radius")?;
                    let s = 1.0 / (r * r);
                    (q([s, s, s, 0., 0., 0., 0., 0., 0., -1.]), b([-r; 3], [r; 3]))
                }
                "ellipsoid" => {
                    let [a, bb, c] = v3(d.radii, "radii")?;
                    (
                        q([
                            1. / (a * a),
                            1. / (bb * bb),
                            1. / (c * c),
                            0.,
                            0.,
                            0.,
                            0.,
                            0.,
                            0.,
                            -1.,
                        ]),
                        b([-a, -bb, -c], [a, bb, c]),
                    )
                }
                "cylinder" | "cone" | "paraboloid" | "hyperboloid" => {
                    let r = need(d.radius, "radius")?;
                    let h = need(d.height, "height")?;
                    let s = 1.0 / (r * r);
                    let (quad, w) = match shape {
                        "cylinder" => (q([s, s, 0., 0., 0., 0., 0., 0., 0., -1.]), r),
                        "cone" => (
                            q([s, s, -1. / (h * h), 0., 0., 0., 0., 0., 2. / h, -1.]),
                            r,
                        ),
                        "paraboloid" => (q([s, s, 0., 0., 0., 0., 0., 0., 1. / h, -1.]), r),
                        _ => {
                            let f = d.flare.unwrap_or(1.5);
                            if !f.is_finite() || f <= 1.0 || f > 100.0 {
                                return Err(Error::invalid(
                                    format!("{field}.flare"),
                                    format!("must be in (1, 100], got {f}"),
                                ));
                            }
                            let c2 = (0.5 * h).powi(2) / (f * f - 1.0);
                            (
                                q([
                                    s,
                                    s,
                                    -1. / c2,
                                    0.,
                                    0.,
                                    0.,
                                    0.,
                                    0.,
                                    h / c2,
                                    -1. - h * h / (4. * c2),
                                ]),
                                r * f,
                            )
                        }
                    };
                    (quad, b([-w, -w, 0.], [w, w, h]))
                }
                "box" => {
                    let [sx, sy, sz] = v3(d.size, "size")?;
                    (
                        q([0., 0., 0., 0., 0., 0., 0., 0., 1. / sz, -2.]),
                        b([-0.5 * sx, -0.5 * sy, 0.], [0.5 * sx, 0.5 * sy, sz]),
                    )
                }
                "plane" => (q([0., 0., 0., 0., 0., 0., 0., 0., 1., 0.]), None),
                other => {
                    return Err(Error::invalid(
                        format!("{field}.shape"),
                        format!("unknown shape {other:?}; use sphere, ellipsoid, cylinder, cone, paraboloid, hyperboloid, box or plane"),
                    ))
                }
            })
        }
    }
}

fn rotation(d: &FreeFormDesc, field: &str) -> Result<DMat3> {
    checked_attitude(&|k| format!("{field}.{k}"), d.heading, d.pitch, d.roll)
}

fn forbid(present: bool, field: &str, key: &str, why: &str) -> Result<()> {
    if present {
        Err(Error::invalid(format!("{field}.{key}"), why.to_string()))
    } else {
        Ok(())
    }
}

impl FreeFormDesc {
    /// Builds object `index` of the scene. `ground` gives the terrain height below a point
    /// (for `above_terrain`) and places `geodetic` positions.
    pub fn build(&self, index: usize, ground: &dyn Ground) -> Result<FreeForm> {
        let name = self
            .name
            .clone()
            .unwrap_or_else(|| format!("object {index}"));
        let field = format!("objects[{index}] ({name:?})");
        let (base, natural) = shape_quadric(self, &field)?;
        for (bad, key) in [
            (self.centre.is_some(), "centre"),
            (self.weight.is_some(), "weight"),
        ] {
            forbid(
                bad,
                &field,
                key,
                "applies to perturbations only; place objects with `position` or `geodetic`",
            )?;
        }
        let position = place(
            &|k| format!("{field}.{k}"),
            self.position,
            self.geodetic,
            self.above_terrain,
            ground,
        )?;
        let bounds = match (self.bounds, natural) {
            (Some([lo, hi]), _) => {
                check_finite(&format!("{field}.bounds"), &[lo, hi].concat())?;
                let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
                if !(lo.cmplt(hi).all()) || (hi - lo).max_element() > 1e7 {
                    return Err(Error::invalid(
                        format!("{field}.bounds"),
                        format!(
                            "empty or absurd bounding box {lo} .. {hi}: need min < max on every axis, sides below 1e7 m"
                        ),
                    ));
                }
                [lo, hi]
            }
            (None, Some(b)) => b,
            (None, None) => {
                return Err(Error::invalid(
                    &field,
                    "raw coefficients and planes need `bounds = [[xmin, ymin, zmin], [xmax, ymax, zmax]]`",
                ))
            }
        };
        let mut nodes = vec![Node {
            q: base,
            weight: 1.0,
            depth: 0,
        }];
        for (i, p) in self.perturb.iter().enumerate() {
            p.flatten(&format!("{field}.perturb[{i}]"), 1, &mut nodes)?;
        }
        if nodes.len() > MAX_NODES {
            return Err(Error::invalid(
                &field,
                format!(
                    "has {} quadrics (base + perturbations); at most {MAX_NODES} per object are supported: split it into several objects",
                    nodes.len()
                ),
            ));
        }
        let m = self.material.unwrap_or_default();
        let mfield = format!("{field}.material");
        if m.colour
            .iter()
            .any(|v| !v.is_finite() || !(0.0..=100.0).contains(v))
        {
            return Err(Error::invalid(
                format!("{mfield}.colour"),
                format!("must be linear RGB in 0..=100, got {:?}", m.colour),
            ));
        }
        let q = [m.ambient, m.diffuse, m.specular];
        if q.iter().any(|v| !v.is_finite() || *v < 0.0 || *v > 1e3) || q.iter().sum::<f32>() <= 0.0
        {
            return Err(Error::invalid(
                &mfield,
                format!(
                    "ambient/diffuse/specular must be ≥ 0 and not all zero, got {:?}",
                    q
                ),
            ));
        }
        if !m.shininess.is_finite() || !(1.0..=10_000.0).contains(&m.shininess) {
            return Err(Error::invalid(
                format!("{mfield}.shininess"),
                format!("must be in 1..=10000, got {}", m.shininess),
            ));
        }
        Ok(FreeForm {
            name,
            rotation: rotation(self, &field)?,
            position,
            nodes,
            bounds,
            material: Material {
                colour: m.colour,
                ambient: m.ambient,
                diffuse: m.diffuse,
                specular: m.specular,
                shininess: m.shininess,
            },
        })
    }

    /// Appends this perturbation (depth `depth`) and its subtree in pre-order.
    fn flatten(&self, field: &str, depth: u32, nodes: &mut Vec<Node>) -> Result<()> {
        if depth > MAX_DEPTH {
            return Err(Error::invalid(
                field,
                format!(
                    "perturbations nest {depth} deep; at most {MAX_DEPTH} levels are supported"
                ),
            ));
        }
        for (bad, key) in [
            (self.position.is_some(), "position"),
            (self.geodetic.is_some(), "geodetic"),
            (self.above_terrain.is_some(), "above_terrain"),
            (self.bounds.is_some(), "bounds"),
            (self.material.is_some(), "material"),
            (self.name.is_some(), "name"),
        ] {
            forbid(
                bad,
                field,
                key,
                "applies to objects only; perturbations take `centre`, `weight` and a shape",
            )?;
        }
        if self.shape.as_deref() == Some("box") {
            return Err(Error::invalid(
                format!("{field}.shape"),
                "a box is not a quadric (it is a bounded slab); use ellipsoid, cylinder, plane or coefficients",
            ));
        }
        let (q, _) = shape_quadric(self, field)?;
        let q = if self.coefficients.is_some() {
            q
        } else {
            q.negated()
        };
        let c = self.centre.unwrap_or([0.0; 3]);
        check_finite(&format!("{field}.centre"), &c)?;
        let w = self.weight.unwrap_or(1.0);
        if !w.is_finite() || w == 0.0 || w.abs() > 1e6 {
            return Err(Error::invalid(
                format!("{field}.weight"),
                format!("must be finite, non-zero and within ±1e6, got {w}"),
            ));
        }
        nodes.push(Node {
            q: q.moved(rotation(self, field)?, DVec3::from(c)),
            weight: w,
            depth,
        });
        for (i, p) in self.perturb.iter().enumerate() {
            p.flatten(&format!("{field}.perturb[{i}]"), depth + 1, nodes)?;
        }
        Ok(())
    }
}
