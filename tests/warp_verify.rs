//! Warp verification: the test pattern (GPU against the CPU reference), the lens and mirror
//! inverses, the spherical-mirror screen against closed-form reflection, the closed loop on
//! every demo display configuration and at several eye positions, and direct vs two-pass
//! sharpness.

mod common;

use common::{gpu, gpu_lock, project_dir};
use glam::DVec3;
use relief::app::pattern_rig::PatternRig;
use relief::app::verify::{verify, VerifyOptions};
use relief::display::pattern::{pattern_rgba8, PatternParams};
use relief::display::screen_points::{projector_coord, screen_points};
use relief::display::{DisplayConfig, Lens, Projector, Screen};

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
    assert!(v.len() >= 5, "demo display configs missing");
    v
}

fn opts(size: u32, two_pass: bool) -> VerifyOptions {
    VerifyOptions {
        channels: Vec::new(),
        eye: None,
        size: (size, size),
        two_pass,
        table_eye: None,
    }
}

#[test]
fn lens_inverse_round_trips() {
    for lens in [
        Lens::Perspective {
            fov: 70.0,
            shift: [0.1, -0.05],
        },
        Lens::Ftheta { fov: 200.0 },
    ]
    .into_iter()
    .flat_map(|l| {
        // Each lens ideal and with a measured distortion (barrel + tangential).
        let measured = relief::display::LensDistortion {
            k1: -0.05,
            k2: 0.01,
            k3: 0.0,
            p1: 0.002,
            p2: -0.001,
        };
        [(l, None), (l, Some(measured))]
    }) {
        let (lens, distortion) = lens;
        let p = Projector {
            position: [0.3, -0.2, 0.1],
            heading: 30.0,
            pitch: 40.0,
            roll: -10.0,
            width: 120,
            height: 90,
            lens,
            distortion,
        };
        let mut n = 0;
        for y in 0..90 {
            for x in 0..120 {
                let (u, v) = (x as f64 + 0.37, y as f64 + 0.81);
                let Some(d) = p.ray(u, v) else { continue };
                let (bu, bv) = p.pixel(d).expect("a ray's own direction is in the field");
                assert!(
                    (bu - u).abs() < 1e-9 && (bv - v).abs() < 1e-9,
                    "{lens:?} {distortion:?} ({u}, {v}) -> ({bu}, {bv})"
                );
                n += 1;
            }
        }
        assert!(n > 5000, "{lens:?}: only {n} pixels in the field");
    }
}

#[test]
fn spherical_mirror_reflects_as_in_closed_form() {
    // Projector at (0, -D, 0) looking +y at a mirror sphere (radius r) at the origin, inside a
    // dome of radius R around the origin. A ray at angle a from the axis (in the xy plane)
    // meets the mirror with sin(i) = (D / r) sin(a), at polar angle psi = i - a from -y, and
    // leaves at angle 2i - a from -y (law of reflection).
    let (d, r, big_r) = (1.5, 0.3, 4.0);
    let screen = Screen::MirrorDome {
        centre: [0.0; 3],
        radius: big_r,
        min_elevation: -90.0,
        mirror_centre: [0.0; 3],
        mirror_radius: r,
    };
    let origin = DVec3::new(0.0, -d, 0.0);
    let mut checked = 0;
    for k in -40..=40 {
        let a = (k as f64 / 40.0) * (r / d).asin() * 0.999;
        let dir = DVec3::new(a.sin(), a.cos(), 0.0);
        let i = (d / r * a.sin()).asin();
        let psi = i - a;
        let m = DVec3::new(r * psi.sin(), -r * psi.cos(), 0.0);
        let out = DVec3::new((2.0 * i - a).sin(), -(2.0 * i - a).cos(), 0.0);
        // |m + t out| = R, positive root.
        let b = m.dot(out);
        let t = -b + (b * b - (m.length_squared() - big_r * big_r)).sqrt();
        let want = m + out * t;
        let got = screen.intersect(origin, dir).expect("ray hits the mirror");
        assert!(
            got.distance(want) < 1e-9,
            "a = {a}: got {got}, closed form {want}"
        );
        // And the inverse: the mirror point that reflects the projector onto the dome point.
        let back = screen
            .mirror_point(origin, want)
            .expect("mirror point found");
        assert!(
            back.distance(m) < 1e-9,
            "a = {a}: mirror point {back} vs {m}"
        );
        checked += 1;
    }
    assert_eq!(checked, 81);
    // A ray past the mirror lights nothing.
    let miss = DVec3::new(0.3, 1.0, 0.0).normalize();
    assert!(screen.intersect(origin, miss).is_none());
}

