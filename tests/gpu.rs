//! GPU output against the CPU oracle and analytic truth (software adapter in CI).
//! Without an adapter these tests fail, unless RELIEF_SKIP_GPU_TESTS=1 (then they say so).

mod common;

use common::{
    gpu, gpu_lock, save_failure_image, save_failure_mask, settings, synthetic_scene,
    terrain_from_fn, terrains,
};
use glam::DVec3;
use rayon::prelude::*;
use relief::cpu;
use relief::gpu::{FrameOutput, RenderSettings, TerrainRenderer, TraceMode};
use relief::scene::{Camera, Pose, Scene, SceneDesc};
use relief::terrain::Terrain;

fn render(
    terrain: &Terrain,
    desc: &SceneDesc,
    cam: &Camera,
    s: RenderSettings,
) -> Option<FrameOutput> {
    let g = gpu()?;
    let mut r = TerrainRenderer::new(g, terrain).expect("renderer");
    Some(r.capture(g, terrain, desc, cam, &s).expect("capture"))
}

fn alps() -> (Scene, Terrain) {
    let scene = Scene::load(&terrains().join("alps.toml")).unwrap();
    let terrain = scene.load_terrain().unwrap();
    (scene, terrain)
}

fn luminance(rgba: &[u8], k: usize) -> f64 {
    let p = &rgba[4 * k..4 * k + 3];
    0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64
}

/// Compares GPU depth with the f64 CPU traversal on every pixel; returns the disagreeing pixels.
/// Pixels whose GPU depth disagrees with the CPU oracle: (x, y, what).
fn compare_with_cpu(terrain: &Terrain, cam: &Camera, out: &FrameOutput) -> Vec<(u32, u32, String)> {
    let (w, h) = (out.width, out.height);
    let cpu_t: Vec<Option<f64>> = (0..w * h)
        .into_par_iter()
        .map(|k| {
            cpu::cast_ray(
                terrain,
                cam.pose.position,
                cam.pixel_ray(k % w, k / w),
                0.0,
                f64::INFINITY,
            )
            .map(|hit| hit.t)
        })
        .collect();
    let mut bad = Vec::new();
    for (k, c) in cpu_t.iter().enumerate() {
        let g = out.depth[k];
        let ok = match (c, g.is_finite()) {
            (Some(c), true) => ((g as f64 - c) / c).abs() <= 1e-3,
            (None, false) => true,
            _ => false,
        };
        if !ok {
            let (x, y) = (k as u32 % w, k as u32 / w);
            bad.push((x, y, format!("({x}, {y}): gpu {g} cpu {c:?}")));
        }
    }
    bad
}

#[test]
fn gpu_depth_matches_cpu_oracle_on_real_dem_from_three_viewpoints() {
    let _l = gpu_lock();
    let (scene, terrain) = alps();
    let views = [
        (
            "oblique",
            Pose {
                position: DVec3::new(22000.0, 52000.0, 2600.0),
                heading: 175.0,
                pitch: -7.0,
                roll: 0.0,
                fov: 60.0,
            },
        ),
        (
            "steep",
            Pose {
                position: DVec3::new(30000.0, 25000.0, 6000.0),
                heading: 40.0,
                pitch: -50.0,
                roll: 10.0,
                fov: 50.0,
            },
        ),
        (
            "grazing",
            Pose {
                position: DVec3::new(10000.0, 80000.0, 700.0),
                heading: 120.0,
                pitch: -0.5,
                roll: 0.0,
                fov: 70.0,
            },
        ),
    ];
    for (name, pose) in views {
        let cam = Camera::new(pose, 320, 240);
        let Some(out) = render(&terrain, &scene.desc, &cam, settings(false, true)) else {
            return;
        };
        let hits = out.depth.iter().filter(|d| d.is_finite()).count();
        assert!(
            hits > 320 * 240 / 10,
            "{name}: only {hits} terrain pixels; the view does not test much"
        );
        let bad = compare_with_cpu(&terrain, &cam, &out);
        let frac = 1.0 - bad.len() as f64 / (320.0 * 240.0);
        if frac < 0.995 {
            let p = save_failure_image(&format!("gpu-vs-cpu-{name}"), 320, 240, &out.rgba);
            let xy: Vec<(u32, u32)> = bad.iter().map(|b| (b.0, b.1)).collect();
            save_failure_mask(&format!("gpu-vs-cpu-{name}"), 320, 240, &xy);
            panic!(
                "{name}: {:.3}% of pixels agree (need 99.5%); image {} and -diff beside it; first disagreeing pixels:\n{}",
                frac * 100.0,
                p.display(),
                bad.iter().take(40).map(|b| b.2.clone()).collect::<Vec<_>>().join("\n")
            );
        }
        eprintln!(
            "{name}: {} of {} pixels disagree (silhouettes): {:?}",
            bad.len(),
            320 * 240,
            bad.iter().take(5).collect::<Vec<_>>()
        );
    }
}

