//! Ray–free-form intersection (f64 reference of `gpu/shaders/freeform.wgsl`), scene-level
//! casting (nearest of terrain and free forms) and shadow queries.
//!
//! Per object: move the ray into the object frame (rigid, so `t` stays in metres), clip it to
//! the bounding box and re-centre it on the entry point `p0` so the per-node quadratics
//! `Q(p0 + s d) = α s² + β s + γ` are well conditioned. If `F'(p0) ≤ 0` the ray hits the box
//! face. Otherwise:
//! * a plain quadric takes the first root of its quadratic (stable formula);
//! * a perturbed one searches `[0, L]` depth first, left to right, with interval enclosures
//!   of `F'` (exact per quadric, monotone through `w·max(Q,0)²`): an interval whose lower bound
//!   is above zero cannot hold the surface and is skipped; otherwise it is halved, down to
//!   `L / 2^levels`. The first leaf reached brackets the first point where `F' ≤ 0`, so no
//!   first hit is missed, whatever the breakpoints; the leaf is refined by linear
//!   interpolation.

use crate::freeform::FreeForm;
use crate::terrain::Terrain;
use glam::DVec3;

/// Interval-halving depth of the GPU search (WGSL `FF_LEVELS`): leaves of `L / 2^16`, refined
/// by linear interpolation, are far below the 1e-4 relative depth the tests ask for.
pub const GPU_LEVELS: u32 = 16;
/// The GPU stops halving earlier where a leaf is already below this fraction of the object's
/// size (half its box diagonal; WGSL `FF_LEAF`): the refined root lies in its leaf, so its
/// distance from the surface stays below a quarter of the 1e-3 · size the tests allow.
pub const GPU_LEAF: f64 = 2.5e-4;
/// Interval-halving depth of the GPU's shadow rays (WGSL `FF_SHADOW_LEVELS`): they only ask
/// whether a root exists, so a leaf of `L / 2^10` whose enclosure admits `F' ≤ 0` counts as
/// blocked (a ray passing within about that of the surface may be called blocked).
pub const GPU_SHADOW_LEVELS: u32 = 10;
/// Interval-halving depth of the CPU reference.
pub const CPU_LEVELS: u32 = 44;
/// Enclosure evaluations after which a search gives up (reported, never silent).
pub const MAX_ITERATIONS: u32 = 16_384;

/// A ray–free-form hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FreeFormHit {
    /// Distance along the unit ray, metres.
    pub t: f64,
    /// Unit world normal: the normalised gradient of `F'`, or the box face where the ray
    /// enters the solid through the bounding box.
    pub normal: DVec3,
    /// Enclosure evaluations spent.
    pub iterations: u32,
}

/// Clips `o + t d` to the box; returns `(t0, t1, entry face normal)`, the normal being zero
/// when the ray starts inside the box.
pub fn clip_box(
    o: DVec3,
    d: DVec3,
    lo: DVec3,
    hi: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, f64, DVec3)> {
    let mut t0 = t_min;
    let mut t1 = t_max;
    let mut n = DVec3::ZERO;
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (mut ta, mut tb) = ((lo[a] - o[a]) * inv, (hi[a] - o[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        if ta > t0 {
            t0 = ta;
            n = DVec3::ZERO;
            n[a] = -d[a].signum();
        }
        t1 = t1.min(tb);
    }
    (t0 <= t1).then_some((t0, t1, n))
}

/// First root in `[0, len]` of `α s² + β s + γ` with `γ > 0` (the ray starts outside).
pub fn plain_first_root(c: [f64; 3], len: f64) -> Option<f64> {
    let [a, b, g] = c;
    let disc = b * b - 4.0 * a * g;
    if disc < 0.0 {
        return None;
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    let r1 = if a != 0.0 { q / a } else { f64::INFINITY };
    let r2 = if q != 0.0 { g / q } else { f64::INFINITY };
    let (lo, hi) = (r1.min(r2), r1.max(r2));
    let s = if lo >= 0.0 { lo } else { hi };
    (s >= 0.0 && s <= len).then_some(s)
}

/// Depth-first interval search for the first `s ∈ [0, len]` with `F'(p0 + s d) ≤ 0`;
/// returns the refined `s` and the number of enclosure evaluations.
pub fn search_first_root(
    ff: &FreeForm,
    coef: &[[f64; 3]],
    len: f64,
    levels: u32,
) -> (Option<f64>, u32) {
    let value = |s: f64| -> f64 {
        // F' from the ray coefficients: same tree walk as `enclose` on a point interval.
        ff.enclose(coef, s, s).0
    };
    let (mut k, mut i) = (0u32, 0u64);
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let w = len / (1u64 << k) as f64;
        let a = i as f64 * w;
        let b = a + w;
        let (lo, _) = ff.enclose(coef, a, b);
        if lo <= 0.0 {
            if k == levels {
                let (fa, fb) = (value(a), value(b));
                let s = if fa > 0.0 && fb < 0.0 {
                    a + w * fa / (fa - fb)
                } else if fa <= 0.0 {
                    a
                } else {
                    b
                };
                return (Some(s), iterations);
            }
            k += 1;
            i *= 2;
            continue;
        }
        i += 1;
        while i & 1 == 0 && k > 0 {
            i >>= 1;
            k -= 1;
        }
        if k == 0 {
            return (None, iterations);
        }
    }
    log::debug!("free-form search gave up after {MAX_ITERATIONS} enclosures");
    (None, iterations)
}

/// First hit of the world ray `origin + t dir` (`dir` unit length) with `t ∈ [t_min, t_max]`.
pub fn intersect(
    ff: &FreeForm,
    origin: DVec3,
    dir: DVec3,
    t_min: f64,
    t_max: f64,
    levels: u32,
) -> Option<FreeFormHit> {
    let o = ff.to_local(origin);
    let d = ff.dir_to_local(dir);
    let [lo, hi] = ff.bounds;
    let (t0, t1, face) = clip_box(o, d, lo, hi, t_min, t_max)?;
    let p0 = o + d * t0;
    if ff.value(p0) <= 0.0 {
        let n = if face == DVec3::ZERO { -d } else { face };
        return Some(FreeFormHit {
            t: t0,
            normal: ff.rotation * n,
            iterations: 0,
        });
    }
    let coef: Vec<[f64; 3]> = ff.nodes.iter().map(|n| n.q.along(p0, d)).collect();
    let len = t1 - t0;
    let (s, iterations) = if ff.nodes.len() == 1 {
        (plain_first_root(coef[0], len), 1)
    } else {
        search_first_root(ff, &coef, len, levels)
    };
    let s = s?;
    let g = ff.value_grad(p0 + d * s).1;
    let n = if g.length_squared() > 0.0 {
        g.normalize()
    } else {
        -d
    };
    Some(FreeFormHit {
        t: t0 + s,
        normal: ff.rotation * n,
        iterations,
    })
}

/// Dense-marching oracle: samples `F'` every `step` metres inside the box and bisects the first
/// bracket 60 times. Misses features thinner than `step`; used only to test [`intersect`].
pub fn march(ff: &FreeForm, origin: DVec3, dir: DVec3, t_max: f64, step: f64) -> Option<f64> {
    let o = ff.to_local(origin);
    let d = ff.dir_to_local(dir);
    let [lo, hi] = ff.bounds;
    let (t0, t1, _) = clip_box(o, d, lo, hi, 0.0, t_max)?;
    let f = |t: f64| ff.value(o + d * t);
    if f(t0) <= 0.0 {
        return Some(t0);
    }
    let mut a = t0;
    loop {
        let b = (a + step).min(t1);
        if f(b) <= 0.0 {
            let (mut l, mut r) = (a, b);
            for _ in 0..60 {
                let m = 0.5 * (l + r);
                if f(m) <= 0.0 {
                    r = m;
                } else {
                    l = m;
                }
            }
            return Some(r);
        }
        if b >= t1 {
            return None;
        }
        a = b;
    }
}

/// What a scene ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    Terrain { cell: [usize; 2] },
    Object(usize),
}

/// Nearest hit among the terrain and the free forms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    pub t: f64,
    pub point: DVec3,
    /// Unit world normal (geometric for terrain, gradient for free forms).
    pub normal: DVec3,
    pub surface: Surface,
}

