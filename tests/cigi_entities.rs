//! CIGI entities attached to a parent and clamped to the ground: placed and drawn where the
//! host puts them. The truth is computed here: attached offsets through the parent's
//! aerospace rotation (`dcm`) into north-east-down metres and then degrees by the WGS84 radii,
//! the ground from the SRTM tile's samples read here (`Dem`), the terrain's slope from those
//! samples half a sample each way.

mod cigi_support;
mod common;

use cigi_support::*;
use common::temp_dir;
use relief::cigi::*;

const CAM: [f64; 3] = [47.45, 9.50, 1300.0];
const HEADING: f64 = 30.0;
const PITCH: f64 = -3.0;
/// The parent's attitude, and the child's offsets (x forward, y right, z down, metres) and
/// attitude relative to it.
const PARENT_YPR: [f64; 3] = [45.0, 10.0, 5.0];
const CHILD_XYZ: [f64; 3] = [150.0, -70.0, -40.0];
const CHILD_YPR: [f64; 3] = [30.0, -5.0, 12.0];
/// Height offsets above the ground of the clamped entities, the conformal one's heading and
/// its pitch and roll offsets from the slope.
const CLAMP_ALT: f64 = 20.0;
const CONFORMAL_ALT: f64 = 12.0;
const CONFORMAL_YPR: [f64; 3] = [80.0, 4.0, -3.0];

/// `dist` metres ahead of the camera along its heading and `right` to its right, at `alt`.
fn ahead(dist: f64, right: f64, alt: f64) -> [f64; 3] {
    let h = HEADING.to_radians();
    let (north, east) = (
        dist * h.cos() - right * h.sin(),
        dist * h.sin() + right * h.cos(),
    );
    let (m, n) = radii(CAM[0]);
    [
        CAM[0] + (north / m).to_degrees(),
        CAM[1] + (east / (n * CAM[0].to_radians().cos())).to_degrees(),
        alt,
    ]
}

/// Geodetic `lla` moved by `ned` metres (north, east, down) in a straight line from it: WGS84
/// through earth-centred coordinates, computed here (`ecef`, then latitude by fixed-point
/// iteration).
fn offset(lla: [f64; 3], ned: [f64; 3]) -> [f64; 3] {
    let (la, lo) = (lla[0].to_radians(), lla[1].to_radians());
    let north = [-la.sin() * lo.cos(), -la.sin() * lo.sin(), la.cos()];
    let east = [-lo.sin(), lo.cos(), 0.0];
    let up = [la.cos() * lo.cos(), la.cos() * lo.sin(), la.sin()];
    let o = ecef(lla);
    let q: [f64; 3] =
        std::array::from_fn(|i| o[i] + north[i] * ned[0] + east[i] * ned[1] - up[i] * ned[2]);
    let (a, f) = (6_378_137.0, 1.0 / 298.257_223_563);
    let e2 = f * (2.0 - f);
    let p = q[0].hypot(q[1]);
    let mut lat = q[2].atan2(p * (1.0 - e2));
    let mut h = 0.0;
    for _ in 0..20 {
        let n = a / (1.0 - e2 * lat.sin().powi(2)).sqrt();
        h = p / lat.cos() - n;
        lat = q[2].atan2(p * (1.0 - e2 * n / (n + h)));
    }
    [lat.to_degrees(), q[1].atan2(q[0]).to_degrees(), h]
}

/// The straight line from geodetic `a` to `b` in metres north, east, down at `a` (through
/// earth-centred coordinates).
fn ned_between(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    let (la, lo) = (a[0].to_radians(), a[1].to_radians());
    let north = [-la.sin() * lo.cos(), -la.sin() * lo.sin(), la.cos()];
    let east = [-lo.sin(), lo.cos(), 0.0];
    let up = [la.cos() * lo.cos(), la.cos() * lo.sin(), la.sin()];
    let (p, q) = (ecef(a), ecef(b));
    let d: [f64; 3] = std::array::from_fn(|i| q[i] - p[i]);
    let dot = |u: [f64; 3]| u[0] * d[0] + u[1] * d[1] + u[2] * d[2];
    [dot(north), dot(east), -dot(up)]
}

fn apply(m: [[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| (0..3).map(|k| m[i][k] * v[k]).sum())
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|x| x / l)
}

