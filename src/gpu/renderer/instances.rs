//! Entity instances among the free forms and the voxel models: scene objects and voxel models
//! used as templates, each with a fixed number of slots allocated when they are uploaded,
//! placed per frame by rewriting the slots' records after the scene's own (the way
//! [`TerrainRenderer::lower_objects`] moves objects on the curved earth); only the placed
//! slots are drawn.

use super::{FrameJob, TerrainRenderer, VoxelRects};
use crate::cpu::voxel::InstanceRect;
use crate::freeform::FreeForm;
use crate::gpu::frame::Stage;
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

/// Where the objects are this frame: lowered on the curved earth, and the voxel passes'
/// rectangles.
impl TerrainRenderer {
    /// On the curved earth, moves every free form, volume and voxel model rigidly down by the
    /// drop below the eye's tangent plane at its anchor (`Terrain::curved_offset`; the CPU
    /// oracle's `cpu::{freeform, volume, voxel}::lowered`), so that objects placed on the
    /// ground stay on it; uploads only when the curvature seen from the eye changed. Nothing
    /// on a flat terrain.
    pub(super) fn lower_objects(&mut self, job: &FrameJob) {
        let terrain = job.terrain;
        let curv = terrain.curvature(job.cam.pose.position);
        if self.lowered_for == Some(curv) || (self.lowered_for.is_none() && curv.is_flat()) {
            self.place_instances(job, false);
            return;
        }
        let offset = |anchor| terrain.curved_offset(&curv, anchor);
        let mut deepest = 0.0f64;
        if let Some(o) = &self.objects {
            let offsets: Vec<_> = o.placed_origins().map(offset).collect();
            deepest = offsets.iter().fold(deepest, |d, v| d.min(v.z));
            o.set_offsets(job.gpu, &offsets);
        }
        self.statics_floor = self.placed_floor + deepest;
        self.objects_floor = self.statics_floor;
        self.place_instances(job, true);
        for v in &mut self.volumes.passes {
            v.offset = offset(v.volume.anchor());
        }
        if let Some(v) = &mut self.voxels {
            let offsets: Vec<_> = v.placed().iter().map(|m| offset(m.position)).collect();
            v.set_offsets(&offsets);
        }
        self.lowered_for = Some(curv);
    }

    /// Pixels the voxel passes run on: rectangles from the models' occupied slabs for a
    /// pinhole camera (partitioned, each with its models), every pixel through a distortion
    /// table; `None` without voxel models.
    pub(super) fn voxel_rects(&self, job: &FrameJob) -> Option<VoxelRects> {
        let v = self.voxels.as_ref()?;
        let (cam, s) = (job.cam, job.s);
        let pinhole = self.table.is_none();
        let full = || {
            vec![InstanceRect {
                rect: crate::cpu::voxel::PixelRect::full(cam.width, cam.height),
                instances: v.active_mask(),
            }]
        };
        let boxes = v.active_boxes();
        let cast = if pinhole {
            crate::cpu::voxel::primary_rects(v.instances(), &boxes, cam)
        } else {
            full()
        };
        let shadows = if job.stage != Stage::Shade || !s.shadows {
            Vec::new()
        } else if pinhole {
            crate::cpu::voxel::shadow_rects(
                v.instances(),
                &boxes,
                cam,
                job.scene.daylight().light,
                // No surface lies lower: the terrain's lowest point, the free
                // forms' and the models' own (their boxes start the sweep); a curved
                // terrain's drop.
                (job.terrain.lowest_z()
                    - job
                        .terrain
                        .curvature(cam.pose.position)
                        .max_drop(job.terrain.cells()))
                .min(self.objects_floor)
                    - 1.0,
            )
        } else {
            full()
        };
        Some((cast, shadows))
    }
}
