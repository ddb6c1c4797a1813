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
    /// `[[cigi.entity]]`: the objects and voxel models drawn for CIGI entities of a type.
    pub templates: Templates,
    /// The scene's `[[volumes]]`, placed, lit by the sun and shadowing each other.
    pub volumes: Vec<Volume>,
    /// The scene's `[[voxels]]` models, placed, less the entity templates.
    pub voxels: Vec<VoxelInstance>,
}

/// The CIGI entity templates of a scene, free forms and voxel models.
#[derive(Clone, Debug, Default)]
pub struct Templates {
    pub objects: Vec<EntityTemplate>,
    pub voxels: Vec<VoxelTemplate>,
}

/// A scene voxel model drawn for every CIGI entity of a type.
#[derive(Clone, Debug)]
pub struct VoxelTemplate {
    pub entity_type: u16,
    /// The model as the scene placed it (its rotation orients it in the body frame).
    pub model: VoxelInstance,
    /// Instances allocated.
    pub max: usize,
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
        Self::load_as(scene, false)
    }

    /// [`World::load`]; `paged` (the scene renders through the paged tile pool,
    /// `--terrain-memory`): a database window is loaded hollow, without its samples
    /// (`Terrain::is_hollow`), so host memory does not grow with the window.
    pub fn load_as(scene: &Scene, paged: bool) -> Result<World> {
        let terrain = scene.load_terrain_as(paged)?;
        let mut objects = scene.free_forms(&terrain)?;
        let mut voxels = scene.voxel_models(&terrain)?;
        let entity = &scene.desc.cigi.entity;
        let templates = Templates {
            objects: (entity.iter())
                .filter_map(|t| {
                    let name = t.freeform.as_ref()?;
                    let object = objects.iter().find(|o| &o.name == name)?.clone();
                    Some(EntityTemplate {
                        entity_type: t.entity_type,
                        object,
                        max: t.max,
                    })
                })
                .collect(),
            voxels: (entity.iter())
                .filter_map(|t| {
                    let name = t.voxels.as_ref()?;
                    let model = voxels.iter().find(|o| &o.name == name)?.clone();
                    Some(VoxelTemplate {
                        entity_type: t.entity_type,
                        model,
                        max: t.max,
                    })
                })
                .collect(),
        };
        objects.retain(|o| !templates.objects.iter().any(|t| t.object.name == o.name));
        voxels.retain(|o| !templates.voxels.iter().any(|t| t.model.name == o.name));
        let volumes = scene.volumes(&terrain)?;
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
        (self.templates.objects.iter())
            .map(|t| (t.object.clone(), t.max))
            .collect()
    }

    /// The voxel templates as the renderer allocates them: `(model, max)`.
    pub fn voxel_template_slots(&self) -> Vec<(VoxelInstance, usize)> {
        (self.templates.voxels.iter())
            .map(|t| (t.model.clone(), t.max))
            .collect()
    }
}

/// The entities of a session drawn from templates at one host time.
#[derive(Clone, Debug, Default)]
pub struct Instances {
    /// `(template index, the template's object at the entity's pose)`, by entity ID.
    pub drawn: Vec<(usize, FreeForm)>,
    /// `(voxel template index, the template's model at the entity's pose)`, by entity ID.
    pub voxels: Vec<(usize, VoxelInstance)>,
    /// Entities (the ownship left aside) not drawn: no template for their type, attached to
    /// a parent, off the terrain, or beyond their template's `max`.
    pub not_drawn: usize,
    /// Inactive entities (hidden).
    pub hidden: usize,
}

/// Every active top-level entity but the ownship (0) whose type has a template, as a copy of
/// the template at the entity's pose at host time `t` (`Session::pose_at`): origin (a voxel
/// model's bottom centre) at its geodetic position (`Terrain::geodetic_to_world`), rotated by
/// its yaw (from true north), pitch and roll after the template's own rotation. The CPU
/// reference draws these objects as the GPU does.
pub fn entity_instances(
    session: &Session,
    terrain: &Terrain,
    templates: &Templates,
    t: f64,
) -> Instances {
    let mut out = Instances::default();
    let mut used = vec![0usize; templates.objects.len()];
    let mut used_voxels = vec![0usize; templates.voxels.len()];
    for e in session.entities().filter(|e| e.id != 0) {
        if e.state == EntityState::Inactive {
            out.hidden += 1;
            continue;
        }
        let pose = || {
            let p = session.pose_at(e.id, t)?;
            let at = terrain.geodetic_to_world("CIGI entity", [p.lat, p.lon, p.alt]);
            Some((
                at.ok()?,
                crate::geom::attitude_matrix(p.yaw, p.pitch, p.roll),
            ))
        };
        let of_type = |ty: u16| ty == e.entity_type;
        let top = e.parent.is_none();
        let object = (templates.objects.iter()).position(|tp| of_type(tp.entity_type));
        let model = (templates.voxels.iter()).position(|tp| of_type(tp.entity_type));
        if let Some(k) = object.filter(|&k| top && used[k] < templates.objects[k].max) {
            if let Some((position, attitude)) = pose() {
                let object = &templates.objects[k].object;
                used[k] += 1;
                out.drawn.push((
                    k,
                    FreeForm {
                        position,
                        rotation: attitude * object.rotation,
                        ..object.clone()
                    },
                ));
                continue;
            }
        } else if let Some(k) = model.filter(|&k| top && used_voxels[k] < templates.voxels[k].max) {
            if let Some((position, attitude)) = pose() {
                let model = &templates.voxels[k].model;
                used_voxels[k] += 1;
                out.voxels.push((
                    k,
                    VoxelInstance {
                        position,
                        rotation: attitude * model.rotation,
                        ..model.clone()
                    },
                ));
                continue;
            }
        }
        out.not_drawn += 1;
    }
    out
}