/// The entities of the test and where they must be: geodetic position and yaw, pitch, roll
/// (the aerospace angles of their body → north-east-down rotation).
struct Truth {
    parent: [f64; 3],
    child: ([f64; 3], [f64; 3]),
    clamped: ([f64; 3], [f64; 3]),
    conformal: ([f64; 3], [f64; 3]),
    /// The clamped and the conformal entity's latitude and longitude (altitude: the offset).
    clamped_at: [f64; 3],
    conformal_at: [f64; 3],
}

fn truth(dem: &Dem) -> Truth {
    let parent = ahead(1500.0, 0.0, 1250.0);
    let r = dcm(PARENT_YPR);
    let child = (
        offset(parent, apply(r, CHILD_XYZ)),
        euler(mat_mul(r, dcm(CHILD_YPR))),
    );
    let clamped_at = ahead(1700.0, 250.0, CLAMP_ALT);
    let ground = dem.height(clamped_at[0], clamped_at[1]);
    let clamped = (
        [clamped_at[0], clamped_at[1], ground + CLAMP_ALT],
        [0.0, 0.0, 0.0],
    );
    let conformal_at = ahead(1200.0, -250.0, CONFORMAL_ALT);
    let conformal = on_slope(dem, conformal_at, CONFORMAL_YPR);
    Truth {
        parent,
        child,
        clamped,
        conformal,
        clamped_at,
        conformal_at,
    }
}

/// Conformal clamping's truth: at `alt` above the ground under `lla`'s latitude and
/// longitude, down the surface normal (from the surface half a sample each way), forward
/// `ypr`'s heading laid into the surface, then its pitch and roll as offsets from that.
fn on_slope(dem: &Dem, [lat, lon, alt]: [f64; 3], ypr: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let h0 = dem.height(lat, lon);
    let d = 0.5 / 1200.0;
    let ned_of = |dlat: f64, dlon: f64| -> [f64; 3] {
        let q = [lat + dlat, lon + dlon, dem.height(lat + dlat, lon + dlon)];
        let m = metres(q, [lat, lon, h0]);
        [m[0], m[1], -m[2]]
    };
    let (e, w, n, s) = (
        ned_of(0.0, d),
        ned_of(0.0, -d),
        ned_of(d, 0.0),
        ned_of(-d, 0.0),
    );
    let east: [f64; 3] = std::array::from_fn(|i| e[i] - w[i]);
    let north: [f64; 3] = std::array::from_fn(|i| n[i] - s[i]);
    let down = unit(cross(north, east));
    let psi = ypr[0].to_radians();
    let level = [psi.cos(), psi.sin(), 0.0];
    let along = level[0] * down[0] + level[1] * down[1];
    let fwd = unit(std::array::from_fn(|i| level[i] - along * down[i]));
    let right = cross(down, fwd);
    let slope = [
        [fwd[0], right[0], down[0]],
        [fwd[1], right[1], down[1]],
        [fwd[2], right[2], down[2]],
    ];
    (
        [lat, lon, h0 + alt],
        euler(mat_mul(slope, dcm([0.0, ypr[1], ypr[2]]))),
    )
}

/// The host's packets: the ownship, the parent (5), the child attached to it (8), the
/// clamped (9) and the conformal (10) entity, all of type 7; an inactive entity (20) with an
/// entity attached to it (21).
fn packets(t: &Truth) -> Vec<HostPacket> {
    let f = |v: [f64; 3]| v.map(|x| x as f32);
    let own = ownship(CAM, HEADING as f32, PITCH as f32, 0.0);
    let parent = EntityControl::placed(5, 7, t.parent, f(PARENT_YPR));
    let child = EntityControl {
        attach: true,
        parent_id: 5,
        ..EntityControl::placed(8, 7, CHILD_XYZ, f(CHILD_YPR))
    };
    let clamped = EntityControl {
        ground_clamp: 1,
        ..EntityControl::placed(9, 7, t.clamped_at, [0.0; 3])
    };
    let conformal = EntityControl {
        ground_clamp: 2,
        ..EntityControl::placed(10, 7, t.conformal_at, f(CONFORMAL_YPR))
    };
    let asleep = EntityControl {
        entity_state: 0,
        ..EntityControl::placed(20, 7, t.parent, [0.0; 3])
    };
    let below = EntityControl {
        attach: true,
        parent_id: 20,
        ..EntityControl::placed(21, 7, [10.0, 0.0, 0.0], [0.0; 3])
    };
    [own, parent, child, clamped, conformal, asleep, below]
        .into_iter()
        .map(HostPacket::from)
        .collect()
}

