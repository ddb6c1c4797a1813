//! The world a scene places, loaded on the CPU: the terrain with its maximum pyramid, the free
//! forms, the CIGI entity templates, the density volumes and the voxel models. No GPU types:
//! the renderers take a [`World`] as it is (`relief::app::upload` puts one on the GPU).

use crate::cigi::{EntityState, Session};
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
    /// The scene's `[[objects]]` (quadric free forms), placed on the terrain, less the entity
    /// templates.
    pub objects: Vec<FreeForm>,
    /// `[[cigi.entity]]`: the objects drawn for CIGI entities of a type.
    pub templates: Vec<EntityTemplate>,
    /// The scene's `[[volumes]]`, placed, lit by the sun and shadowing each other.
    pub volumes: Vec<Volume>,
    /// The scene's `[[voxels]]` models, placed.
    pub voxels: Vec<VoxelInstance>,
}

/// A scene object drawn for every CIGI entity of a type.
#[derive(Clone, Debug)]
pub struct EntityTemplate {
    pub entity_type: u16,
    /// The object as the scene built it (its rotation orients the model in the body frame).
    pub object: FreeForm,
    /// Instances allocated.
    pub max: usize,
}

impl World {
    /// Loads what `scene` names, in order: terrain (and pyramid), free forms, volumes, voxel
    /// models. The first input that fails is the error (it names its file or table).
    pub fn load(scene: &Scene) -> Result<World> {
        let terrain = scene.load_terrain()?;
        let mut objects = scene.free_forms(&terrain)?;
        let templates = (scene.desc.cigi.entity.iter())
            .filter_map(|t| {
                let object = objects.iter().find(|o| o.name == t.freeform)?.clone();
                Some(EntityTemplate {
                    entity_type: t.entity_type,
                    object,
                    max: t.max,
                })
            })
            .collect::<Vec<_>>();
        objects.retain(|o| !templates.iter().any(|t| t.object.name == o.name));
        let volumes = scene.volumes(&terrain)?;
        let voxels = scene.voxel_models(&terrain)?;
        Ok(World {
            terrain,
            objects,
            templates,
            volumes,
            voxels,
        })
    }

    /// The templates as the renderer allocates them: `(object, max)`.
    pub fn template_slots(&self) -> Vec<(FreeForm, usize)> {
        (self.templates.iter())
            .map(|t| (t.object.clone(), t.max))
            .collect()
    }
}

/// The entities of a session drawn from templates at one host time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Instances {
    /// `(template index, the template's object at the entity's pose)`, by entity ID.
    pub drawn: Vec<(usize, FreeForm)>,
    /// Entities (the ownship left aside) not drawn: no template for their type, attached to
    /// a parent, off the terrain, or beyond their template's `max`.
    pub not_drawn: usize,
    /// Inactive entities (hidden).
    pub hidden: usize,
}

/// Every active top-level entity but the ownship (0) whose type has a template, as a copy of
/// the template at the entity's pose at host time `t` (`Session::pose_at`): origin at its
/// geodetic position (`Terrain::geodetic_to_world`), rotated by its yaw (from true north),
/// pitch and roll after the template's own rotation. The CPU reference draws these objects as
/// the GPU does.
pub fn entity_instances(
    session: &Session,
    terrain: &Terrain,
    templates: &[EntityTemplate],
    t: f64,
) -> Instances {
    let mut out = Instances::default();
    let mut used = vec![0usize; templates.len()];
    for e in session.entities().filter(|e| e.id != 0) {
        if e.state == EntityState::Inactive {
            out.hidden += 1;
            continue;
        }
        let k = templates
            .iter()
            .position(|tp| tp.entity_type == e.entity_type);
        let placed = k.filter(|&k| used[k] < templates[k].max && e.parent.is_none());
        let posed = placed.and_then(|k| {
            let p = session.pose_at(e.id, t)?;
            let at = terrain.geodetic_to_world("CIGI entity", [p.lat, p.lon, p.alt]);
            let attitude = crate::geom::attitude_matrix(p.yaw, p.pitch, p.roll);
            let object = &templates[k].object;
            Some(FreeForm {
                position: at.ok()?,
                rotation: attitude * object.rotation,
                ..object.clone()
            })
        });
        match (placed, posed) {
            (Some(k), Some(ff)) => {
                used[k] += 1;
                out.drawn.push((k, ff));
            }
            _ => out.not_drawn += 1,
        }
    }
    out
}
