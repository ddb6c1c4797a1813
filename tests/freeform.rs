//! Quadric free forms: model and scene tables, the CPU reference against analytic truth and
//! dense marching, and the GPU passes against both.

mod common;

use common::{
    gpu, gpu_lock, read_json, save_failure_image, save_failure_images, settings, terrain_from_fn,
    terrains, Rng,
};
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use relief::cpu::freeform::{self as cff, Surface, CPU_LEVELS};
use relief::freeform::{FreeForm, Quadric};
use relief::gpu::{FrameOutput, TerrainRenderer};
use relief::scene::{Camera, Pose, Scene};
use relief::terrain::Terrain;
use std::path::Path;

/// A scene whose `[[objects]]` come from `objects` (TOML) over a procedural placeholder
/// terrain; the objects are built against `terrain`.
fn objects_from_toml(objects: &str, terrain: &Terrain) -> relief::Result<Vec<FreeForm>> {
    let text = format!("[terrain.procedural]\nsize = 2\n[camera]\nposition = [0.0, 0.0, 100.0]\n[fog]\nvisibility = 0.0\n{objects}");
    let scene = Scene::parse(&text, Path::new("objects.toml"))?;
    scene.free_forms(terrain)
}

fn render(
    terrain: &Terrain,
    objects: &[FreeForm],
    cam: &Camera,
    shadows: bool,
    sun: Option<(f64, f64)>,
) -> Option<FrameOutput> {
    let g = gpu()?;
    let mut desc = common::synthetic_scene(cam.width, cam.height, "position = [0.0, 0.0, 100.0]");
    if let Some((az, el)) = sun {
        desc.sun.azimuth = az;
        desc.sun.elevation = el;
    }
    let mut r = TerrainRenderer::new(g, terrain).expect("renderer");
    r.set_objects(g, objects).expect("objects upload");
    Some(
        r.capture(g, terrain, &desc, cam, &settings(shadows, true))
            .expect("capture"),
    )
}

fn flat_terrain() -> Terrain {
    terrain_from_fn(65, 10.0, |_, _| 0.0)
}

fn random_rotation(rng: &mut Rng) -> DMat3 {
    DMat3::from_euler(
        glam::EulerRot::ZXY,
        rng.range(0.0, 6.3),
        rng.range(-1.5, 1.5),
        rng.range(-3.1, 3.1),
    )
}

// ---------------------------------------------------------------- model

#[test]
fn moved_quadric_is_the_quadric_of_the_moved_point() {
    let mut rng = Rng::new(3);
    for _ in 0..200 {
        let q = Quadric(std::array::from_fn(|_| rng.range(-2.0, 2.0)));
        let rot = random_rotation(&mut rng);
        let c = DVec3::new(
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
        );
        let m = q.moved(rot, c);
        for _ in 0..10 {
            let p = DVec3::new(
                rng.range(-9.0, 9.0),
                rng.range(-9.0, 9.0),
                rng.range(-9.0, 9.0),
            );
            let want = q.eval(rot.transpose() * (p - c));
            assert!((m.eval(p) - want).abs() < 1e-9 * (1.0 + want.abs()));
            // The along-ray coefficients reproduce the value at s = 1.5.
            let d = DVec3::new(0.3, -0.5, 0.8).normalize();
            let [a, b, g] = m.along(p, d);
            let s = 1.5;
            let v = m.eval(p + d * s);
            assert!((a * s * s + b * s + g - v).abs() < 1e-9 * (1.0 + v.abs()));
        }
    }
}

/// A pair of inside points whose midpoint is outside, if random sampling finds one.
fn non_convex_witness(ff: &FreeForm, rng: &mut Rng) -> Option<(DVec3, DVec3)> {
    let [lo, hi] = ff.bounds;
    let inside = |p: DVec3| ff.value(p) <= 0.0;
    let mut points = Vec::new();
    while points.len() < 400 {
        let p = DVec3::new(
            rng.range(lo.x, hi.x),
            rng.range(lo.y, hi.y),
            rng.range(lo.z, hi.z),
        );
        if inside(p) {
            points.push(p);
        }
    }
    for (i, &a) in points.iter().enumerate() {
        for &b in &points[i + 1..] {
            if !inside(0.5 * (a + b)) {
                return Some((a, b));
            }
        }
    }
    None
}

#[test]
fn convexity_is_claimed_only_for_convex_solids() {
    let t = flat_terrain();
    let mut rng = Rng::new(11);
    for (shape, convex) in [
        ("shape = \"sphere\"\nradius = 5", true),
        ("shape = \"ellipsoid\"\nradii = [6, 3, 2]\npitch = 30", true),
        ("shape = \"box\"\nsize = [4, 6, 2]\nheading = 20", true),
        ("shape = \"cylinder\"\nradius = 3\nheight = 8", true),
        ("shape = \"paraboloid\"\nradius = 3\nheight = 8", true),
        // Not claimed: a saddle-shaped quadric (the cone's nappe in its box is convex, but
        // its quadratic part is indefinite, so it is conservatively left out).
        ("shape = \"hyperboloid\"\nradius = 3\nheight = 8", false),
        ("shape = \"cone\"\nradius = 3\nheight = 8", false),
        (
            "shape = \"sphere\"\nradius = 5\n[[objects.perturb]]\nshape = \"sphere\"\nradius = 2\ncentre = [0, 0, 5]\nweight = -2",
            false,
        ),
    ] {
        let objects = objects_from_toml(
            &format!("[[objects]]\nname = \"o\"\nposition = [300.0, 300.0, 0.0]\n{shape}\n"),
            &t,
        )
        .expect(shape);
        let ff = &objects[0];
        assert_eq!(ff.is_convex(), convex, "{shape}");
        if convex {
            let w = non_convex_witness(ff, &mut rng);
            assert!(w.is_none(), "{shape}: claimed convex, but {w:?}");
        }
    }
    // The sampling finds non-convexity where there is some (the dented sphere and the
    // hyperboloid's waist), so the check above can fail.
    for shape in [
        "shape = \"hyperboloid\"\nradius = 3\nheight = 8",
        "shape = \"sphere\"\nradius = 5\n[[objects.perturb]]\nshape = \"sphere\"\nradius = 3\ncentre = [0, 0, 5]\nweight = -4",
    ] {
        let objects = objects_from_toml(
            &format!("[[objects]]\nname = \"o\"\nposition = [300.0, 300.0, 0.0]\n{shape}\n"),
            &t,
        )
        .expect(shape);
        assert!(non_convex_witness(&objects[0], &mut rng).is_some(), "{shape}");
    }
}

