//! Entity instances among the free forms: scene objects used as templates, each with a fixed
//! number of slots allocated when the objects are uploaded, placed per frame by rewriting the
//! slots' records after the scene objects' (the way [`TerrainRenderer::lower_objects`] moves
//! objects on the curved earth); only the placed slots are drawn.

use super::{FrameJob, TerrainRenderer};
use crate::freeform::FreeForm;
use crate::gpu::Gpu;
use crate::Result;

impl TerrainRenderer {
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

    /// Uploads the instances' records when they changed (or `moved`: the curvature did).
    pub(super) fn place_instances(&mut self, job: &FrameJob, moved: bool) {
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
