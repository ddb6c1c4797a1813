//! Every composed WGSL pass parses and validates with naga; no GPU needed.

/// Validates `src` as written (parameter blocks in uniform buffers) and as bound on
/// lavapipe (read-only storage buffers, `relief::gpu::ParamSpace::Storage`).
fn validate(name: &str, src: &str) {
    use relief::gpu::ParamSpace;
    validate_one(name, &ParamSpace::Uniform.wgsl(src));
    let storage = ParamSpace::Storage.wgsl(src);
    assert!(
        !storage.contains("var<uniform>"),
        "{name}: a uniform block is left"
    );
    validate_one(&format!("{name} (storage parameters)"), &storage);
}

fn validate_one(name: &str, src: &str) {
    let module = match naga::front::wgsl::parse_str(src) {
        Ok(m) => m,
        Err(e) => panic!("{name}.wgsl does not parse:\n{}", e.emit_to_string(src)),
    };
    let mut v = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    );
    if let Err(e) = v.validate(&module) {
        panic!("{name}.wgsl does not validate:\n{}", e.emit_to_string(src));
    }
}

#[test]
fn all_shaders_validate_with_naga() {
    for (name, src) in relief::gpu::shaders::all() {
        validate(name, &src);
    }
}

#[test]
fn every_specialised_variant_validates_with_naga() {
    // The passes built per switch combination (gpu::specialise): every combination, not only
    // the all-on and all-off ones `all()` lists.
    use relief::gpu::shaders;
    use relief::gpu::variants::FfTables;
    use relief::gpu::variants::ShadeFeatures;
    use relief::gpu::variants::VolumeSwitches;
    let bit = |bits: u32, k: u32| bits & (1 << k) != 0;
    for bits in 0..512 {
        let f = ShadeFeatures {
            shadows: bit(bits, 0),
            drape: bit(bits, 1),
            voxels: bit(bits, 2),
            volume_shadows: bit(bits, 3),
            curved: bit(bits, 4),
            lod: bit(bits, 5),
            paged: [0, 2][bit(bits, 6) as usize],
            drape_mips: bit(bits, 7),
            near: bit(bits, 8),
            // Cloud layers on in half of the combinations (odd parity: on and off with each
            // state of every other switch and each pair of them), not doubling the 512.
            clouds: bits.count_ones() % 2 == 1,
        };
        validate(&format!("shade {f:?}"), &shaders::shade(f));
        for tables in [
            FfTables::Storage,
            FfTables::Uniform {
                objects: 3,
                nodes: 7,
            },
        ] {
            validate(
                &format!("shade_objects {f:?} {tables:?}"),
                &shaders::shade_objects(f, tables),
            );
        }
    }
    for bits in 0..256 {
        let sw = VolumeSwitches {
            skip: bit(bits, 0),
            termination: bit(bits, 1),
            jitter: bit(bits, 2),
            mipmaps: bit(bits, 3),
            shell: bit(bits, 4),
            slices: bit(bits, 5),
            shadow: bit(bits, 6),
            sampled_fetch: bit(bits, 7),
        };
        validate(&format!("volume {sw:?}"), &shaders::volume(sw));
    }
}

#[test]
fn naga_rejects_a_broken_shader() {
    // The check above can fail: a type error is reported.
    let src = relief::gpu::shaders::cast(false, false, false)
        .replace("let t1 = tt.y;", "let t1: u32 = tt.y;");
    let module = naga::front::wgsl::parse_str(&src);
    let invalid = match module {
        Err(_) => true,
        Ok(m) => naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&m)
        .is_err(),
    };
    assert!(invalid);
}

#[test]
fn free_form_constants_match_the_cpu_side() {
    let src = relief::gpu::shaders::objects(true, relief::gpu::variants::FfTables::Storage);
    let ray_nodes = format!(
        "const FF_RAY_NODES: u32 = {}u;",
        relief::gpu::shaders::FF_RAY_NODES
    );
    assert!(
        src.contains(&ray_nodes),
        "WGSL and shaders::FF_RAY_NODES differ"
    );
    let levels = format!(
        "const FF_LEVELS: u32 = {}u;",
        relief::cpu::freeform::GPU_LEVELS
    );
    assert!(
        src.contains(&levels),
        "WGSL and cpu::freeform::GPU_LEVELS differ"
    );
    let shadow_levels = format!(
        "const FF_SHADOW_LEVELS: u32 = {}u;",
        relief::cpu::freeform::GPU_SHADOW_LEVELS
    );
    assert!(
        src.contains(&shadow_levels),
        "WGSL and cpu::freeform::GPU_SHADOW_LEVELS differ"
    );
    let leaf = format!(
        "const FF_LEAF: f32 = {:e};",
        relief::cpu::freeform::GPU_LEAF
    );
    assert!(
        src.contains(&leaf),
        "WGSL and cpu::freeform::GPU_LEAF differ"
    );
    let nodes = format!(
        "const FF_MAX_NODES: u32 = {}u;",
        relief::freeform::MAX_NODES
    );
    let depth = format!(
        "const FF_MAX_DEPTH: u32 = {}u;",
        relief::freeform::MAX_DEPTH
    );
    assert!(src.contains(&nodes) && src.contains(&depth));
}

