//! Entity instances among the free forms and the voxel models: scene objects and voxel models
//! used as templates, each with a fixed number of slots allocated when they are uploaded,
//! placed per frame by rewriting the slots' records after the scene's own (the way
//! [`TerrainRenderer::lower_objects`] moves objects on the curved earth); only the placed
//! slots are drawn.

use super::{FrameJob, TerrainRenderer};
use crate::freeform::FreeForm;
use crate::gpu::Gpu;
use crate::Result;

impl TerrainRenderer {
    /// Uploads the scene's voxel models (none: no voxel passes). Refuses models over the
    /// adapter's storage-buffer limits with the limit in the message.
    pub fn set_voxels(&mut self, gpu: &Gpu, models: &[crate::voxel::VoxelInstance]) -> Result<()> {
        self.set_voxels_with_templates(gpu, models, &[])
    }

    /// [`Self::set_voxels`] with `max` slots for each CIGI entity template `(model, max)`,
    /// placed per frame by [`Self::set_voxel_instances`].
    pub fn set_voxels_with_templates(
        &mut self,
        gpu: &Gpu,
        models: &[crate::voxel::VoxelInstance],
        templates: &[(crate::voxel::VoxelInstance, usize)],
    ) -> Result<()> {
        self.voxels = if models.is_empty() && templates.is_empty() {
            None
        } else {
            Some(crate::gpu::voxels::VoxelPasses::with_templates(
                gpu, models, templates,
            )?)
        };
        self.voxel_instances_dirty = true;
        self.lowered_for = None;
        self.targets = None;
        Ok(())
    }

    /// Uploads the scene's free forms and entity templates (`(object, max instances)`): the
    /// templates are not drawn until [`Self::set_instances`] places copies of them.
    pub fn set_objects_with_templates(
        &mut self,
        gpu: &Gpu,
        objects: &[FreeForm],
        templates: &[(FreeForm, usize)],
    ) -> Result<()> {
        self.upload_with_templates(gpu, objects, templates, true)
    }

    /// The instances to draw from the next frame on: `(template index, the template's object
    /// posed)`, world positions as placed (lowered on the curved earth like every object);
    /// at most the templates' slots in all are drawn.
    pub fn set_instances(&mut self, instances: Vec<(usize, FreeForm)>) {
        if instances != self.instances || self.instances_dirty {
            self.instances = instances;
            self.instances_dirty = true;
        }
    }

    /// The CIGI entities drawn from voxel templates from the next frame on: `(template
    /// index, the template's model posed)`; at most each template's slots are drawn.
    pub fn set_voxel_instances(&mut self, instances: Vec<(usize, crate::voxel::VoxelInstance)>) {
        let same = instances.len() == self.voxel_instances.len()
            && (instances.iter().zip(&self.voxel_instances)).all(|(a, b)| {
                a.0 == b.0 && a.1.position == b.1.position && a.1.rotation == b.1.rotation
            });
        if !same {
            self.voxel_instances = instances;
            self.voxel_instances_dirty = true;
        }
    }

    /// Places the voxel templates' slots when they changed (or `moved`).
    fn place_voxel_instances(&mut self, job: &FrameJob, moved: bool) {
        if !(self.voxel_instances_dirty || moved) {
            return;
        }
        if let Some(v) = &mut self.voxels {
            let terrain = job.terrain;
            let curv = terrain.curvature(job.cam.pose.position);
            v.set_slots(&self.voxel_instances, |p| {
                if curv.is_flat() {
                    glam::DVec3::ZERO
                } else {
                    terrain.curved_offset(&curv, p)
                }
            });
        }
        self.voxel_instances_dirty = false;
    }

    /// Uploads the instances' records when they changed (or `moved`: the curvature did).
    pub(super) fn place_instances(&mut self, job: &FrameJob, moved: bool) {
        self.place_voxel_instances(job, moved);
        if !(self.instances_dirty || moved) {
            return;
        }
        let Some(o) = &mut self.objects else {
            self.instances_dirty = false;
            return;
        };
        let terrain = job.terrain;
        let curv = terrain.curvature(job.cam.pose.position);
        let placed: Vec<(usize, FreeForm)> = self
            .instances
            .iter()
            .map(|(k, ff)| {
                let offset = if curv.is_flat() {
                    glam::DVec3::ZERO
                } else {
                    terrain.curved_offset(&curv, ff.position)
                };
                (*k, ff.translated(offset))
            })
            .collect();
        let n = o.set_instances(job.gpu, &placed);
        let floor = placed[..n]
            .iter()
            .map(|(_, ff)| {
                let (c, r) = ff.bounding_sphere();
                c.z - r
            })
            .fold(f64::INFINITY, f64::min);
        self.objects_floor = self.statics_floor.min(floor);
        self.instances_dirty = false;
    }
}
