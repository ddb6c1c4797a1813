//! The list of marked pixels built on the GPU (`--aa-list gpu`, the default on GPUs) is the
//! one the CPU makes from the same edge mask, entry for entry, and frames rendered with either
//! are byte-identical.

mod common;

/// A `w` x `h` mask with about `density`% of its pixels marked 16, 8 or 4 (and some bytes that
/// are no sample count: not in the list).
fn mask(w: u32, h: u32, density: u32, seed: &mut u32) -> Vec<u8> {
    (0..w * h)
        .map(|_| {
            *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let r = *seed >> 8;
            if r % 100 < density {
                [16u8, 8, 4, 3][(r / 100 % 4) as usize]
            } else {
                0
            }
        })
        .collect()
}

#[test]
fn the_gpu_builds_the_cpus_list_entry_for_entry() {
    let _l = common::gpu_lock();
    let Some(g) = common::gpu() else { return };
    let mut seed = 11u32;
    // Tiles cut by the screen's edges (21x13, 1x1, 1283x721), one tile, small and large
    // screens, few marks and every pixel marked.
    for (w, h, densities) in [
        (21, 13, &[0u32, 3, 30, 100][..]),
        (1, 1, &[0, 100][..]),
        (8, 8, &[50][..]),
        (320, 180, &[2, 100][..]),
        (1283, 721, &[1, 100][..]),
    ] {
        for &d in densities {
            let m = mask(w, h, d, &mut seed);
            let cpu = relief::gpu::antialias::list_on_cpu(&m, w, h).expect("CPU list");
            let gpu = relief::gpu::antialias::list_on_gpu(g, &m, w, h).expect("GPU list");
            assert_eq!(gpu.1, cpu.1, "{w}x{h} at {d}%: the parts' lengths");
            let first_difference = gpu.0.iter().zip(&cpu.0).position(|(a, b)| a != b);
            assert!(
                gpu.0.len() == cpu.0.len() && first_difference.is_none(),
                "{w}x{h} at {d}%: {} entries against {}, first difference at {first_difference:?}",
                gpu.0.len(),
                cpu.0.len()
            );
            assert_eq!(cpu.0.is_empty(), d == 0, "{w}x{h} at {d}%");
        }
    }
    // A mask of the wrong size is refused, not read past its end, and one over the
    // adapter's texture size too.
    assert!(relief::gpu::antialias::list_on_gpu(g, &[0; 5], 2, 3).is_err());
    assert!(relief::gpu::antialias::list_on_cpu(&[0; 5], 2, 3).is_err());
    let wide = g.device.limits().max_texture_dimension_2d + 1;
    assert!(relief::gpu::antialias::list_on_gpu(g, &vec![0; wide as usize], wide, 1).is_err());
}

/// End to end from the command line: the same anti-aliased frames (PNG and depth TIFF) with
/// the list built on either side, on a terrain scene and on the free forms of the airfield,
/// with the adaptive counts and with 16 samples everywhere (the reference, whose list is every
/// pixel); a bad value is refused naming the option.
#[test]
fn frames_are_the_same_with_the_list_built_on_the_gpu() {
    let _l = common::gpu_lock();
    if common::gpu().is_none() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("relief-aa-list-{}", std::process::id()));
    let relief = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_relief"))
            .args(args)
            .env("NODEVICE_SELECT", "1")
            .output()
            .unwrap()
    };
    for (scene, aa, size) in [
        ("alps.toml", "edges", "200x120"),
        ("airfield.toml", "edges", "200x120"),
        ("alps.toml", "reference", "96x54"),
    ] {
        let path = common::terrains().join(scene);
        let mut files = Vec::new();
        for list in ["cpu", "gpu"] {
            let out = dir.join(format!("{scene}-{aa}-{list}"));
            let o = relief(&[
                "render",
                path.to_str().unwrap(),
                "--size",
                size,
                "--antialias",
                aa,
                "--frames",
                "2",
                "--aa-list",
                list,
                "--out",
                out.to_str().unwrap(),
            ]);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let json: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(out.join("frame_0001.json")).unwrap(),
            )
            .unwrap();
            assert!(
                json["antialias"]["pixels"].as_u64().unwrap() > 0,
                "{scene}: nothing anti-aliased: {json}"
            );
            files.push(
                [
                    "frame_0000.png",
                    "depth_0000.tiff",
                    "frame_0001.png",
                    "depth_0001.tiff",
                ]
                .map(|f| std::fs::read(out.join(f)).unwrap()),
            );
        }
        assert!(
            files[0] == files[1],
            "{scene} with {aa}: the frames differ between --aa-list cpu and gpu"
        );
    }
    let o = relief(&["render", "--aa-list", "sometimes"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("aa-list"));
    let _ = std::fs::remove_dir_all(&dir);
}
