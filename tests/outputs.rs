//! A run that fails at frame N keeps the complete frames before N, says N, and leaves no
//! temporary or half-written file.

mod common;

use common::{relief_cli, temp_dir};

#[test]
fn a_render_failing_at_frame_2_keeps_frames_0_and_1_and_says_2() {
    let _l = common::gpu_lock();
    let dir = temp_dir("outputs-frame-n");
    let out = dir.join("out");
    // frame 2's PNG path is taken by a directory.
    std::fs::create_dir_all(out.join("frame_0002.png")).unwrap();
    let o = relief_cli(
        &[
            "render",
            "terrains/alps.toml",
            "--size",
            "32x24",
            "--frames",
            "4",
            "--out",
            out.to_str().unwrap(),
        ],
        &[("RUST_LOG", "off")],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.contains("frame 2"),
        "the error does not name frame 2: {err}"
    );
    assert!(
        err.contains("2 frame(s) before it are complete"),
        "the error does not say what is kept: {err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
    let mut names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "depth_0000.tiff",
            "depth_0001.tiff",
            "frame_0000.json",
            "frame_0000.png",
            "frame_0001.json",
            "frame_0001.png",
            "frame_0002.png",
        ],
        "frames 0 and 1 complete, nothing of frames 2 and 3, no temporary file"
    );
    for n in ["0000", "0001"] {
        let img = image::open(out.join(format!("frame_{n}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (32, 24));
        let (w, h, _) =
            relief::app::output::read_depth_tiff(&out.join(format!("depth_{n}.tiff"))).unwrap();
        assert_eq!((w, h), (32, 24));
        let meta: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join(format!("frame_{n}.json"))).unwrap(),
        )
        .unwrap();
        assert_eq!(meta["width"], 32);
    }
}
