//! `[cigi]`: how a CIGI host's entities look. `[[cigi.entity]]` maps an entity type to one
//! of the scene's `[[objects]]` or `[[voxels]]` models, used as a template: it is not drawn
//! where the scene places it; up to `max` entities of the type are drawn as copies of it at
//! their poses.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Most instances one template may have.
pub const MAX_INSTANCES: usize = 1024;

/// `[cigi]`.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct CigiDesc {
    /// `[[cigi.entity]]`: entity type → template.
    pub entity: Vec<EntityTemplateDesc>,
}

/// `[[cigi.entity]] type = N, freeform = "name" (or voxels = "name"), max = M`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EntityTemplateDesc {
    /// The CIGI entity type (Entity Control's entity type).
    #[serde(rename = "type")]
    pub entity_type: u16,
    /// The `name` of the `[[objects]]` entry drawn for it; that object's heading, pitch and
    /// roll orient the model in the entity's body frame, its position is not used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub freeform: Option<String>,
    /// Or the `name` of the `[[voxels]]` model drawn for it (its bottom centre at the
    /// entity's position, its heading, pitch and roll in the body frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub voxels: Option<String>,
    /// Instances allocated (entities of the type beyond them are counted, not drawn).
    #[serde(default = "default_max")]
    pub max: usize,
}

fn default_max() -> usize {
    16
}

impl CigiDesc {
    pub fn is_empty(&self) -> bool {
        self.entity.is_empty()
    }

    /// Types are unique, templates name objects or voxel models of the scene (one of the
    /// two), `max` within 1..=1024; voxel models and voxel template slots together at most
    /// `voxel::desc::MAX_INSTANCES`.
    pub fn validate(
        &self,
        objects: &[crate::freeform::FreeFormDesc],
        voxels: &[crate::voxel::VoxelDesc],
    ) -> Result<()> {
        let mut voxel_slots = voxels.len();
        for (i, e) in self.entity.iter().enumerate() {
            let field = |k: &str| format!("cigi.entity[{i}].{k}");
            if self.entity[..i]
                .iter()
                .any(|o| o.entity_type == e.entity_type)
            {
                return Err(Error::invalid(
                    field("type"),
                    format!("entity type {} has a template already", e.entity_type),
                ));
            }
            match (&e.freeform, &e.voxels) {
                (Some(f), None) if !objects.iter().any(|o| o.name.as_ref() == Some(f)) => {
                    return Err(Error::invalid(
                        field("freeform"),
                        format!("no [[objects]] entry is named {f:?}"),
                    ));
                }
                (None, Some(v)) if !voxels.iter().any(|o| o.name.as_ref() == Some(v)) => {
                    return Err(Error::invalid(
                        field("voxels"),
                        format!("no [[voxels]] entry is named {v:?}"),
                    ));
                }
                (Some(_), None) => {}
                (None, Some(_)) => voxel_slots = voxel_slots.saturating_add(e.max),
                _ => {
                    return Err(Error::invalid(
                        field("freeform/voxels"),
                        "give exactly one of freeform = \"name\" and voxels = \"name\"",
                    ))
                }
            }
            if !(1..=MAX_INSTANCES).contains(&e.max) {
                return Err(Error::invalid(
                    field("max"),
                    format!("must be 1..={MAX_INSTANCES}, got {}", e.max),
                ));
            }
        }
        let most = crate::voxel::desc::MAX_INSTANCES;
        if voxel_slots > most {
            return Err(Error::invalid(
                "cigi.entity",
                format!("[[voxels]] models and voxel templates' max add up to {voxel_slots}, at most {most}"),
            ));
        }
        Ok(())
    }
}