#[test]
fn projector_coord_inverts_every_demo_channel() {
    for (name, cfg) in configs() {
        for (ci, ch) in cfg.channels.iter().enumerate() {
            let p = ch.projector;
            let pts = screen_points(&cfg.screen, &p);
            let (mut n, mut worst) = (0, 0.0f64);
            for (k, s) in pts.points.iter().enumerate().step_by(13) {
                let Some(s) = s else { continue };
                let (u, v) = (
                    (k as u32 % p.width) as f64 + 0.5,
                    (k as u32 / p.width) as f64 + 0.5,
                );
                let Some((bu, bv)) = projector_coord(&cfg.screen, &p, *s) else {
                    let m = cfg.screen.mirror_point(DVec3::from(p.position), *s);
                    let pix = m.and_then(|m| p.pixel(m - DVec3::from(p.position)));
                    panic!("{name}[{ci}] pixel {k} ({u}, {v}): no inverse; mirror point {m:?} pixel {pix:?}")
                };
                worst = worst.max((bu - u).hypot(bv - v));
                n += 1;
            }
            assert!(n > 100, "{name}[{ci}]: {n} pixels");
            assert!(worst < 1e-4, "{name}[{ci}]: inverse off by {worst} px");
        }
    }
}

#[test]
fn gpu_pattern_matches_the_cpu_pattern() {
    let _l = gpu_lock();
    let Some(g) = gpu() else { return };
    let mut rig = PatternRig::new(g).unwrap();
    for (name, cfg) in configs() {
        let ch = &cfg.channels[0];
        let mut p = ch.projector;
        p.width /= 2;
        p.height /= 2;
        let pts = screen_points(&cfg.screen, &p);
        let grid = PatternParams::grid(DVec3::new(0.0, 0.7, 0.7));
        let grating = PatternParams {
            boresight: grid.boresight,
            grating: 60.0,
        };
        let eye = DVec3::from(cfg.eye.position);
        let v = rig.render(g, &pts, eye, &grid, &grating).unwrap();
        let (mut n, mut off, mut sum) = (0usize, 0usize, 0.0f64);
        for (k, t) in v.table.iter().enumerate() {
            if t[3] < 0.0 {
                assert_eq!(&v.grid[k * 4..k * 4 + 3], &[0, 0, 0], "{name}: black pixel");
                continue;
            }
            let d = DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64);
            for (img, params) in [(&v.grid, &grid), (&v.grating, &grating)] {
                let want = pattern_rgba8(d, t[3] as f64, params);
                let worst = (0..3)
                    .map(|c| (img[k * 4 + c] as i32 - want[c] as i32).abs())
                    .max()
                    .unwrap();
                sum += worst as f64;
                if worst > 2 && off < 5 {
                    eprintln!(
                        "{name} px {k}: gpu {:?} cpu {want:?} dir {d} cone {} grating {}",
                        &img[k * 4..k * 4 + 4],
                        t[3],
                        params.grating
                    );
                }
                off += usize::from(worst > 2);
                n += 1;
            }
        }
        assert!(n > 1000, "{name}: {n} samples");
        assert!(
            off * 1000 <= n,
            "{name}: {off} of {n} pattern samples differ from the CPU by more than 2/255"
        );
        assert!(
            sum / (n as f64) < 0.5,
            "{name}: mean difference {}",
            sum / n as f64
        );
    }
}

