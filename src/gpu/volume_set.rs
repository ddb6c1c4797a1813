//! A scene's density volumes on the GPU as one set: the per-volume passes, the volume-sun pass
//! and the composite pass, and what the frame records with them.

use super::util::encode_fullscreen;
use super::volumes::{CompositePass, CompositeTargets, VolumePass, VolumeSunPass, VolumeTargets};
use super::Gpu;
use crate::volume::{TransferFunction, Volume, VolumeSettings};
use crate::{Error, Result};

/// Density volumes a scene may hold (each is a full-screen pass per frame).
pub const MAX_VOLUMES: usize = 8;

/// The scene's volumes and the passes that shadow the surfaces with them and composite them.
#[derive(Default)]
pub(crate) struct VolumeSet {
    pub passes: Vec<VolumePass>,
    /// The volume-sun pass (built with the first volume).
    pub sun: Option<VolumeSunPass>,
    /// The composite pass for the scene's volumes (with volumes).
    pub composite: Option<CompositePass>,
    /// The volumes shadow the surfaces but are not composited
    /// (`TerrainRenderer::set_volumes_hidden`).
    pub hidden: bool,
}

impl VolumeSet {
    /// Uploads the scene's `volumes` in place of the current ones, with their shadows on each
    /// other baked in (`volume::shadow::shadow_each_other`).
    pub fn set(&mut self, gpu: &Gpu, volumes: &[Volume]) -> Result<()> {
        if volumes.len() > MAX_VOLUMES {
            return Err(Error::invalid(
                "volumes",
                format!(
                    "{} [[volumes]] tables, at most {MAX_VOLUMES}: merge some into one grid",
                    volumes.len()
                ),
            ));
        }
        self.passes = volumes
            .iter()
            .map(|v| VolumePass::new(gpu, v))
            .collect::<Result<_>>()?;
        self.shadow_each_other(gpu);
        if !self.passes.is_empty() && self.sun.is_none() {
            self.sun = Some(VolumeSunPass::new(gpu));
        }
        self.composite =
            (!self.passes.is_empty()).then(|| CompositePass::new(gpu, self.passes.len() as u32));
        Ok(())
    }

    /// Reclassifies every volume with a new transfer function.
    pub fn set_transfer(&mut self, gpu: &Gpu, tf: TransferFunction) {
        for v in &mut self.passes {
            v.set_transfer(gpu, tf.clone());
        }
        self.shadow_each_other(gpu);
    }

    /// Bakes the volumes' shadows on each other into their grids again and uploads them.
    fn shadow_each_other(&mut self, gpu: &Gpu) {
        let mut vols: Vec<_> = self.passes.iter_mut().map(|v| &mut v.volume).collect();
        crate::volume::desc::shadow_each_other(&mut vols);
        for v in &self.passes {
            v.upload_shadows(gpu);
        }
    }

    /// Changes every volume's sampling switches.
    pub fn set_settings(&mut self, gpu: &Gpu, settings: VolumeSettings) {
        let mut reclassified = false;
        for v in &mut self.passes {
            if v.volume.settings.mipmaps != settings.mipmaps {
                v.volume.settings = settings;
                let tf = v.volume.transfer.clone();
                v.set_transfer(gpu, tf);
                reclassified = true;
            }
            v.volume.settings = settings;
        }
        // Reclassifying recomputed the self-shadowing grids without the other volumes.
        if reclassified {
            self.shadow_each_other(gpu);
        }
    }

    /// Some volume shadows what lies below it.
    pub fn any_casts_shadow(&self) -> bool {
        self.passes.iter().any(|v| v.casts_shadow())
    }

    /// Per volume, its passes' bind groups for a frame's targets (none before the first
    /// volume): `data` is the capture data target, `gbuffer` the final G-buffer.
    pub fn targets(
        &self,
        gpu: &Gpu,
        frame_ub: &wgpu::Buffer,
        ray_table: &wgpu::TextureView,
        data: &wgpu::Texture,
        gbuffer: &wgpu::TextureView,
    ) -> Vec<VolumeTargets> {
        match &self.sun {
            Some(sun_pass) => self
                .passes
                .iter()
                .map(|v| {
                    v.targets(
                        gpu,
                        frame_ub,
                        ray_table,
                        &data.create_view(&Default::default()),
                        sun_pass,
                        gbuffer,
                    )
                })
                .collect(),
            None => Vec::new(),
        }
    }

    /// Builds the volume pipelines for the current switches unless they exist; returns their
    /// indices for [`VolumeSet::encode`].
    pub fn prepare(&mut self, gpu: &Gpu) -> Vec<usize> {
        self.passes.iter_mut().map(|v| v.prepare(gpu)).collect()
    }

    /// Uploads every volume's uniforms for an eye at world position `eye`.
    pub fn write_uniforms(&self, gpu: &Gpu, eye: glam::DVec3) {
        for v in &self.passes {
            v.write_uniforms(gpu, eye);
        }
    }

    /// Records the volume-sun pass into `target` over the shadow-casting volumes; false (and
    /// nothing recorded) without the pass.
    pub fn encode_sun(
        &self,
        enc: &mut wgpu::CommandEncoder,
        targets: &[VolumeTargets],
        target: &wgpu::TextureView,
    ) -> bool {
        let Some(sun_pass) = &self.sun else {
            return false;
        };
        let casting: Vec<_> = (self.passes.iter().zip(targets))
            .filter(|(v, _)| v.casts_shadow())
            .map(|(_, vt)| &vt.sun_bg)
            .collect();
        sun_pass.encode(enc, &casting, target);
        true
    }

    /// Records each volume's pass into its result layer (pipelines from
    /// [`VolumeSet::prepare`]) and the composite pass into `colour`.
    pub fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipelines: &[usize],
        targets: &[VolumeTargets],
        (cp, ct): (&CompositePass, &CompositeTargets),
        colour: &wgpu::TextureView,
    ) {
        for (i, vt) in targets.iter().enumerate() {
            encode_fullscreen(
                enc,
                "volume",
                self.passes[i].pipeline(pipelines[i]),
                &vt.bg,
                &[&ct.result_views[i], &ct.stats_views[i]],
            );
        }
        encode_fullscreen(enc, "volume composite", &cp.pipeline, &ct.bg, &[colour]);
    }
}