/// The scene: the camera at the ownship, and a red ellipsoid as the template of type 7.
fn entity_scene(dir: &std::path::Path, name: &str, objects: &str) -> std::path::PathBuf {
    scene(dir, name, CAM, [HEADING, PITCH, 0.0], objects)
}

fn ellipsoid(name: &str, lla: [f64; 3], ypr: [f64; 3]) -> String {
    format!(
        "[[objects]]\nname = \"{name}\"\nshape = \"ellipsoid\"\nradii = [80.0, 30.0, 20.0]\n\
         geodetic = [{:?}, {:?}, {:?}]\nheading = {:?}\npitch = {:?}\nroll = {:?}\n\
         material = {{ colour = [0.9, 0.1, 0.1], ambient = 0.6, diffuse = 0.4, specular = 0.0, shininess = 10.0 }}\n",
        lla[0], lla[1], lla[2], ypr[0], ypr[1], ypr[2]
    )
}

/// The scene's template of entity type 7: a red ellipsoid, placed out of the way.
fn ball_template() -> String {
    ellipsoid("ball", [47.2, 9.2, 3000.0], [0.0; 3])
        + "[[cigi.entity]]\ntype = 7\nfreeform = \"ball\"\nmax = 8\n"
}

/// `relief serve SCENE` at 160x120, synchronous, for `frames` frames captured into `dir`,
/// with `args` besides.
fn serve(scene: &std::path::Path, dir: &std::path::Path, frames: u32, args: &[&str]) -> Ig {
    let n = frames.to_string();
    let mut all = vec![
        "--size",
        "160x120",
        "--cigi-sync",
        "--frames",
        &n,
        "--capture-frames",
        dir.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    Ig::start(scene, &all, host_socket())
}

/// The library's placements against the truth: positions within 0.01 m, axes within 0.002
/// rad (the conformal slope: the truth measures it in metres at the entity, the library in the
/// terrain's world).
#[test]
fn attached_and_clamped_entities_are_placed_where_the_host_puts_them() {
    let dir = temp_dir("cigi-entity-placement");
    let t = truth(&Dem::load());
    let template = ball_template();
    let sc = relief::scene::Scene::load(&entity_scene(&dir, "scene", &template)).unwrap();
    let world = relief::world::World::load(&sc).unwrap();
    let mut session = Session::new();
    session
        .receive(&message(ig_control(1, None, false), &packets(&t)), 0.0)
        .unwrap();
    let terrain = &world.terrain;
    for (id, (lla, ypr)) in [
        (5, (t.parent, PARENT_YPR)),
        (8, t.child),
        (9, t.clamped),
        (10, t.conformal),
    ] {
        let p = relief::world::entity_placement(&session, terrain, id, 0.0).unwrap();
        let want = terrain.geodetic_to_world("truth", lla).unwrap();
        let off = (p.position - want).length();
        // The attitude's columns (right, forward, up; east-north-up) against the truth's
        // body → north-east-down rotation (columns forward, right, down).
        let r = dcm(ypr);
        let ned = |v: glam::DVec3| [v.y, v.x, -v.z];
        let col = |k: usize| [r[0][k], r[1][k], r[2][k]];
        let axes = [
            (ned(p.attitude.y_axis), col(0)),
            (ned(p.attitude.x_axis), col(1)),
            (ned(-p.attitude.z_axis), col(2)),
        ];
        let turn = axes
            .iter()
            .flat_map(|(a, b)| (0..3).map(move |i| (a[i] - b[i]).abs()))
            .fold(0.0, f64::max);
        eprintln!("entity {id}: {off:.3} m from the truth, axes within {turn:.2e}");
        assert!(off <= 0.01, "entity {id}: {off} m");
        assert!(turn <= 2e-3, "entity {id}: axes {turn}");
    }
    // The clamped entities stand on the terrain, not at the altitude the host sent.
    let unclamped = terrain.geodetic_to_world("truth", t.clamped_at).unwrap().z;
    let p9 = relief::world::entity_placement(&session, terrain, 9, 0.0).unwrap();
    assert!(p9.position.z - unclamped > 500.0, "{}", p9.position.z);
    let inst = relief::world::entity_instances(&session, terrain, &world.templates, 0.0);
    assert_eq!(
        (inst.drawn.len(), inst.not_drawn, inst.hidden),
        (4, 0, 2),
        "drawn, not drawn, hidden (the inactive entity and the one attached to it)"
    );
    // Fully transparent (alpha 0): hidden too, and lines of sight pass through it.
    let mut faded = Session::new();
    let clear = EntityControl {
        alpha: 0,
        ..EntityControl::placed(9, 7, t.clamped_at, [0.0; 3])
    };
    faded
        .receive(&message(ig_control(1, None, false), &[clear.into()]), 0.0)
        .unwrap();
    let none = relief::world::entity_instances(&faded, terrain, &world.templates, 0.0);
    assert_eq!((none.drawn.len(), none.hidden), (0, 1));

    // Conformal Clamped Entity Control moves the conformal entity: a new position and heading,
    // its altitude, pitch and roll offsets kept from its Entity Control.
    let to = ahead(900.0, 150.0, 0.0);
    let moved = ConformalClampedEntityControl {
        entity_id: 10,
        yaw: 200.0,
        lat: to[0],
        lon: to[1],
    };
    session
        .receive(&message(ig_control(2, None, false), &[moved.into()]), 1.0)
        .unwrap();
    let at = session.host_time_at(1.0);
    let p = relief::world::entity_placement(&session, terrain, 10, at).unwrap();
    let (lla, ypr) = on_slope(
        &Dem::load(),
        [to[0], to[1], CONFORMAL_ALT],
        [200.0, CONFORMAL_YPR[1], CONFORMAL_YPR[2]],
    );
    let off = (p.position - terrain.geodetic_to_world("truth", lla).unwrap()).length();
    let got = relief::geom::attitude_angles(p.attitude);
    eprintln!("moved by Conformal Clamped Entity Control: {off:.3} m from the truth, attitude {got:?} against {ypr:?}");
    assert!(off <= 0.01, "{off} m");
    let turn = [got.0 - ypr[0], got.1 - ypr[1], got.2 - ypr[2]]
        .map(|d| (d + 180.0).rem_euclid(360.0) - 180.0);
    assert!(turn.iter().all(|d| d.abs() < 0.01), "{turn:?}");
}

/// `relief serve` draws them there: its frame equals `relief render` of the template placed
/// as a scene object at each truth pose.
#[test]
fn attached_and_clamped_entities_are_drawn_where_the_host_puts_them() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-entity-drawn");
    let t = truth(&Dem::load());
    let template = ball_template();
    let served_scene = entity_scene(&dir, "served", &template);
    let frames = dir.join("frames");
    let ig = serve(&served_scene, &frames, 4, &["--no-shadows"]);
    let own = ownship(CAM, HEADING as f32, PITCH as f32, 0.0);
    ig.exchange(&message(ig_control(10, None, false), &[own.into()]), 10);
    ig.exchange(&message(ig_control(11, None, false), &packets(&t)), 11);
    // Where the IG put them: the clamped entity and the child in geodetic coordinates, the
    // child in its parent's frame too.
    let ask = |object_id: u16, coordinate_system: u8| -> HostPacket {
        PositionRequest {
            object_id,
            part_id: 0,
            continuous: false,
            object_class: 0,
            coordinate_system,
        }
        .into()
    };
    let mut asked = packets(&t);
    asked.extend([ask(9, 0), ask(10, 0), ask(8, 0), ask(8, 1)]);
    let m = ig.exchange(&message(ig_control(12, None, false), &asked), 12);
    // Queries in the parent's frame, and the same queries given geodetically at the truth.
    let relative = relative_queries(&t);
    let mut asked = packets(&t);
    asked.extend(relative.iter().cloned());
    let q = ig.exchange(&message(ig_control(13, None, false), &asked), 13);
    ig.finish();
    check_relative_answers(&t, &q);
    let answers: Vec<PositionResponse> = (m.packets.iter())
        .filter_map(|p| match p {
            IgPacket::PositionResponse(r) => Some(*r),
            _ => None,
        })
        .collect();
    assert_eq!(answers.len(), 4, "{answers:?}");
    for (r, (id, system, lla, ypr)) in answers.iter().zip([
        (9, 0, t.clamped.0, t.clamped.1),
        (10, 0, t.conformal.0, t.conformal.1),
        (8, 0, t.child.0, t.child.1),
        (8, 1, CHILD_XYZ, CHILD_YPR),
    ]) {
        let off = if system == 0 {
            let d = metres([r.lat, r.lon, r.alt], lla);
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        } else {
            let d = [r.lat - lla[0], r.lon - lla[1], r.alt - lla[2]];
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        };
        let turn = [r.yaw, r.pitch, r.roll]
            .iter()
            .zip(ypr)
            .map(|(a, b)| (f64::from(*a) - b + 180.0).rem_euclid(360.0) - 180.0)
            .fold(0.0f64, |x, d| x.max(d.abs()));
        eprintln!("position of {id} (system {system}): {off:.3} m, {turn:.4}° from the truth");
        assert_eq!((r.object_id, r.coordinate_system), (id, system));
        assert!(off <= 0.01 && turn <= 0.01, "entity {id}: {off} m, {turn}°");
    }
    let json = common::read_json(&frames.join("frame_0001.json"));
    assert_eq!(json["cigi"]["drawn"], 4, "{}", json["cigi"]);
    assert_eq!(json["cigi"]["hidden"], 2, "{}", json["cigi"]);
    let served = image_at(&frames.join("frame_0001.png"));
    let base = image_at(&frames.join("frame_0000.png"));
    let objects = ellipsoid("parent", t.parent, PARENT_YPR)
        + &ellipsoid("child", t.child.0, t.child.1)
        + &ellipsoid("clamped", t.clamped.0, t.clamped.1)
        + &ellipsoid("conformal", t.conformal.0, t.conformal.1);
    let placed = entity_scene(&dir, "placed", &objects);
    let rendered = render_frame(&placed, &dir.join("rendered"), &["--no-shadows"]);
    // Each object alone shows (none hides behind the terrain or another).
    for (name, lla, ypr) in [
        ("child", t.child.0, t.child.1),
        ("clamped", t.clamped.0, t.clamped.1),
        ("conformal", t.conformal.0, t.conformal.1),
    ] {
        let alone = entity_scene(&dir, name, &ellipsoid(name, lla, ypr));
        let img = render_frame(&alone, &dir.join(name), &["--no-shadows"]);
        let shown = img
            .pixels()
            .zip(base.pixels())
            .filter(|(a, b)| {
                (0..3)
                    .map(|c| u32::from(a.0[c].abs_diff(b.0[c])))
                    .sum::<u32>()
                    > 6
            })
            .count();
        eprintln!("{name}: {shown} pixels");
        assert!(shown >= 20, "{name} shows in {shown} pixels");
    }
    // Pixels more than 2 levels apart in a channel.
    let apart = |a: &image::RgbaImage, b: &image::RgbaImage| {
        a.pixels()
            .zip(b.pixels())
            .filter(|(p, q)| (0..3).any(|c| p.0[c].abs_diff(q.0[c]) > 2))
            .count()
    };
    let (d, differ, without) = (
        mean_diff(&served, &rendered),
        apart(&served, &rendered),
        apart(&served, &base),
    );
    eprintln!("served vs render of the four objects at the truth: {d:.4}/255, {differ} pixels apart; {without} pixels apart from the frame without entities");
    // Sub-metre differences between the truth's placement and the library's (the flat
    // terrain's world frame) may move an edge pixel or two.
    assert!(differ <= 2, "{differ} pixels differ ({d}/255)");
    assert!(without >= 100, "the entities show: {without} pixels");
}

