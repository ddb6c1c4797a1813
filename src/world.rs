//! The world a scene places, loaded on the CPU: the terrain with its maximum pyramid, the free
//! forms, the CIGI entity templates, the density volumes and the voxel models. No GPU types:
//! the renderers take a [`World`] as it is (`relief::app::upload` puts one on the GPU).

use crate::cigi::{EntityState, Session};
use crate::freeform::FreeForm;
use crate::geodesy;
use crate::geom::attitude_matrix;
use crate::scene::Scene;
use crate::terrain::Terrain;
use crate::volume::Volume;
use crate::voxel::VoxelInstance;
use crate::Result;
use glam::{DMat3, DVec3};

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
    /// Entities (the ownship left aside) not drawn: no template for their type, off the
    /// terrain (or attached below one that is), or beyond their template's `max`.
    pub not_drawn: usize,
    /// Inactive entities, those attached below one and fully transparent ones (alpha 0):
    /// hidden.
    pub hidden: usize,
    /// Every drawn entity: its ID, where it stands and which of `drawn` or `voxels` it is
    /// (lines of sight against entities, `cpu::bodies`).
    pub bodies: Vec<Body>,
}

/// A drawn entity ([`Instances::bodies`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    pub id: u16,
    /// The entity's alpha (Entity Control; 1–255: drawn opaque, lines of sight compare it
    /// with their alpha threshold).
    pub alpha: u8,
    pub placement: Placement,
    pub shape: BodyShape,
}

/// Which instance a [`Body`] is drawn as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BodyShape {
    /// Index into [`Instances::drawn`].
    Object(usize),
    /// Index into [`Instances::voxels`].
    Voxels(usize),
}

/// Where an entity is in the world at host time `t` ([`entity_placement`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// World position of the entity's origin.
    pub position: DVec3,
    /// Its geodetic position: latitude, longitude (degrees), metres above mean sea level.
    pub geodetic: [f64; 3],
    /// Its attitude: columns the body's right, forward and up in the world, which is
    /// east-north-up (`geom::attitude_matrix`).
    pub attitude: DMat3,
}

/// Geodetic position of the point at body offsets `[x forward, y right, z down]` (metres)
/// from a body at geodetic `origin` with attitude `m` (columns right, forward, up in its
/// east-north-up frame): a straight line in the body's frame, exact through ECEF (heights
/// above mean sea level taken as above the ellipsoid: their difference is what counts).
pub fn body_point(origin: [f64; 3], m: &DMat3, [x, y, z]: [f64; 3]) -> [f64; 3] {
    let enu = m.y_axis * x + m.x_axis * y - m.z_axis * z;
    let at = geodesy::ecef_of(origin) + geodesy::enu_basis(origin[0], origin[1]) * enu;
    geodesy::lla_of(at)
}

/// The body offsets `[x forward, y right, z down]` of geodetic `lla` from a body at `origin`
/// with attitude `m` (the inverse of [`body_point`]).
pub fn body_offsets(origin: [f64; 3], m: &DMat3, lla: [f64; 3]) -> [f64; 3] {
    let d = geodesy::enu_basis(origin[0], origin[1]).transpose()
        * (geodesy::ecef_of(lla) - geodesy::ecef_of(origin));
    [d.dot(m.y_axis), d.dot(m.x_axis), -d.dot(m.z_axis)]
}

/// How deep attachments are followed (the session refuses cycles; this bounds the work).
const MAX_ATTACH_DEPTH: usize = 32;

/// Entity `id`'s placement at host time `t` (`Session::pose_at`), `None` where it is off the
/// terrain, inactive as an ancestor, or unknown:
/// * **top level**: its geodetic position (`Terrain::geodetic_to_world`) and yaw (from true
///   north), pitch and roll. **Ground clamp** (Entity Control's Ground/Ocean Clamp; the sea
///   is the terrain at `sea_level`): non-conformal (1) puts it at the terrain's height under
///   it plus its altitude, now an offset; conformal (2) also stands it on the terrain's slope
///   (its up the surface normal across half a sample each way, its heading kept), its pitch
///   and roll offsets from that.
/// * **attached** to a parent (clamping ignored, as CIGI says): the parent's placement moved
///   by the offsets x forward, y right, z down (metres, a straight line in the parent's body
///   frame: [`body_point`]) and turned by yaw, pitch and roll relative to the parent's body.
pub fn entity_placement(
    session: &Session,
    terrain: &Terrain,
    id: u16,
    t: f64,
) -> Option<Placement> {
    placement_at(session, terrain, id, t, 0)
}

