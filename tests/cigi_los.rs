//! CIGI lines of sight meet the entities the IG draws, not only the terrain: `relief serve`
//! with a sphere (a free-form template) and a voxel model (a voxel template) placed by the
//! host answers LOS segments and vectors with the entity's ID, range, intersection, normal and
//! colour. Truths: the sphere's intersections solved here in ECEF (the test's own WGS84
//! code), the voxel model's from the CPU reference's voxel cast of the same model placed as a
//! scene object at the entity's pose.

mod cigi_support;
mod common;

use cigi_support::*;
use common::temp_dir;
use relief::cigi::*;

const CAM: [f64; 3] = [47.45, 9.50, 1300.0];
const HEADING: f64 = 30.0;
/// The sphere's radius (m) and linear colour.
const RADIUS: f64 = 40.0;
const COLOUR: [f32; 3] = [0.2, 0.6, 0.9];

/// `dist` metres ahead of the camera along its heading and `east` metres east of that, at
/// `alt`.
fn ahead(dist: f64, east: f64, alt: f64) -> [f64; 3] {
    let h = HEADING.to_radians();
    moved([CAM[0], CAM[1], alt], dist * h.sin() + east, dist * h.cos())
}

/// `p` moved `east` and `north` metres (first order in the WGS84 radii; the truths below take
/// the points as given).
fn moved(p: [f64; 3], east: f64, north: f64) -> [f64; 3] {
    let (m, n) = radii(p[0]);
    [
        p[0] + (north / m).to_degrees(),
        p[1] + (east / (n * p[0].to_radians().cos())).to_degrees(),
        p[2],
    ]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Metres from ECEF `o` along unit `d` to the first intersection with the sphere about `c`.
fn sphere_hit(o: [f64; 3], d: [f64; 3], c: [f64; 3]) -> Option<f64> {
    let oc = sub(o, c);
    let b = dot(oc, d);
    let disc = b * b - (dot(oc, oc) - RADIUS * RADIUS);
    (disc >= 0.0).then(|| -b - disc.sqrt())
}

/// The sphere's intersection along the segment from geodetic `a` to `b`: metres from `a`.
fn segment_truth(a: [f64; 3], b: [f64; 3], centre: [f64; 3]) -> Option<f64> {
    let (o, e) = (ecef(a), ecef(b));
    let v = sub(e, o);
    let len = dot(v, v).sqrt();
    sphere_hit(o, v.map(|x| x / len), ecef(centre)).filter(|t| *t <= len)
}

/// sRGB 8-bit of a linear value.
fn srgb8(c: f32) -> u8 {
    let c = f64::from(c);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

fn segment(id: u16, extended: bool, a: [f64; 3], b: [f64; 3]) -> LosSegmentRequest {
    LosSegmentRequest {
        request_id: id,
        extended,
        source_lat: a[0],
        source_lon: a[1],
        source_alt: a[2],
        destination_lat: b[0],
        destination_lon: b[1],
        destination_alt: b[2],
        ..LosSegmentRequest::default()
    }
}

/// A `[[voxels]]` entry of `axes.vox` at 3 m a voxel at geodetic `at`.
fn voxels_at(at: [f64; 3]) -> String {
    let axes = common::terrains().join("voxels/axes.vox");
    format!(
        "[[voxels]]\nname = \"axes\"\nfile = {axes:?}\nvoxel_size = 3.0\n\
         geodetic = [{:?}, {:?}, {:?}]\n",
        at[0], at[1], at[2]
    )
}

/// The IG's scene over N47E009 with its templates (type 9 the sphere, type 8 `axes.vox` at
/// 3 m a voxel, both placed out of view), written to `dir/served.toml`; where the sphere (1.5
/// km ahead, 200 m above the ground) and the voxel model (400 m east of it, 100 m up) go.
fn setup(dir: &std::path::Path, dem: &Dem) -> (std::path::PathBuf, [f64; 3], [f64; 3]) {
    let [r, g, b] = COLOUR;
    let templates = format!(
        "[[objects]]\nname = \"sphere\"\nshape = \"ellipsoid\"\nradii = [{RADIUS:?}, {RADIUS:?}, {RADIUS:?}]\n\
         geodetic = [47.2, 9.2, 3000.0]\n\
         material = {{ colour = [{r:?}, {g:?}, {b:?}], ambient = 0.6, diffuse = 0.4, specular = 0.0, shininess = 10.0 }}\n\
         [[cigi.entity]]\ntype = 9\nfreeform = \"sphere\"\nmax = 2\n{}\
         [[cigi.entity]]\ntype = 8\nvoxels = \"axes\"\nmax = 2\n",
        voxels_at([47.2, 9.25, 3000.0])
    );
    let served = scene(dir, "served", CAM, [HEADING, -3.0, 0.0], &templates);
    let s0 = ahead(1500.0, 0.0, 0.0);
    let sphere = [s0[0], s0[1], dem.height(s0[0], s0[1]) + 200.0];
    let v0 = ahead(1500.0, 400.0, 0.0);
    let model = [v0[0], v0[1], dem.height(v0[0], v0[1]) + 100.0];
    (served, sphere, model)
}

/// `relief serve` of `scene` at 160x120 for `frames` frames, synchronous.
fn serve(scene: &std::path::Path, dir: &std::path::Path, frames: u32) -> Ig {
    serve_with(scene, dir, frames, &[])
}

/// [`serve`] with `extra` arguments.
fn serve_with(scene: &std::path::Path, dir: &std::path::Path, frames: u32, extra: &[&str]) -> Ig {
    let n = frames.to_string();
    let out = dir.join("frames");
    let mut args = vec![
        "--size",
        "160x120",
        "--no-shadows",
        "--cigi-sync",
        "--frames",
        &n,
        "--capture-frames",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    Ig::start(scene, &args, host_socket())
}

#[test]
fn lines_of_sight_meet_the_entities_the_ig_draws() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-los-entities");
    let dem = Dem::load();
    let (served, sphere, model) = setup(&dir, &dem);

    // The voxel truth: the model placed by a scene at the entity's pose, a vertical line down
    // the column of its first voxel, cast by the CPU reference in that scene's world.
    let truth_scene = scene(&dir, "truth", CAM, [HEADING, -3.0, 0.0], &voxels_at(model));
    let sc = relief::scene::Scene::load(&truth_scene).unwrap();
    let world = relief::world::World::load(&sc).unwrap();
    let terrain = &world.terrain;
    let inst = world.voxels[0].clone();
    let m = &inst.frames[0];
    let v = m.voxels[0].pos.map(f64::from);
    let top = glam::DVec3::new(v[0] + 0.5, v[1] + 0.5, v[2] + 1.0);
    let column = inst.position + inst.rotation * ((top - inst.anchor()) * inst.voxel_size);
    let [clat, clon, _] = terrain.world_to_geodetic(column).unwrap();
    let (g0, g1) = (
        [clat, clon, model[2] + 500.0],
        [clat, clon, model[2] - 50.0],
    );
    let (w0, w1) = (
        terrain.geodetic_to_world("truth", g0).unwrap(),
        terrain.geodetic_to_world("truth", g1).unwrap(),
    );
    let cast = relief::cpu::voxel::VoxelScene::new(vec![inst.clone()]);
    let len = (w1 - w0).length();
    let voxel_truth = cast
        .cast(w0, (w1 - w0) / len, 0.0, len, 0.0)
        .expect("the column of a voxel meets the model");

    let ig = serve(&served, &dir, 2);
    let own = ownship(CAM, HEADING as f32, -3.0, 0.0);
    let entities: Vec<HostPacket> = vec![
        own.into(),
        EntityControl::placed(30, 9, sphere, [0.0; 3]).into(),
        EntityControl::placed(31, 8, model, [0.0; 3]).into(),
    ];
    ig.exchange(&message(ig_control(10, None, false), &entities), 10);

    let east = |p: [f64; 3], e: f64| moved(p, e, 0.0);
    let requests: Vec<(u16, LosSegmentRequest)> = vec![
        // Down through the centre, 25 m east of it, 60 m east (past it).
        (1, segment(1, true, up(sphere, 500.0), up(sphere, -500.0))),
        (
            2,
            segment(
                2,
                true,
                east(up(sphere, 500.0), 25.0),
                east(up(sphere, -500.0), 25.0),
            ),
        ),
        (
            3,
            segment(
                3,
                true,
                east(up(sphere, 500.0), 60.0),
                east(up(sphere, -500.0), 60.0),
            ),
        ),
        // Basic.
        (5, segment(5, false, up(sphere, 500.0), up(sphere, -500.0))),
        // The destination in the sphere's frame (500 m below its origin).
        (
            6,
            LosSegmentRequest {
                destination_entity_frame: true,
                destination_entity_valid: true,
                destination_entity_id: 30,
                ..segment(6, true, up(sphere, 500.0), [0.0, 0.0, 500.0])
            },
        ),
        (7, segment(7, true, g0, g1)),
        // From the sphere's centre up: a line leaving the body it starts in does not meet it.
        (8, segment(8, true, sphere, up(sphere, 500.0))),
    ];
    let mut asked = entities.clone();
    asked.extend(requests.iter().map(|(_, r)| HostPacket::from(*r)));
    asked.push(
        LosVectorRequest {
            request_id: 4,
            extended: true,
            azimuth: 0.0,
            elevation: -90.0,
            min_range: 0.0,
            max_range: 1000.0,
            source_lat: sphere[0],
            source_lon: sphere[1],
            source_alt: sphere[2] + 500.0,
            ..LosVectorRequest::default()
        }
        .into(),
    );
    let answer = ig.exchange(&message(ig_control(11, None, false), &asked), 11);
    ig.finish();

    let extended = |id: u16| -> LosExtendedResponse {
        *answer
            .packets
            .iter()
            .find_map(|p| match p {
                IgPacket::LosExtendedResponse(r) if r.request_id == id => Some(r),
                _ => None,
            })
            .unwrap_or_else(|| panic!("no extended response to {id}: {:?}", answer.packets))
    };
    let colour = COLOUR.map(srgb8);
    // The segments and the vector that meet the sphere.
    for (id, a, b) in [
        (1, up(sphere, 500.0), up(sphere, -500.0)),
        (
            2,
            east(up(sphere, 500.0), 25.0),
            east(up(sphere, -500.0), 25.0),
        ),
        (4, up(sphere, 500.0), up(sphere, -500.0)),
        (6, up(sphere, 500.0), up(sphere, -500.0)),
    ] {
        let r = extended(id);
        let truth = segment_truth(a, b, sphere).unwrap();
        let at = [r.lat, r.lon, r.alt];
        let off = dot(sub(ecef(at), ecef(a)), sub(ecef(at), ecef(a))).sqrt();
        eprintln!(
            "request {id}: entity {} at {:.3} m (truth {truth:.3} m), the point {off:.3} m from the source, normal elevation {:.3}°, colour {:?}",
            r.entity_id, r.range, r.normal_elevation, [r.red, r.green, r.blue, r.alpha]
        );
        assert!(
            r.valid && r.range_valid && r.entity_valid && !r.visible,
            "{r:?}"
        );
        assert_eq!(r.entity_id, 30);
        assert!(
            (r.range - truth).abs() < 0.01,
            "request {id}: {} against {truth}",
            r.range
        );
        assert!(
            (off - truth).abs() < 0.01,
            "request {id}: the point lies {off} m out"
        );
        assert_eq!(
            [r.red, r.green, r.blue, r.alpha],
            [colour[0], colour[1], colour[2], 255]
        );
    }
    // Straight down through the centre: the normal points up.
    assert!(extended(1).normal_elevation > 89.99, "{:?}", extended(1));
    assert!((extended(1).range - (500.0 - RADIUS)).abs() < 0.01);
    // Past the sphere: the terrain.
    let past = extended(3);
    eprintln!("request 3 (60 m east): {past:?}");
    assert!(!past.entity_valid && past.valid, "{past:?}");
    let ground = dem.height(past.lat, past.lon);
    assert!(
        (past.alt - ground).abs() < 0.5,
        "met the terrain: {} against {ground}",
        past.alt
    );
    // Basic.
    let basic = answer
        .packets
        .iter()
        .find_map(|p| match p {
            IgPacket::LosResponse(r) if r.request_id == 5 => Some(*r),
            _ => None,
        })
        .expect("a basic response");
    assert!(
        basic.valid && basic.entity_valid && !basic.visible,
        "{basic:?}"
    );
    assert_eq!(basic.entity_id, 30);
    assert!((basic.range - (500.0 - RADIUS)).abs() < 0.01, "{basic:?}");
    let inside = extended(8);
    assert!(
        inside.valid && inside.visible && !inside.entity_valid,
        "{inside:?}"
    );
    // The voxel model. It spans about 800 m: at the corner the column is taken from, its rigid
    // body frame (a tangent plane, as the IG places it) lies D²/2R ≈ 2.4 cm above the scene's
    // flat placement of the same model: the bound is 5 cm.
    let vox = extended(7);
    eprintln!(
        "request 7: entity {} at {:.3} m (CPU voxel cast of the scene's model {:.3} m), colour {:?}",
        vox.entity_id, vox.range, voxel_truth.t, [vox.red, vox.green, vox.blue]
    );
    assert!(vox.entity_valid && !vox.visible, "{vox:?}");
    assert_eq!(vox.entity_id, 31);
    assert!(
        (vox.range - voxel_truth.t).abs() < 0.05,
        "{} against {}",
        vox.range,
        voxel_truth.t
    );
    assert_eq!(
        [vox.red, vox.green, vox.blue, vox.alpha],
        voxel_truth.colour
    );
}

/// `--cigi-los every`: a line of sight is answered with one response for every surface it
/// meets, nearest first, each saying how many there are; the request's alpha threshold lets
/// it through entities fainter than the threshold (an entity's alpha scales its surfaces').
/// Two spheres one above the other over the terrain, the upper one at alpha 100; truths
/// solved in ECEF as above, the terrain's from the DEM.
#[test]
fn every_intersection_is_answered_and_the_alpha_threshold_lets_lines_through() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-los-every");
    let dem = Dem::load();
    let (served, sphere, _) = setup(&dir, &dem);
    let faint = up(sphere, 120.0);
    let ig = serve_with(&served, &dir, 3, &["--cigi-los", "every"]);
    let own = ownship(CAM, HEADING as f32, -3.0, 0.0);
    let entities: Vec<HostPacket> = vec![
        own.into(),
        EntityControl::placed(30, 9, sphere, [0.0; 3]).into(),
        EntityControl {
            alpha: 100,
            ..EntityControl::placed(32, 9, faint, [0.0; 3])
        }
        .into(),
    ];
    ig.exchange(&message(ig_control(10, None, false), &entities), 10);
    let (top, bottom) = (up(sphere, 500.0), up(sphere, -500.0));
    let threshold = |r: LosSegmentRequest, alpha: u8| LosSegmentRequest {
        alpha_threshold: alpha,
        ..r
    };
    let sky = moved(up(sphere, 1000.0), 300.0, 0.0);
    let mut asked = entities.clone();
    asked.extend([
        HostPacket::from(segment(1, true, top, bottom)),
        threshold(segment(2, true, top, bottom), 101).into(),
        segment(3, false, top, bottom).into(),
        threshold(segment(5, true, top, bottom), 255).into(),
        segment(6, true, sky, moved(sky, 500.0, 0.0)).into(),
        LosVectorRequest {
            request_id: 4,
            extended: true,
            alpha_threshold: 100,
            azimuth: 0.0,
            elevation: -90.0,
            min_range: 0.0,
            max_range: 1000.0,
            source_lat: top[0],
            source_lon: top[1],
            source_alt: top[2],
            ..LosVectorRequest::default()
        }
        .into(),
    ]);
    let answer = ig.exchange(&message(ig_control(11, None, false), &asked), 11);
    // 700 such requests would need 117,600 bytes of responses: past the budget each gets its
    // nearest only, and the datagram stays whole.
    let many: Vec<HostPacket> = (100..800)
        .map(|id| segment(id, true, top, bottom).into())
        .collect();
    let (flood, raw) = ig.exchange_raw(&message(ig_control(12, None, false), &many), 12);
    ig.finish();
    let mut per_id = std::collections::BTreeMap::<u16, Vec<u8>>::new();
    for p in &flood.packets {
        if let IgPacket::LosExtendedResponse(r) = p {
            per_id.entry(r.request_id).or_default().push(r.count);
        }
    }
    let full = per_id.values().filter(|c| c.len() == 3).count();
    eprintln!(
        "700 requests: a datagram of {} bytes, {full} answered with all 3 intersections",
        raw.len()
    );
    assert!(raw.len() <= 65_507 && per_id.len() == 700);
    assert!(per_id
        .values()
        .all(|c| c.iter().all(|&n| usize::from(n) == c.len())));
    let budget = relief::app::cigi_ig::answer::EVERY_BUDGET;
    assert!(
        full >= budget / (3 * 56) - 1 && full < 700,
        "{full} against {budget} bytes"
    );

    let extended = |id: u16| -> Vec<LosExtendedResponse> {
        (answer.packets.iter())
            .filter_map(|p| match p {
                IgPacket::LosExtendedResponse(r) if r.request_id == id => Some(*r),
                _ => None,
            })
            .collect()
    };
    let faint_truth = segment_truth(top, bottom, faint).unwrap();
    let sphere_truth = segment_truth(top, bottom, sphere).unwrap();
    // Each response of a request: the entity met (0: the terrain), in the order sent.
    let check = |id: u16, rs: &[LosExtendedResponse], entities: &[u16]| {
        let got: Vec<(u16, f64)> = rs.iter().map(|r| (r.entity_id, r.range)).collect();
        eprintln!("request {id}: {got:?}");
        assert_eq!(rs.len(), entities.len(), "request {id}: {rs:?}");
        for (r, &e) in rs.iter().zip(entities) {
            assert_eq!(usize::from(r.count), entities.len(), "{r:?}");
            assert!(r.valid && r.range_valid && !r.visible, "{r:?}");
            assert_eq!(r.entity_valid, e != 0, "{r:?}");
            assert_eq!(r.entity_id, e, "request {id}: {got:?}");
            let truth = match e {
                32 => faint_truth,
                30 => sphere_truth,
                _ => {
                    let ground = dem.height(r.lat, r.lon);
                    assert!((r.alt - ground).abs() < 0.5, "{} against {ground}", r.alt);
                    continue;
                }
            };
            assert!((r.range - truth).abs() < 0.01, "{r:?} against {truth}");
            assert_eq!(r.alpha, if e == 32 { 100 } else { 255 }, "{r:?}");
        }
        assert!(
            rs.windows(2).all(|w| w[0].range < w[1].range),
            "request {id}: {got:?}"
        );
    };
    check(1, &extended(1), &[32, 30, 0]);
    check(2, &extended(2), &[30, 0]);
    check(4, &extended(4), &[32, 30, 0]);
    check(5, &extended(5), &[30, 0]);
    let basic: Vec<LosResponse> = (answer.packets.iter())
        .filter_map(|p| match p {
            IgPacket::LosResponse(r) if r.request_id == 3 => Some(*r),
            _ => None,
        })
        .collect();
    let ids: Vec<u16> = basic.iter().map(|r| r.entity_id).collect();
    assert_eq!(ids, [32, 30, 0], "{basic:?}");
    assert!(basic.iter().all(|r| r.count == 3 && r.valid && !r.visible));
    assert!((basic[0].range - faint_truth).abs() < 0.01, "{basic:?}");
    // A line in the sky meets nothing: one response, visible.
    let clear = extended(6);
    assert_eq!(clear.len(), 1, "{clear:?}");
    assert!(
        clear[0].visible && !clear[0].range_valid && clear[0].count == 1,
        "{clear:?}"
    );
    // The terrain's point lies on the segment's ray below both spheres.
    let ground = extended(1)[2];
    assert!(ground.range > sphere_truth + 2.0 * RADIUS, "{ground:?}");
}

/// Collision Detection Segments: each frame the IG tests the segments of entities whose
/// collision detection is on against the terrain and the other entities drawn, and notifies
/// the first contact with its distance from the segment's first point.
#[test]
fn collision_segments_report_the_terrain_and_the_entities_they_meet() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-collisions");
    let dem = Dem::load();
    let (served, sphere, _) = setup(&dir, &dem);
    let ig = serve(&served, &dir, 2);
    // Entity 40 hovers 30 m above the ground (no template: not drawn); entity 41 300 m above
    // the sphere's centre; entity 42 as 40 but with collision detection off.
    let p = ahead(800.0, -300.0, 0.0);
    let low = [p[0], p[1], dem.height(p[0], p[1]) + 30.0];
    let on = |id: u16, lla: [f64; 3], detect: bool| -> HostPacket {
        EntityControl {
            collision_detection: detect,
            ..EntityControl::placed(id, 99, lla, [0.0; 3])
        }
        .into()
    };
    let seg = |entity_id: u16, segment_id: u8, enabled: bool, z2: f32| -> HostPacket {
        CollisionSegmentDefinition {
            entity_id,
            segment_id,
            enabled,
            z2,
            ..CollisionSegmentDefinition::default()
        }
        .into()
    };
    let own = ownship(CAM, HEADING as f32, -3.0, 0.0);
    let above = [sphere[0], sphere[1], sphere[2] + 300.0];
    let mut packets = vec![
        own.into(),
        EntityControl::placed(30, 9, sphere, [0.0; 3]).into(),
        on(40, low, true),
        on(41, above, true),
        on(42, low, false),
    ];
    // 40: 50 m down (the ground at 30 m), 20 m up (nothing), and one defined then disabled;
    // 41: 400 m down (the sphere's top at 260 m); 42: 50 m down (detection off).
    packets.extend([
        seg(40, 1, true, 50.0),
        seg(40, 2, true, -20.0),
        seg(40, 3, true, 50.0),
        seg(40, 3, false, 50.0),
        seg(41, 1, true, 400.0),
        seg(42, 1, true, 50.0),
    ]);
    ig.exchange(&message(ig_control(10, None, false), &packets), 10);
    let answer = ig.exchange(&message(ig_control(11, None, false), &packets[..5]), 11);
    ig.finish();
    let mut got: Vec<CollisionSegmentNotification> = answer
        .packets
        .iter()
        .filter_map(|p| match p {
            IgPacket::CollisionSegmentNotification(n) => Some(*n),
            _ => None,
        })
        .collect();
    got.sort_by_key(|n| (n.entity_id, n.segment_id));
    eprintln!("notifications: {got:?}");
    let keys: Vec<(u16, u8)> = got.iter().map(|n| (n.entity_id, n.segment_id)).collect();
    assert_eq!(keys, [(40, 1), (41, 1)]);
    let (ground, body) = (got[0], got[1]);
    assert!(!ground.entity_contact, "{ground:?}");
    assert!(
        (f64::from(ground.distance) - 30.0).abs() < 0.01,
        "{ground:?}"
    );
    let truth = segment_truth(above, up(above, -400.0), sphere).unwrap();
    assert!(
        body.entity_contact && body.contacted_entity_id == 30,
        "{body:?}"
    );
    assert!(
        (f64::from(body.distance) - truth).abs() < 0.01,
        "{body:?} against {truth}"
    );
    assert!((truth - 260.0).abs() < 1e-6);
}