#[test]
fn gradient_is_continuous_across_perturbation_breakpoints() {
    let t = flat_terrain();
    let ff = &objects_from_toml(
        r#"
[[objects]]
shape = "sphere"
radius = 10.0
position = [0.0, 0.0, 0.0]
[[objects.perturb]]
shape = "sphere"
radius = 6.0
centre = [8.0, 0.0, 0.0]
weight = 3.0
"#,
        &t,
    )
    .unwrap()[0];
    // Q of the perturbation is zero on the sphere |p - (8,0,0)| = 6: cross it along x.
    let x0 = 2.0;
    let (_, g_in) = ff.value_grad(DVec3::new(x0 + 1e-7, 0.3, 0.2));
    let (_, g_out) = ff.value_grad(DVec3::new(x0 - 1e-7, 0.3, 0.2));
    assert!((g_in - g_out).length() < 1e-5, "{g_in} vs {g_out}");
    // And the perturbation really acts inside its sphere.
    let plain = Quadric([0.01, 0.01, 0.01, 0., 0., 0., 0., 0., 0., -1.]);
    let p = DVec3::new(9.0, 0.0, 0.0);
    assert!(ff.value(p) > plain.eval(p) + 0.5);
}

/// The gradient bound of anti-aliasing's near-miss search holds: at 20,000 random points of
/// each airfield object's box widened by the margin, and at its corners, |∇F'| stays within
/// it; and it is not vacuous (within 3x the largest gradient found).
#[test]
fn gradient_bound_holds_over_the_widened_box() {
    let scene = Scene::load(&terrains().join("airfield.toml")).unwrap();
    let terrain = scene.load_terrain().unwrap();
    let objects = scene.free_forms(&terrain).unwrap();
    let mut rng = Rng::new(29);
    let mut perturbed = 0;
    let start = std::time::Instant::now();
    let bounds: Vec<f64> = (objects.iter())
        .map(|ff| ff.gradient_bound(relief::gpu::objects::NEAR_MARGIN * ff.size()))
        .collect();
    eprintln!(
        "{} objects bounded in {:.1} ms",
        objects.len(),
        start.elapsed().as_secs_f64() * 1e3
    );
    for (ff, &bound) in objects.iter().zip(&bounds) {
        let margin = relief::gpu::objects::NEAR_MARGIN * ff.size();
        let (lo, hi) = (ff.bounds[0] - margin, ff.bounds[1] + margin);
        let mut most = 0.0f64;
        for k in 0..20_008 {
            let p = if k < 8 {
                DVec3::new(
                    [lo.x, hi.x][k & 1],
                    [lo.y, hi.y][(k >> 1) & 1],
                    [lo.z, hi.z][k >> 2],
                )
            } else {
                DVec3::new(
                    rng.range(lo.x, hi.x),
                    rng.range(lo.y, hi.y),
                    rng.range(lo.z, hi.z),
                )
            };
            let g = ff.value_grad(p).1.length();
            assert!(
                g <= bound * (1.0 + 1e-9),
                "{}: |grad| {g} at {p} over the bound {bound}",
                ff.name
            );
            most = most.max(g);
        }
        assert!(
            bound.is_finite() && bound <= 3.0 * most,
            "{}: bound {bound}, largest {most}",
            ff.name
        );
        eprintln!("{}: bound {bound:.3}, largest found {most:.3}", ff.name);
        perturbed += usize::from(ff.nodes.len() > 1);
    }
    assert!(perturbed >= 10, "only {perturbed} perturbed objects");
}

// ---------------------------------------------------------------- CPU reference

/// Independent analytic first hit of a ray with an ellipsoid (centre, rotation, radii).
fn ellipsoid_hit(o: DVec3, d: DVec3, c: DVec3, rot: DMat3, radii: DVec3) -> Option<f64> {
    let lo = (rot.transpose() * (o - c)) / radii;
    let ld = (rot.transpose() * d) / radii;
    let a = ld.dot(ld);
    let b = 2.0 * lo.dot(ld);
    let cc = lo.dot(lo) - 1.0;
    let disc = b * b - 4.0 * a * cc;
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / (2.0 * a);
    (t > 0.0).then_some(t)
}

#[test]
fn cpu_plain_ellipsoids_match_the_analytic_distance() {
    let t = flat_terrain();
    let mut rng = Rng::new(11);
    let mut hits = 0;
    for n in 0..50 {
        let radii = DVec3::new(
            rng.range(1.0, 30.0),
            rng.range(1.0, 30.0),
            rng.range(1.0, 30.0),
        );
        let (h, p, r) = (
            rng.range(0.0, 360.0),
            rng.range(-80.0, 80.0),
            rng.range(-180.0, 180.0),
        );
        let c = DVec3::new(
            rng.range(-50.0, 50.0),
            rng.range(-50.0, 50.0),
            rng.range(0.0, 50.0),
        );
        let ff = objects_from_toml(
            &format!(
                "[[objects]]\nshape = \"ellipsoid\"\nradii = [{}, {}, {}]\nposition = [{}, {}, {}]\nheading = {h}\npitch = {p}\nroll = {r}\n",
                radii.x, radii.y, radii.z, c.x, c.y, c.z
            ),
            &t,
        )
        .unwrap()
        .remove(0);
        for _ in 0..200 {
            let o = c + DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            )
            .normalize()
                * 200.0;
            let target = c + DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ) * radii.max_element();
            let d = (target - o).normalize();
            let want = ellipsoid_hit(o, d, c, ff.rotation, radii);
            let got = cff::intersect(&ff, o, d, 0.0, f64::INFINITY, CPU_LEVELS).map(|h| h.t);
            match (want, got) {
                (Some(w), Some(g)) => {
                    hits += 1;
                    assert!((w - g).abs() < 1e-9 * w, "object {n}: {g} vs analytic {w}");
                }
                (None, None) => {}
                (w, g) => panic!("object {n}: analytic {w:?}, cpu {g:?}"),
            }
        }
    }
    assert!(hits > 3000, "only {hits} hits: the rays do not test much");
}