#[test]
fn gpu_gives_exact_distances_on_flat_and_ramp_terrains() {
    let _l = gpu_lock();
    type Surface = fn(f64, f64) -> f64;
    let cases: [(&str, Surface); 2] = [
        ("flat", |_, _| 100.0),
        ("ramp", |x, y| 50.0 + 0.12 * x - 0.07 * y),
    ];
    for (name, f) in cases {
        let terrain = terrain_from_fn(257, 10.0, f);
        let desc = synthetic_scene(160, 120, "position = [300.0, 200.0, 600.0]");
        let cam = Camera::new(
            Pose {
                position: DVec3::new(300.0, 200.0, 600.0),
                heading: 30.0,
                pitch: -35.0,
                roll: 5.0,
                fov: 80.0,
            },
            160,
            120,
        );
        let Some(out) = render(&terrain, &desc, &cam, settings(true, true)) else {
            return;
        };
        let (a, b, c) = (
            f(0.0, 0.0),
            f(1.0, 0.0) - f(0.0, 0.0),
            f(0.0, 1.0) - f(0.0, 0.0),
        );
        let ext = 2560.0;
        let (mut checked, mut worst) = (0, 0.0f64);
        for k in 0..160 * 120u32 {
            let d = cam.pixel_ray(k % 160, k / 160);
            let o = cam.pose.position;
            let t = (a + b * o.x + c * o.y - o.z) / (d.z - b * d.x - c * d.y);
            let p = o + d * t;
            let g = out.depth[k as usize];
            if t > 0.0 && p.x > 5.0 && p.y > 5.0 && p.x < ext - 5.0 && p.y < ext - 5.0 {
                assert!(g.is_finite(), "{name}: pixel {k} is sky, expected t = {t}");
                let rel = ((g as f64 - t) / t).abs();
                worst = worst.max(rel);
                assert!(
                    rel < 1e-4,
                    "{name}: pixel {k}: gpu {g} exact {t} (relative error {rel:e})"
                );
                checked += 1;
            } else if t <= 0.0 || p.x < -5.0 || p.y < -5.0 || p.x > ext + 5.0 || p.y > ext + 5.0 {
                assert!(!g.is_finite(), "{name}: pixel {k} hit at {g}, expected sky");
            }
        }
        assert!(checked > 5000, "{name}: only {checked} pixels checked");
        eprintln!("{name}: {checked} pixels, worst relative error {worst:e}");
    }
}

#[test]
fn ridge_shadows_on_gpu_match_cpu_line_of_sight() {
    let _l = gpu_lock();
    let (mut scene, terrain) = alps();
    scene.desc.sun.azimuth = 110.0;
    scene.desc.sun.elevation = 8.0;
    // No haze: distant shadows would fade into it and the brightness test would measure fog.
    scene.desc.fog.visibility = 0.0;
    let sun = scene.desc.sun.direction();
    let cam = Camera::new(
        Pose {
            position: DVec3::new(26000.0, 12000.0, 3800.0),
            heading: 10.0,
            pitch: -20.0,
            roll: 0.0,
            fov: 60.0,
        },
        240,
        180,
    );
    let Some(lit) = render(&terrain, &scene.desc, &cam, settings(false, true)) else {
        return;
    };
    let Some(shad) = render(&terrain, &scene.desc, &cam, settings(true, true)) else {
        return;
    };
    let (w, h) = (240u32, 180u32);
    let classes: Vec<Option<bool>> = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let hit = cpu::cast_ray(
                &terrain,
                cam.pose.position,
                cam.pixel_ray(k % w, k / w),
                0.0,
                f64::INFINITY,
            )?;
            // Surfaces facing the sun clearly, so only cast shadows count.
            (hit.normal.dot(sun) > 0.3)
                .then(|| cpu::sun_visible(&terrain, hit.point, hit.normal, sun))
        })
        .collect();
    let (mut shadowed, mut dark, mut sunny, mut bright) = (0, 0, 0, 0);
    for (k, c) in classes.iter().enumerate() {
        match c {
            Some(false) => {
                shadowed += 1;
                if shad.flags[k] & 2 != 0
                    && luminance(&shad.rgba, k) < 0.75 * luminance(&lit.rgba, k)
                {
                    dark += 1;
                }
            }
            Some(true) => {
                sunny += 1;
                if shad.flags[k] & 2 == 0
                    && shad.rgba[4 * k..4 * k + 4] == lit.rgba[4 * k..4 * k + 4]
                {
                    bright += 1;
                }
            }
            None => {}
        }
    }
    eprintln!("shadowed {shadowed} (dark {dark}), sunny {sunny} (unchanged {bright})");
    assert!(
        shadowed > 200,
        "only {shadowed} pixels in cast shadow: the view does not test shadows"
    );
    assert!(sunny > 200, "only {sunny} sunlit pixels");
    if (dark as f64) < 0.97 * shadowed as f64 || (bright as f64) < 0.97 * sunny as f64 {
        let p = save_failure_image("shadows", w, h, &shad.rgba);
        panic!("{dark}/{shadowed} CPU-shadowed pixels are dark on the GPU, {bright}/{sunny} CPU-lit pixels are unchanged; image {}", p.display());
    }
}

