//! Image sizes over the adapter's limits or the memory budget: a one-line error naming
//! `--size` (or the projector channel), exit status 1, no panic, no file written.

mod common;

use common::{relief_cli, temp_dir};

fn assert_refused(args: &[&str], out: &std::path::Path, needles: &[&str]) {
    let o = relief_cli(args, &[("RUST_LOG", "error")]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` not in: {err}");
    }
    let left: Vec<_> = std::fs::read_dir(out)
        .map(|d| d.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(left.is_empty(), "{args:?} left {left:?}");
}

#[test]
fn an_output_size_over_the_adapter_or_the_budget_is_refused_naming_size() {
    let _l = common::gpu_lock();
    let dir = temp_dir("device-limits");
    let out = dir.join("out");
    let o = out.to_str().unwrap();
    // 16384² needs a 4 GiB readback buffer and ~23 GiB of targets: over every software
    // adapter's buffer limit and over the default budget.
    assert_refused(
        &[
            "render",
            "terrains/alps.toml",
            "--size",
            "16384x16384",
            "--out",
            o,
        ],
        &out,
        &["--size", "16384x16384"],
    );
    // 4096² fits the adapter but not a 256 MiB budget.
    assert_refused(
        &[
            "render",
            "terrains/alps.toml",
            "--size",
            "4096x4096",
            "--memory-budget",
            "256",
            "--out",
            o,
        ],
        &out,
        &["--size", "4096x4096", "memory budget", "--memory-budget"],
    );
}

#[test]
fn a_projector_channel_over_the_budget_is_refused_naming_the_channel() {
    let _l = common::gpu_lock();
    let dir = temp_dir("device-limits-channel");
    let cfg = std::fs::read_to_string(common::project_dir().join("distortion/cylinder-3ch.toml"))
        .unwrap()
        .replacen(
            "width = 640\nheight = 400",
            "width = 8192\nheight = 8192",
            1,
        );
    let path = dir.join("big-channel.toml");
    std::fs::write(&path, cfg).unwrap();
    let out = dir.join("out");
    assert_refused(
        &[
            "render",
            "terrains/alps.toml",
            "--display",
            path.to_str().unwrap(),
            "--channel",
            "0",
            "--memory-budget",
            "1024",
            "--out",
            out.to_str().unwrap(),
        ],
        &out,
        &["8192x8192", "memory budget"],
    );
}

/// A wgpu error that no error scope catches (here an invalid buffer) is returned by the next
/// `Gpu::wait`, and by every one after it, instead of wgpu's default panic. A device of its
/// own: the shared one stays clean.
#[test]
fn a_wgpu_error_no_scope_catches_is_an_error_of_the_next_wait_not_a_panic() {
    let _l = common::gpu_lock();
    if common::gpu().is_none() {
        return;
    }
    let g = relief::gpu::Gpu::new().unwrap();
    g.wait().unwrap();
    // MAP_READ with STORAGE needs a feature relief does not ask for: a validation error.
    let _invalid = g.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("invalid on purpose"),
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let e = g.wait().unwrap_err().to_string();
    assert!(
        e.contains("wgpu error") && e.contains("invalid on purpose"),
        "{e}"
    );
    assert_eq!(g.wait().unwrap_err().to_string(), e);
}