/// A ground vehicle's eye: the ownship clamped conformally rides the terrain 3 m above it,
/// pitched and rolled with the slope; the served frame equals `relief render` from the truth's
/// eye.
#[test]
fn a_conformally_clamped_ownship_rides_the_slope() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-clamped-ownship");
    let dem = Dem::load();
    let at = ahead(1200.0, -250.0, 3.0);
    let ypr = [CONFORMAL_YPR[0], 0.0, 0.0];
    let (eye, eye_ypr) = on_slope(&dem, at, ypr);
    let served_scene = scene(&dir, "served", [47.6, 9.6, 900.0], [45.0, 0.0, 0.0], "");
    let frames = dir.join("frames");
    let ig = serve(&served_scene, &frames, 1, &[]);
    let own = EntityControl {
        ground_clamp: 2,
        ..ownship(at, ypr[0] as f32, 0.0, 0.0)
    };
    ig.exchange(&message(ig_control(1, None, false), &[own.into()]), 1);
    ig.finish();
    let served = image_at(&frames.join("frame_0000.png"));
    let truth = scene(&dir, "eye", eye, eye_ypr, "");
    let rendered = render_frame(&truth, &dir.join("rendered"), &[]);
    let level = scene(&dir, "level", eye, ypr, "");
    let unrolled = render_frame(&level, &dir.join("level"), &[]);
    let (d, d_level) = (mean_diff(&served, &rendered), mean_diff(&served, &unrolled));
    eprintln!(
        "eye pitch {:.2}°, roll {:.2}° on the slope; served vs render there {d:.4}/255, vs the level eye {d_level:.2}/255",
        eye_ypr[1], eye_ypr[2]
    );
    assert!(d <= 0.05, "{d}/255");
    assert!(d_level > 2.0, "the slope turns the eye: {d_level}/255");
}