fn placement_at(
    session: &Session,
    terrain: &Terrain,
    id: u16,
    t: f64,
    depth: usize,
) -> Option<Placement> {
    let e = session.entity(id)?;
    let p = session.pose_at(id, t)?;
    if let Some(parent) = e.parent {
        if depth >= MAX_ATTACH_DEPTH || session.entity(parent)?.state == EntityState::Inactive {
            return None;
        }
        let up = placement_at(session, terrain, parent, t, depth + 1)?;
        let geodetic = body_point(up.geodetic, &up.attitude, [p.lat, p.lon, p.alt]);
        return Some(Placement {
            position: terrain.geodetic_to_world("CIGI entity", geodetic).ok()?,
            geodetic,
            attitude: up.attitude * attitude_matrix(p.yaw, p.pitch, p.roll),
        });
    }
    let (geodetic, attitude) = match e.ground_clamp {
        1 | 2 => {
            let ground = terrain.ground_msl(p.lat, p.lon)?;
            let attitude = if e.ground_clamp == 2 {
                conformal(terrain, p.lat, p.lon, p.yaw)? * attitude_matrix(0.0, p.pitch, p.roll)
            } else {
                attitude_matrix(p.yaw, p.pitch, p.roll)
            };
            ([p.lat, p.lon, ground + p.alt], attitude)
        }
        _ => (
            [p.lat, p.lon, p.alt],
            attitude_matrix(p.yaw, p.pitch, p.roll),
        ),
    };
    Some(Placement {
        position: terrain.geodetic_to_world("CIGI entity", geodetic).ok()?,
        geodetic,
        attitude,
    })
}

/// The attitude of a body standing on the terrain at (lat, lon) with heading `yaw`: up the
/// surface normal (from the surface half a sample east, west, north and south), forward the
/// heading's direction in the surface.
fn conformal(terrain: &Terrain, lat: f64, lon: f64, yaw: f64) -> Option<DMat3> {
    let geo = terrain.field.geo?;
    let (dlat, dlon) = (0.5 * geo.dlat.abs(), 0.5 * geo.dlon.abs());
    let at = |lat: f64, lon: f64| -> Option<DVec3> {
        let h = terrain.ground_msl(lat, lon)?;
        terrain.geodetic_to_world("CIGI entity", [lat, lon, h]).ok()
    };
    let east = at(lat, lon + dlon)? - at(lat, lon - dlon)?;
    let north = at(lat + dlat, lon)? - at(lat - dlat, lon)?;
    let up = east.cross(north).try_normalize()?;
    // The heading's direction on the level (world axes as the attitude's), laid into the
    // surface.
    let level = attitude_matrix(yaw, 0.0, 0.0);
    let fwd = (level.y_axis - up * level.y_axis.dot(up)).try_normalize()?;
    Some(DMat3::from_cols(fwd.cross(up), fwd, up))
}

/// Every active entity but the ownship (0) whose type has a template, as a copy of the
/// template at the entity's placement at host time `t` ([`entity_placement`]: top level or
/// attached, clamped to the ground or not): origin (a voxel model's bottom centre) there,
/// rotated by the entity's attitude after the template's own rotation. An entity attached
/// below an inactive one is hidden with it; an entity whose alpha is 0 (fully transparent) is
/// hidden (other alphas draw it opaque). The CPU reference draws these objects as the GPU
/// does.
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
        if e.state == EntityState::Inactive || e.alpha == 0 || hidden_above(session, e.parent) {
            out.hidden += 1;
            continue;
        }
        let pose = || entity_placement(session, terrain, e.id, t);
        let of_type = |ty: u16| ty == e.entity_type;
        let object = (templates.objects.iter()).position(|tp| of_type(tp.entity_type));
        let model = (templates.voxels.iter()).position(|tp| of_type(tp.entity_type));
        if let Some(k) = object.filter(|&k| used[k] < templates.objects[k].max) {
            if let Some(placement) = pose() {
                let object = &templates.objects[k].object;
                used[k] += 1;
                out.bodies.push(Body {
                    id: e.id,
                    alpha: e.alpha,
                    placement,
                    shape: BodyShape::Object(out.drawn.len()),
                });
                out.drawn.push((
                    k,
                    FreeForm {
                        position: placement.position,
                        rotation: placement.attitude * object.rotation,
                        ..object.clone()
                    },
                ));
                continue;
            }
        } else if let Some(k) = model.filter(|&k| used_voxels[k] < templates.voxels[k].max) {
            if let Some(placement) = pose() {
                let model = &templates.voxels[k].model;
                used_voxels[k] += 1;
                out.bodies.push(Body {
                    id: e.id,
                    alpha: e.alpha,
                    placement,
                    shape: BodyShape::Voxels(out.voxels.len()),
                });
                out.voxels.push((
                    k,
                    VoxelInstance {
                        position: placement.position,
                        rotation: placement.attitude * model.rotation,
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

/// Whether an ancestor from `parent` up is inactive (its attached entities hide with it).
fn hidden_above(session: &Session, mut parent: Option<u16>) -> bool {
    for _ in 0..MAX_ATTACH_DEPTH {
        let Some(e) = parent.and_then(|id| session.entity(id)) else {
            return false;
        };
        if e.state == EntityState::Inactive {
            return true;
        }
        parent = e.parent;
    }
    false
}