#[test]
fn closed_loop_error_is_below_one_arcmin_on_every_demo_config() {
    let _l = gpu_lock();
    let Some(g) = gpu() else { return };
    let mut rig = PatternRig::new(g).unwrap();
    for (name, cfg) in configs() {
        let (r, img) = verify(g, &mut rig, &cfg, &name, &opts(160, false)).unwrap();
        eprintln!(
            "{name}: mean {:.4} max {:.4} arc-min over {} eye pixels",
            r.mean_error_arcmin, r.max_error_arcmin, r.covered_pixels
        );
        assert!(
            r.covered_pixels > 160 * 160 / 8,
            "{name}: only {} eye pixels covered",
            r.covered_pixels
        );
        assert!(
            r.mean_error_arcmin < 1.0,
            "{name}: mean error {} arc-min",
            r.mean_error_arcmin
        );
        for c in &r.channels {
            assert!(c.eye_pixels > 0, "{name}: channel {} never seen", c.name);
        }
        assert_eq!(img.as_seen.len(), 160 * 160 * 4);
        // Geometric blends hand the light over across every overlap.
        if cfg.channels.iter().all(|c| c.blend.is_some_and(|b| b.auto)) {
            let [lo, mean, hi] = r.blend_sum.expect("blended channels overlap");
            eprintln!(
                "{name}: blended light over {} overlap pixels: min {lo:.3} mean {mean:.4} max {hi:.3}",
                r.overlap_pixels
            );
            assert!(
                r.overlap_pixels > 50,
                "{name}: {} overlap pixels",
                r.overlap_pixels
            );
            assert!(
                (mean - 1.0).abs() < 0.02 && lo > 0.85 && hi < 1.15,
                "{name}: blended light sums to {lo:.3}..{hi:.3} (mean {mean:.3}), not 1"
            );
        }
    }
}

#[test]
fn moving_eye_tables_follow_the_eye_and_a_stale_table_is_caught() {
    let _l = gpu_lock();
    let Some(g) = gpu() else { return };
    let cfg = DisplayConfig::load(&project_dir().join("distortion/dome-moving-eye.toml")).unwrap();
    let mut rig = PatternRig::new(g).unwrap();
    let base = DVec3::from(cfg.eye.position);
    let mut tables: Vec<Vec<[f32; 4]>> = Vec::new();
    let pts = screen_points(&cfg.screen, &cfg.channels[0].projector);
    let grid = PatternParams::grid(DVec3::Z);
    for offset in [
        DVec3::ZERO,
        DVec3::new(0.15, 0.0, 0.0),
        DVec3::new(-0.1, 0.2, 0.1),
        DVec3::new(0.0, -0.2, 0.25),
    ] {
        let eye = base + offset;
        let o = VerifyOptions {
            eye: Some(eye),
            ..opts(128, false)
        };
        let (r, _) = verify(g, &mut rig, &cfg, "dome-moving-eye", &o).unwrap();
        assert!(
            r.mean_error_arcmin < 1.0 && r.covered_pixels > 3000,
            "eye {eye}: mean {} arc-min over {} pixels",
            r.mean_error_arcmin,
            r.covered_pixels
        );
        tables.push(rig.render(g, &pts, eye, &grid, &grid).unwrap().table);
    }
    // The table changes with the eye.
    for t in &tables[1..] {
        let moved = t
            .iter()
            .zip(&tables[0])
            .filter(|(a, b)| a[3] >= 0.0 && b[3] >= 0.0)
            .map(|(a, b)| {
                let (a, b) = (
                    DVec3::new(a[0].into(), a[1].into(), a[2].into()),
                    DVec3::new(b[0].into(), b[1].into(), b[2].into()),
                );
                a.angle_between(b)
            })
            .fold(0.0f64, f64::max);
        assert!(moved > 1f64.to_radians(), "table moved only {moved} rad");
    }
    // A table generated for an eye 5 cm away (tracking lag) leaves an error the check sees.
    let o = VerifyOptions {
        table_eye: Some(base + DVec3::new(0.05, 0.0, 0.0)),
        ..opts(128, false)
    };
    let (r, _) = verify(g, &mut rig, &cfg, "dome-moving-eye", &o).unwrap();
    assert!(
        r.mean_error_arcmin > 30.0,
        "stale table: mean error only {} arc-min",
        r.mean_error_arcmin
    );
}