/// `p` raised by `h` metres.
fn up(p: [f64; 3], h: f64) -> [f64; 3] {
    [p[0], p[1], p[2] + h]
}

/// Collision Detection Volumes: each frame the volumes of entities whose collision detection
/// is on are tested against the other entities' volumes (spheres and cuboids, turned with
/// their entity and by their own angles), and each overlap is notified to the entity that
/// asked. Margins of 5 m each way decide every pair.
#[test]
fn collision_volumes_report_the_volumes_they_overlap() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-volumes");
    let dem = Dem::load();
    let (served, _, _) = setup(&dir, &dem);
    let ig = serve(&served, &dir, 2);
    let a0 = ahead(600.0, 0.0, 0.0);
    let a = [a0[0], a0[1], dem.height(a0[0], a0[1]) + 500.0];
    let north = moved(a, 0.0, 100.0);
    let south = moved(a, 0.0, -100.0);
    let east = moved(a, 100.0, 0.0);
    let entity = |id: u16, lla: [f64; 3], detect: bool| -> HostPacket {
        EntityControl {
            collision_detection: detect,
            ..EntityControl::placed(id, 99, lla, [0.0; 3])
        }
        .into()
    };
    let sphere = |entity_id: u16, volume_id: u8, r: f32| -> HostPacket {
        CollisionVolumeDefinition {
            entity_id,
            volume_id,
            enabled: true,
            radius_height: r,
            ..CollisionVolumeDefinition::default()
        }
        .into()
    };
    // A box 140 m long (forward), 20 m wide and high; turned by `yaw` from its entity.
    let bar = |entity_id: u16, volume_id: u8, yaw: f32| -> HostPacket {
        CollisionVolumeDefinition {
            entity_id,
            volume_id,
            enabled: true,
            cuboid: true,
            depth: 140.0,
            width: 20.0,
            radius_height: 20.0,
            yaw,
            ..CollisionVolumeDefinition::default()
        }
        .into()
    };
    let own = ownship(CAM, HEADING as f32, -3.0, 0.0);
    let packets = vec![
        own.into(),
        // 50 (heading north): a sphere of 35 m, a bar along its heading, a bar turned east.
        entity(50, a, true),
        sphere(50, 1, 35.0),
        bar(50, 2, 0.0),
        bar(50, 3, 90.0),
        // 100 m south, 51: a sphere of 25 m, 5 m short of the bar (centred on 50, it reaches
        // 70 m each way); 100 m north, 52: 35 m, 5 m into it (detection on too).
        entity(51, south, false),
        sphere(51, 1, 25.0),
        entity(52, north, true),
        sphere(52, 1, 35.0),
        // 100 m east: 53, a sphere of 35 m: 5 m into the turned bar.
        entity(53, east, false),
        sphere(53, 1, 35.0),
    ];
    ig.exchange(&message(ig_control(10, None, false), &packets), 10);
    let answer = ig.exchange(&message(ig_control(11, None, false), &packets[..1]), 11);
    ig.finish();
    let mut got: Vec<[u16; 4]> = answer
        .packets
        .iter()
        .filter_map(|p| match p {
            IgPacket::CollisionVolumeNotification(n) => {
                assert!(n.entity_contact, "{n:?}");
                Some([
                    n.entity_id,
                    u16::from(n.volume_id),
                    n.contacted_entity_id,
                    u16::from(n.contacted_volume_id),
                ])
            }
            _ => None,
        })
        .collect();
    got.sort();
    eprintln!("volume notifications: {got:?}");
    assert_eq!(got, [[50, 2, 52, 1], [50, 3, 53, 1], [52, 1, 50, 2]]);
}