#[test]
fn volume_constants_match_the_cpu_side() {
    use relief::gpu::shaders;
    use relief::gpu::variants::VolumeSwitches;
    let src = shaders::volume(VolumeSwitches::ALL);
    // The transfer table is a uniform array of VOL_TABLE entries: the buffer the renderer
    // uploads (TABLE_SIZE entries) must hold all of it.
    let table = format!(
        "const VOL_TABLE: u32 = {}u;",
        relief::volume::transfer::TABLE_SIZE
    );
    assert!(src.contains(&table), "WGSL VOL_TABLE and TABLE_SIZE differ");
    assert!(src.contains("var<uniform> vol_table: array<vec4<f32>, VOL_TABLE>;"));
    let brick = format!("const VOL_BRICK: u32 = {}u;", relief::volume::BRICK);
    assert!(
        src.contains(&brick),
        "WGSL VOL_BRICK and volume::BRICK differ"
    );
}

#[test]
fn voxel_constants_match_the_cpu_side() {
    use relief::gpu::shaders;
    let src = shaders::voxels(3);
    for (what, want) in [
        (
            "VOX_EMPTY_BIT",
            format!(
                "const VOX_EMPTY_BIT: u32 = {:#x}u;",
                relief::gpu::voxels::EMPTY_BIT
            ),
        ),
        (
            "VOX_BRICK",
            format!("const VOX_BRICK: i32 = {};", relief::voxel::BRICK),
        ),
        (
            "VOX_CODE_WORDS",
            format!(
                "const VOX_CODE_WORDS: u32 = {}u;",
                relief::gpu::voxels::CODE_WORDS
            ),
        ),
    ] {
        assert!(
            src.contains(&want),
            "WGSL {what} differs from the CPU side: want `{want}`"
        );
    }
}

#[test]
fn full_screen_passes_never_discard() {
    // The full-screen passes start from LoadOp::DontCare (renderer `encode_fullscreen`): that is
    // sound only while every pixel is written, i.e. no fragment of theirs discards.
    use relief::gpu::shaders;
    use relief::gpu::variants::ShadeFeatures;
    use relief::gpu::variants::VolumeSwitches;
    for (name, src) in [
        ("raygen", shaders::raygen()),
        ("tile", shaders::tile(true)),
        ("cast", shaders::cast(true, true, false)),
        ("shade", shaders::shade(ShadeFeatures::ALL)),
        (
            "shade (free forms)",
            shaders::shade_objects(ShadeFeatures::ALL, relief::gpu::variants::FfTables::Storage),
        ),
        ("volume", shaders::volume(VolumeSwitches::ALL)),
        ("pattern", shaders::pattern()),
        ("blend", shaders::blend()),
    ] {
        let code: String = src
            .lines()
            .map(|l| l.split("//").next().unwrap_or(""))
            .collect::<Vec<_>>()
            .join("\n");
        assert!(!code.contains("discard"), "{name} discards a fragment");
    }
}

#[test]
fn the_paged_terrain_include_validates_with_naga() {
    // terrain_paged.wgsl is an include for the traversal; a small entry point calls each of
    // its functions so that naga checks them all.
    let src = format!(
        "{}\n@group(0) @binding(0) var<storage, read_write> out: array<f32>;\n\
         @compute @workgroup_size(8, 8)\n\
         fn main(@builtin(global_invocation_id) id: vec3<u32>) {{\n\
             let c = paged_cell_max(id.z, id.xy);\n\
             let p = paged_patch_corners(id.z, id.xy);\n\
             let r = finest_resident(id.z, id.xy);\n\
             out[id.x] = c + p.x + p.w + f32(r);\n\
         }}\n",
        relief::gpu::shaders::TERRAIN_PAGED
    );
    for pools in 1..=relief::gpu::shaders::MAX_POOL_BINDINGS {
        let src = format!("{src}\n{}", relief::gpu::shaders::paged_pools(pools));
        validate_one(&format!("terrain_paged ({pools} pool bindings)"), &src);
    }
    // The Rust twins of its structs have the WGSL sizes.
    assert_eq!(
        std::mem::size_of::<relief::gpu::terrain_pool::PagedParams>(),
        48
    );
    assert_eq!(
        std::mem::size_of::<relief::gpu::terrain_pool::PagedLevel>(),
        32
    );
}

/// `relief::gpu::STORAGE_BUFFERS_PER_STAGE`, what `Gpu::new` requires of an adapter (it
/// refuses one that allows fewer, naming it), is the most storage buffers an entry point of a
/// terrain scene's passes uses, with the parameter blocks in uniform buffers (every adapter but
/// lavapipe, which allows far more). Paged terrain pools and free-form tables in storage
/// buffers need more; they check their own need where they are built.
#[test]
fn the_storage_buffers_an_adapter_must_allow_are_what_the_passes_bind() {
    use relief::gpu::ParamSpace;
    let mut most = (0, String::new());
    let own_check = |name: &str| name.contains("paged") || name.contains("storage tables");
    for (name, src) in relief::gpu::shaders::all() {
        if own_check(name) {
            continue;
        }
        let src = ParamSpace::Uniform.wgsl(&src);
        let module = naga::front::wgsl::parse_str(&src).unwrap();
        let info = naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap();
        for (i, ep) in module.entry_points.iter().enumerate() {
            let uses = info.get_entry_point(i);
            let n = module
                .global_variables
                .iter()
                .filter(|(h, v)| {
                    matches!(v.space, naga::AddressSpace::Storage { .. }) && !uses[*h].is_empty()
                })
                .count();
            if n > most.0 {
                most = (n, format!("{name}: {}", ep.name));
            }
        }
    }
    assert_eq!(
        most.0 as u32,
        relief::gpu::STORAGE_BUFFERS_PER_STAGE,
        "the most storage buffers an entry point binds ({})",
        most.1
    );
}
