//! PFM and Bourke warp files: the real SGCT files parse, round trips are exact, bad files
//! give clear errors.

mod common;

use common::project_dir;
use relief::display::warp::{read_bourke, read_pfm, write_bourke, write_pfm, Pfm, RowOrder};
use std::path::PathBuf;

fn data(name: &str) -> PathBuf {
    project_dir().join("tests/data").join(name)
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("relief-warp-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

#[test]
fn sgct_files_parse() {
    let m = read_bourke(&data("standard_16x9.data")).unwrap();
    assert_eq!((m.mesh_type, m.nx, m.ny, m.nodes.len()), (2, 100, 60, 6000));
    assert_eq!(m.nodes[0].x, -1.77778);
    assert!(m
        .nodes
        .iter()
        .all(|n| n.x.abs() <= 1.77778 + 1e-9 && n.y.abs() <= 1.0 + 1e-9));
    let p = read_pfm(&data("surface1.pfm"), RowOrder::BottomToTop).unwrap();
    assert_eq!((p.width, p.height, p.channels), (100, 100, 3));
    assert!(p
        .data
        .chunks_exact(3)
        .all(|px| px[0].is_finite() && px[1].is_finite() && px[2].is_nan()));
    // Row order is explicit: reading top-to-bottom flips the rows.
    let q = read_pfm(&data("surface1.pfm"), RowOrder::TopToBottom).unwrap();
    assert_eq!(p.pixel(3, 0)[..2], q.pixel(3, 99)[..2]);
}

#[test]
fn round_trips_are_exact() {
    let m = read_bourke(&data("standard_16x9.data")).unwrap();
    let out = tmp("mesh.data");
    write_bourke(&out, &m).unwrap();
    assert_eq!(read_bourke(&out).unwrap(), m);
    let p = Pfm {
        width: 3,
        height: 2,
        channels: 3,
        data: vec![
            0.1,
            f32::NAN,
            -3.5e-7,
            1.0,
            2.0,
            3.0,
            4.0,
            5.0,
            6.0,
            7.0,
            8.0,
            f32::MAX,
            0.0,
            -0.0,
            1e-38,
            9.0,
            10.0,
            11.0,
        ],
    };
    for order in [RowOrder::BottomToTop, RowOrder::TopToBottom] {
        let f = tmp("w.pfm");
        write_pfm(&f, &p, order).unwrap();
        let back = read_pfm(&f, order).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!((back.width, back.height, back.channels), (3, 2, 3));
        assert_eq!(bits(&back.data), bits(&p.data), "{order:?}");
    }
    let g = read_pfm(&data("surface1.pfm"), RowOrder::BottomToTop).unwrap();
    let f = tmp("s.pfm");
    write_pfm(&f, &g, RowOrder::BottomToTop).unwrap();
    let back = read_pfm(&f, RowOrder::BottomToTop).unwrap();
    assert!(back
        .data
        .iter()
        .zip(&g.data)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
}

#[test]
fn bad_warp_files_give_clear_errors() {
    let good = std::fs::read(data("surface1.pfm")).unwrap();
    let mesh = std::fs::read_to_string(data("standard_16x9.data")).unwrap();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("header", b"P6\n100 100\n255\n".to_vec(), "PF"),
        ("short", good[..good.len() / 2].to_vec(), "short data"),
        ("zero scale", b"PF\n2 2\n0.0\n".to_vec(), "scale"),
        ("size", b"PF\n-2 2\n-1.0\n".to_vec(), "size"),
    ];
    for (label, bytes, want) in cases {
        let f = tmp("bad.pfm");
        std::fs::write(&f, bytes).unwrap();
        let e = read_pfm(&f, RowOrder::BottomToTop)
            .expect_err(label)
            .to_string();
        assert!(e.contains(want) && e.contains("bad.pfm"), "{label}: {e}");
    }
    let lines: Vec<&str> = mesh.lines().collect();
    let mesh_cases: Vec<(&str, String, &str)> = vec![
        ("count", lines[..lines.len() - 3].join("\n"), "6000 nodes"),
        ("type", format!("3\n{}", lines[1..].join("\n")), "mesh type"),
        ("number", mesh.replacen("-1.77778", "-1.7x", 1), "5 numbers"),
        ("nan", mesh.replacen("-1.77778", "nan", 1), "finite"),
        (
            "dims",
            format!("2\n100\n{}", lines[2..].join("\n")),
            "nx ny",
        ),
        ("empty", String::new(), "empty"),
    ];
    for (label, text, want) in mesh_cases {
        let f = tmp("bad.data");
        std::fs::write(&f, text).unwrap();
        let e = read_bourke(&f).expect_err(label).to_string();
        assert!(e.contains(want) && e.contains("bad.data"), "{label}: {e}");
    }
}

#[test]
fn cli_exports_and_inspects_a_dome_warp() {
    let exe = env!("CARGO_BIN_EXE_relief");
    let cfg = project_dir().join("distortion/dome-moving-eye.toml");
    for name in ["dome.pfm", "dome.data"] {
        let out = tmp(name);
        let st = std::process::Command::new(exe)
            .args([
                "warp",
                "export",
                cfg.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ])
            .status()
            .unwrap();
        assert!(st.success());
        let o = std::process::Command::new(exe)
            .args(["warp", "inspect", out.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(o.status.success());
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(
            text.contains(if name.ends_with("pfm") {
                "PFM 512x512"
            } else {
                "65x65 nodes"
            }),
            "{text}"
        );
    }
    // The exported 3-D warp holds the screen points: all on the 1.5 m dome.
    let p = read_pfm(&tmp("dome.pfm"), RowOrder::BottomToTop).unwrap();
    let r: Vec<f32> = p
        .data
        .chunks_exact(3)
        .filter(|q| q[0].is_finite())
        .map(|q| (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt())
        .collect();
    assert!(r.len() > 100_000 && r.iter().all(|r| (r - 1.5).abs() < 1e-4));
    let bad = std::process::Command::new(exe)
        .args(["warp", "inspect", "nope.pfm"])
        .output()
        .unwrap();
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("nope.pfm"));
}
