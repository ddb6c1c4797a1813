//! Curved-screen distortion tables: CPU reference against closed-form geometry, the GPU table
//! against the CPU table, and direct-mode renders against the CPU oracle.

mod common;

use common::{gpu, gpu_lock, project_dir, terrains};
use glam::DVec3;
use relief::cpu::distortion::{ray_table, world_from_display};
use relief::display::screen_points::screen_points;
use relief::display::{DisplayConfig, Lens, Projector, Screen};
use relief::geom::attitude_basis;
use relief::gpu::{RenderSettings, TerrainRenderer, TraceMode};
use relief::scene::{Camera, Scene};

const ARCMIN: f64 = std::f64::consts::PI / (180.0 * 60.0);

fn configs() -> Vec<(String, DisplayConfig)> {
    let mut v: Vec<_> = std::fs::read_dir(project_dir().join("distortion"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                DisplayConfig::load(&p).unwrap(),
            )
        })
        .collect();
    v.sort_by(|a, b| a.0.cmp(&b.0));
    assert!(v.len() >= 3, "demo display configs missing");
    v
}

#[test]
fn ftheta_projector_at_dome_centre_gives_the_ftheta_mapping() {
    let screen = Screen::Dome {
        centre: [0.0; 3],
        radius: 3.0,
        min_elevation: -90.0,
    };
    let p = Projector {
        position: [0.0; 3],
        heading: 0.0,
        pitch: 90.0,
        roll: 0.0,
        width: 96,
        height: 96,
        lens: Lens::Ftheta { fov: 180.0 },
        distortion: None,
    };
    let table = ray_table(
        &screen_points(&screen, &p),
        DVec3::ZERO,
        world_from_display(0.0, 0.0, 0.0),
    );
    let (mut worst, mut n) = (0.0f64, 0);
    for y in 0..96 {
        for x in 0..96 {
            let (du, dv) = (x as f64 + 0.5 - 48.0, y as f64 + 0.5 - 48.0);
            let r = (du * du + dv * dv).sqrt();
            let ray = table.rays[y * 96 + x];
            if r > 48.0 {
                assert!(
                    ray.is_none(),
                    "pixel ({x}, {y}) outside the fisheye circle is lit"
                );
                continue;
            }
            // Looking up, image right is display +x and image down is display +y.
            let theta = r / 48.0 * std::f64::consts::FRAC_PI_2;
            let want = DVec3::new(theta.sin() * du / r, theta.sin() * dv / r, theta.cos());
            let (d, _) =
                ray.unwrap_or_else(|| panic!("pixel ({x}, {y}) inside the circle is black"));
            worst = worst.max(d.angle_between(want));
            n += 1;
        }
    }
    assert!(n > 7000);
    assert!(
        worst < 0.1 * ARCMIN,
        "worst f-theta error {} arc-min",
        worst / ARCMIN
    );
}

#[test]
fn off_centre_eye_on_a_cylinder_matches_closed_form_geometry() {
    let (radius, bottom, top) = (3.0, -1.2, 1.4);
    let screen = Screen::Cylinder {
        centre: [0.0; 3],
        radius,
        bottom,
        top,
    };
    let p = Projector {
        position: [0.1, -0.4, 0.9],
        heading: 25.0,
        pitch: -6.0,
        roll: 2.0,
        width: 64,
        height: 40,
        lens: Lens::Perspective {
            fov: 64.0,
            shift: [0.05, -0.02],
        },
        distortion: None,
    };
    let eye = DVec3::new(0.3, -0.2, 0.1);
    let (heading, pitch, roll) = (140.0, -3.0, 4.0);
    let table = ray_table(
        &screen_points(&screen, &p),
        eye,
        world_from_display(heading, pitch, roll),
    );
    let (right, down, fwd) = attitude_basis(p.heading, p.pitch, p.roll);
    let (vr, vd, vf) = attitude_basis(heading, pitch, roll);
    let f = 0.5 * 64.0 / 32f64.to_radians().tan();
    let mut checked = 0;
    for y in 0..40 {
        for x in 0..64 {
            let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
            let c = DVec3::new(
                (u - 32.0 - 0.05 * 64.0) / f,
                (v - 20.0 + 0.02 * 40.0) / f,
                1.0,
            )
            .normalize();
            let d = right * c.x + down * c.y + fwd * c.z;
            // |o.xy + t d.xy| = R, larger root.
            let o = DVec3::from(p.position);
            let (a, b, cc) = (
                d.x * d.x + d.y * d.y,
                2.0 * (o.x * d.x + o.y * d.y),
                o.x * o.x + o.y * o.y - radius * radius,
            );
            let t = (-b + (b * b - 4.0 * a * cc).sqrt()) / (2.0 * a);
            let hit = o + d * t;
            let ray = table.rays[y * 64 + x];
            if hit.z < bottom || hit.z > top {
                assert!(
                    ray.is_none(),
                    "pixel ({x}, {y}) misses the cylinder but is lit"
                );
                continue;
            }
            let e = (hit - eye).normalize();
            let want = vr * e.x + vf * e.y - vd * e.z;
            let (got, cone) = ray.unwrap();
            assert!(
                got.angle_between(want) < 1e-3 * ARCMIN,
                "pixel ({x}, {y}): {}",
                got.angle_between(want) / ARCMIN
            );
            assert!(cone > 0.0 && cone < 0.02, "pixel ({x}, {y}) cone {cone}");
            checked += 1;
        }
    }
    assert!(checked > 1500, "only {checked} pixels on the screen");
}