/// Nearest hit of `origin + t dir` (`dir` unit) among the terrain and `objects`.
pub fn cast_scene(
    terrain: &Terrain,
    objects: &[FreeForm],
    origin: DVec3,
    dir: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<SceneHit> {
    let mut best = super::query::cast_ray(terrain, origin, dir, t_min, t_max).map(|h| SceneHit {
        t: h.t,
        point: h.point,
        normal: h.normal,
        surface: Surface::Terrain { cell: h.cell },
    });
    for (id, ff) in objects.iter().enumerate() {
        let far = best.map_or(t_max, |b| b.t);
        if let Some(h) = intersect(ff, origin, dir, t_min, far, CPU_LEVELS) {
            if best.is_none_or(|b| h.t < b.t) {
                best = Some(SceneHit {
                    t: h.t,
                    point: origin + dir * h.t,
                    normal: h.normal,
                    surface: Surface::Object(id),
                });
            }
        }
    }
    best
}

/// Offset (metres along the normal) from which shadow rays leave a free form's surface,
/// shared with the shader.
pub fn object_shadow_offset(ff: &FreeForm) -> f64 {
    1e-3 * ff.size()
}

/// True when the ray from `p` towards the sun meets no free form.
pub fn objects_clear(objects: &[FreeForm], p: DVec3, to_sun: DVec3) -> bool {
    objects
        .iter()
        .all(|ff| intersect(ff, p, to_sun, 0.0, f64::INFINITY, CPU_LEVELS).is_none())
}

/// Sun visibility of a scene hit: shadow ray through the terrain pyramid and the free forms,
/// leaving the surface at the offset the shader uses.
pub fn scene_sun_visible(
    terrain: &Terrain,
    objects: &[FreeForm],
    hit: &SceneHit,
    to_sun: DVec3,
) -> bool {
    if hit.normal.dot(to_sun) <= 0.0 {
        return false;
    }
    let off = match hit.surface {
        Surface::Terrain { .. } => super::query::shadow_offset(terrain),
        Surface::Object(id) => object_shadow_offset(&objects[id]),
    };
    let p = hit.point + hit.normal * off;
    super::query::cast_ray(terrain, p, to_sun, 0.0, f64::INFINITY).is_none()
        && objects_clear(objects, p, to_sun)
}

/// The free forms as the eye at `eye` sees them on the curved earth: each lowered rigidly by
/// the drop below the eye's tangent plane at its origin ([`Terrain::curved_offset`]); copies
/// of `objects` on a flat terrain. The GPU renderer does the same per frame.
pub fn lowered(terrain: &Terrain, eye: DVec3, objects: &[FreeForm]) -> Vec<FreeForm> {
    let curv = terrain.curvature(eye);
    objects
        .iter()
        .map(|o| o.translated(terrain.curved_offset(&curv, o.position)))
        .collect()
}
