//! Puts a [`World`] on the GPU: a renderer holding its terrain, free forms, volumes and voxel
//! models.

use crate::gpu::{Gpu, TerrainRenderer};
use crate::world::World;
use crate::Result;

/// A renderer for `world`: its terrain, then its free forms, volumes and voxel models.
pub fn renderer(gpu: &Gpu, world: &World) -> Result<TerrainRenderer> {
    let mut renderer = TerrainRenderer::new(gpu, &world.terrain)?;
    objects(gpu, &mut renderer, world)?;
    Ok(renderer)
}

/// Uploads `world`'s free forms (with the CIGI entity templates' slots), volumes and voxel
/// models (with theirs) to `renderer`.
pub fn objects(gpu: &Gpu, renderer: &mut TerrainRenderer, world: &World) -> Result<()> {
    renderer.set_objects_with_templates(gpu, &world.objects, &world.template_slots())?;
    renderer.set_volumes(gpu, &world.volumes)?;
    renderer.set_voxels_with_templates(gpu, &world.voxels, &world.voxel_template_slots())
}
