//! The CPU reference traversal against analytic truth, brute force and dense marching.

mod common;

use common::{terrain_from_fn, terrains, Rng};
use glam::DVec3;
use rayon::prelude::*;
use relief::cpu::traverse::{intersect, GridRay, TraversalStats};
use relief::cpu::{self, march::march};
use relief::terrain::{Terrain, TerrainFrame};

fn pinhole_dirs(heading: f64, pitch: f64, n: usize) -> Vec<DVec3> {
    let cam = relief::scene::Camera::new(
        relief::scene::Pose {
            position: DVec3::ZERO,
            heading,
            pitch,
            roll: 0.0,
            fov: 70.0,
        },
        n as u32,
        n as u32,
    );
    (0..n * n)
        .map(|k| cam.pixel_ray((k % n) as u32, (k / n) as u32))
        .collect()
}

#[test]
fn flat_and_ramp_terrains_give_exact_distances() {
    // Planes are reproduced exactly by bilinear patches.
    type Surface = Box<dyn Fn(f64, f64) -> f64 + Sync>;
    let cases: [(&str, Surface); 2] = [
        ("flat", Box::new(|_, _| 100.0)),
        ("ramp", Box::new(|x, y| 50.0 + 0.12 * x - 0.07 * y)),
    ];
    for (name, f) in cases {
        let terrain = terrain_from_fn(129, 10.0, &f);
        let eye = DVec3::new(300.0, 200.0, 400.0);
        let mut checked = 0;
        for d in pinhole_dirs(30.0, -40.0, 64) {
            // Ray-plane intersection: z = a + b x + c y.
            let (a, b, c) = (
                f(0.0, 0.0),
                f(1.0, 0.0) - f(0.0, 0.0),
                f(0.0, 1.0) - f(0.0, 0.0),
            );
            let t = (a + b * eye.x + c * eye.y - eye.z) / (d.z - b * d.x - c * d.y);
            let p = eye + d * t;
            let inside = t > 0.0 && p.x > 1.0 && p.y > 1.0 && p.x < 1279.0 && p.y < 1279.0;
            let hit = cpu::cast_ray(&terrain, eye, d, 0.0, f64::INFINITY);
            if inside {
                let h = hit.unwrap_or_else(|| panic!("{name}: ray {d} missed, expected t = {t}"));
                // Heights are stored as f32 (≈ 1e-8 relative), so the plane is exact to about that.
                assert!(
                    (h.t - t).abs() / t < 1e-6,
                    "{name}: t = {} expected {t}",
                    h.t
                );
                checked += 1;
            } else if t <= 0.0 || p.x < -1.0 || p.y < -1.0 || p.x > 1281.0 || p.y > 1281.0 {
                assert!(
                    hit.is_none(),
                    "{name}: ray {d} hit outside the grid at {:?}",
                    hit
                );
            }
        }
        assert!(checked > 1000, "{name}: only {checked} rays checked");
    }
}

