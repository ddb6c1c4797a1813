//! The world a scene places, loaded on the CPU: the terrain with its maximum pyramid, the free
//! forms, the density volumes and the voxel models. No GPU types: the renderers take a
//! [`World`] as it is (`relief::app::upload` puts one on the GPU).

use crate::freeform::FreeForm;
use crate::scene::Scene;
use crate::terrain::Terrain;
use crate::volume::Volume;
use crate::voxel::VoxelInstance;
use crate::Result;

/// Everything a scene places in the world, loaded and checked.
pub struct World {
    /// The height field placed in the world, with its maximum pyramid.
    pub terrain: Terrain,
    /// The scene's `[[objects]]` (quadric free forms), placed on the terrain.
    pub objects: Vec<FreeForm>,
    /// The scene's `[[volumes]]`, placed, lit by the sun and shadowing each other.
    pub volumes: Vec<Volume>,
    /// The scene's `[[voxels]]` models, placed.
    pub voxels: Vec<VoxelInstance>,
}

impl World {
    /// Loads what `scene` names, in order: terrain (and pyramid), free forms, volumes, voxel
    /// models. The first input that fails is the error (it names its file or table).
    pub fn load(scene: &Scene) -> Result<World> {
        let terrain = scene.load_terrain()?;
        let objects = scene.free_forms(&terrain)?;
        let volumes = scene.volumes(&terrain)?;
        let voxels = scene.voxel_models(&terrain)?;
        Ok(World {
            terrain,
            objects,
            volumes,
            voxels,
        })
    }
}
