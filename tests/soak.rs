//! Long runs: `relief bench soak` on each software adapter (Vulkan and GL) as a child
//! process. Before the fix, lavapipe grew about 3.5 MB a frame (it compiled every pass again
//! each frame with the uniform values inlined, and kept the code); the bound here is 4 KiB a
//! frame.

mod common;

use common::{backends, relief_cli};

/// Largest RSS slope accepted (KiB per frame over frames 100..500).
const MAX_SLOPE_KIB: f64 = 4.0;

#[test]
fn soak_keeps_memory_and_wgpu_objects_flat_on_every_adapter() {
    let _l = common::gpu_lock();
    for backend in backends() {
        let o = relief_cli(
            &[
                "bench",
                "soak",
                "terrains/alps.toml",
                "--size",
                "160x120",
                "--frames",
                "600",
                "--json",
            ],
            &[("WGPU_BACKEND", backend)],
        );
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{backend}: relief bench soak failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let r: serde_json::Value = serde_json::from_str(&stdout).expect("one JSON object");
        let d = &r["details"];
        let slope = d["rss_slope_kib_per_frame"].as_f64().unwrap();
        let rss = d["rss_kib"].as_array().unwrap();
        eprintln!(
            "{backend} ({}): RSS {} -> {} KiB, slope {slope:.3} KiB/frame, frame p50 {:.2} ms p99 {:.2} ms max {:.2} ms",
            r["adapter"], rss[0], rss[rss.len() - 1], d["frame_ms_p50"].as_f64().unwrap(),
            d["frame_ms_p99"].as_f64().unwrap(), d["frame_ms_max"].as_f64().unwrap()
        );
        assert_eq!(rss.len(), 600, "{backend}: one RSS figure per frame");
        assert_eq!(d["window"], serde_json::json!([100, 500]));
        assert!(
            slope < MAX_SLOPE_KIB,
            "{backend}: RSS grows {slope:.1} KiB per frame (< {MAX_SLOPE_KIB} required)"
        );
        let (a, b) = (&d["resources_start"], &d["resources_end"]);
        assert!(
            a.as_array().is_some_and(|v| !v.is_empty()),
            "{backend}: no wgpu report"
        );
        assert_eq!(a, b, "{backend}: wgpu objects at frames 100 and 500 differ");
    }
}

/// The same with every frame anti-aliased (`--antialias edges`: the edge mask read back, the
/// list, the sample atlas and its batches, the resolve, each frame), on each software adapter.
#[test]
fn an_anti_aliased_soak_keeps_memory_and_wgpu_objects_flat() {
    let _l = common::gpu_lock();
    for backend in backends() {
        let args = [
            "bench",
            "soak",
            "terrains/alps.toml",
            "--size",
            "160x90",
            "--frames",
            "600",
            "--antialias",
            "edges",
            "--json",
        ];
        let o = relief_cli(&args, &[("WGPU_BACKEND", backend)]);
        assert!(
            o.status.success(),
            "{backend}: relief bench soak --antialias edges failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let r: serde_json::Value =
            serde_json::from_str(&String::from_utf8_lossy(&o.stdout)).expect("one JSON object");
        let d = &r["details"];
        let slope = d["rss_slope_kib_per_frame"].as_f64().unwrap();
        let rays = d["antialias_extra_rays"].as_u64().unwrap();
        eprintln!(
            "{backend}: anti-aliased soak ({}): slope {slope:.3} KiB/frame, {rays} sub-pixel rays, frame p50 {:.2} ms",
            r["adapter"],
            d["frame_ms_p50"].as_f64().unwrap()
        );
        // Every frame of the alps path marks edges: at least 4 rays for 100 pixels a frame.
        assert!(rays >= 600 * 400, "{backend}: the frames were anti-aliased");
        assert!(
            slope < MAX_SLOPE_KIB,
            "{backend}: RSS grows {slope:.1} KiB per frame (< {MAX_SLOPE_KIB} required)"
        );
        assert_eq!(
            d["resources_start"], d["resources_end"],
            "{backend}: wgpu objects at frames 100 and 500 differ"
        );
    }
}

#[test]
fn soak_slope_fits_a_known_line() {
    // The fit itself, on exact data: 3 KiB a frame from 1000 KiB, with one frame's noise
    // cancelling around the centre.
    let y: Vec<f64> = (0..400).map(|i| 1000.0 + 3.0 * i as f64).collect();
    assert!((relief::app::figures::slope(&y) - 3.0).abs() < 1e-9);
    let flat = vec![5.0; 50];
    assert_eq!(relief::app::figures::slope(&flat), 0.0);
    assert_eq!(relief::app::figures::window(600), [100, 500]);
    assert_eq!(relief::app::figures::window(100), [20, 100]);
}
