// One density volume's uniforms (`gpu::types::VolumeUniforms`), shared by the volume pass and
// the volume-sun pass.

struct Volume {
    // Eye in the volume frame (metres from the box corner); w = step in metres.
    eye_local: vec4<f32>,
    local_from_world_0: vec4<f32>,
    local_from_world_1: vec4<f32>,
    local_from_world_2: vec4<f32>,
    // The volume's axes in the world.
    world_from_local_0: vec4<f32>,
    world_from_local_1: vec4<f32>,
    world_from_local_2: vec4<f32>,
    // Box size in metres; w = smallest voxel side.
    extent: vec4<f32>,
    // Voxel spacing in metres; w = transmittance below which a ray stops.
    spacing: vec4<f32>,
    // Voxels x, y, z; mip levels.
    dims: vec4<u32>,
    // Bricks x, y, z; unused (the pass branches on the compile-time constants SKIP,
    // TERMINATION, JITTER, MIPMAPS, SHELL, SLICES, SHADOW and SAMPLED_FETCH, `gpu::volumes::VolumeSwitches`).
    bricks: vec4<u32>,
    // Ambient, diffuse, specular weights; shininess.
    material: vec4<f32>,
    shell_centre: vec4<f32>,
    shell_radii: vec4<f32>,
}