#[test]
fn demo_configs_load_and_bad_configs_are_refused() {
    for (name, cfg) in configs() {
        for c in &cfg.channels {
            let pts = screen_points(&cfg.screen, &c.projector);
            let lit = pts.points.iter().filter(|p| p.is_some()).count();
            assert!(
                lit > pts.points.len() / 3,
                "{name} channel {}: only {lit} pixels reach the screen",
                c.name
            );
        }
    }
    let dir = common::temp_dir("display");
    let good = std::fs::read_to_string(project_dir().join("distortion/dome-fisheye.toml")).unwrap();
    for (label, text, want) in [
        (
            "unknown key",
            good.replace("min_elevation", "min_elevashun"),
            "min_elevashun",
        ),
        (
            "zero radius",
            good.replace("radius = 3.0", "radius = 0.0"),
            "screen.radius",
        ),
        (
            "no channel",
            good[..good.find("[[channel]]").unwrap()].to_string(),
            "channel",
        ),
        (
            "bad fov",
            good.replace("fov = 180.0", "fov = 0.0"),
            "lens.fov",
        ),
        (
            "nan",
            good.replace(
                "position = [0.0, 0.0, 0.0]\n\n[[channel]]",
                "position = [nan, 0.0, 0.0]\n\n[[channel]]",
            ),
            "eye.position",
        ),
    ] {
        let p = dir.join("bad.toml");
        std::fs::write(&p, text).unwrap();
        let err = DisplayConfig::load(&p).expect_err(label).to_string();
        assert!(
            err.contains(want) && err.contains("bad.toml"),
            "{label}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn gpu_table_matches_cpu_table_and_direct_renders_match_the_oracle() {
    let _l = gpu_lock();
    let Some(g) = gpu() else { return };
    let scene = Scene::load(&terrains().join("alps.toml")).unwrap();
    let terrain = scene.load_terrain().unwrap();
    let pose = scene.camera(0, &terrain).pose;
    let settings = RenderSettings {
        mode: TraceMode::Pyramid,
        shadows: false,
        tile_prepass: true,
        max_steps: 4096,
        lod: None,
        antialias: relief::gpu::Antialias::OFF,
    };
    for (name, cfg) in configs() {
        for (ci, ch) in cfg.channels.iter().enumerate() {
            // Small projectors keep the test quick; the geometry is the same.
            let mut p = ch.projector;
            p.width /= 4;
            p.height /= 4;
            let pts = screen_points(&cfg.screen, &p);
            let mut r = TerrainRenderer::new(g, &terrain).unwrap();
            // The eye moves between frames: each frame's table must follow it.
            for (frame, dz) in [0.0, 0.3].iter().enumerate() {
                let eye = DVec3::from(cfg.eye.position) + DVec3::new(0.0, 0.0, *dz);
                if frame == 0 {
                    r.set_display(g, &pts, eye).unwrap();
                } else {
                    r.set_eye(eye);
                }
                let cam = Camera::new(pose, p.width, p.height);
                let out = r
                    .capture(g, &terrain, &scene.desc, &cam, &settings)
                    .unwrap();
                let gpu_rays = r.read_ray_table(g).unwrap();
                let m = world_from_display(pose.heading, pose.pitch, pose.roll);
                let cpu = ray_table(&pts, eye, m);
                let (mut worst, mut bad) = (0.0f64, 0usize);
                for (k, (c, gr)) in cpu.rays.iter().zip(&gpu_rays).enumerate() {
                    match c {
                        None => {
                            assert!(
                                gr[3] < 0.0,
                                "{name}[{ci}] pixel {k}: black on the CPU, lit on the GPU"
                            );
                            assert_eq!(
                                out.flags[k] & 8,
                                8,
                                "{name}[{ci}] pixel {k} should render black"
                            );
                        }
                        Some((d, _)) => {
                            let gd = DVec3::new(gr[0] as f64, gr[1] as f64, gr[2] as f64);
                            worst = worst.max(gd.angle_between(*d));
                            let t = relief::cpu::cast_ray(
                                &terrain,
                                pose.position,
                                *d,
                                0.0,
                                f64::INFINITY,
                            )
                            .map(|h| h.t);
                            let g = out.depth[k];
                            let ok = match t {
                                Some(t) => g.is_finite() && ((g as f64 - t) / t).abs() < 1e-3,
                                None => !g.is_finite(),
                            };
                            bad += usize::from(!ok);
                        }
                    }
                }
                assert!(
                    worst < 0.5 * ARCMIN,
                    "{name}[{ci}] frame {frame}: GPU table off by {} arc-min",
                    worst / ARCMIN
                );
                let lit = cpu.rays.iter().filter(|r| r.is_some()).count();
                assert!(bad * 200 <= lit, "{name}[{ci}] frame {frame}: {bad} of {lit} pixels disagree with the CPU oracle");
            }
        }
    }
}

#[test]
fn blend_ramps_of_an_overlap_add_up_to_full_light_and_bad_blends_are_refused() {
    use relief::display::blend::{ramp, Blend, BlendEdge};
    let mut rng = common::Rng::new(7);
    for _ in 0..10_000 {
        let (x, p) = (rng.range(-0.2, 1.2), rng.range(0.5, 10.0));
        let s = ramp(x, p) + ramp(1.0 - x, p);
        assert!(
            (s - 1.0).abs() < 1e-12,
            "f({x}) + f(1 - {x}) = {s} for p = {p}"
        );
    }
    let edge = BlendEdge {
        width: 0.1,
        exponent: 2.0,
    };
    let b = Blend {
        left: Some(edge),
        right: None,
        top: None,
        bottom: Some(edge),
        gamma: 2.2,
        auto: false,
        auto_exponent: 2.0,
    };
    // Full light away from the edges, none at the border, half light mid-ramp.
    assert_eq!(b.light_weight(50, 10, 100, 100), 1.0);
    assert!(b.light_weight(0, 10, 100, 100) < 0.01);
    assert!((b.light_weight(4, 10, 1000, 100) * 1.0 - ramp(4.5 / 100.0, 2.0)).abs() < 1e-12);
    assert!(
        (b.pixel_factor(4, 10, 1000, 100, 1.0) - ramp(4.5 / 100.0, 2.0).powf(1.0 / 2.2)).abs()
            < 1e-12
    );
    for (bad, field) in [
        (
            Blend {
                left: Some(BlendEdge {
                    width: 0.7,
                    exponent: 2.0,
                }),
                ..b
            },
            "left.width",
        ),
        (
            Blend {
                top: Some(BlendEdge {
                    width: 0.1,
                    exponent: f64::NAN,
                }),
                ..b
            },
            "top.exponent",
        ),
        (Blend { gamma: 0.3, ..b }, "gamma"),
        (
            Blend {
                auto_exponent: 0.0,
                ..b
            },
            "auto_exponent",
        ),
    ] {
        let e = bad.validate("channel[0].blend").unwrap_err().to_string();
        assert!(e.contains(field) && e.contains("channel[0].blend"), "{e}");
    }
}

#[test]
fn gpu_edge_blend_matches_the_cpu_factor_in_direct_mode() {
    use relief::display::blend::ChannelBlend;
    use relief::display::pattern::PatternParams;
    let _l = common::gpu_lock();
    let cfg = DisplayConfig::load(&project_dir().join("distortion/cylinder-3ch.toml")).unwrap();
    // Geometric weights of the centre channel: complementary to its neighbours' weights.
    let cb = ChannelBlend::new(&cfg, 1).expect("the centre channel blends");
    let mask = cb.mask.clone().expect("an auto blend has a mask");
    let (w, h) = (cb.width, cb.height);
    let pts = screen_points(&cfg.screen, &cfg.channels[1].projector);
    let mut pairs = 0;
    for k in (0..mask.len()).step_by(7) {
        let Some(s) = pts.points[k] else { continue };
        let mut sum = mask[k] as f64;
        let mut others = 0;
        for j in [0usize, 2] {
            let q = cfg.channels[j].projector;
            if let Some((u, v)) =
                relief::display::screen_points::projector_coord(&cfg.screen, &q, s)
            {
                if relief::display::blend::border_margin(u, v, q.width, q.height).is_some() {
                    let others_of_j = cfg
                        .channels
                        .iter()
                        .enumerate()
                        .filter(|(i, _)| *i != j)
                        .map(|(_, c)| &c.projector);
                    sum += relief::display::blend::geometric_weight(
                        &cfg.screen,
                        &q,
                        (u, v),
                        s,
                        others_of_j,
                        2.0,
                    );
                    others += 1;
                }
            }
        }
        if others > 0 {
            pairs += 1;
            // The centre pixel's weight is taken at its centre, the neighbours' at the exact
            // point: they agree to the weight's change over half a pixel.
            assert!((sum - 1.0).abs() < 0.05, "pixel {k}: weights sum to {sum}");
        }
    }
    assert!(pairs > 100, "only {pairs} overlap pixels checked");
    let Some(g) = common::gpu() else {
        return;
    };
    let terrain = common::terrain_from_fn(2, 1.0, |_, _| 0.0);
    let desc = common::synthetic_scene(w, h, "position = [0.5, 0.5, 100.0]");
    let cam = Camera::new(
        relief::scene::Pose {
            position: DVec3::new(0.5, 0.5, 100.0),
            heading: 0.0,
            pitch: 0.0,
            roll: 0.0,
            fov: 60.0,
        },
        w,
        h,
    );
    let settings = RenderSettings::from_scene(&desc);
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    r.set_display(g, &pts, DVec3::from(cfg.eye.position))
        .unwrap();
    r.set_pattern(g, Some(PatternParams::grid(DVec3::Y)));
    let plain = r.capture(g, &terrain, &desc, &cam, &settings).unwrap();
    r.set_blend(g, Some(&cb)).unwrap();
    let blended = r.capture(g, &terrain, &desc, &cam, &settings).unwrap();
    let mut want = plain.rgba.clone();
    cb.apply_rgba8(&mut want);
    let worst = want
        .iter()
        .zip(&blended.rgba)
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap();
    let darkened = (0..want.len() / 4)
        .filter(|&k| (0..3).any(|c| blended.rgba[4 * k + c] < plain.rgba[4 * k + c]))
        .count();
    let ramp_px = mask.iter().filter(|&&m| m > 0.0 && m < 1.0).count();
    eprintln!("{darkened} pixels darkened by the blend ({ramp_px} with partial weight); worst |GPU − CPU| {worst}/255");
    assert!(
        worst <= 1,
        "GPU blend differs from the CPU factor by {worst}/255"
    );
    assert!(
        darkened > ramp_px / 4,
        "only {darkened} of {ramp_px} blended pixels darkened"
    );
    // Where the centre projector is alone nothing changes.
    for (k, m) in mask.iter().enumerate() {
        if *m == 1.0 {
            assert_eq!(
                &blended.rgba[4 * k..4 * k + 3],
                &plain.rgba[4 * k..4 * k + 3],
                "pixel {k} changed"
            );
        }
    }
}

#[test]
fn a_channel_view_offset_turns_the_gpu_table_as_the_cpu_reference_does() {
    let _l = gpu_lock();
    let cfg = DisplayConfig::load(&project_dir().join("distortion/cylinder-3ch.toml")).unwrap();
    let mut p = cfg.channels[1].projector;
    p.width /= 4;
    p.height /= 4;
    let points = screen_points(&cfg.screen, &p);
    let eye = DVec3::from(cfg.eye.position);
    let offset = relief::display::ViewOffset {
        heading: 25.0,
        pitch: -4.0,
        roll: 3.0,
    };
    let Some(g) = gpu() else {
        return;
    };
    let terrain = common::terrain_from_fn(2, 1.0, |_, _| 0.0);
    let desc = common::synthetic_scene(p.width, p.height, "position = [0.5, 0.5, 100.0]");
    let pose = relief::scene::Pose {
        position: DVec3::new(0.5, 0.5, 100.0),
        heading: 30.0,
        pitch: 5.0,
        roll: -10.0,
        fov: 60.0,
    };
    let cam = Camera::new(pose, p.width, p.height);
    let settings = RenderSettings::from_scene(&desc);
    let mut r = TerrainRenderer::new(g, &terrain).unwrap();
    r.set_display(g, &points, eye).unwrap();
    r.set_pattern(
        g,
        Some(relief::display::pattern::PatternParams::grid(DVec3::Y)),
    );
    r.set_view_offset(offset.matrix());
    r.capture(g, &terrain, &desc, &cam, &settings).unwrap();
    let gpu_table = r.read_ray_table(g).unwrap();
    let w = world_from_display(pose.heading, pose.pitch, pose.roll);
    let with = ray_table(&points, eye, w * offset.matrix());
    let without = ray_table(&points, eye, w);
    let (mut worst, mut turned, mut n) = (0.0f64, f64::INFINITY, 0);
    for (k, e) in gpu_table.iter().enumerate() {
        let (Some((d, _)), Some((d0, _))) = (with.rays[k], without.rays[k]) else {
            assert!(e[3] < 0.0, "pixel {k} shows a screen only on the GPU");
            continue;
        };
        let gd = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64);
        worst = worst.max(gd.angle_between(d).to_degrees() * 60.0);
        turned = turned.min(gd.angle_between(d0).to_degrees());
        n += 1;
    }
    eprintln!(
        "{n} rays: GPU vs CPU with the offset {worst:.4} arc-min; every ray turned ≥ {turned:.2}°"
    );
    assert!(n > 1000);
    assert!(
        worst < 0.5,
        "GPU table with a view offset is {worst} arc-min off the CPU"
    );
    assert!(
        turned > 5.0,
        "the offset did not turn the table (min {turned}°)"
    );
}

#[test]
fn measured_lens_distortion_moves_the_screen_points_and_folding_models_are_refused() {
    let cfg = DisplayConfig::load(&project_dir().join("distortion/dome-5proj.toml")).unwrap();
    let p = cfg.channels[0].projector;
    let d = p.distortion.expect("the front channel has a measured lens");
    let ideal = Projector {
        distortion: None,
        ..p
    };
    let (a, b) = (
        screen_points(&cfg.screen, &p),
        screen_points(&cfg.screen, &ideal),
    );
    // Corner pixel: barrel distortion pulls the imaged corner inwards, so the real pixel there
    // sees further out than the ideal lens says.
    let k = 0;
    let (pa, pb) = (a.points[k].unwrap(), b.points[k].unwrap());
    let eye = DVec3::from(cfg.eye.position);
    let moved = (pa - eye).angle_between(pb - eye).to_degrees();
    eprintln!("corner ray moved {moved:.3}° by {d:?}");
    assert!(moved > 0.5, "distortion moved the corner ray only {moved}°");
    // The model round-trips through the projector's own pixel function.
    let dir = (pa - DVec3::from(p.position)).normalize();
    let (u, v) = p.pixel(dir).unwrap();
    assert!(
        (u - 0.5).abs() < 1e-6 && (v - 0.5).abs() < 1e-6,
        "({u}, {v})"
    );
    // A model that folds over inside the image is refused, naming the field.
    let text = std::fs::read_to_string(project_dir().join("distortion/dome-5proj.toml"))
        .unwrap()
        .replace("k1 = -0.04, k2 = 0.006", "k1 = -0.9, k2 = 0.0");
    let dir = common::temp_dir("fold");
    let path = dir.join("fold.toml");
    std::fs::write(&path, text).unwrap();
    let e = DisplayConfig::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("channel[0].projector.distortion") && e.contains("invert"),
        "{e}"
    );
}