#[test]
fn single_bilinear_cell_matches_brute_force_root_search() {
    let mut rng = Rng::new(7);
    let mut tangents = 0;
    for case in 0..100_000 {
        // One cell with random corner heights (a saddle most of the time).
        let h = [
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
        ];
        let terrain = terrain_from_fn(2, 1.0, |x, y| {
            let (i, j) = (x.round() as usize, y.round() as usize);
            h[j * 2 + i]
        });
        let o = DVec3::new(
            rng.range(-1.0, 2.0),
            rng.range(-1.0, 2.0),
            rng.range(-6.0, 8.0),
        );
        let target = DVec3::new(
            rng.range(0.0, 1.0),
            rng.range(0.0, 1.0),
            rng.range(-5.0, 5.0),
        );
        let d = (target - o).normalize();
        let exact = cpu::cast_ray(&terrain, o, d, 0.0, f64::INFINITY).map(|hit| hit.t);
        // Brute force: dense sign search of z - h(x, y) over the cell, then bisection.
        let r = GridRay {
            o,
            d,
            curv: relief::terrain::curved::GridCurvature::FLAT,
        };
        let f = |t: f64| {
            let p = r.at(t);
            terrain.height_at_grid(p.x, p.y).map(|hh| p.z - hh)
        };
        let Some((t0, t1)) = relief::cpu::traverse::clip_to_box(&terrain, &r, 0.0, f64::INFINITY)
        else {
            assert!(exact.is_none(), "case {case}: hit outside the box");
            continue;
        };
        let n = 4000;
        let mut brute = None;
        let mut prev = t0;
        if f(t0).is_some_and(|v| v <= 0.0) {
            brute = Some(t0);
        } else {
            for k in 1..=n {
                let t = t0 + (t1 - t0) * k as f64 / n as f64;
                if f(t).is_some_and(|v| v <= 0.0) {
                    let (mut lo, mut hi) = (prev, t);
                    for _ in 0..100 {
                        let m = 0.5 * (lo + hi);
                        if f(m).is_some_and(|v| v <= 0.0) {
                            hi = m
                        } else {
                            lo = m
                        }
                    }
                    brute = Some(hi);
                    break;
                }
                prev = t;
            }
        }
        match (exact, brute) {
            (Some(a), Some(b)) => assert!(
                (a - b).abs() <= 1e-7 * (1.0 + b),
                "case {case}: exact {a} vs brute force {b}"
            ),
            (None, Some(b)) => panic!("case {case}: exact intersection missed the root at {b}"),
            (Some(a), None) => {
                // Only a tangent touch can slip between the brute-force samples.
                let v = f(a).unwrap_or(f64::INFINITY).abs();
                assert!(
                    v < 1e-6,
                    "case {case}: exact hit at {a} is not on the surface (residual {v})"
                );
                tangents += 1;
            }
            (None, None) => {}
        }
    }
    assert!(
        tangents < 100,
        "{tangents} hits were not confirmed by brute force"
    );
}

fn load_alps() -> Terrain {
    let field = relief::terrain::hgt::load(&terrains().join("N47E009.hgt")).unwrap();
    let frame = TerrainFrame {
        origin: DVec3::ZERO,
        axis_x: DVec3::X,
        axis_y: DVec3::Y,
        normal: DVec3::Z,
        spacing: field.spacing,
    };
    Terrain::new(field, frame, 1.0).unwrap()
}

#[test]
fn pyramid_traversal_never_misses_on_the_real_dem() {
    let terrain = load_alps();
    let ext = [
        1200.0 * terrain.field.spacing[0],
        1200.0 * terrain.field.spacing[1],
    ];
    let mut rng = Rng::new(42);
    let rays: Vec<(DVec3, DVec3)> = (0..100_000)
        .map(|_| {
            let (x, y) = (rng.range(0.0, ext[0]), rng.range(0.0, ext[1]));
            let ground = cpu::terrain_point_below(&terrain, DVec3::new(x, y, 0.0)).unwrap();
            let o = DVec3::new(x, y, ground.z + rng.range(5.0, 2500.0));
            let (az, el) = (
                rng.range(0.0, std::f64::consts::TAU),
                rng.range(-40f64.to_radians(), 4f64.to_radians()),
            );
            (
                o,
                DVec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin()),
            )
        })
        .collect();
    let t_max = 20_000.0;
    let results: Vec<(Option<f64>, Option<f64>)> = rays
        .par_iter()
        .map(|&(o, d)| {
            (
                cpu::cast_ray(&terrain, o, d, 0.0, t_max).map(|h| h.t),
                march(&terrain, o, d, t_max, 0.1),
            )
        })
        .collect();
    let (mut hits, mut earlier) = (0, 0);
    for (k, (&(o, d), &(pyr, dense))) in rays.iter().zip(&results).enumerate() {
        match (pyr, dense) {
            (Some(a), Some(b)) => {
                if (a - b).abs() > 1e-5 * b {
                    // The pyramid may find a thin crossing the march stepped over: then it is
                    // earlier and on the surface.
                    let p = o + d * a;
                    let res = cpu::height_above_terrain(&terrain, p).unwrap().abs();
                    assert!(
                        a < b && res < 1e-3,
                        "ray {k}: pyramid t = {a}, march t = {b}, residual {res}"
                    );
                    earlier += 1;
                }
                hits += 1;
            }
            (None, Some(b)) => {
                panic!("ray {k} ({o}, {d}): the pyramid traversal missed a hit at t = {b}")
            }
            (Some(a), None) => {
                let res = cpu::height_above_terrain(&terrain, o + d * a)
                    .unwrap()
                    .abs();
                assert!(
                    res < 1e-3,
                    "ray {k}: pyramid hit at {a} is off the surface by {res}"
                );
                earlier += 1;
            }
            (None, None) => {}
        }
    }
    assert!(
        hits > 30_000,
        "only {hits} of 100000 rays hit: the test does not exercise the traversal"
    );
    assert!(earlier < 200, "{earlier} rays disagree with dense marching");
}