/// The least and greatest DEM heights over the square `half` metres each way around `at`
/// (a 41 x 41 grid: the DEM's cells are about 30 m, its surface bilinear between samples).
fn heights_around(dem: &Dem, at: [f64; 3], half: f64) -> (f64, f64) {
    let mut range = (f64::MAX, f64::MIN);
    for i in 0..41 {
        for j in 0..41 {
            let f = |k: i32| (f64::from(k) / 20.0 - 1.0) * half;
            let p = moved(at, f(i), f(j));
            let h = dem.height(p[0], p[1]);
            range = (range.0.min(h), range.1.max(h));
        }
    }
    range
}

/// Collision Detection Volumes against the terrain: each frame a volume of an entity whose
/// detection is on and that reaches below the terrain's surface is notified with
/// `entity_contact` false. A sphere of 10 m and a box 40 x 10 x 6 m pitched 20° nose up (its
/// lowest corner 20 sin 20° + 3 cos 20° = 9.66 m below its centre), each placed once 3 m into
/// the ground (below the lowest DEM height under it) and once 3 m clear of it (above the
/// highest), 300 m apart.
#[test]
fn collision_volumes_report_the_terrain_they_reach_below() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-volumes-terrain");
    let dem = Dem::load();
    let (served, _, _) = setup(&dir, &dem);
    let ig = serve(&served, &dir, 2);
    let drop = 20.0 * 20f64.to_radians().sin() + 3.0 * 20f64.to_radians().cos();
    let mut packets: Vec<HostPacket> = vec![ownship(CAM, HEADING as f32, -3.0, 0.0).into()];
    let mut expected = Vec::new();
    for (k, (cuboid, into)) in [(false, true), (false, false), (true, true), (true, false)]
        .into_iter()
        .enumerate()
    {
        let id = 70 + k as u16;
        let at = ahead(800.0, 300.0 * k as f64, 0.0);
        let (reach, below) = if cuboid { (21.0, drop) } else { (10.0, 10.0) };
        let (lo, hi) = heights_around(&dem, at, reach);
        let alt = if into {
            lo + below - 3.0
        } else {
            hi + below + 3.0
        };
        packets.push(
            EntityControl {
                collision_detection: true,
                ..EntityControl::placed(id, 99, [at[0], at[1], alt], [0.0; 3])
            }
            .into(),
        );
        packets.push(
            CollisionVolumeDefinition {
                entity_id: id,
                volume_id: 1,
                enabled: true,
                cuboid,
                depth: 40.0,
                width: 10.0,
                radius_height: if cuboid { 6.0 } else { 10.0 },
                pitch: if cuboid { 20.0 } else { 0.0 },
                ..CollisionVolumeDefinition::default()
            }
            .into(),
        );
        eprintln!("entity {id}: ground {lo:.1}–{hi:.1} m, centre at {alt:.1} m");
        if into {
            expected.push(id);
        }
    }
    ig.exchange(&message(ig_control(10, None, false), &packets), 10);
    let answer = ig.exchange(&message(ig_control(11, None, false), &packets[..1]), 11);
    ig.finish();
    let got: Vec<u16> = (answer.packets.iter())
        .filter_map(|p| match p {
            IgPacket::CollisionVolumeNotification(n) => {
                assert!(!n.entity_contact && n.volume_id == 1, "{n:?}");
                assert_eq!(
                    [n.contacted_entity_id, u16::from(n.contacted_volume_id)],
                    [0, 0]
                );
                Some(n.entity_id)
            }
            _ => None,
        })
        .collect();
    eprintln!("terrain contacts: {got:?}");
    assert_eq!(got, expected);
}