#[test]
fn a_measured_pfm_warp_drives_the_table_like_the_model_it_came_from() {
    let _l = gpu_lock();
    let dir = common::temp_dir("pfm-warp");
    let src = project_dir().join("distortion/dome-5proj.toml");
    // The zenith channel's geometry exported as a 3-D PFM, then used as a measured warp.
    relief::app::warp::export(&src, 4, None, &dir.join("zenith.pfm"), 8).unwrap();
    let blended = std::fs::read_to_string(&src).unwrap();
    // Geometric blends invert the models: a config with a measured warp gives them up.
    let text = blended.replace("[channel.blend]\nauto = true\n", "");
    let with_warp = text.replace(
        "name = \"zenith\"",
        "name = \"zenith\"\nwarp = \"zenith.pfm\"",
    );
    assert_ne!(with_warp, text);
    std::fs::write(dir.join("measured.toml"), &with_warp).unwrap();
    let cfg = DisplayConfig::load(&dir.join("measured.toml")).unwrap();
    let model = screen_points(&cfg.screen, &cfg.channels[4].projector);
    let measured = cfg.channel_points(4).unwrap();
    let mut worst: f64 = 0.0;
    for (a, b) in model.points.iter().zip(&measured.points) {
        match (a, b) {
            (Some(a), Some(b)) => worst = worst.max(a.distance(*b)),
            (None, None) => {}
            _ => panic!("screen coverage differs between the model and its exported warp"),
        }
    }
    assert!(worst < 1e-5, "warp file points {worst} m off the model's");
    let eye = DVec3::from(cfg.eye.position);
    if let Some(g) = gpu() {
        let terrain = common::terrain_from_fn(2, 1.0, |_, _| 0.0);
        let (w, h) = (measured.width, measured.height);
        let desc = common::synthetic_scene(w, h, "position = [0.5, 0.5, 100.0]");
        let pose = relief::scene::Pose {
            position: DVec3::new(0.5, 0.5, 100.0),
            heading: 10.0,
            pitch: 0.0,
            roll: 0.0,
            fov: 60.0,
        };
        let cam = Camera::new(pose, w, h);
        let mut r = TerrainRenderer::new(g, &terrain).unwrap();
        r.set_display(g, &measured, eye).unwrap();
        r.set_pattern(
            g,
            Some(relief::display::pattern::PatternParams::grid(DVec3::Z)),
        );
        r.capture(g, &terrain, &desc, &cam, &RenderSettings::from_scene(&desc))
            .unwrap();
        let table = r.read_ray_table(g).unwrap();
        let cpu = ray_table(&model, eye, world_from_display(10.0, 0.0, 0.0));
        let mut worst_arcmin: f64 = 0.0;
        for (e, c) in table.iter().zip(&cpu.rays) {
            if let Some((d, _)) = c {
                let gd = DVec3::new(e[0] as f64, e[1] as f64, e[2] as f64);
                worst_arcmin = worst_arcmin.max(gd.angle_between(*d).to_degrees() * 60.0);
            }
        }
        eprintln!("measured warp: points within {worst:.2e} m, GPU table within {worst_arcmin:.4} arc-min of the model's");
        assert!(worst_arcmin < 0.5);
    }
    // Bad warps: 2-D u,v, wrong size, unknown row order, geometric blend with a warp file.
    std::fs::copy(
        project_dir().join("tests/data/surface1.pfm"),
        dir.join("uv.pfm"),
    )
    .unwrap();
    for (name, edit, want) in [
        ("uv", "warp = \"uv.pfm\"", "3-D"),
        ("size", "", "resolution"),
        (
            "rows",
            "warp = \"zenith.pfm\"\nwarp_rows = \"sideways\"",
            "warp_rows",
        ),
    ] {
        // The size case keeps the file and shrinks the projector after loading.
        let t = if name == "size" {
            with_warp.clone()
        } else {
            text.replace("name = \"zenith\"", &format!("name = \"zenith\"\n{edit}"))
        };
        let p = dir.join(format!("{name}.toml"));
        std::fs::write(&p, &t).unwrap();
        let e = match DisplayConfig::load(&p) {
            Err(e) => e.to_string(),
            Ok(c) => {
                let mut c = c;
                if name == "size" {
                    c.channels[4].projector.width = 10;
                }
                c.channel_points(4).unwrap_err().to_string()
            }
        };
        assert!(e.contains(want), "{name}: {e}");
    }
    let auto = blended.replace(
        "name = \"zenith\"",
        "name = \"zenith\"\nwarp = \"zenith.pfm\"",
    );
    std::fs::write(dir.join("auto.toml"), auto).unwrap();
    let e = DisplayConfig::load(&dir.join("auto.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("blend.auto") && e.contains("warp"), "{e}");
}