/// The parent's body offsets of the queries: a HAT/HOT point, a segment's far end, a
/// vector's azimuth and elevation from the body's x axis and xy plane.
const HOT_XYZ: [f64; 3] = [200.0, 50.0, 0.0];
const SEGMENT_END: [f64; 3] = [3000.0, 0.0, 1500.0];
const VECTOR_AZ_EL: [f64; 2] = [20.0, -30.0];

/// HOT (1) and HAT (2) of a point in entity 5's frame; a segment from it to a point in its
/// frame, extended, the intersection given back in its frame (3) and geodetically (4); a
/// vector from it (5); and the geodetic twins the test computes: the segment (13), the vector
/// (15).
fn relative_queries(t: &Truth) -> Vec<HostPacket> {
    let r = dcm(PARENT_YPR);
    let hot = |request_id: u16, request_type: u8| -> HostPacket {
        HatHotRequest {
            request_id,
            request_type,
            entity_frame: true,
            update_period: 0,
            entity_id: 5,
            lat: HOT_XYZ[0],
            lon: HOT_XYZ[1],
            alt: HOT_XYZ[2],
        }
        .into()
    };
    let segment = |request_id: u16, relative: bool, response: bool| -> HostPacket {
        let (a, b) = if relative {
            ([0.0; 3], SEGMENT_END)
        } else {
            (t.parent, offset(t.parent, apply(r, SEGMENT_END)))
        };
        LosSegmentRequest {
            request_id,
            extended: true,
            source_entity_frame: relative,
            destination_entity_frame: relative,
            response_entity_frame: response,
            entity_id: 5,
            source_lat: a[0],
            source_lon: a[1],
            source_alt: a[2],
            destination_lat: b[0],
            destination_lon: b[1],
            destination_alt: b[2],
            ..LosSegmentRequest::default()
        }
        .into()
    };
    let vector = |request_id: u16, relative: bool| -> HostPacket {
        let [az, el] = if relative {
            VECTOR_AZ_EL
        } else {
            truth_az_el(VECTOR_AZ_EL)
        };
        let a = if relative { [0.0; 3] } else { t.parent };
        LosVectorRequest {
            request_id,
            extended: true,
            source_entity_frame: relative,
            entity_id: 5,
            azimuth: az as f32,
            elevation: el as f32,
            min_range: 0.0,
            max_range: 8000.0,
            source_lat: a[0],
            source_lon: a[1],
            source_alt: a[2],
            ..LosVectorRequest::default()
        }
        .into()
    };
    vec![
        hot(1, 1),
        hot(2, 0),
        segment(3, true, true),
        segment(4, true, false),
        segment(13, false, false),
        vector(5, true),
        vector(15, false),
    ]
}