#[test]
fn pyramid_is_conservative_for_odd_sizes_and_real_data() {
    let mut rng = Rng::new(3);
    let noise: Vec<f64> = (0..38 * 38).map(|_| rng.range(0.0, 100.0)).collect();
    let odd = terrain_from_fn(38, 5.0, |x, y| {
        noise[(y / 5.0).round() as usize * 38 + (x / 5.0).round() as usize]
    });
    for terrain in [odd, load_alps()] {
        let pyr = &terrain.pyramid;
        let [cw, ch] = terrain.cells();
        for j in 0..ch {
            for i in 0..cw {
                let f = &terrain.field;
                let m = f
                    .at(i, j)
                    .max(f.at(i + 1, j))
                    .max(f.at(i, j + 1))
                    .max(f.at(i + 1, j + 1));
                assert_eq!(pyr.get(0, i as i64, j as i64), m);
            }
        }
        for l in 1..pyr.levels.len() {
            let lv = pyr.levels[l];
            for j in 0..lv.cells[1] as i64 {
                for i in 0..lv.cells[0] as i64 {
                    let kids = (0..4)
                        .map(|k| pyr.get(l - 1, 2 * i + (k & 1), 2 * j + (k >> 1)))
                        .fold(f32::MIN, f32::max);
                    assert_eq!(pyr.get(l, i, j), kids, "level {l} cell ({i}, {j})");
                }
            }
        }
        assert_eq!(pyr.levels.last().unwrap().cells, [1, 1]);
        assert_eq!(pyr.get(pyr.top(), 0, 0), terrain.max_height);
    }
}

#[test]
fn queries_height_line_of_sight_and_stats() {
    let terrain = terrain_from_fn(65, 10.0, |x, _| {
        if (300.0..=340.0).contains(&x) {
            200.0
        } else {
            0.0
        }
    });
    // A 200 m wall at x = 300..340 m.
    assert_eq!(
        cpu::height_above_terrain(&terrain, DVec3::new(100.0, 100.0, 50.0)),
        Some(50.0)
    );
    let top = cpu::terrain_point_below(&terrain, DVec3::new(320.0, 300.0, 0.0)).unwrap();
    assert!((top.z - 200.0).abs() < 1e-9);
    assert!(cpu::terrain_point_below(&terrain, DVec3::new(-5.0, 10.0, 0.0)).is_none());
    let (a, b) = (
        DVec3::new(100.0, 300.0, 20.0),
        DVec3::new(500.0, 300.0, 20.0),
    );
    assert!(
        !cpu::line_of_sight(&terrain, a, b),
        "the wall blocks the view"
    );
    assert!(cpu::line_of_sight(
        &terrain,
        a + DVec3::Z * 300.0,
        b + DVec3::Z * 300.0
    ));
    let r = GridRay::from_world(&terrain, a, (b - a).normalize());
    let mut stats = TraversalStats::default();
    let (t, cell) = intersect(&terrain, &r, 0.0, 1e9, 10_000, &mut stats).unwrap();
    assert!(
        (t - 191.0).abs() < 1e-9,
        "the wall ramps from 0 to 200 m over x = 290..300, so z = 20 is met at x = 291: t = {t}"
    );
    assert_eq!(cell[0], 29);
    assert!(stats.steps > 0 && stats.patch_tests > 0 && !stats.exhausted);
    // Sun visibility: behind the wall (west side, sun in the east, low) is shadowed.
    let sun = DVec3::new(1.0, 0.0, 0.2).normalize();
    assert!(!cpu::sun_visible(
        &terrain,
        DVec3::new(250.0, 300.0, 0.0),
        DVec3::Z,
        sun
    ));
    assert!(cpu::sun_visible(
        &terrain,
        DVec3::new(450.0, 300.0, 0.0),
        DVec3::Z,
        sun
    ));
}
