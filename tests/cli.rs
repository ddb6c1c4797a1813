//! The `relief` binary: error paths of `render` (none reach the GPU) and `query`.

mod common;

use common::{temp_dir, terrains};
use std::path::Path;
use std::process::Output;

fn relief(args: &[&str]) -> Output {
    common::relief_cli(args, &[])
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Asserts a failing exit whose stderr mentions every needle; returns stderr.
fn assert_fails(what: &str, o: &Output, needles: &[&str]) -> String {
    let (out, err) = text(o);
    assert!(
        !o.status.success(),
        "{what}: expected a non-zero exit, got {}\nstdout: {out}\nstderr: {err}",
        o.status
    );
    for n in needles {
        assert!(
            err.contains(n),
            "{what}: stderr should mention `{n}`\nstderr: {err}"
        );
    }
    err
}

/// Frame files (`frame_*`, `depth_*`, partial or not) in `dir`, which may not exist.
fn frame_files(dir: &Path) -> Vec<String> {
    match std::fs::read_dir(dir) {
        Err(_) => Vec::new(),
        Ok(rd) => rd
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("frame_") || n.starts_with("depth_"))
            .collect(),
    }
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn render_missing_scene_fails_and_writes_nothing() {
    let dir = temp_dir("cli-missing");
    let out = dir.join("out");
    let o = relief(&["render", "does-not-exist.toml", "--out", &s(&out)]);
    assert_fails("missing scene", &o, &["does-not-exist.toml"]);
    assert_eq!(
        frame_files(&out),
        Vec::<String>::new(),
        "no frame files for a missing scene"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_invalid_fov_fails_and_writes_nothing() {
    let dir = temp_dir("cli-fov");
    let scene = dir.join("fov.toml");
    std::fs::write(
        &scene,
        "[terrain.procedural]\nsize = 65\n[camera]\nposition = [100.0, 100.0, 3000.0]\nfov = 0.0\n",
    )
    .unwrap();
    let out = dir.join("out");
    let o = relief(&["render", &s(&scene), "--out", &s(&out)]);
    assert_fails("fov = 0", &o, &["camera.fov"]);
    assert_eq!(
        frame_files(&out),
        Vec::<String>::new(),
        "no frame files for an invalid scene"
    );
    assert_eq!(
        frame_files(&dir),
        Vec::<String>::new(),
        "nothing written next to the scene either"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_truncated_hgt_fails_naming_the_file() {
    let dir = temp_dir("cli-trunc");
    let hgt = dir.join("N47E009.hgt");
    let bytes = std::fs::read(terrains().join("N47E009.hgt")).unwrap();
    std::fs::write(&hgt, &bytes[..1000]).unwrap();
    let scene = dir.join("trunc.toml");
    std::fs::write(
        &scene,
        "[terrain]\nsource = \"N47E009.hgt\"\n[camera]\nposition = [20000.0, 20000.0, 4000.0]\n",
    )
    .unwrap();
    let out = dir.join("out");
    let o = relief(&["render", &s(&scene), "--out", &s(&out)]);
    assert_fails("truncated .hgt", &o, &[&s(&hgt), "truncated"]);
    assert_eq!(
        frame_files(&out),
        Vec::<String>::new(),
        "no frame files for a truncated terrain"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_zero_size_is_rejected() {
    let dir = temp_dir("cli-size");
    let out = dir.join("out");
    let alps = s(&terrains().join("alps.toml"));
    let o = relief(&["render", &alps, "--size", "0x10", "--out", &s(&out)]);
    assert_fails("--size 0x10", &o, &["0x10", "1..=16384"]);
    let o = relief(&["render", &alps, "--size", "640", "--out", &s(&out)]);
    assert_fails("--size 640", &o, &["WIDTHxHEIGHT"]);
    assert_eq!(frame_files(&out), Vec::<String>::new());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Parses `z = <number> m` from the `query --at` output.
fn parse_height(stdout: &str) -> f64 {
    let z = stdout
        .split("z = ")
        .nth(1)
        .unwrap_or_else(|| panic!("no `z = ` in query output: {stdout}"));
    z.split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap_or_else(|e| panic!("bad height in `{stdout}`: {e}"))
}

#[test]
fn query_height_inside_and_outside() {
    let alps = s(&terrains().join("alps.toml"));
    let o = relief(&["query", &alps, "--at", "26000,28000"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "query --at 26000,28000 failed: {err}");
    let z = parse_height(&out);
    assert!(
        (388.0..=2937.0).contains(&z),
        "height {z} outside the tile's range 388..2937 m"
    );
    // Both spellings of a negative coordinate.
    for args in [
        &["query", &alps, "--at=-5,-5"][..],
        &["query", &alps, "--at", "-5,-5"][..],
    ] {
        let o = relief(args);
        assert_fails(&format!("{args:?}"), &o, &["outside"]);
    }
}

#[test]
fn query_line_of_sight() {
    let alps = s(&terrains().join("alps.toml"));
    let o = relief(&["query", &alps, "--los", "1000,1000,5000", "2000,2000,5000"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "los query failed: {err}");
    assert!(
        out.contains("clear") && !out.contains("blocked"),
        "5000 m above the tile must be clear: {out}"
    );
    // Negative coordinates are values, not flags (the start is off the grid, south-west).
    let o = relief(&[
        "query",
        &alps,
        "--los",
        "-1000,-1000,5000",
        "2000,2000,5000",
    ]);
    let (out, err) = text(&o);
    assert!(
        o.status.success(),
        "los query with negative coordinates failed: {err}"
    );
    assert!(
        out.contains("clear"),
        "5000 m from off the grid must be clear: {out}"
    );
    // 500 m high across the Alpstein (Säntis 2502 m): blocked.
    let o = relief(&[
        "query",
        &alps,
        "--los",
        "15000,28000,500",
        "40000,28000,500",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "los query failed: {err}");
    assert!(
        out.contains("blocked") && !out.contains("clear"),
        "a 500 m line through the Alpstein must be blocked: {out}"
    );
}

#[test]
fn query_without_a_question_fails() {
    let alps = s(&terrains().join("alps.toml"));
    let o = relief(&["query", &alps]);
    assert_fails("query without --at/--los", &o, &["--at", "--los"]);
}

#[test]
fn voxel_bench_without_voxel_models_is_refused() {
    let alps = s(&terrains().join("alps.toml"));
    let o = relief(&["bench", "voxels", &alps]);
    assert_fails(
        "bench voxels alps",
        &o,
        &["alps.toml", "no [[voxels]] model"],
    );
}