/// Perturbed test objects: dents (positive weights), bumps (negative weights), a depth-2
/// nesting, and a dome carved by a plane.
const PERTURBED: &str = r#"
[[objects]]
name = "dented ball"
shape = "sphere"
radius = 10.0
position = [0.0, 0.0, 20.0]
[[objects.perturb]]
shape = "sphere"
radius = 6.0
centre = [9.0, 0.0, 0.0]
weight = 4.0
[[objects.perturb]]
shape = "ellipsoid"
radii = [3.0, 12.0, 3.0]
centre = [0.0, 0.0, 9.0]
weight = 2.0

[[objects]]
name = "bumpy ellipsoid"
shape = "ellipsoid"
radii = [12.0, 7.0, 5.0]
position = [40.0, 10.0, 15.0]
heading = 30.0
pitch = 20.0
bounds = [[-15.0, -10.0, -8.0], [15.0, 10.0, 8.0]]
[[objects.perturb]]
shape = "sphere"
radius = 4.0
centre = [10.0, 0.0, 3.0]
weight = -1.5
[[objects.perturb]]
shape = "sphere"
radius = 3.0
centre = [-6.0, 5.0, 0.0]
weight = -0.8

[[objects]]
name = "domed tank"
shape = "cylinder"
radius = 6.0
height = 12.0
position = [-30.0, 20.0, 0.0]
bounds = [[-6.5, -6.5, 0.0], [6.5, 6.5, 12.0]]
[[objects.perturb]]
coefficients = [0, 0, 0, 0, 0, 0, 0, 0, 0.4, -3.2]
[[objects.perturb]]
shape = "ellipsoid"
radii = [30.0, 30.0, 0.4]
centre = [0.0, 0.0, 4.0]
weight = -0.05

[[objects]]
name = "balloon"
shape = "sphere"
radius = 9.0
position = [-20.0, -30.0, 30.0]
bounds = [[-9.0, -9.0, -13.0], [9.0, 9.0, 9.0]]
[[objects.perturb]]
coefficients = [0, 0, 0, 0, 0, 0, 0, 0, -0.12, 0.0]
[[objects.perturb.perturb]]
shape = "sphere"
radius = 4.0
centre = [0.0, 0.0, -13.0]
weight = -0.2
[[objects.perturb.perturb.perturb]]
shape = "sphere"
radius = 1.0
centre = [0.0, 0.0, -15.0]
weight = 0.5
"#;

#[test]
fn cpu_first_hit_is_never_missed_against_dense_marching_on_1e5_rays() {
    let t = flat_terrain();
    let objects = objects_from_toml(PERTURBED, &t).unwrap();
    assert_eq!(objects[3].nodes.len(), 4, "the balloon nests three levels");
    let n_rays = 100_000;
    let results: Vec<(usize, Option<f64>, Option<f64>, f64)> = (0..n_rays)
        .into_par_iter()
        .map(|k| {
            let mut rng = Rng::new(1000 + k as u64);
            let id = k % objects.len();
            let ff = &objects[id];
            let (c, r) = ff.bounding_sphere();
            let dir_out = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            )
            .normalize();
            let o = c + dir_out * (3.0 * r);
            let target = c + DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ) * r;
            let d = (target - o).normalize();
            let got = cff::intersect(ff, o, d, 0.0, f64::INFINITY, CPU_LEVELS).map(|h| h.t);
            let marched = cff::march(ff, o, d, f64::INFINITY, ff.size() / 2000.0);
            (id, got, marched, ff.size())
        })
        .collect();
    let mut hits = 0;
    for (k, (id, got, marched, size)) in results.iter().enumerate() {
        if let Some(m) = marched {
            hits += 1;
            let g = got.unwrap_or_else(|| {
                panic!(
                    "ray {k} on {:?}: marching hits at {m}, the search misses",
                    objects[*id].name
                )
            });
            assert!(
                g <= m + 1e-6 * size,
                "ray {k} on {:?}: search {g} is behind the marched first hit {m}",
                objects[*id].name
            );
        }
    }
    assert!(
        hits > 20_000,
        "only {hits} of {n_rays} rays hit: the test is too weak"
    );
}

#[test]
fn cpu_hits_lie_on_the_surface_or_on_a_box_face() {
    let t = flat_terrain();
    let objects = objects_from_toml(PERTURBED, &t).unwrap();
    let mut rng = Rng::new(5);
    let mut checked = 0;
    for k in 0..20_000 {
        let ff = &objects[k % objects.len()];
        let (c, r) = ff.bounding_sphere();
        let o = c + DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        )
        .normalize()
            * (3.0 * r);
        let d = (c + DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        ) * r
            - o)
            .normalize();
        if let Some(h) = cff::intersect(ff, o, d, 0.0, f64::INFINITY, CPU_LEVELS) {
            let p = ff.to_local(o + d * h.t);
            let (v, g) = ff.value_grad(p);
            let [lo, hi] = ff.bounds;
            let on_face = (p - lo).min_element().min((hi - p).min_element()) < 1e-9 * ff.size();
            if on_face {
                assert!(v <= 1e-9, "box-face hit outside the solid: F' = {v}");
            } else {
                assert!(
                    v.abs() / g.length() < 1e-9 * ff.size(),
                    "residual {}",
                    v.abs() / g.length()
                );
            }
            assert!((h.normal.length() - 1.0).abs() < 1e-9);
            assert!(h.normal.dot(d) <= 1e-9, "normal faces away from the ray");
            checked += 1;
        }
    }
    assert!(checked > 5000);
}

