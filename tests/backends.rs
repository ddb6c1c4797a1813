//! The same pictures on GL and Vulkan: each volume demo scene rendered by the CLI on
//! lavapipe and on llvmpipe (GL) must agree to a mean under 1/255 and a 99th percentile
//! under 4/255 over every channel of every pixel (before the fix GL rendered them black).

mod common;

use common::{backends, relief_cli, temp_dir};

fn render(scene: &str, backend: &str, out: &std::path::Path) -> image::RgbaImage {
    let o = relief_cli(
        &[
            "render",
            scene,
            "--size",
            "160x120",
            "--out",
            out.to_str().unwrap(),
        ],
        &[("WGPU_BACKEND", backend)],
    );
    assert!(
        o.status.success(),
        "{scene} on {backend}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    image::open(out.join("frame_0000.png")).unwrap().to_rgba8()
}

#[test]
fn volumes_on_gl_equal_volumes_on_vulkan() {
    let _l = common::gpu_lock();
    let have = backends();
    if have.len() < 2 {
        eprintln!("skipping: needs both the Vulkan and the GL adapter, found {have:?}");
        return;
    }
    let dir = temp_dir("backends");
    for scene in [
        "terrains/brain.toml",
        "terrains/clouds.toml",
        "terrains/function4d.toml",
    ] {
        let name = scene
            .trim_start_matches("terrains/")
            .trim_end_matches(".toml");
        let vk = render(scene, "vulkan", &dir.join(format!("{name}-vk")));
        let gl = render(scene, "gl", &dir.join(format!("{name}-gl")));
        let mut d: Vec<u8> = (vk.pixels().zip(gl.pixels()))
            .flat_map(|(a, b)| (0..3).map(move |c| a[c].abs_diff(b[c])))
            .collect();
        let lit = gl
            .pixels()
            .filter(|p| p[0] > 8 || p[1] > 8 || p[2] > 8)
            .count();
        d.sort_unstable();
        let mean = d.iter().map(|&v| v as f64).sum::<f64>() / d.len() as f64;
        let p99 = d[(d.len() - 1) * 99 / 100];
        eprintln!(
            "{name}: GL vs Vulkan mean {mean:.3}/255, p99 {p99}/255, max {}/255; {lit} of {} GL pixels not black",
            d[d.len() - 1],
            gl.pixels().len()
        );
        assert!(
            lit > gl.pixels().len() / 2,
            "{name}: the GL frame is mostly black"
        );
        if mean >= 1.0 || p99 >= 4 {
            let p = common::save_failure_images(&format!("backends-{name}-gl"), 160, 120, &gl, &vk);
            panic!(
                "{name}: GL differs from Vulkan: mean {mean:.3}/255 (< 1), p99 {p99}/255 (< 4); {}",
                p.display()
            );
        }
    }
}