#[test]
fn tile_prepass_changes_nothing_and_frames_are_deterministic() {
    let _l = gpu_lock();
    let (scene, terrain) = alps();
    let cam = scene.camera(0, &terrain);
    let cam = Camera::new(cam.pose, 256, 144);
    let Some(a) = render(&terrain, &scene.desc, &cam, settings(true, true)) else {
        return;
    };
    let Some(b) = render(&terrain, &scene.desc, &cam, settings(true, true)) else {
        return;
    };
    assert!(
        a.rgba == b.rgba
            && a.depth
                .iter()
                .zip(&b.depth)
                .all(|(x, y)| x.to_bits() == y.to_bits()),
        "two renders differ"
    );
    let Some(c) = render(&terrain, &scene.desc, &cam, settings(true, false)) else {
        return;
    };
    let differ = a
        .depth
        .iter()
        .zip(&c.depth)
        .filter(|(x, y)| {
            x.is_finite() != y.is_finite() || (x.is_finite() && ((*x - *y) / *y).abs() > 1e-4)
        })
        .count();
    assert!(
        differ <= 256 * 144 / 1000,
        "{differ} pixels change with the tile pre-pass"
    );
    let steps = |o: &FrameOutput| o.steps.iter().map(|&s| s as f64).sum::<f64>();
    assert!(
        steps(&a) < steps(&c),
        "the tile pre-pass should save traversal steps"
    );
}

#[test]
fn compute_and_fragment_ray_generation_give_the_same_frame() {
    let _l = gpu_lock();
    let Some(g) = gpu() else { return };
    let (scene, terrain) = alps();
    let cam = Camera::new(scene.camera(0, &terrain).pose, 200, 120);
    let mut frames = Vec::new();
    for k in [
        relief::gpu::KernelPath::Compute,
        relief::gpu::KernelPath::Fragment,
    ] {
        let mut r = TerrainRenderer::with_kernels(g, &terrain, k).expect("renderer");
        frames.push(
            r.capture(g, &terrain, &scene.desc, &cam, &settings(true, true))
                .expect("capture"),
        );
    }
    let differ = frames[0]
        .depth
        .iter()
        .zip(&frames[1].depth)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert!(
        differ <= 200 * 120 / 1000,
        "{differ} pixels differ between compute and fragment ray generation"
    );
    assert!(frames[0].depth.iter().any(|d| d.is_finite()));
}

#[test]
fn march_baseline_agrees_with_pyramid_on_most_pixels() {
    let _l = gpu_lock();
    let (scene, terrain) = alps();
    let cam = Camera::new(scene.camera(0, &terrain).pose, 160, 90);
    let march = RenderSettings {
        mode: TraceMode::March {
            step_cells: 0.5,
            bisections: 10,
        },
        shadows: false,
        tile_prepass: false,
        max_steps: 1 << 20,
        lod: None,
        antialias: relief::gpu::Antialias::OFF,
    };
    let Some(m) = render(&terrain, &scene.desc, &cam, march) else {
        return;
    };
    let bad = compare_with_cpu(&terrain, &cam, &m);
    assert!(
        bad.len() < 160 * 90 / 50,
        "march baseline disagrees on {} pixels",
        bad.len()
    );
    let mean_steps = m.steps.iter().map(|&s| s as f64).sum::<f64>() / (160.0 * 90.0);
    assert!(
        mean_steps > 20.0,
        "march took only {mean_steps} steps per ray: not a fixed-step march"
    );
}