#[test]
fn direct_mode_is_sharper_than_two_pass() {
    // Criterion: at a median 0.4 cycles per projector pixel, direct ray casting keeps at least
    // 95% of the grating's contrast in the projector image and two-pass warping at least 0.1
    // less; as seen from the eye, direct keeps at least 0.05 more than two-pass.
    let _l = gpu_lock();
    let Some(g) = gpu() else { return };
    let mut rig = PatternRig::new(g).unwrap();
    for file in ["cylinder-3ch.toml", "dome-fisheye.toml"] {
        let cfg = DisplayConfig::load(&project_dir().join("distortion").join(file)).unwrap();
        let (r, img) = verify(g, &mut rig, &cfg, file, &opts(160, true)).unwrap();
        for c in &r.channels {
            let two = c.contrast_two_pass.expect("two-pass ran");
            eprintln!(
                "{file}[{}]: contrast direct {:.3}, two-pass {two:.3} ({})",
                c.channel,
                c.contrast_direct,
                c.two_pass_intermediate.as_deref().unwrap_or("")
            );
            assert!(
                c.contrast_direct >= 0.95,
                "{file}[{}]: direct {}",
                c.channel,
                c.contrast_direct
            );
            assert!(
                two <= c.contrast_direct - 0.1,
                "{file}[{}]: two-pass {two} vs direct {}",
                c.channel,
                c.contrast_direct
            );
        }
        let seen_two = r.seen_contrast_two_pass.unwrap();
        assert!(
            r.seen_contrast_direct >= seen_two + 0.05,
            "{file}: as seen, direct {} vs two-pass {seen_two}",
            r.seen_contrast_direct
        );
        assert!(img.as_seen_two_pass.is_some());
    }
}

fn relief(args: &[&str]) -> std::process::Output {
    common::relief_cli(args, &[])
}