// ---------------------------------------------------------------- bad input

#[test]
fn bad_free_forms_are_refused_with_the_object_named() {
    let t = flat_terrain();
    let cases = [
        (
            "[[objects]]\nname = \"zero\"\ncoefficients = [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]\nposition = [0.0, 0.0, 0.0]\nbounds = [[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]\n",
            "degenerate",
        ),
        (
            "[[objects]]\nname = \"nan\"\ncoefficients = [1, 1, 1, 0, 0, 0, 0, 0, 0, nan]\nposition = [0.0, 0.0, 0.0]\nbounds = [[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]\n",
            "finite",
        ),
        (
            "[[objects]]\nname = \"flat box\"\nshape = \"sphere\"\nradius = 1.0\nposition = [0.0, 0.0, 0.0]\nbounds = [[-1.0, -1.0, 1.0], [1.0, 1.0, 1.0]]\n",
            "empty",
        ),
        (
            "[[objects]]\nname = \"deep\"\nshape = \"sphere\"\nradius = 1.0\nposition = [0.0, 0.0, 0.0]\n[[objects.perturb]]\nshape = \"sphere\"\nradius = 1.0\n[[objects.perturb.perturb]]\nshape = \"sphere\"\nradius = 1.0\n[[objects.perturb.perturb.perturb]]\nshape = \"sphere\"\nradius = 1.0\n[[objects.perturb.perturb.perturb.perturb]]\nshape = \"sphere\"\nradius = 1.0\n",
            "nest 4 deep",
        ),
        (
            "[[objects]]\nname = \"odd\"\nshape = \"torus\"\nposition = [0.0, 0.0, 0.0]\n",
            "unknown shape",
        ),
        (
            "[[objects]]\nname = \"raw\"\ncoefficients = [1, 1, 1, 0, 0, 0, 0, 0, 0, -1]\nposition = [0.0, 0.0, 0.0]\n",
            "need `bounds",
        ),
        (
            "[[objects]]\nname = \"neg\"\nshape = \"sphere\"\nradius = -2.0\nposition = [0.0, 0.0, 0.0]\n",
            "positive",
        ),
        (
            "[[objects]]\nname = \"w\"\nshape = \"sphere\"\nradius = 2.0\nposition = [0.0, 0.0, 0.0]\n[[objects.perturb]]\nshape = \"sphere\"\nradius = 1.0\nweight = inf\n",
            "weight",
        ),
        (
            "[[objects]]\nname = \"floating\"\nshape = \"sphere\"\nradius = 2.0\nposition = [1e9, 0.0, 0.0]\nabove_terrain = 1.0\n",
            "outside the terrain",
        ),
    ];
    for (toml, want) in cases {
        let err = objects_from_toml(toml, &t).expect_err(toml).to_string();
        assert!(err.contains(want), "{toml}\n-> {err}\n(wanted {want:?})");
        let name = toml.split('"').nth(1).unwrap();
        assert!(
            err.contains(name),
            "error does not name the object {name:?}: {err}"
        );
    }
    // Unknown keys are errors too (the scene parser names them).
    let err = objects_from_toml(
        "[[objects]]\nshape = \"sphere\"\nradius = 1.0\nposition = [0.0, 0.0, 0.0]\ncolor = [1, 0, 0]\n",
        &t,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("color"), "{err}");
}

// ---------------------------------------------------------------- GPU

fn camera(position: DVec3, heading: f64, pitch: f64, w: u32, h: u32) -> Camera {
    Camera::new(
        Pose {
            position,
            heading,
            pitch,
            roll: 0.0,
            fov: 60.0,
        },
        w,
        h,
    )
}

/// Analytic first hit with a capped cylinder (axis z from `base`, radius r, height h).
fn capped_cylinder_hit(o: DVec3, d: DVec3, base: DVec3, r: f64, h: f64) -> Option<f64> {
    let lo = o - base;
    // Slab z in [0, h].
    let (mut t0, mut t1) = if d.z.abs() < 1e-15 {
        if lo.z < 0.0 || lo.z > h {
            return None;
        }
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        let (a, b) = ((0.0 - lo.z) / d.z, (h - lo.z) / d.z);
        (a.min(b), a.max(b))
    };
    let a = d.x * d.x + d.y * d.y;
    let b = 2.0 * (lo.x * d.x + lo.y * d.y);
    let c = lo.x * lo.x + lo.y * lo.y - r * r;
    if a < 1e-15 {
        if c > 0.0 {
            return None;
        }
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        t0 = t0.max((-b - s) / (2.0 * a));
        t1 = t1.min((-b + s) / (2.0 * a));
    }
    (t0 <= t1 && t0 > 0.0).then_some(t0)
}

