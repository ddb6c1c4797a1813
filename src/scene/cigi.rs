//! `[cigi]`: how a CIGI host's entities look. `[[cigi.entity]]` maps an entity type to one
//! of the scene's `[[objects]]`, used as a template: that object is not drawn where the scene
//! places it; up to `max` entities of the type are drawn as copies of it at their poses.

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

/// `[[cigi.entity]] type = N, freeform = "name", max = M`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EntityTemplateDesc {
    /// The CIGI entity type (Entity Control's entity type).
    #[serde(rename = "type")]
    pub entity_type: u16,
    /// The `name` of the `[[objects]]` entry drawn for it; that object's heading, pitch and
    /// roll orient the model in the entity's body frame, its position is not used.
    pub freeform: String,
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

    /// Types are unique, templates name objects of the scene, `max` within 1..=1024.
    pub fn validate(&self, objects: &[crate::freeform::FreeFormDesc]) -> Result<()> {
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
            if !objects
                .iter()
                .any(|o| o.name.as_deref() == Some(e.freeform.as_str()))
            {
                return Err(Error::invalid(
                    field("freeform"),
                    format!("no [[objects]] entry is named {:?}", e.freeform),
                ));
            }
            if !(1..=MAX_INSTANCES).contains(&e.max) {
                return Err(Error::invalid(
                    field("max"),
                    format!("must be 1..={MAX_INSTANCES}, got {}", e.max),
                ));
            }
        }
        Ok(())
    }
}