/// Azimuth from north and elevation (degrees) of the parent's body direction `[az, el]`.
fn truth_az_el([az, el]: [f64; 2]) -> [f64; 2] {
    let (a, e) = (az.to_radians(), el.to_radians());
    let ned = apply(
        dcm(PARENT_YPR),
        [a.cos() * e.cos(), a.sin() * e.cos(), -e.sin()],
    );
    [
        ned[1].atan2(ned[0]).to_degrees(),
        (-ned[2]).asin().to_degrees(),
    ]
}

fn check_relative_answers(t: &Truth, m: &IgMessage) {
    let dem = Dem::load();
    let r = dcm(PARENT_YPR);
    let point = offset(t.parent, apply(r, HOT_XYZ));
    let ground = dem.height(point[0], point[1]);
    let mut los = std::collections::BTreeMap::new();
    let mut heights = std::collections::BTreeMap::new();
    for p in &m.packets {
        match p {
            IgPacket::HatHotResponse(h) => {
                assert!(h.valid, "{h:?}");
                heights.insert(h.request_id, h.height);
            }
            IgPacket::LosExtendedResponse(l) => {
                los.insert(l.request_id, *l);
            }
            _ => {}
        }
    }
    let (hot, hat) = (heights[&1], heights[&2]);
    eprintln!(
        "HOT in the parent's frame {hot:.3} m (truth {ground:.3}), HAT {hat:.3} m (truth {:.3})",
        point[2] - ground
    );
    assert!((hot - ground).abs() <= 0.01, "HOT {hot} against {ground}");
    assert!((hat - (point[2] - ground)).abs() <= 0.01, "HAT {hat}");
    // The segment in the parent's frame is the segment between the truth's points.
    let (rel, geo, back) = (los[&4], los[&13], los[&3]);
    eprintln!(
        "segment: range {:.3} m in the parent's frame, {:.3} m geodetic; visible {} / {}",
        rel.range, geo.range, rel.visible, geo.visible
    );
    assert!(rel.valid && geo.valid && rel.range_valid && !rel.visible && !geo.visible);
    assert!((rel.range - geo.range).abs() <= 0.01);
    let hit = [geo.lat, geo.lon, geo.alt];
    let d = metres([rel.lat, rel.lon, rel.alt], hit);
    assert!(
        d.iter().all(|x| x.abs() <= 0.01),
        "intersection {d:?} m apart"
    );
    // Given back in the parent's frame: the truth's offsets of the geodetic intersection.
    let ned = ned_between(t.parent, hit);
    let body: [f64; 3] = std::array::from_fn(|i| (0..3).map(|k| r[k][i] * ned[k]).sum());
    let given = [back.lat, back.lon, back.alt];
    let off: Vec<f64> = (0..3).map(|i| given[i] - body[i]).collect();
    eprintln!("intersection in the parent's frame {given:?}, truth {body:?}");
    assert!(off.iter().all(|x| x.abs() <= 0.01), "{off:?}");
    assert!((back.range - geo.range).abs() <= 0.01);
    // The vector in the parent's frame is the vector the truth's azimuth and elevation give.
    let (rel, geo) = (los[&5], los[&15]);
    eprintln!(
        "vector: range {:.3} m in the parent's frame, {:.3} m geodetic (azimuth, elevation {:?})",
        rel.range,
        geo.range,
        truth_az_el(VECTOR_AZ_EL)
    );
    assert!(rel.valid && rel.range_valid && geo.range_valid);
    assert!((rel.range - geo.range).abs() <= 0.05);
}