#[test]
fn oversized_data_is_refused_with_the_limit_in_the_message() {
    let _l = gpu_lock();
    let Some(g) = gpu() else { return };
    let err =
        relief::gpu::check_buffer_limit(g, "height table", 1 << 40, "use a smaller height map")
            .unwrap_err()
            .to_string();
    assert!(
        err.contains("height table") && err.contains("allows"),
        "{err}"
    );
    let terrain = terrain_from_fn(9, 1.0, |_, _| 0.0);
    let desc = synthetic_scene(8, 8, "position = [1.0, 1.0, 5.0]");
    let cam = Camera::new(
        Pose {
            position: DVec3::new(1.0, 1.0, 5.0),
            heading: 0.0,
            pitch: -10.0,
            roll: 0.0,
            fov: 60.0,
        },
        100_000,
        8,
    );
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    let err = r
        .capture(g, &terrain, &desc, &cam, &settings(false, true))
        .unwrap_err()
        .to_string();
    assert!(err.contains("100000x8") && err.contains("limit"), "{err}");
}

#[test]
fn cli_bench_primary_prints_its_timing_as_json() {
    // The figure benches/embree_compare.py alternates with Embree's.
    let _l = gpu_lock();
    if gpu().is_none() {
        return;
    }
    let run = |extra: &[&str]| {
        let alps = terrains().join("alps.toml");
        let mut args = vec!["bench", "primary", alps.to_str().unwrap()];
        args.extend(["--size", "96x64", "--frames", "2"]);
        args.extend(extra);
        common::relief_cli(&args, &[])
    };
    let out = run(&["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(96), Some(64))
    );
    let ms = v["details"]["primary_ms"].as_f64().unwrap();
    let rps = v["details"]["rays_per_second"].as_f64().unwrap();
    assert!(
        ms > 0.0 && (rps * ms * 1e-3 - 96.0 * 64.0).abs() < 1e-6 * rps,
        "{v}"
    );
    // It times the primary rays only: the other measurements are refused with it.
    let clash = run(&["--freeforms"]);
    assert!(!clash.status.success());
    assert!(String::from_utf8_lossy(&clash.stderr).contains("--freeforms"));
}

#[test]
fn cli_render_writes_png_depth_and_metadata_that_recreate_the_rays() {
    let _l = gpu_lock();
    if gpu().is_none() {
        return;
    }
    let out = common::temp_dir("cli-render");
    let scene = terrains().join("alps.toml");
    let status = common::relief_command(
        &[
            "render",
            scene.to_str().unwrap(),
            "--size",
            "96x64",
            "--frames",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    )
    .status()
    .unwrap();
    assert!(status.success());
    let (_, terrain) = alps();
    for f in 0..2 {
        let png = image::open(out.join(format!("frame_{f:04}.png"))).unwrap();
        assert_eq!((png.width(), png.height()), (96, 64));
        let (w, h, depth) =
            relief::app::output::read_depth_tiff(&out.join(format!("depth_{f:04}.tiff"))).unwrap();
        assert_eq!((w, h), (96, 64));
        let meta: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join(format!("frame_{f:04}.json"))).unwrap(),
        )
        .unwrap();
        // Re-create each pixel's ray from the metadata alone, as an outside tool would.
        let m = &meta["camera"]["world_from_camera"];
        let row = |r: usize| {
            DVec3::new(
                m[r][0].as_f64().unwrap(),
                m[r][1].as_f64().unwrap(),
                m[r][2].as_f64().unwrap(),
            )
        };
        let origin = DVec3::new(
            m[0][3].as_f64().unwrap(),
            m[1][3].as_f64().unwrap(),
            m[2][3].as_f64().unwrap(),
        );
        let k = &meta["camera"]["intrinsics"];
        let (fx, fy, cx, cy) = (
            k["fx"].as_f64().unwrap(),
            k["fy"].as_f64().unwrap(),
            k["cx"].as_f64().unwrap(),
            k["cy"].as_f64().unwrap(),
        );
        let mut checked = 0;
        for y in (0..64).step_by(7) {
            for x in (0..96).step_by(7) {
                let c = DVec3::new((x as f64 + 0.5 - cx) / fx, (y as f64 + 0.5 - cy) / fy, 1.0);
                let d = DVec3::new(row(0).dot(c), row(1).dot(c), row(2).dot(c)).normalize();
                let cpu_t = cpu::cast_ray(&terrain, origin, d, 0.0, f64::INFINITY).map(|hit| hit.t);
                let g = depth[(y * 96 + x) as usize];
                match cpu_t {
                    Some(t) => assert!(
                        ((g as f64 - t) / t).abs() < 1e-3,
                        "frame {f} pixel ({x}, {y}): file {g}, recreated ray {t}"
                    ),
                    None => assert!(
                        g == f32::INFINITY,
                        "frame {f} pixel ({x}, {y}): file {g}, recreated ray misses"
                    ),
                }
                checked += 1;
            }
        }
        assert!(checked > 100);
        assert!(meta["adapter"]["name"]
            .as_str()
            .is_some_and(|s| !s.is_empty()));
        assert!(meta["primary_rays_per_second"].as_f64().unwrap() > 0.0);
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// Dusk and night (`scene::daylight`): the GPU's sky at every sky pixel is the analytic sky of
/// the daylight the sun's elevation gives (gradient from the horizon to the zenith, the sun's
/// glow), within one 8-bit level, from full day (30°) through sunset (1°) to night (−8°, −20°);
/// the sunlit ground under it only darkens as the sun sinks; a full moon at night lights it
/// again (the sky then has the moon's glow).
#[test]
fn the_sky_and_the_ground_follow_the_sun_into_night() {
    let _l = gpu_lock();
    let terrain = terrain_from_fn(129, 10.0, |x, y| 100.0 + 0.05 * x + 0.03 * y);
    let position = DVec3::new(640.0, 300.0, 400.0);
    let cam = Camera::new(
        Pose {
            position,
            heading: 20.0,
            pitch: 5.0,
            roll: 0.0,
            fov: 80.0,
        },
        160,
        120,
    );
    let mut ground_before = f64::INFINITY;
    let moon = relief::scene::Moon {
        azimuth: 35.0,
        elevation: 25.0,
        illuminated: 1.0,
    };
    let cases = [30.0, 5.0, 1.0, -3.0, -8.0, -20.0].map(|e| (e, None));
    for (elevation, moon) in cases.into_iter().chain([(-20.0, Some(moon))]) {
        let mut desc = synthetic_scene(160, 120, "position = [640.0, 300.0, 400.0]");
        desc.sun.azimuth = 30.0;
        desc.sun.elevation = elevation;
        desc.moon = moon;
        let Some(out) = render(&terrain, &desc, &cam, settings(true, true)) else {
            return;
        };
        let day = desc.daylight();
        assert_eq!(day.moonlit, moon.is_some());
        let (mut sky, mut worst, mut ground) = (0, 0i32, Vec::new());
        for k in 0..160 * 120usize {
            let px = &out.rgba[4 * k..4 * k + 3];
            if out.depth[k].is_finite() {
                ground.push(luminance(&out.rgba, k));
                continue;
            }
            let c = common::daylight_sky(&day, cam.pixel_ray(k as u32 % 160, k as u32 / 160));
            let want = [c.x, c.y, c.z].map(relief::colour::linear_to_srgb8);
            let off = (0..3)
                .map(|i| (i32::from(px[i]) - i32::from(want[i])).abs())
                .max()
                .unwrap();
            assert!(
                off <= 1,
                "sun at {elevation}°: sky pixel {k} is {px:?}, the daylight's sky {want:?}"
            );
            worst = worst.max(off);
            sky += 1;
        }
        let mean = ground.iter().sum::<f64>() / ground.len().max(1) as f64;
        eprintln!(
            "sun at {elevation}°{}: {sky} sky pixels within {worst} of the daylight's sky, ground luminance {mean:.1}",
            if moon.is_some() { ", a full moon 25° up" } else { "" }
        );
        assert!(
            sky > 3000 && ground.len() > 3000,
            "{sky} sky, {} ground",
            ground.len()
        );
        if moon.is_some() {
            assert!(
                mean > 3.0 * ground_before,
                "moonlight: {mean} against {ground_before}"
            );
        } else {
            assert!(
                mean < ground_before,
                "the ground brightened as the sun sank: {mean}"
            );
            ground_before = mean;
        }
    }
}