#[test]
fn gpu_plain_quadrics_match_analytic_distance_and_silhouettes() {
    let _l = gpu_lock();
    let t = flat_terrain();
    let objects = objects_from_toml(
        r#"
[[objects]]
name = "sphere"
shape = "sphere"
radius = 20.0
position = [280.0, 160.0, 40.0]
[[objects]]
name = "ellipsoid"
shape = "ellipsoid"
radii = [30.0, 15.0, 10.0]
position = [370.0, 170.0, 30.0]
heading = 30.0
roll = 15.0
[[objects]]
name = "cylinder"
shape = "cylinder"
radius = 12.0
height = 40.0
position = [330.0, 260.0, 0.0]
"#,
        &t,
    )
    .unwrap();
    let (w, h) = (200u32, 150u32);
    let cam = camera(DVec3::new(320.0, -60.0, 60.0), 0.0, -8.0, w, h);
    let Some(out) = render(&t, &objects, &cam, false, None) else {
        return;
    };
    let truth: Vec<Option<(usize, f64)>> = (0..w * h)
        .map(|k| {
            let d = cam.pixel_ray(k % w, k / w);
            let o = cam.pose.position;
            let cands = [
                ellipsoid_hit(
                    o,
                    d,
                    objects[0].position,
                    objects[0].rotation,
                    DVec3::splat(20.0),
                ),
                ellipsoid_hit(
                    o,
                    d,
                    objects[1].position,
                    objects[1].rotation,
                    DVec3::new(30.0, 15.0, 10.0),
                ),
                capped_cylinder_hit(o, d, objects[2].position, 12.0, 40.0),
            ];
            cands
                .iter()
                .enumerate()
                .filter_map(|(i, t)| t.map(|t| (i, t)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
        })
        .collect();
    let id_at = |x: i64, y: i64| -> Option<usize> {
        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
            return None;
        }
        truth[(y as u32 * w + x as u32) as usize].map(|t| t.0)
    };
    let (mut covered, mut worst, mut edge_only) = (0, 0.0f64, true);
    let mut bad = Vec::new();
    for (k, &tk) in truth.iter().enumerate() {
        let gpu_id = out.objects[k].checked_sub(1).map(|i| i as usize);
        let (x, y) = ((k as u32 % w) as i64, (k as u32 / w) as i64);
        match (tk, gpu_id) {
            (Some((i, tt)), Some(g)) if i == g => {
                covered += 1;
                let e = ((out.depth[k] as f64 - tt) / tt).abs();
                worst = worst.max(e);
                if e >= 1e-4 {
                    bad.push(format!(
                        "({x}, {y}) {}: gpu {} analytic {tt}",
                        objects[i].name, out.depth[k]
                    ));
                }
            }
            (a, g) => {
                if a.map(|a| a.0) != g {
                    // Coverage may differ only on the silhouette: some neighbour has the GPU's answer.
                    let near = (-1..=1).any(|dy| (-1..=1).any(|dx| id_at(x + dx, y + dy) == g));
                    if !near {
                        edge_only = false;
                        bad.push(format!(
                            "({x}, {y}): analytic {:?}, gpu {g:?}",
                            a.map(|a| a.0)
                        ));
                    }
                }
            }
        }
    }
    eprintln!("{covered} covered pixels, worst relative depth error {worst:.2e}");
    if !bad.is_empty() || !edge_only {
        let p = save_failure_image("freeform-plain", w, h, &out.rgba);
        panic!(
            "{} bad pixels, e.g. {:?}; image {}",
            bad.len(),
            &bad[..bad.len().min(10)],
            p.display()
        );
    }
    assert!(covered > 1000, "only {covered} covered pixels");
}

/// A ball with four perturbations: five nodes, more than the GPU's per-ray node slots
/// (`shaders::FF_RAY_NODES`), so a scene holding it runs the general enclosure loop.
const FIVE_NODES: &str = r#"
[[objects]]
name = "five-node ball"
shape = "sphere"
radius = 8.0
position = [0.0, 0.0, 12.0]
[[objects.perturb]]
shape = "sphere"
radius = 3.0
centre = [8.0, 0.0, 0.0]
weight = 3.0
[[objects.perturb]]
shape = "sphere"
radius = 3.0
centre = [-8.0, 0.0, 0.0]
weight = 3.0
[[objects.perturb]]
shape = "sphere"
radius = 3.0
centre = [0.0, 0.0, 8.0]
weight = -2.0
[[objects.perturb]]
shape = "ellipsoid"
radii = [2.0, 10.0, 2.0]
centre = [0.0, -7.0, 0.0]
weight = 1.5
"#;

#[test]
fn gpu_perturbed_hits_lie_on_the_surface() {
    // Twice: objects of at most FF_RAY_NODES nodes (per-ray node data in the interval search),
    // then with a five-node object added (the general loop over the node buffer).
    let t = flat_terrain();
    let small = objects_from_toml(PERTURBED, &t).unwrap();
    assert!(small
        .iter()
        .all(|o| o.nodes.len() <= relief::gpu::shaders::FF_RAY_NODES));
    let mut general = small.clone();
    general.extend(objects_from_toml(FIVE_NODES, &t).unwrap());
    assert!(general
        .iter()
        .any(|o| o.nodes.len() > relief::gpu::shaders::FF_RAY_NODES));
    perturbed_hits_lie_on_the_surface(&t, small);
    perturbed_hits_lie_on_the_surface(&t, general);
}

fn perturbed_hits_lie_on_the_surface(t: &Terrain, mut objects: Vec<FreeForm>) {
    let _l = gpu_lock();
    for (i, ff) in objects.iter_mut().enumerate() {
        ff.position = DVec3::new(240.0 + 40.0 * i as f64, 330.0, ff.position.z);
    }
    let (w, h) = (240u32, 120u32);
    let cam = Camera::new(
        Pose {
            position: DVec3::new(320.0, 200.0, 50.0),
            heading: 0.0,
            pitch: -12.0,
            roll: 0.0,
            fov: 90.0,
        },
        w,
        h,
    );
    let Some(out) = render(t, &objects, &cam, false, None) else {
        return;
    };
    let mut per_object = vec![0; objects.len()];
    let mut bad = Vec::new();
    for k in 0..(w * h) as usize {
        let Some(id) = out.objects[k].checked_sub(1) else {
            continue;
        };
        let ff = &objects[id as usize];
        per_object[id as usize] += 1;
        let d = cam.pixel_ray(k as u32 % w, k as u32 / w);
        let p = ff.to_local(cam.pose.position + d * out.depth[k] as f64);
        let (v, g) = ff.value_grad(p);
        let [lo, hi] = ff.bounds;
        let on_face = (p - lo).min_element().min((hi - p).min_element()) < 1e-3 * ff.size();
        let ok = if on_face {
            v <= 1e-3 * ff.size() * g.length()
        } else {
            v.abs() / g.length() < 1e-3 * ff.size()
        };
        if !ok {
            bad.push(format!(
                "{}: residual {:.2e} (size {:.1})",
                ff.name,
                v.abs() / g.length(),
                ff.size()
            ));
        }
    }
    eprintln!("free-form pixels per object: {per_object:?}");
    assert!(
        per_object.iter().all(|n| *n > 100),
        "an object is (nearly) invisible: {per_object:?}"
    );
    if !bad.is_empty() {
        let p = save_failure_image("freeform-perturbed", w, h, &out.rgba);
        panic!(
            "{} hits off the surface, e.g. {:?}; image {}",
            bad.len(),
            &bad[..bad.len().min(10)],
            p.display()
        );
    }
}

/// What the CPU oracle sees at a pixel: sky, terrain, or object id; with the distance.
fn cpu_pixel(
    terrain: &Terrain,
    objects: &[FreeForm],
    cam: &Camera,
    k: u32,
) -> Option<cff::SceneHit> {
    cff::cast_scene(
        terrain,
        objects,
        cam.pose.position,
        cam.pixel_ray(k % cam.width, k / cam.width),
        0.0,
        f64::INFINITY,
    )
}

/// Per pixel against the CPU oracle: the object the CPU sees there (None for terrain or sky)
/// and whether the GPU agrees (same sky/terrain/object class and id, depth within 0.1%).
fn oracle_agreement(
    terrain: &Terrain,
    objects: &[FreeForm],
    cam: &Camera,
    out: &FrameOutput,
) -> Vec<(Option<usize>, bool)> {
    (0..cam.width * cam.height)
        .into_par_iter()
        .map(|k| {
            let gpu_obj = out.objects[k as usize].checked_sub(1).map(|i| i as usize);
            let depth = out.depth[k as usize] as f64;
            match cpu_pixel(terrain, objects, cam, k) {
                None => (None, !depth.is_finite()),
                Some(hit) => {
                    let (cpu_obj, same_surface) = match hit.surface {
                        Surface::Object(i) => (Some(i), gpu_obj == Some(i)),
                        Surface::Terrain { .. } => (None, gpu_obj.is_none()),
                    };
                    let depth_ok = ((depth - hit.t) / hit.t).abs() <= 1e-3;
                    (cpu_obj, same_surface && depth_ok)
                }
            }
        })
        .collect()
}

#[test]
fn gpu_matches_cpu_oracle_on_the_airfield_demo() {
    let _l = gpu_lock();
    let mut scene = Scene::load(&terrains().join("airfield.toml")).unwrap();
    scene.desc.output.width = 320;
    scene.desc.output.height = 240;
    let terrain = scene.load_terrain().unwrap();
    let objects = scene.free_forms(&terrain).unwrap();
    let quadrics: usize = objects.iter().map(|o| o.nodes.len()).sum();
    assert!(
        quadrics >= 45,
        "the demo has only {quadrics} second-order functions"
    );
    let cam = scene.camera(0, &terrain);
    let Some(g) = gpu() else {
        return;
    };
    // Both homes of the object tables: uniform buffers (the demo fits) and storage buffers
    // (scenes beyond the uniform-binding size).
    for storage in [false, true] {
        let mut r = TerrainRenderer::new(g, &terrain).unwrap();
        if storage {
            r.set_objects_in_storage(g, &objects).unwrap();
        } else {
            r.set_objects(g, &objects).unwrap();
        }
        let out = r
            .capture(g, &terrain, &scene.desc, &cam, &settings(true, true))
            .unwrap();
        let n = 320 * 240;
        let pixels = oracle_agreement(&terrain, &objects, &cam, &out);
        let agree = pixels.iter().filter(|p| p.1).count();
        let object_pixels = pixels.iter().filter(|p| p.0.is_some()).count();
        let frac = agree as f64 / n as f64;
        eprintln!(
            "storage tables {storage}: {agree}/{n} pixels agree ({:.3}%), {object_pixels} free-form pixels",
            100.0 * frac
        );
        assert!(
            object_pixels > 2000,
            "the view shows only {object_pixels} free-form pixels"
        );
        if frac < 0.995 {
            let p = save_failure_image("airfield", 320, 240, &out.rgba);
            panic!(
                "storage tables {storage}: only {:.3}% of pixels agree with the CPU oracle; image {}",
                100.0 * frac,
                p.display()
            );
        }
    }
}

#[test]
fn overflowing_bins_still_find_the_nearest_object_of_both_kinds() {
    // 300 objects (plain spheres and perturbed balls in turn) strung out along the ray through
    // the centre of one 16x16 bin, all within 2.3° of it: that bin lists more than the 255
    // objects a bin holds, so the passes fall back to testing every object of their kind
    // there. GPU against the CPU oracle, as for the demo.
    let _l = gpu_lock();
    let terrain = flat_terrain();
    let cam = camera(DVec3::new(5.0, 320.0, 12.0), 90.0, 0.0, 160, 120);
    let axis = cam.pixel_ray(88, 56);
    let u = axis.cross(DVec3::Z).normalize();
    let v = u.cross(axis);
    let mut text = String::new();
    for i in 0..300 {
        let d = 60.0 + 1.8 * i as f64;
        let (a, r) = (2.4 * i as f64, 0.02 * d * (i % 7) as f64 / 6.0);
        let p = cam.pose.position + axis * d + (u * a.cos() + v * a.sin()) * r;
        let radius = 0.02 * d;
        let shape = if i % 2 == 0 {
            format!("shape = \"sphere\"\nradius = {radius}")
        } else {
            format!("shape = \"sphere\"\nradius = {radius}\n[[objects.perturb]]\nshape = \"sphere\"\nradius = {}\ncentre = [0, 0, {}]\nweight = -3", 0.6 * radius, 0.8 * radius)
        };
        text.push_str(&format!(
            "[[objects]]\nname = \"ball {i}\"\nposition = [{}, {}, {}]\n{shape}\n",
            p.x, p.y, p.z
        ));
    }
    let objects = objects_from_toml(&text, &terrain).unwrap();
    assert!(
        objects.iter().any(|o| o.nodes.len() == 1) && objects.iter().any(|o| o.nodes.len() > 1)
    );
    let Some(out) = render(&terrain, &objects, &cam, true, None) else {
        return;
    };
    let n = cam.width * cam.height;
    let pixels = oracle_agreement(&terrain, &objects, &cam, &out);
    let (mut agree, mut object_pixels, mut object_agree, mut kinds) = (0, 0, 0, [0, 0]);
    for &(cpu_obj, ok) in &pixels {
        agree += ok as u32;
        if let Some(i) = cpu_obj {
            object_pixels += 1;
            object_agree += ok as u32;
            kinds[(objects[i].nodes.len() > 1) as usize] += 1;
        }
    }
    let frac = agree as f64 / n as f64;
    eprintln!("{agree}/{n} agree, {object_agree}/{object_pixels} object pixels (plain, perturbed: {kinds:?})");
    assert!(
        kinds[0] > 20 && kinds[1] > 20,
        "both kinds visible: {kinds:?}"
    );
    // The objects cover few pixels: hold them to 95% on their own (silhouettes may differ).
    if frac < 0.995 || (object_agree as f64) < 0.95 * object_pixels as f64 {
        let p = save_failure_image("freeform-overflow", cam.width, cam.height, &out.rgba);
        panic!(
            "{:.3}% of pixels, {object_agree} of {object_pixels} object pixels agree; image {}",
            100.0 * frac,
            p.display()
        );
    }
}

#[test]
fn occlusion_and_shadows_work_both_ways_between_terrain_and_free_forms() {
    let _l = gpu_lock();
    // A plain with a ridge across it (y = 300) and a hill east of a low pad.
    let t = terrain_from_fn(65, 10.0, |x, y| {
        80.0 * (-((y - 300.0) / 40.0).powi(2)).exp()
            + 70.0 * (-((x - 420.0).powi(2) + (y - 120.0).powi(2)) / (30.0f64 * 30.0)).exp()
    });
    let objects = objects_from_toml(
        r#"
[[objects]]
name = "behind the ridge"
shape = "sphere"
radius = 40.0
position = [300.0, 420.0, 50.0]
[[objects]]
name = "caster"
shape = "ellipsoid"
radii = [12.0, 12.0, 20.0]
position = [300.0, 150.0, 35.0]
[[objects]]
name = "receiver"
shape = "cylinder"
radius = 14.0
height = 30.0
position = [250.0, 150.0, 0.0]
[[objects]]
name = "pad in the hill's shadow"
shape = "cylinder"
radius = 20.0
height = 3.0
position = [360.0, 120.0, 0.0]
"#,
        &t,
    )
    .unwrap();
    let (w, h) = (200u32, 150u32);
    let cam = Camera::new(
        Pose {
            position: DVec3::new(320.0, -50.0, 140.0),
            heading: 0.0,
            pitch: -25.0,
            roll: 0.0,
            fov: 70.0,
        },
        w,
        h,
    );
    // Low sun from the east: the hill shadows the pad, the caster shadows the receiver and
    // the ground west of it; the ridge hides part of the sphere behind it.
    let (az, el) = (90.0, 14.0);
    let Some(out) = render(&t, &objects, &cam, true, Some((az, el))) else {
        return;
    };
    let sun = relief::scene::Sun {
        azimuth: az,
        elevation: el,
        ..Default::default()
    }
    .direction();
    #[derive(Clone, Copy, PartialEq, Debug)]
    enum Class {
        Other,
        TerrainOverObject,
        ObjectOverTerrain,
        TerrainShadowedByObject,
        ObjectShadowedByTerrain,
        ObjectShadowedByObject,
    }
    let classes: Vec<(Class, Option<cff::SceneHit>)> = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let d = cam.pixel_ray(k % w, k / w);
            let o = cam.pose.position;
            let Some(hit) = cpu_pixel(&t, &objects, &cam, k) else {
                return (Class::Other, None);
            };
            let behind = objects
                .iter()
                .any(|ff| cff::intersect(ff, o, d, hit.t, f64::INFINITY, CPU_LEVELS).is_some());
            let terrain_behind =
                relief::cpu::cast_ray(&t, o, d, hit.t * 1.001, f64::INFINITY).is_some();
            let class = match hit.surface {
                Surface::Terrain { .. } if behind => Class::TerrainOverObject,
                Surface::Object(_) if terrain_behind && hit.normal.dot(sun) <= 0.2 => {
                    Class::ObjectOverTerrain
                }
                _ if hit.normal.dot(sun) <= 0.2 => Class::Other,
                surface => {
                    let off = match surface {
                        Surface::Terrain { .. } => relief::cpu::query::shadow_offset(&t),
                        Surface::Object(i) => cff::object_shadow_offset(&objects[i]),
                    };
                    let p = hit.point + hit.normal * off;
                    let by_terrain =
                        relief::cpu::cast_ray(&t, p, sun, 0.0, f64::INFINITY).is_some();
                    let by_object = !cff::objects_clear(&objects, p, sun);
                    match (surface, by_terrain, by_object) {
                        (Surface::Terrain { .. }, false, true) => Class::TerrainShadowedByObject,
                        (Surface::Object(_), true, false) => Class::ObjectShadowedByTerrain,
                        (Surface::Object(_), false, true) => Class::ObjectShadowedByObject,
                        (Surface::Object(_), _, _) if terrain_behind => Class::ObjectOverTerrain,
                        _ => Class::Other,
                    }
                }
            };
            (class, Some(hit))
        })
        .collect();
    let at = |x: i64, y: i64| -> Option<Class> {
        (x >= 0 && y >= 0 && x < w as i64 && y < h as i64)
            .then(|| classes[(y * w as i64 + x) as usize].0)
    };
    let mut stats = std::collections::BTreeMap::new();
    for (k, &(class, hit)) in classes.iter().enumerate() {
        let (x, y) = ((k as u32 % w) as i64, (k as u32 / w) as i64);
        // Interior pixels only: the 3x3 neighbourhood has the same class.
        if class == Class::Other
            || !(-1..=1).all(|dy| (-1..=1).all(|dx| at(x + dx, y + dy) == Some(class)))
        {
            continue;
        }
        let hit = hit.unwrap();
        let gpu_obj = out.objects[k].checked_sub(1).map(|i| i as usize);
        let shadow = out.flags[k] & 2 != 0;
        let ok = match class {
            Class::TerrainOverObject => gpu_obj.is_none(),
            Class::ObjectOverTerrain => {
                matches!(hit.surface, Surface::Object(i) if gpu_obj == Some(i))
            }
            Class::TerrainShadowedByObject => gpu_obj.is_none() && shadow,
            Class::ObjectShadowedByTerrain | Class::ObjectShadowedByObject => {
                gpu_obj.is_some() && shadow
            }
            Class::Other => true,
        };
        let e = stats.entry(format!("{class:?}")).or_insert((0, 0));
        e.0 += 1;
        e.1 += ok as usize;
    }
    eprintln!("interior pixels per class (count, GPU agrees): {stats:?}");
    for class in [
        "TerrainOverObject",
        "ObjectOverTerrain",
        "TerrainShadowedByObject",
        "ObjectShadowedByTerrain",
        "ObjectShadowedByObject",
    ] {
        let (n, ok) = stats.get(class).copied().unwrap_or((0, 0));
        if n < 20 || ok != n {
            let p = save_failure_image("freeform-occlusion", w, h, &out.rgba);
            panic!("{class}: {ok} of {n} interior pixels right (need ≥ 20, all right); {stats:?}; image {}", p.display());
        }
    }
}

