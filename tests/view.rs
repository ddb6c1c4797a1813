//! `relief view`: the window against the headless renderer, terrain following, resizing, bad
//! input, several channels; plus the CPU parts (motion, path CSV, stats, overlay font, present
//! shader). Window tests start their own Xvfb (skipped, saying why, when it is not installed;
//! CI installs it) and run the `relief` binary in it.

mod common;

use common::{relief_command, temp_dir, terrains, Xvfb};
use relief::app::view::motion::{self, Controls, Mode, Motion};
use relief::app::view::{present, stats};
use std::path::Path;
use std::process::{Output, Stdio};

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// Window tests need an adapter (or skip as the GPU tests do) and an X server.
fn window_env() -> Option<(Xvfb, std::sync::MutexGuard<'static, ()>)> {
    let lock = common::gpu_lock();
    common::gpu()?;
    Some((Xvfb::start()?, lock))
}

fn relief(args: &[&str], display: Option<&str>, envs: &[(&str, &str)]) -> Output {
    let mut c = relief_command(args, envs);
    if let Some(d) = display {
        c.env("DISPLAY", d);
    }
    c.output().expect("the relief binary runs")
}

fn check_ok(what: &str, o: &Output) -> String {
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success(),
        "{what}: exit {}\nstdout: {out}\nstderr: {err}",
        o.status
    );
    out
}

fn load_rgb(p: &Path) -> image::RgbImage {
    image::open(p)
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        .to_rgb8()
}

/// Mean absolute difference over all channels, in 0..=1.
fn mean_error(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions(), "image sizes differ");
    let sum: u64 = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| x.abs_diff(*y) as u64)
        .sum();
    sum as f64 / a.as_raw().len() as f64 / 255.0
}

/// Asserts `actual` equals `expected` within a mean error of 1/255; saves it on failure.
fn assert_matches(name: &str, actual: &Path, expected: &Path) {
    let (a, e) = (load_rgb(actual), load_rgb(expected));
    let err = mean_error(&a, &e);
    if err > 1.0 / 255.0 {
        let rgba = |i: &image::RgbImage| image::DynamicImage::ImageRgb8(i.clone()).to_rgba8();
        let p = common::save_failure_images(name, a.width(), a.height(), &rgba(&a), &rgba(&e));
        panic!(
            "{name}: {} differs from {} by a mean {:.4} (> 1/255); saved {}",
            actual.display(),
            expected.display(),
            err,
            p.display()
        );
    }
    eprintln!("{name}: mean error {err:.5}");
}

/// Per-channel standard deviation summed: 0 for a blank (single-colour) image.
fn spread(img: &image::RgbImage) -> f64 {
    let n = (img.width() * img.height()) as f64;
    (0..3)
        .map(|c| {
            let v: Vec<f64> = img.pixels().map(|p| p[c] as f64).collect();
            let m = v.iter().sum::<f64>() / n;
            (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n).sqrt()
        })
        .sum()
}

fn adapter_of(meta: &Path) -> String {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(meta).unwrap()).unwrap();
    format!("{} {}", v["adapter"]["name"], v["adapter"]["backend"])
}

/// Rows of a CSV with a header, as maps from column name to value.
fn read_csv(p: &Path) -> Vec<std::collections::HashMap<String, f64>> {
    let text = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(String::from)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(|f| f.parse::<f64>().unwrap()))
                .collect()
        })
        .collect()
}

#[test]
fn window_frames_match_headless_render() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let dir = temp_dir("match");
    let cap = dir.join("cap");
    let grab = dir.join("grab");
    let stats_csv = dir.join("stats.csv");
    // alps.toml has a [path] at 30 fps: at --rate 30 window frame N is path frame N.
    let o = relief(
        &[
            "view",
            "terrains/alps.toml",
            "--size",
            "160x120",
            "--frames",
            "64",
            "--rate",
            "30",
            "--unpaced",
            "--no-overlay",
            "--capture-frames",
            &s(&cap),
            "--grab",
            "40",
            "--screenshot-dir",
            &s(&grab),
            "--stats-csv",
            &s(&stats_csv),
        ],
        Some(&x.display),
        &[],
    );
    let out = check_ok("relief view", &o);
    assert!(out.contains("64 frames"), "summary: {out}");
    for needle in ["p50", "p99", "dropped frames", "latency"] {
        assert!(out.contains(needle), "summary lacks `{needle}`: {out}");
    }
    let rows = read_csv(&stats_csv);
    assert_eq!(rows.len(), 64, "one stats row per frame");
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r["frame"], i as f64);
        assert!(r["latency_ms"] > 0.0 && r["cpu_ms"] > 0.0, "row {i}: {r:?}");
    }
    assert!(
        rows.iter().any(|r| r["gpu_ms"] > 0.0),
        "no frame has a GPU time"
    );

    let head = dir.join("headless");
    for n in ["40", "63"] {
        check_ok(
            "relief render",
            &relief(
                &[
                    "render",
                    "terrains/alps.toml",
                    "--size",
                    "160x120",
                    "--first",
                    n,
                    "--frames",
                    "1",
                    "--out",
                    &s(&head),
                ],
                None,
                &[],
            ),
        );
    }
    assert_eq!(
        adapter_of(&cap.join("frame_0040.json")),
        adapter_of(&head.join("frame_0040.json")),
        "window and headless must run on the same adapter"
    );
    for n in ["0040", "0063"] {
        assert_matches(
            &format!("view-capture-{n}"),
            &cap.join(format!("frame_{n}.png")),
            &head.join(format!("frame_{n}.png")),
        );
        let (_, _, a) =
            relief::app::output::read_depth_tiff(&cap.join(format!("depth_{n}.tiff"))).unwrap();
        let (_, _, b) =
            relief::app::output::read_depth_tiff(&head.join(format!("depth_{n}.tiff"))).unwrap();
        assert!(
            a.iter()
                .zip(&b)
                .all(|(x, y)| x == y || (x - y).abs() <= 1e-4 * y.abs()),
            "frame {n}: window and headless depths differ"
        );
    }
    // What was presented: the swap-chain image, and the window's pixels in the X server.
    // wgpu's GL backend offers no COPY_SRC on the swap chain: there, and only there, the
    // swap-chain readback is skipped (the X server's copy is still compared).
    let expected = head.join("frame_0040.png");
    let surface = grab.join("surface_0040.png");
    if !surface.exists() && adapter_of(&cap.join("frame_0040.json")).contains("Gl") {
        eprintln!("skipping the swap-chain readback comparison: the GL backend's surface does not allow COPY_SRC");
    } else {
        assert_matches("view-surface-0040", &surface, &expected);
    }
    let x11 = grab.join("x11_0040.png");
    assert!(x11.exists(), "no X server readback: {}", o_stderr(&o));
    assert!(
        spread(&load_rgb(&x11)) > 10.0,
        "the X server's copy of the window is blank"
    );
    assert_matches("view-x11-0040", &x11, &expected);
    let _ = std::fs::remove_dir_all(&dir);
}