#[test]
fn cli_verify_and_two_pass_render_write_their_files_and_refuse_bad_input() {
    let _l = gpu_lock();
    if gpu().is_none() {
        return;
    }
    let dir = common::temp_dir("verify");
    let cfg = project_dir().join("distortion/dome-moving-eye.toml");
    let out = dir.join("v");
    let o = relief(&[
        "warp",
        "verify",
        cfg.to_str().unwrap(),
        "--size",
        "96x96",
        "--out",
        out.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("geometric error: mean"), "{text}");
    for f in [
        "as_seen_from_eye.png",
        "reference_from_eye.png",
        "diff_from_eye.png",
        "as_seen_from_eye_two_pass.png",
        "channel_0_direct.png",
        "channel_0_two_pass.png",
        "verify.json",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("verify.json")).unwrap()).unwrap();
    assert!(json["mean_error_arcmin"].as_f64().unwrap() < 1.0);
    // A channel that does not exist: clear error, non-zero exit, nothing written.
    let bad = dir.join("bad");
    let o = relief(&[
        "warp",
        "verify",
        cfg.to_str().unwrap(),
        "--channel",
        "3",
        "--out",
        bad.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("--channel") && err.contains("1 channel"),
        "{err}"
    );
    assert!(!bad.exists(), "files written for a refused run");
    // Two-pass render of the test pattern through the same channel.
    let r = dir.join("r");
    let o = relief(&[
        "render",
        project_dir().join("terrains/alps.toml").to_str().unwrap(),
        "--display",
        cfg.to_str().unwrap(),
        "--two-pass",
        "--pattern",
        "--out",
        r.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let meta = std::fs::read_to_string(r.join("frame_0000.json")).unwrap();
    assert!(meta.contains("two-pass: 6 pinhole image(s)"), "{meta}");
    let img = image::open(r.join("frame_0000.png")).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (512, 512));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_mirror_domes_are_refused_by_field() {
    let good = std::fs::read_to_string(project_dir().join("distortion/mirror-dome.toml")).unwrap();
    let dir = common::temp_dir("mirror");
    for (label, text, want) in [
        (
            "mirror outside the dome",
            good.replace(
                "mirror_centre = [0.0, -2.0, 0.35]",
                "mirror_centre = [0.0, -2.4, 0.35]",
            ),
            "screen.mirror_centre/mirror_radius",
        ),
        (
            "zero mirror",
            good.replace("mirror_radius = 0.3", "mirror_radius = 0.0"),
            "screen.mirror_radius",
        ),
        (
            "missing mirror",
            good.replace("mirror_radius = 0.3\n", ""),
            "mirror_radius",
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
fn dome_master_pixels_and_directions_round_trip() {
    use relief::display::dome_master::{direction, pixel};
    for fov in [180.0, 220.0, 120.0] {
        let size = 512;
        // Zenith at the centre, the front (display +y) at the bottom, +x to the right.
        assert!(
            direction(256.0, 256.0, size, fov)
                .unwrap()
                .distance(DVec3::Z)
                < 1e-12
        );
        let bottom = direction(256.0, 511.0, size, fov).unwrap();
        let right = direction(511.0, 256.0, size, fov).unwrap();
        assert!(
            bottom.y > 0.9 * (0.5 * fov).to_radians().sin().min(1.0) && bottom.x.abs() < 1e-12,
            "{bottom}"
        );
        assert!(right.x > 0.0 && right.y.abs() < 1e-12, "{right}");
        assert!(
            direction(2.0, 2.0, size, fov).is_none(),
            "corner outside the circle"
        );
        let mut worst: f64 = 0.0;
        for k in 0..2000 {
            let (x, y) = ((k * 37 % 512) as f64 + 0.25, (k * 91 % 512) as f64 + 0.75);
            if let Some(d) = direction(x, y, size, fov) {
                assert!((d.length() - 1.0).abs() < 1e-12);
                let (px, py) = pixel(d, size, fov).unwrap();
                worst = worst.max((px - x).hypot(py - y));
            }
        }
        assert!(worst < 1e-9, "fov {fov}: round trip off by {worst} px");
    }
    assert!(
        pixel(DVec3::new(0.0, 1.0, -0.5), 512, 180.0).is_none(),
        "below the horizon"
    );
}

/// The colour a smooth synthetic dome master holds for direction `d`: (d + 1) / 2.
fn master_colour(d: DVec3) -> [u8; 3] {
    [d.x, d.y, d.z].map(|v| ((v + 1.0) * 0.5 * 255.0).round() as u8)
}

/// Writes a 512² 180° dome master of [`master_colour`] into `dir`; returns its path.
fn smooth_dome_master(dir: &std::path::Path) -> std::path::PathBuf {
    use relief::display::dome_master::direction;
    let size = 512u32;
    let mut img = vec![0u8; (size * size * 4) as usize];
    for y in 0..size {
        for x in 0..size {
            let k = ((y * size + x) * 4) as usize;
            if let Some(d) = direction(x as f64 + 0.5, y as f64 + 0.5, size, 180.0) {
                img[k..k + 3].copy_from_slice(&master_colour(d));
            }
            img[k + 3] = 255;
        }
    }
    let master = dir.join("master.png");
    relief::app::output::write_png(&master, size, size, &img).unwrap();
    master
}

/// The demo dome without its edge blends (so colours compare unattenuated), written to `dir`.
fn unblended_dome(dir: &std::path::Path) -> std::path::PathBuf {
    let config = dir.join("dome-5proj-unblended.toml");
    std::fs::write(
        &config,
        std::fs::read_to_string(project_dir().join("distortion/dome-5proj.toml"))
            .unwrap()
            .replace("[channel.blend]\nauto = true\n", ""),
    )
    .unwrap();
    config
}

#[test]
fn warp_apply_gives_each_projector_pixel_the_dome_master_colour_of_its_direction() {
    let dir = common::temp_dir("dome-master");
    let master = smooth_dome_master(&dir);
    let config = unblended_dome(&dir);
    let cfg = DisplayConfig::load(&config).unwrap();
    for channel in [0usize, 4] {
        let out = dir.join(format!("ch{channel}.png"));
        relief::app::warp::apply_dome_master(&config, channel, None, &master, 180.0, &out).unwrap();
        let got = image::open(&out).unwrap().to_rgba8();
        let p = cfg.channels[channel].projector;
        assert_eq!(got.dimensions(), (p.width, p.height));
        let pts = screen_points(&cfg.screen, &p);
        let eye = DVec3::from(cfg.eye.position);
        let (mut n, mut worst) = (0usize, 0u8);
        for (k, s) in pts.points.iter().enumerate() {
            let Some(d) = s.and_then(|s| (s - eye).try_normalize()) else {
                continue;
            };
            // Stay a pixel inside the master's circle, where bilinear reads only lit texels.
            if d.z < 0.02 {
                continue;
            }
            let want = master_colour(d);
            let px = got.get_pixel(k as u32 % p.width, k as u32 / p.width).0;
            for c in 0..3 {
                worst = worst.max(px[c].abs_diff(want[c]));
            }
            n += 1;
        }
        eprintln!("channel {channel}: {n} pixels, worst |warped − exact| {worst}/255");
        assert!(
            n > 10_000,
            "channel {channel}: only {n} pixels inside the master"
        );
        assert!(
            worst <= 2,
            "channel {channel}: warped colour off by {worst}/255"
        );
    }
    // Bad input: not square, not an image.
    let e =
        relief::app::warp::apply_dome_master(&config, 0, None, &config, 180.0, &dir.join("x.png"))
            .unwrap_err()
            .to_string();
    assert!(
        e.contains("dome-5proj-unblended.toml") && e.contains("dome master"),
        "{e}"
    );
    relief::app::output::write_png(&dir.join("wide.png"), 4, 2, &[0; 32]).unwrap();
    let e = relief::app::warp::apply_dome_master(
        &config,
        0,
        None,
        &dir.join("wide.png"),
        180.0,
        &dir.join("x.png"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("square"), "{e}");
    assert!(!dir.join("x.png").exists());
}

#[test]
fn cli_renders_a_square_dome_master() {
    let _l = gpu_lock();
    if gpu().is_none() {
        return;
    }
    let dir = common::temp_dir("dm-cli");
    let o = relief(&[
        "render",
        "terrains/alps.toml",
        "--dome-master",
        "180",
        "--pattern",
        "--size",
        "96x64",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(dir.join("frame_0000.png")).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (64, 64));
    assert_eq!(
        &img.get_pixel(0, 0).0[..3],
        &[0, 0, 0],
        "corner outside the fisheye is black"
    );
    assert_ne!(
        &img.get_pixel(32, 32).0[..3],
        &[0, 0, 0],
        "the zenith shows the pattern"
    );
    let o = relief(&[
        "render",
        "terrains/alps.toml",
        "--dome-master",
        "0",
        "--out",
        dir.join("bad").to_str().unwrap(),
    ]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--dome-master"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_exported_bourke_mesh_warps_a_dome_master_like_the_display_model() {
    let dir = common::temp_dir("mesh-apply");
    let master = smooth_dome_master(&dir);
    let config = unblended_dome(&dir);
    let cfg = DisplayConfig::load(&config).unwrap();
    let channel = 4; // the zenith projector: all of it inside the 180° master
    let p = cfg.channels[channel].projector;
    let mesh = dir.join("zenith.data");
    relief::app::warp::export(&config, channel, None, &mesh, 4).unwrap();
    let via_mesh = dir.join("mesh.png");
    let via_model = dir.join("model.png");
    relief::app::warp::apply_mesh(&mesh, &master, (p.width, p.height), &via_mesh).unwrap();
    relief::app::warp::apply_dome_master(&config, channel, None, &master, 180.0, &via_model)
        .unwrap();
    let a = image::open(&via_mesh).unwrap().to_rgba8();
    let b = image::open(&via_model).unwrap().to_rgba8();
    let (mut n, mut sum, mut worst) = (0usize, 0u64, 0u8);
    for (pa, pb) in a.pixels().zip(b.pixels()) {
        if pb.0[..3] == [0, 0, 0] {
            continue;
        }
        n += 1;
        for c in 0..3 {
            let d = pa.0[c].abs_diff(pb.0[c]);
            sum += d as u64;
            worst = worst.max(d);
        }
    }
    let mean = sum as f64 / (3 * n.max(1)) as f64;
    eprintln!("{n} pixels: mesh vs model mean {mean:.3}/255, worst {worst}/255");
    assert!(n > 50_000, "only {n} lit pixels");
    assert!(
        mean < 0.5 && worst <= 3,
        "mesh warp differs from the model: mean {mean}, worst {worst}"
    );
    // A small ordered mesh works; a disordered one is refused, naming the file.
    std::fs::write(
        dir.join("small.data"),
        "2\n2 2\n-1 -1 0 0 1\n1 -1 1 0 1\n-1 1 0 1 1\n1 1 1 1 1\n",
    )
    .unwrap();
    let ok =
        relief::app::warp::apply_mesh(&dir.join("small.data"), &master, (8, 8), &dir.join("b.png"));
    assert!(ok.is_ok(), "a 2x2 ordered mesh is fine: {ok:?}");
    std::fs::write(
        dir.join("disordered.data"),
        "2\n2 2\n1 -1 0 0 1\n-1 -1 1 0 1\n-1 1 0 1 1\n1 1 1 1 1\n",
    )
    .unwrap();
    let e = relief::app::warp::apply_mesh(
        &dir.join("disordered.data"),
        &master,
        (8, 8),
        &dir.join("c.png"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("disordered.data") && e.contains("increase"),
        "{e}"
    );
    assert!(!dir.join("c.png").exists());
}