#[test]
fn cli_renders_the_airfield_and_refuses_a_bad_object_before_writing() {
    let dir = common::temp_dir("ff-cli");
    let run = |args: &[&str]| common::relief_cli(args, &[]);
    // A broken object: the error names it and nothing is written.
    let bad = dir.join("bad.toml");
    let scene = std::fs::read_to_string(terrains().join("airfield.toml"))
        .unwrap()
        .replace(
            "source = \"N47E009.hgt\"",
            &format!("source = {:?}", terrains().join("N47E009.hgt")),
        )
        .replacen("radius = 14\n", "radius = nan\n", 1);
    std::fs::write(&bad, scene).unwrap();
    let out_bad = dir.join("bad-out");
    let o = run(&[
        "render",
        bad.to_str().unwrap(),
        "--out",
        out_bad.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a NaN radius must fail");
    assert!(err.contains("hangar 1") && err.contains("radius"), "{err}");
    assert!(!out_bad.join("frame_0000.png").exists());
    if gpu().is_none() {
        return;
    }
    let _l = gpu_lock();
    let out = dir.join("out");
    let o = run(&[
        "render",
        "terrains/airfield.toml",
        "--size",
        "160x120",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let meta = read_json(&out.join("frame_0000.json"));
    assert_eq!(meta["free_forms"], 56);
    assert!(
        meta["free_form_pixels"].as_u64().unwrap() > 300,
        "{}",
        meta["free_form_pixels"]
    );
    let (w, h, depth) = relief::app::output::read_depth_tiff(&out.join("depth_0000.tiff")).unwrap();
    assert_eq!((w, h), (160, 120));
    assert!(depth.iter().filter(|d| d.is_finite()).count() > 8000);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_frame_after_another_equals_a_frame_from_a_fresh_renderer() {
    // Per-frame state must not leak between frames (the free-form shadow target is never
    // cleared: its marks carry the frame's stamp). Frame B rendered after frame A (another
    // heading, so A's shadows fall on other pixels) must equal frame B from a fresh renderer,
    // byte for byte, with and without shadows in between.
    let _l = gpu_lock();
    let mut scene = Scene::load(&terrains().join("airfield.toml")).unwrap();
    scene.desc.output.width = 160;
    scene.desc.output.height = 120;
    let terrain = scene.load_terrain().unwrap();
    let objects = scene.free_forms(&terrain).unwrap();
    let b = scene.camera(0, &terrain);
    let mut a = b;
    a.pose.heading += 12.0;
    let Some(g) = gpu() else {
        return;
    };
    let fresh = {
        let mut r = TerrainRenderer::new(g, &terrain).unwrap();
        r.set_objects(g, &objects).unwrap();
        r.capture(g, &terrain, &scene.desc, &b, &settings(true, true))
            .unwrap()
    };
    let shadowed = fresh.flags.iter().filter(|&&f| f & 2 != 0).count();
    assert!(shadowed > 20, "only {shadowed} pixels in shadow");
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    r.set_objects(g, &objects).unwrap();
    for before in [true, false] {
        r.capture(g, &terrain, &scene.desc, &a, &settings(before, true))
            .unwrap();
        let after = r
            .capture(g, &terrain, &scene.desc, &b, &settings(true, true))
            .unwrap();
        let differ = (0..fresh.flags.len())
            .filter(|&i| {
                fresh.rgba[4 * i..4 * i + 4] != after.rgba[4 * i..4 * i + 4]
                    || fresh.flags[i] != after.flags[i]
                    || fresh.depth[i].to_bits() != after.depth[i].to_bits()
            })
            .count();
        if differ > 0 {
            let p = save_failure_images("frame-after-frame", 160, 120, &after.rgba, &fresh.rgba);
            panic!(
                "{differ} pixels differ from a fresh renderer's frame (previous frame with shadows: {before}); image {}",
                p.display()
            );
        }
    }
}