fn o_stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn aircraft_follows_terrain_above_minimum() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let dir = temp_dir("aircraft");
    let script = dir.join("dive.csv");
    // Full throttle, push the nose down to -30° in the first second, then hold the dive: without
    // the floor the aircraft flies into the Alpstein's northern slopes.
    std::fs::write(
        &script,
        "time,throttle,pitch,roll,yaw\n0,1,-1,0,0\n1,1,0,0,0\n",
    )
    .unwrap();
    let path = dir.join("flown.csv");
    let min_agl = 50.0;
    let o = relief(
        &[
            "view",
            "terrains/alps.toml",
            "--size",
            "96x72",
            "--mode",
            "aircraft",
            "--start",
            "25900,30400,1500,180",
            "--script",
            &s(&script),
            "--min-agl",
            "50",
            "--record",
            &s(&path),
            "--rate",
            "30",
            "--frames",
            "240",
            "--unpaced",
            "--no-shadows",
        ],
        Some(&x.display),
        &[],
    );
    check_ok("relief view --mode aircraft", &o);
    let rows = read_csv(&path);
    assert_eq!(rows.len(), 240, "one recorded pose per frame");
    let scene = relief::scene::Scene::load(&terrains().join("alps.toml")).unwrap();
    let terrain = scene.load_terrain().unwrap();
    let mut lowest = f64::INFINITY;
    let mut ground = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let p = glam::DVec3::new(r["x"], r["y"], r["alt"]);
        let agl = relief::cpu::query::height_above_terrain(&terrain, p)
            .unwrap_or_else(|| panic!("frame {i}: {p} is off the terrain"));
        assert!(
            agl >= min_agl,
            "frame {i}: {agl:.3} m above the terrain, minimum {min_agl}"
        );
        lowest = lowest.min(agl);
        ground.push(p.z - agl);
    }
    // The dive reached the floor (so the floor, not luck, kept the altitude) ...
    assert!(
        lowest < min_agl + 1.0,
        "the aircraft never came down to the floor (lowest {lowest:.1} m)"
    );
    // ... over terrain that changes height along the way.
    let (lo, hi) = ground
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), g| {
            (a.min(*g), b.max(*g))
        });
    assert!(hi - lo > 50.0, "flat ground only ({lo:.0}..{hi:.0} m)");
    let first = &rows[0];
    let last = &rows[rows.len() - 1];
    assert!(
        first["y"] - last["y"] > 500.0,
        "the aircraft did not fly south"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn resize_mid_run_keeps_rendering_at_the_new_size() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let dir = temp_dir("resize");
    let stats_csv = dir.join("stats.csv");
    let cap = dir.join("cap");
    let o = relief(
        &[
            "view",
            "terrains/alps.toml",
            "--size",
            "160x120",
            "--frames",
            "10",
            "--unpaced",
            "--resize-at",
            "4",
            "200x150",
            "--stats-csv",
            &s(&stats_csv),
            "--capture-frames",
            &s(&cap),
        ],
        Some(&x.display),
        &[],
    );
    check_ok("relief view --resize-at", &o);
    let rows = read_csv(&stats_csv);
    assert_eq!(rows.len(), 10);
    for r in &rows {
        let want = if r["frame"] <= 4.0 {
            (160.0, 120.0)
        } else {
            (200.0, 150.0)
        };
        assert_eq!(
            (r["width"], r["height"]),
            want,
            "frame {} has the wrong size",
            r["frame"]
        );
    }
    assert_eq!(
        load_rgb(&cap.join("frame_0004.png")).dimensions(),
        (160, 120)
    );
    assert_eq!(
        load_rgb(&cap.join("frame_0005.png")).dimensions(),
        (200, 150)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Bad input fails before any window: the runs have no DISPLAY at all, so reaching the window
/// system would be a different error.
#[test]
fn bad_input_fails_before_a_window_opens() {
    let dir = temp_dir("bad");
    let check = |what: &str, o: &Output, needles: &[&str]| {
        let err = o_stderr(o);
        assert!(!o.status.success(), "{what}: expected failure\n{err}");
        for n in needles {
            assert!(err.contains(n), "{what}: stderr lacks `{n}`:\n{err}");
        }
        assert!(
            !err.contains("opened window") && !err.contains("window system"),
            "{what}: got as far as the window:\n{err}"
        );
    };
    let o = relief(&["view", "does-not-exist.toml"], None, &[]);
    check("missing scene", &o, &["does-not-exist.toml"]);

    let bad_cfg = dir.join("bad-display.toml");
    std::fs::write(
        &bad_cfg,
        "[screen]\nkind = \"dome\"\ncentre = [0.0, 0.0, 0.0]\nradius = -3.0\n[eye]\nposition = [0.0, 0.0, 0.0]\n",
    )
    .unwrap();
    let o = relief(
        &["view", "terrains/alps.toml", "--display", &s(&bad_cfg)],
        None,
        &[],
    );
    check("bad display config", &o, &["bad-display.toml"]);

    let o = relief(
        &[
            "view",
            "terrains/alps.toml",
            "--display",
            "distortion/cylinder-3ch.toml",
            "--channel",
            "7",
        ],
        None,
        &[],
    );
    check("channel out of range", &o, &["--channel", "3 channel(s)"]);

    let bad_path = dir.join("path.csv");
    std::fs::write(
        &bad_path,
        "time,x,y,alt,heading,pitch,roll\n0,1,2,3,4,5,6\n0,1,2,3,4,5\n",
    )
    .unwrap();
    let o = relief(
        &["view", "terrains/alps.toml", "--path", &s(&bad_path)],
        None,
        &[],
    );
    check("short path row", &o, &["path.csv", "line 3"]);

    let o = relief(
        &["view", "terrains/alps.toml"],
        None,
        &[("WGPU_ADAPTER_NAME", "no-such-adapter")],
    );
    check("no adapter", &o, &["no-such-adapter", "matches no adapter"]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn one_window_per_channel_each_matches_headless() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let dir = temp_dir("channels");
    let cfg = dir.join("two.toml");
    let channel = |name: &str, heading: f64| {
        format!(
            "[[channel]]\nname = \"{name}\"\n[channel.projector]\nposition = [0.0, -0.4, 0.9]\nheading = {heading}\npitch = -6.0\nwidth = 96\nheight = 64\nlens = {{ kind = \"perspective\", fov = 64.0, shift = [0.0, 0.0] }}\n"
        )
    };
    std::fs::write(
        &cfg,
        format!(
            "[screen]\nkind = \"cylinder\"\ncentre = [0.0, 0.0, 0.0]\nradius = 3.0\nbottom = -1.2\ntop = 1.4\n[eye]\nposition = [0.0, 0.0, 0.0]\n{}{}",
            channel("left", -40.0),
            channel("right", 40.0)
        ),
    )
    .unwrap();
    let cap = dir.join("cap");
    let o = relief(
        &[
            "view",
            "terrains/alps.toml",
            "--display",
            &s(&cfg),
            "--frames",
            "3",
            "--rate",
            "30",
            "--unpaced",
            "--no-overlay",
            "--capture-frames",
            &s(&cap),
            "--grab",
            "2",
            "--screenshot-dir",
            &s(&dir),
        ],
        Some(&x.display),
        &[],
    );
    let out = check_ok("relief view --display", &o);
    assert!(out.contains("2 window(s)"), "{out}");
    for c in ["0", "1"] {
        let head = dir.join(format!("head{c}"));
        check_ok(
            "relief render --display",
            &relief(
                &[
                    "render",
                    "terrains/alps.toml",
                    "--display",
                    &s(&cfg),
                    "--channel",
                    c,
                    "--first",
                    "2",
                    "--frames",
                    "1",
                    "--out",
                    &s(&head),
                ],
                None,
                &[],
            ),
        );
        let expected = head.join("frame_0002.png");
        assert_matches(
            &format!("view-channel-{c}"),
            &cap.join(format!("channel_{c}/frame_0002.png")),
            &expected,
        );
        // The windows sit side by side, so the X server shows each one whole.
        assert_matches(
            &format!("view-channel-{c}-x11"),
            &dir.join(format!("x11_0002_c{c}.png")),
            &expected,
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn debug_views_show_depth_and_traversal_steps() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let dir = temp_dir("debug-views");
    let mut shots = Vec::new();
    for view in ["colour", "depth", "steps"] {
        let out = dir.join(view);
        let o = relief(
            &[
                "view",
                "terrains/alps.toml",
                "--size",
                "96x72",
                "--frames",
                "1",
                "--no-overlay",
                "--debug-view",
                view,
                "--grab",
                "0",
                "--screenshot-dir",
                &s(&out),
            ],
            Some(&x.display),
            &[],
        );
        check_ok(&format!("relief view --debug-view {view}"), &o);
        // The swap-chain image, or where the surface cannot be read back (wgpu's GL backend)
        // the window's pixels in the X server.
        let surface = out.join("surface_0000.png");
        if surface.exists() {
            shots.push(load_rgb(&surface));
        } else {
            eprintln!("{view}: no swap-chain readback on this adapter; using the X server's copy");
            shots.push(load_rgb(&out.join("x11_0000.png")));
        }
    }
    let grey = |img: &image::RgbImage| {
        img.pixels()
            .filter(|p| p[0] == p[1] && p[1] == p[2])
            .count()
    };
    let n = (96 * 72) as usize;
    // Depth: grey levels on the terrain (only the sky is tinted), and not the colour image.
    assert!(grey(&shots[1]) > n / 2, "depth view is not grey");
    assert!(spread(&shots[1]) > 10.0, "depth view is flat");
    assert!(mean_error(&shots[0], &shots[1]) > 0.05);
    // Steps: a heat map, differing from both.
    assert!(spread(&shots[2]) > 10.0, "step view is flat");
    assert!(mean_error(&shots[2], &shots[0]) > 0.05 && mean_error(&shots[2], &shots[1]) > 0.05);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs `relief args` on `display`, pressing `presses` then Escape in its window
/// (`keys_then_escape`); returns its output once it has ended.
#[cfg(target_os = "linux")]
fn run_with_keys(display: &str, args: &[&str], presses: &[(u32, std::time::Duration)]) -> Output {
    let child = relief_command(args, &[("DISPLAY", display)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let keys = keys_then_escape(display, presses);
    let o = child.wait_with_output().unwrap();
    keys.unwrap();
    o
}

/// Key presses through XTEST (as a user's): the first mapped window named `relief…` gets the
/// focus and the pointer, each key of `presses` is held for its time in turn, then Escape is
/// pressed.
#[cfg(target_os = "linux")]
fn keys_then_escape(display: &str, presses: &[(u32, std::time::Duration)]) -> Result<(), String> {
    use std::ffi::CString;
    use x11_dl::{keysym, xlib, xtest};
    let x = xlib::Xlib::open().map_err(|e| format!("libX11: {e}"))?;
    let t = xtest::Xf86vmode::open().map_err(|e| format!("libXtst: {e}"))?;
    let name = CString::new(display).unwrap();
    // SAFETY: Xlib calls on a connection opened and closed here; returned lists and names are
    // checked for null and freed with XFree.
    unsafe {
        let dpy = (x.XOpenDisplay)(name.as_ptr());
        if dpy.is_null() {
            return Err(format!("cannot open {display}"));
        }
        let root = (x.XDefaultRootWindow)(dpy);
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
        let window = loop {
            let (mut r, mut parent, mut kids, mut n) = (0, 0, std::ptr::null_mut(), 0);
            (x.XQueryTree)(dpy, root, &mut r, &mut parent, &mut kids, &mut n);
            let mut found = None;
            for i in 0..n as usize {
                let w = *kids.add(i);
                let mut attrs: xlib::XWindowAttributes = std::mem::zeroed();
                (x.XGetWindowAttributes)(dpy, w, &mut attrs);
                let mut title = std::ptr::null_mut();
                if attrs.map_state == xlib::IsViewable
                    && (x.XFetchName)(dpy, w, &mut title) != 0
                    && !title.is_null()
                {
                    let s = std::ffi::CStr::from_ptr(title)
                        .to_string_lossy()
                        .into_owned();
                    (x.XFree)(title.cast());
                    if s.starts_with("relief") {
                        found = Some((w, attrs.x + attrs.width / 2, attrs.y + attrs.height / 2));
                    }
                }
            }
            if !kids.is_null() {
                (x.XFree)(kids.cast());
            }
            if let Some(f) = found {
                break f;
            }
            if std::time::Instant::now() > deadline {
                (x.XCloseDisplay)(dpy);
                return Err("no relief window was mapped within 30 s".into());
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        };
        // Let a few frames go by at the start pose, then fly.
        std::thread::sleep(std::time::Duration::from_millis(300));
        // No window manager: give the window the keyboard focus as one would.
        (x.XSetInputFocus)(dpy, window.0, xlib::RevertToPointerRoot, xlib::CurrentTime);
        (t.XTestFakeMotionEvent)(dpy, 0, window.1, window.2, 0);
        (x.XFlush)(dpy);
        std::thread::sleep(std::time::Duration::from_millis(100));
        let key = |sym: u32, down: bool| {
            let code = (x.XKeysymToKeycode)(dpy, sym as u64);
            (t.XTestFakeKeyEvent)(dpy, code as u32, down as i32, 0);
            (x.XFlush)(dpy);
        };
        for &(sym, hold) in presses {
            key(sym, true);
            std::thread::sleep(hold);
            key(sym, false);
            std::thread::sleep(std::time::Duration::from_millis(200));
        }
        key(keysym::XK_Escape, true);
        key(keysym::XK_Escape, false);
        (x.XCloseDisplay)(dpy);
    }
    Ok(())
}

#[cfg(target_os = "linux")]
#[test]
fn keyboard_flies_the_camera_and_escape_quits() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let dir = temp_dir("keys");
    let path = dir.join("flown.csv");
    let args = [
        "view",
        "terrains/alps.toml",
        "--size",
        "96x72",
        "--mode",
        "free",
        "--start",
        "20000,40000,2500,180",
        "--rate",
        "30",
        "--frames",
        "900",
        "--no-shadows",
        "--record",
        &s(&path),
    ];
    let hold = std::time::Duration::from_millis(1000);
    let o = run_with_keys(&x.display, &args, &[(x11_dl::keysym::XK_w, hold)]);
    check_ok("relief view (keys)", &o);
    let rows = read_csv(&path);
    assert!(
        rows.len() < 900,
        "Escape did not end the run ({} frames)",
        rows.len()
    );
    let (first, last) = (&rows[0], &rows[rows.len() - 1]);
    assert_eq!(
        (first["x"], first["y"], first["alt"]),
        (20000.0, 40000.0, 2500.0)
    );
    // W held: forward is south (heading 180) at 200 m/s; the sim steps 1/30 s per frame, so the
    // distance follows from the frames W was down, whatever the wall time.
    let moved = first["y"] - last["y"];
    let frames_moving = rows.windows(2).filter(|w| w[1]["y"] < w[0]["y"]).count();
    assert!(frames_moving > 0, "W moved nothing");
    assert!(
        (moved - frames_moving as f64 * 200.0 / 30.0).abs() < 1e-6,
        "moved {moved} m in {frames_moving} frames"
    );
    assert!((last["x"] - 20000.0).abs() < 1e-6 && last["alt"] == 2500.0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// E turns anti-aliasing off and on again while the window runs: the statistics CSV's
/// anti-aliased pixels and extra rays go from the frame's figures to none and back.
#[cfg(target_os = "linux")]
#[test]
fn the_e_key_turns_anti_aliasing_off_and_on() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let dir = temp_dir("aa-key");
    let csv = dir.join("stats.csv");
    let args = [
        "view",
        "terrains/alps.toml",
        "--size",
        "96x72",
        "--antialias",
        "edges",
        "--rate",
        "30",
        "--frames",
        "900",
        "--no-shadows",
        "--stats-csv",
        &s(&csv),
    ];
    let (e, press) = (x11_dl::keysym::XK_e, std::time::Duration::from_millis(50));
    let o = run_with_keys(&x.display, &args, &[(e, press), (e, press)]);
    check_ok("relief view (E)", &o);
    let rows = read_csv(&csv);
    assert!(rows.len() < 900, "Escape did not end the run");
    // Runs of frames with and without anti-aliasing: on (from the command line), off, on.
    let on: Vec<bool> = rows.iter().map(|r| r["aa_pixels"] > 0.0).collect();
    let mut runs: Vec<bool> = on.clone();
    runs.dedup();
    assert_eq!(runs, [true, false, true], "anti-aliased frames: {on:?}");
    for r in &rows {
        let (p, rays) = (r["aa_pixels"], r["aa_extra_rays"]);
        assert!(
            (4.0 * p..=16.0 * p).contains(&rays),
            "{p} anti-aliased pixels, {rays} extra rays"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---- CPU parts: no window, no GPU ----

#[test]
fn present_shader_validates() {
    let src = relief::app::view::present_shader();
    let module = naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| {
        panic!("present.wgsl:\n{}", e.emit_to_string(&src));
    });
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("present.wgsl: {}", e.emit_to_string(&src)));
}

#[test]
fn overlay_font_and_text_packing() {
    let font = present::font_words();
    let art = |c: char| -> String {
        (0..7)
            .map(|y| {
                (0..5)
                    .map(|x| {
                        if present::glyph_pixel(&font, c, x, y) {
                            '#'
                        } else {
                            '.'
                        }
                    })
                    .collect::<String>()
            })
            .collect::<Vec<_>>()
            .join("/")
    };
    assert_eq!(art('1'), "..#../.##../..#../..#../..#../..#../.###.");
    assert_eq!(art('L'), "#..../#..../#..../#..../#..../#..../#####");
    assert_eq!(art('m'), art('M'), "lower case shows as upper case");
    assert_eq!(art(' '), art('~'), "no glyph is blank");
    // Every glyph the overlay uses is distinct.
    let used = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ.:-+/%";
    for (i, a) in used.chars().enumerate() {
        assert!(art(a).contains('#'), "{a} is blank");
        for b in used.chars().skip(i + 1) {
            assert_ne!(art(a), art(b), "{a} and {b} look the same");
        }
    }
    let (words, cols, rows) = present::pack_text(&["ab".into(), "xyz9".into()]);
    assert_eq!((cols, rows), (4, 2));
    let bytes: Vec<u8> = words
        .iter()
        .flatten()
        .flat_map(|w| w.to_le_bytes())
        .collect();
    assert_eq!(&bytes[..8], b"AB  XYZ9");
}

fn flat_terrain(height: f64) -> relief::terrain::Terrain {
    common::terrain_from_fn(65, 30.0, |x, y| height + 0.2 * x + 0.1 * y)
}

fn level_pose(x: f64, y: f64, z: f64) -> relief::scene::Pose {
    relief::scene::Pose {
        position: glam::DVec3::new(x, y, z),
        heading: 90.0,
        pitch: 0.0,
        roll: 0.0,
        fov: 60.0,
    }
}

#[test]
fn aircraft_dive_stops_at_the_floor_and_free_flight_too() {
    let terrain = flat_terrain(100.0);
    for mode in [Mode::Aircraft, Mode::Free] {
        let mut m = Motion::new(mode, level_pose(300.0, 900.0, 400.0), None, 25.0);
        let c = Controls {
            throttle: Some(1.0),
            pitch: -1.0,
            forward: 1.0,
            up: -1.0,
            ..Controls::default()
        };
        let mut lowest = f64::INFINITY;
        for i in 0..300 {
            m.step(i as f64 / 60.0, 1.0 / 60.0, &c, &terrain);
            let agl = relief::cpu::query::height_above_terrain(&terrain, m.pose.position).unwrap();
            assert!(agl >= 25.0, "{mode:?} step {i}: {agl} m above ground");
            lowest = lowest.min(agl);
        }
        assert!(
            lowest < 25.01,
            "{mode:?} never reached the floor ({lowest})"
        );
        assert!(m.floor_contacts > 0);
    }
}

/// A paged window that moved with the eye: the motion stays in the scene's own frame, 9 km
/// east of the terrain's grid here, and its floor is the terrain under the position mapped
/// into the terrain's frame (`step_over`). Over the scene frame's own point there is no grid,
/// hence no floor.
#[test]
fn the_floor_is_the_terrain_under_the_position_in_its_frame() {
    let terrain = flat_terrain(100.0);
    let shift = glam::DVec3::new(-9000.0, 0.0, 0.0);
    let c = Controls {
        forward: 1.0,
        up: -1.0,
        ..Controls::default()
    };
    let mut m = Motion::new(Mode::Free, level_pose(9300.0, 900.0, 400.0), None, 25.0);
    for i in 0..300 {
        m.step_over(i as f64 / 60.0, 1.0 / 60.0, &c, &terrain, |p| p + shift);
        let at = m.pose.position + shift;
        let agl = relief::cpu::query::height_above_terrain(&terrain, at).unwrap();
        assert!(agl >= 25.0, "step {i}: {agl} m above ground");
    }
    assert!(m.floor_contacts > 0);
    let mut m = Motion::new(Mode::Free, level_pose(9300.0, 900.0, 400.0), None, 25.0);
    for i in 0..300 {
        m.step(i as f64 / 60.0, 1.0 / 60.0, &c, &terrain);
    }
    assert_eq!(m.floor_contacts, 0);
}

#[test]
fn aircraft_banks_into_a_turn_and_loses_height_when_slow() {
    let terrain = flat_terrain(0.0);
    let mut m = Motion::new(Mode::Aircraft, level_pose(900.0, 900.0, 3000.0), None, 10.0);
    // Roll right for a second, then hold the bank: the heading turns right.
    for i in 0..120 {
        let c = Controls {
            throttle: Some(0.6),
            roll: if i < 60 { 0.5 } else { 0.0 },
            ..Controls::default()
        };
        m.step(i as f64 / 60.0, 1.0 / 60.0, &c, &terrain);
    }
    assert!((m.pose.roll - 30.0).abs() < 1e-9, "roll {}", m.pose.roll);
    assert!(m.pose.heading > 93.0, "heading {}", m.pose.heading);
    // Throttle off, level: speed decays below the stall and gravity pulls the aircraft down.
    let mut m = Motion::new(Mode::Aircraft, level_pose(900.0, 900.0, 3000.0), None, 10.0);
    let idle = Controls {
        throttle: Some(0.0),
        ..Controls::default()
    };
    for i in 0..60 * 60 {
        m.step(i as f64 / 60.0, 1.0 / 60.0, &idle, &terrain);
    }
    assert!(m.aircraft.speed < m.params.stall_speed);
    assert!(m.pose.position.z < 2900.0, "z {}", m.pose.position.z);
}

#[test]
fn recorded_path_plays_back_exactly() {
    let dir = temp_dir("record");
    let file = dir.join("p.csv");
    let terrain = flat_terrain(0.0);
    let mut m = Motion::new(Mode::Aircraft, level_pose(900.0, 900.0, 500.0), None, 10.0);
    let mut rec = motion::PathRecorder::create(&file).unwrap();
    let mut poses = Vec::new();
    for i in 0..50 {
        let t = i as f64 / 30.0;
        let c = Controls {
            throttle: Some(0.8),
            roll: 0.3,
            pitch: 0.2,
            ..Controls::default()
        };
        m.step(t, 1.0 / 30.0, &c, &terrain);
        rec.record(t, &m.pose).unwrap();
        poses.push((t, m.pose));
    }
    rec.finish().unwrap();
    let path = motion::read_path_csv(&file, 60.0).unwrap();
    for (t, p) in &poses {
        let q = path.pose_at(*t);
        assert_eq!(q.position, p.position, "t = {t}");
        assert_eq!((q.heading, q.pitch, q.roll), (p.heading, p.pitch, p.roll));
    }
    // Broken files name the line.
    std::fs::write(&file, "0,1,2,3,4,5,6\n1,1,2,x,4,5,6\n").unwrap();
    let e = motion::read_path_csv(&file, 60.0).unwrap_err().to_string();
    assert!(e.contains("line 2") && e.contains("alt"), "{e}");
    std::fs::write(&file, "0,1,2,3,4,5,6\n0,1,2,3,4,5,6\n").unwrap();
    let e = motion::read_path_csv(&file, 60.0).unwrap_err().to_string();
    assert!(e.contains("does not increase"), "{e}");
    let script = dir.join("s.csv");
    std::fs::write(&script, "0,1.5,0,0,0\n").unwrap();
    let e = motion::ControlScript::load(&script)
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 1") && e.contains("throttle"), "{e}");
    std::fs::write(
        &script,
        "time,throttle,pitch,roll,yaw\n1,0.5,0,0,0\n2,1,1,0,0\n",
    )
    .unwrap();
    let sc = motion::ControlScript::load(&script).unwrap();
    assert_eq!(sc.at(0.5), None);
    assert_eq!(sc.at(1.5).unwrap().throttle, Some(0.5));
    assert_eq!(sc.at(9.0).unwrap().pitch, 1.0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn frame_statistics() {
    let v = [5.0, 1.0, 4.0, 2.0, 3.0, f64::NAN];
    assert_eq!(relief::app::figures::percentile(&v, 50.0), Some(3.0));
    assert_eq!(relief::app::figures::percentile(&v, 99.0), Some(5.0));
    assert_eq!(relief::app::figures::percentile(&v, 0.0), Some(1.0));
    assert_eq!(relief::app::figures::percentile(&[], 50.0), None);
    let p = 1000.0 / 60.0;
    assert_eq!(stats::dropped_slots(p, p), 0);
    assert_eq!(stats::dropped_slots(1.4 * p, p), 0);
    assert_eq!(stats::dropped_slots(2.0 * p, p), 1);
    assert_eq!(stats::dropped_slots(5.1 * p, p), 4);
    let frames: Vec<stats::FrameStat> = (0..11)
        .map(|i| stats::FrameStat {
            frame: i,
            start_s: i as f64 * 0.02,
            frame_ms: if i == 0 { 0.0 } else { 20.0 },
            latency_ms: 10.0 + i as f64,
            gpu_ms: f64::NAN,
            ..Default::default()
        })
        .collect();
    let s = stats::summarize(&frames);
    assert!((s.fps - 50.0).abs() < 1e-9, "fps {}", s.fps);
    assert_eq!(s.frame_ms_p50, 20.0);
    assert_eq!(s.latency_ms_p99, 20.0);
    assert_eq!(s.gpu_ms_p50, None);
}

/// Hours in a window: the frame loop's statistics stay bounded however long the run (kept
/// whole, they grew the process by about 0.2 KiB a frame, 40 MB an hour at 60 Hz), and the
/// streamed summary agrees with the exact figures over the same frames: each percentile at
/// most 0.1% below `figures::percentile`'s, the RSS fit over frames 100..500 the same, the
/// whole run's slope that of a least-squares fit over all of it. 100,000 frames whose GPU
/// times arrive two frames late, and a few never.
#[test]
fn run_statistics_stay_bounded_and_agree_with_the_exact_figures() {
    use relief::app::figures::{percentile, slope};
    let mut rng = common::Rng::new(22);
    let mut run = stats::RunStats::default();
    let (mut frame_ms, mut gpu_ms, mut rss) = (Vec::new(), Vec::new(), Vec::new());
    let n = 100_000u64;
    let mut most_pending = 0;
    for i in 0..n {
        let s = stats::FrameStat {
            frame: i,
            start_s: i as f64 / 60.0,
            frame_ms: if i == 0 { 0.0 } else { rng.range(10.0, 40.0) },
            latency_ms: rng.range(5.0, 80.0),
            gpu_ms: f64::NAN,
            rss_kib: 250_000 + i / 1000 + (rng.range(0.0, 64.0) as u64),
            ..Default::default()
        };
        run.push(s);
        frame_ms.push(s.frame_ms);
        rss.push(s.rss_kib as f64);
        let g = rng.range(1.0, 30.0);
        // Frames 7, 107, 207, … never get theirs.
        gpu_ms.push(if i % 100 == 7 { f64::NAN } else { g });
        if i >= 2 && (i - 2) % 100 != 7 {
            run.set_gpu_ms(i - 2, gpu_ms[i as usize - 2]);
        }
        let _ = run.settle(i.saturating_sub(8), false);
        most_pending = most_pending.max(run.pending());
    }
    for f in [n - 2, n - 1] {
        if f % 100 != 7 {
            run.set_gpu_ms(f, gpu_ms[f as usize]);
        }
    }
    let rest = run.settle(n, true);
    assert!(rest.len() <= 9, "{} frames left to settle", rest.len());
    assert!(most_pending <= 9, "{most_pending} frames pending at once");
    let s = run.summary();
    assert_eq!(s.frames, n as usize);
    let close = |what: &str, streamed: f64, exact: f64| {
        assert!(
            streamed <= exact && streamed >= exact * (1.0 - 1.001e-3),
            "{what}: streamed {streamed}, exact {exact}"
        );
    };
    for q in [50.0, 99.0] {
        let exact = percentile(&frame_ms[1..], q).unwrap();
        close(
            "frame time",
            if q == 50.0 {
                s.frame_ms_p50
            } else {
                s.frame_ms_p99
            },
            exact,
        );
        let exact = percentile(&gpu_ms, q).unwrap();
        let streamed = if q == 50.0 {
            s.gpu_ms_p50
        } else {
            s.gpu_ms_p99
        };
        close("GPU time", streamed.unwrap(), exact);
    }
    assert_eq!(s.rss_window, [100, 500]);
    assert_eq!(s.rss_slope_kib_per_frame, slope(&rss[100..500]));
    let whole = slope(&rss[100..]);
    let run_slope = s.rss_run_slope_kib_per_frame.unwrap();
    assert!(
        (run_slope - whole).abs() <= 1e-9 * whole.abs().max(1e-6),
        "{run_slope} vs {whole}"
    );
    assert!(
        (run_slope - 0.001).abs() < 1e-4,
        "the RSS's own slope: {run_slope}"
    );
    // The later part: from frame 32,768 (the last power of two in the first half) on.
    let late = rss[n as usize - 1] - rss[32_768];
    assert_eq!(s.rss_late, Some(([32_768, n as u32], late as i64)));
}

/// A one-time step early in a run (llvmpipe GL keeps its first 1 MiB upload buffer to the end,
/// made at frame 1,737 of an anti-aliased window at 160x90) gives the whole run a slope; the
/// later part's change does not see it, and does see growth that goes on.
#[test]
fn the_later_part_of_a_run_ignores_an_early_step() {
    let summary = |rss: &dyn Fn(u64) -> u64| {
        let mut run = stats::RunStats::default();
        for i in 0..5_200u64 {
            run.push(stats::FrameStat {
                frame: i,
                start_s: i as f64 / 60.0,
                rss_kib: rss(i),
                ..Default::default()
            });
        }
        run.settle(5_200, true);
        run.summary()
    };
    let step = summary(&|i| 193_404 + if i >= 1_737 { 1_028 } else { 0 });
    assert!(step.rss_run_slope_kib_per_frame.unwrap() > 0.2);
    assert_eq!(step.rss_late, Some(([2_048, 5_200], 0)));
    let leak = summary(&|i| 193_404 + i / 2);
    assert_eq!(leak.rss_late, Some(([2_048, 5_200], 5_199 / 2 - 1_024)));
    let mut run = stats::RunStats::default();
    for i in 0..256u64 {
        run.push(stats::FrameStat {
            frame: i,
            ..Default::default()
        });
    }
    assert_eq!(
        run.summary().rss_late,
        None,
        "256 frames have no later part from 128"
    );
}

#[test]
fn eye_feed_lines() {
    let p = Path::new("eyes.csv");
    let f = motion::EyeFeed::parse(p, "x,y,z\n0,0,0\n# moved\n0.1,-0.2,0.3\n").unwrap();
    assert_eq!(f.at(0), glam::DVec3::ZERO);
    assert_eq!(f.at(1), glam::DVec3::new(0.1, -0.2, 0.3));
    assert_eq!(f.at(99), glam::DVec3::new(0.1, -0.2, 0.3));
    let e = motion::EyeFeed::parse(p, "0,0\n").unwrap_err().to_string();
    assert!(e.contains("eyes.csv") && e.contains("line 1"), "{e}");
}

/// Hours in a window: 600 unpaced frames, the RSS slope over frames 100..500 and wgpu's live
/// objects at frames 100 and 500 from the exit summary. Before the fix lavapipe grew about
/// 3.6 MB a frame here.
#[test]
fn view_keeps_memory_and_wgpu_objects_flat() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let o = relief(
        &[
            "view",
            "terrains/alps.toml",
            "--size",
            "160x120",
            "--frames",
            "600",
            "--unpaced",
            "--no-overlay",
        ],
        Some(&x.display),
        &[],
    );
    let out = check_ok("relief view (soak)", &o);
    eprintln!("{out}");
    let memory = out
        .lines()
        .find(|l| l.starts_with("memory:"))
        .unwrap_or_else(|| panic!("no memory line in the summary: {out}"));
    let slope: f64 = memory
        .split("RSS slope ")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no RSS slope in `{memory}`"));
    assert!(slope < 4.0, "RSS grows {slope} KiB per frame: {memory}");
    assert!(
        memory.contains("wgpu objects at frames 100 and 500: unchanged"),
        "wgpu objects changed between frames 100 and 500: {memory}"
    );
}

/// `relief view --terrain-memory 8` on a database scene (the 16x16 × 257² synthetic mosaic of
/// `tests/paged.rs`, its finest level): the window pages each frame without waiting; once the
/// view's tiles are resident its frame equals the headless `render --terrain-memory 8` (which
/// waits for them) within a mean error of 1/255.
#[test]
fn paged_window_matches_headless_paged_render() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let db = common::pager_mosaic();
    let dir = temp_dir("paged-view");
    let scene = dir.join("mosaic.toml");
    let text = format!(
        "[terrain]\ndatabase = {:?}\nwindow = [46.0, 12.0, 54.0, 20.0]\ncurved = false\n[camera]\nposition = [120000.0, 434000.0, 3700.0]\nheading = 90.0\npitch = -12.0\nfov = 60.0\n[output]\nwidth = 160\nheight = 120\n",
        s(&db)
    );
    std::fs::write(&scene, text).unwrap();
    let cap = dir.join("cap");
    let o = relief(
        &[
            "view",
            &s(&scene),
            "--size",
            "160x120",
            "--frames",
            "60",
            "--no-overlay",
            "--terrain-memory",
            "8",
            "--capture-frames",
            &s(&cap),
        ],
        Some(&x.display),
        &[],
    );
    check_ok("relief view --terrain-memory", &o);
    let head = dir.join("head");
    let r = relief(
        &[
            "render",
            &s(&scene),
            "--terrain-memory",
            "8",
            "--out",
            &s(&head),
        ],
        None,
        &[],
    );
    check_ok("relief render --terrain-memory", &r);
    assert_matches(
        "paged-view",
        &cap.join("frame_0059.png"),
        &head.join("frame_0000.png"),
    );
}

#[test]
fn anti_aliased_window_frames_match_headless_render() {
    let Some((x, _lock)) = window_env() else {
        return;
    };
    let dir = temp_dir("antialias");
    let (cap, head) = (dir.join("cap"), dir.join("headless"));
    let (cap_s, head_s) = (s(&cap), s(&head));
    let common = ["--size", "160x120", "--antialias", "edges"];
    let mut args = vec![
        "view",
        "terrains/alps.toml",
        "--frames",
        "8",
        "--rate",
        "30",
    ];
    args.extend_from_slice(&["--unpaced", "--no-overlay", "--capture-frames", &cap_s]);
    args.extend_from_slice(&common);
    check_ok(
        "relief view --antialias edges",
        &relief(&args, Some(&x.display), &[]),
    );
    let mut args = vec![
        "render",
        "terrains/alps.toml",
        "--first",
        "5",
        "--frames",
        "1",
    ];
    args.extend_from_slice(&["--out", &head_s]);
    args.extend_from_slice(&common);
    check_ok("relief render --antialias edges", &relief(&args, None, &[]));
    assert_matches(
        "view-antialias-0005",
        &cap.join("frame_0005.png"),
        &head.join("frame_0005.png"),
    );
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cap.join("frame_0005.json")).unwrap())
            .unwrap();
    let rays = meta["antialias"]["extra_rays"].as_u64().unwrap_or(0);
    assert!(rays > 0, "the window's frame JSON reports its extra rays");
    let _ = std::fs::remove_dir_all(&dir);
}