/// A chase view: the lowest view's View Control names entity 5, not the ownship, with the eye
/// 300 m behind it, 50 m above and pitched 5° down relative to it; the served frame equals
/// `relief render` from the eye the test computes, with the entity's template placed as a
/// scene object where the host put it.
#[test]
fn a_view_riding_another_entity_looks_from_it() {
    let _serial = one_ig_test_at_a_time();
    let dir = temp_dir("cigi-chase-view");
    let t = truth(&Dem::load());
    let (xyz, ypr) = ([-300.0, 0.0, -50.0], [0.0, -5.0, 0.0]);
    let r = dcm(PARENT_YPR);
    let eye = offset(t.parent, apply(r, xyz));
    let eye_ypr = euler(mat_mul(r, dcm(ypr)));
    let template = ball_template();
    let served_scene = entity_scene(&dir, "served", &template);
    let frames = dir.join("frames");
    let ig = serve(&served_scene, &frames, 1, &[]);
    let own = ownship(CAM, HEADING as f32, PITCH as f32, 0.0);
    let f = |v: [f64; 3]| v.map(|x| x as f32);
    let parent = EntityControl::placed(5, 7, t.parent, f(PARENT_YPR));
    let chase = ViewControl {
        view_id: 0,
        group_id: 0,
        x_enable: true,
        y_enable: true,
        z_enable: true,
        roll_enable: true,
        pitch_enable: true,
        yaw_enable: true,
        entity_id: 5,
        x: xyz[0] as f32,
        y: xyz[1] as f32,
        z: xyz[2] as f32,
        roll: ypr[2] as f32,
        pitch: ypr[1] as f32,
        yaw: ypr[0] as f32,
    };
    ig.exchange(
        &message(
            ig_control(1, None, false),
            &[own.into(), parent.into(), chase.into()],
        ),
        1,
    );
    ig.finish();
    let served = image_at(&frames.join("frame_0000.png"));
    let json = common::read_json(&frames.join("frame_0000.json"));
    let placed = scene(
        &dir,
        "eye",
        eye,
        eye_ypr,
        &ellipsoid("parent", t.parent, PARENT_YPR),
    );
    let rendered = render_frame(&placed, &dir.join("rendered"), &[]);
    let from_ownship = render_frame(
        &entity_scene(&dir, "own", &ellipsoid("parent", t.parent, PARENT_YPR)),
        &dir.join("own"),
        &[],
    );
    let (d, d_own) = (
        mean_diff(&served, &rendered),
        mean_diff(&served, &from_ownship),
    );
    eprintln!(
        "chase eye {eye:?} heading {:.3} pitch {:.3} roll {:.3}: served vs render there {d:.4}/255, vs the ownship's eye {d_own:.2}/255; JSON camera {}",
        eye_ypr[0], eye_ypr[1], eye_ypr[2], json["camera"]["geodetic"]
    );
    assert!(d <= 0.05, "{d}/255");
    assert!(d_own > 2.0, "the view moved: {d_own}/255");
}