/// A frame whose answers and collision notifications would pass UDP's 65,507 bytes: 1,000
/// extended LOS requests (56,000 bytes of responses) and 1,024 collision segments that all
/// meet the ground (16,384 bytes). Every query is answered, the notifications fill what room
/// is left and the rest are dropped and counted (they come again next frame); the datagram is
/// sent whole.
#[test]
fn a_full_datagram_drops_collision_notifications_not_answers() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-full-datagram");
    let dem = Dem::load();
    let (served, sphere, _) = setup(&dir, &dem);
    let ig = serve(&served, &dir, 2);
    let p = ahead(800.0, -300.0, 0.0);
    let low = [p[0], p[1], dem.height(p[0], p[1]) + 30.0];
    let mut packets: Vec<HostPacket> = vec![ownship(CAM, HEADING as f32, -3.0, 0.0).into()];
    for entity_id in 60..64u16 {
        packets.push(
            EntityControl {
                collision_detection: true,
                ..EntityControl::placed(entity_id, 99, low, [0.0; 3])
            }
            .into(),
        );
        for segment_id in 0..=255u8 {
            packets.push(
                CollisionSegmentDefinition {
                    entity_id,
                    segment_id,
                    enabled: true,
                    z2: 50.0,
                    ..CollisionSegmentDefinition::default()
                }
                .into(),
            );
        }
    }
    ig.exchange(&message(ig_control(10, None, false), &packets), 10);
    let (top, bottom) = (up(sphere, 500.0), up(sphere, -500.0));
    let asked: Vec<HostPacket> = (0..1000)
        .map(|id| segment(id, true, top, bottom).into())
        .collect();
    let (answer, raw) = ig.exchange_raw(&message(ig_control(11, None, false), &asked), 11);
    let out = ig.finish();
    let los = (answer.packets.iter())
        .filter(|p| matches!(p, IgPacket::LosExtendedResponse(_)))
        .count();
    let notified = (answer.packets.iter())
        .filter(|p| matches!(p, IgPacket::CollisionSegmentNotification(_)))
        .count();
    let room = (65_507 - 24 - 1000 * 56) / 16;
    eprintln!(
        "a datagram of {} bytes: {los} LOS responses, {notified} of 1024 notifications (room for {room})",
        raw.len()
    );
    assert!(raw.len() <= 65_507, "{}", raw.len());
    assert_eq!(los, 1000);
    assert_eq!(notified, room);
    let counters = out
        .lines()
        .find_map(|l| l.strip_prefix("cigi-counters: "))
        .expect("the counters line");
    let j: serde_json::Value = serde_json::from_str(counters).unwrap();
    eprintln!(
        "collisions {} dropped {}",
        j["collisions"], j["collisions_dropped"]
    );
    assert_eq!(j["collisions_dropped"].as_u64(), Some(1024 - room as u64));
}