/// On a paged database window (held hollow, `[terrain] memory`) ground clamping reads no tile
/// on the frame's thread: the first placement over ground whose tiles are not in memory comes
/// at once from a coarser level, the tiles are read in the background, and within a few
/// frames' time the clamped and the conformal entity stand where the truth puts them.
#[test]
fn clamped_entities_stand_on_a_paged_window_without_waiting_for_the_disk() {
    use std::time::{Duration, Instant};
    let dir = temp_dir("cigi-entity-paged");
    let db = common::db_build(
        dir.join("n47e009.reliefdb"),
        &common::terrains().join("N47E009.hgt"),
    );
    let text = format!(
        "[terrain]\ndatabase = {db:?}\nmemory = 8\n[camera]\ngeodetic = {CAM:?}\nheading = {HEADING:?}\n{}",
        ball_template()
    );
    let sc = relief::scene::Scene::parse(&text, &dir.join("scene.toml")).unwrap();
    let world = relief::world::World::load_as(&sc, true).unwrap();
    let terrain = &world.terrain;
    assert!(terrain.is_hollow());
    let t = truth(&Dem::load());
    let mut session = Session::new();
    session
        .receive(&message(ig_control(1, None, false), &packets(&t)), 0.0)
        .unwrap();
    let off = |id: u16, lla: [f64; 3]| -> f64 {
        let p = relief::world::entity_placement(&session, terrain, id, 0.0)
            .expect("placed at once, from what is in memory");
        (p.position - terrain.geodetic_to_world("truth", lla).unwrap()).length()
    };
    // The first placement is the first height asked: its tile is not in memory. (Entity 10's,
    // asked next, may share that tile, which the prefetcher may have read by then.)
    let first = off(9, t.clamped.0);
    eprintln!("at once: {first:.1} m from the truth");
    assert!(
        first > 0.01,
        "a tile not in memory was read on the frame's thread: {first} m"
    );
    let start = Instant::now();
    loop {
        let now = [off(9, t.clamped.0), off(10, t.conformal.0)];
        if now.iter().all(|d| *d <= 0.01) {
            eprintln!(
                "{:.1} ms later: {:.3} m and {:.3} m",
                start.elapsed().as_secs_f64() * 1e3,
                now[0],
                now[1]
            );
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "never exact: {now:?}"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}
