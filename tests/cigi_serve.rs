//! `relief serve` obeying a CIGI host written here, over loopback only: the ownship's view
//! against `relief render` of the same geodetic camera, HAT/HOT against the DEM's bilinear
//! surface read from the `.hgt` by this test, line of sight against a dense march of that
//! surface, the IG's datagrams decoded by tshark, a synchronous host, and a flood of hostile
//! datagrams while a valid host flies. relief's `cigi` encoder writes the host's datagrams;
//! every truth is computed here.

mod cigi_support;
mod common;

use cigi_support::{
    host_socket, ig_control, mean_diff, ownship, render_frame, sof, sun_at, Dem, Ig,
};
use common::{relief_cli, temp_dir, terrains, Rng, Xvfb};
use relief::cigi::*;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const SIZE: &str = "160x120";

/// `relief serve SCENE --cigi 0 --size 160x120 ARGS`.
fn start_ig(scene: &Path, args: &[&str], host: UdpSocket) -> Ig {
    Ig::start(scene, &with_size(args), host)
}

/// `--size 160x120` and `args`.
fn with_size<'a>(args: &[&'a str]) -> Vec<&'a str> {
    let mut all = vec!["--size", SIZE];
    all.extend_from_slice(args);
    all
}

fn message(frame: u32, packets: &[HostPacket]) -> Vec<u8> {
    let mut m = MessageBuilder::host(&ig_control(frame, None, false), ByteOrder::Big);
    for p in packets {
        m.push_any(p);
    }
    m.finish()
}

/// A scene over N47E009 (`.hgt`) with the camera at geodetic `lla`, written to `dir/NAME.toml`.
fn scene_named(
    dir: &Path,
    name: &str,
    lla: [f64; 3],
    heading: f64,
    pitch: f64,
    roll: f64,
) -> PathBuf {
    let hgt = terrains().join("N47E009.hgt");
    let text = format!(
        "[terrain]\nsource = {hgt:?}\n[sun]\nazimuth = 245.0\nelevation = 24.0\n\
         [fog]\nvisibility = 90000.0\nscale_height = 3000.0\n\
         [camera]\ngeodetic = [{:?}, {:?}, {:?}]\nheading = {heading:?}\npitch = {pitch:?}\nroll = {roll:?}\nfov = 60.0\n\
         [output]\nwidth = 160\nheight = 120\n",
        lla[0], lla[1], lla[2]
    );
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

fn scene(dir: &Path, lla: [f64; 3], heading: f64, pitch: f64, roll: f64) -> PathBuf {
    scene_named(dir, "scene", lla, heading, pitch, roll)
}

#[test]
fn the_ownship_view_equals_render_of_the_same_geodetic_camera() {
    ownship_view_equals_render("cigi-serve-view", &[]);
}

/// The same with `--antialias edges` on both commands: the IG anti-aliases its frames as
/// `render` does and reports it in the frame JSON.
#[test]
fn the_anti_aliased_ownship_view_equals_render_too() {
    let j = ownship_view_equals_render("cigi-serve-view-aa", &["--antialias", "edges"]);
    let aa = &j["antialias"];
    assert_eq!(aa["adaptive"], true, "{aa}");
    let (pixels, rays) = (
        aa["pixels"].as_u64().unwrap(),
        aa["extra_rays"].as_u64().unwrap(),
    );
    assert!(pixels > 100 && rays >= 4 * pixels, "{aa}");
}

/// Serves one frame of a scene whose camera is elsewhere, the host placing the ownship at a
/// geodetic camera; compares it with `relief render` of a scene with that camera (both with
/// `args`) and returns the served frame's JSON.
fn ownship_view_equals_render(name: &str, args: &[&str]) -> serde_json::Value {
    let dir = temp_dir(name);
    let lla = [47.37, 9.31, 2300.0];
    let (heading, pitch, roll) = (182.0f32, -6.0f32, 4.0f32);
    let scene = scene(&dir, lla, heading.into(), pitch.into(), roll.into());
    // The IG's scene has its camera elsewhere, looking elsewhere: only CIGI places it.
    let elsewhere = scene_named(&dir, "elsewhere", [47.6, 9.6, 900.0], 45.0, 10.0, 0.0);
    let served = dir.join("served");
    let mut ig_args = vec![
        "--cigi-sync",
        "--frames",
        "1",
        "--capture-frames",
        served.to_str().unwrap(),
    ];
    ig_args.extend_from_slice(args);
    let ig = start_ig(&elsewhere, &ig_args, host_socket());
    let own = ownship(lla, heading, pitch, roll);
    let (m, _) = ig.exchange_raw(&message(7, &[own.into()]), 7);
    assert_eq!(sof(&m).ig_frame, 0);
    ig.finish();
    let a = image::open(served.join("frame_0000.png"))
        .unwrap()
        .to_rgba8();
    let b = render_frame(&scene, &dir.join("rendered"), args);
    let d = mean_diff(&a, &b);
    eprintln!("served vs rendered {args:?}: mean difference {d:.4}/255");
    assert!(d <= 1.0, "mean difference {d}/255");
    let j = common::read_json(&served.join("frame_0000.json"));
    assert_eq!(j["cigi"]["host_frame"], 7);
    assert_eq!(j["cigi"]["ig_frame"], 0);
    let g = j["camera"]["geodetic"].as_array().unwrap();
    for k in 0..3 {
        assert!((g[k].as_f64().unwrap() - lla[k]).abs() < 1e-9, "{g:?}");
    }
    j
}

/// A paged database scene (`--terrain-memory 8`) whose window follows the ownship: the
/// scene's window is 2° x 2° (513² samples of the 16x16 × 257² mosaic) around 49N 15E; the host
/// flies the ownship to 51N 17.3E, a degree and more beyond its north-east corner, looking
/// down. The IG moves the window with the eye (`paging.window` in the frame JSON), pages the
/// tiles there, and its first frame from the 30th on with every tile of the view resident
/// (within 600) is `relief render` (in memory) of a scene with the same geodetic camera and a
/// window around it: mean difference ≤ 1/255. Without the move the eye is off the window,
/// which holds no terrain under it.
#[test]
fn a_paged_window_follows_the_ownship_past_its_edge() {
    follow_past_the_edge("serve", &[]);
}

/// The same through `relief view --cigi` (Xvfb): its frame JSON has no `paging`, the picture
/// alone shows the window moved (the host flies on until it does, at most 600 frames).
#[test]
fn a_paged_window_follows_the_ownship_past_its_edge_in_view() {
    let Some(x) = Xvfb::start() else { return };
    follow_past_the_edge("view", &[("DISPLAY", x.display.as_str())]);
}

fn follow_past_the_edge(command: &str, env: &[(&str, &str)]) {
    let dir = temp_dir(&format!("cigi-{command}-follow"));
    let db = common::pager_mosaic();
    let scene_at = |name: &str, window: [f64; 4], lla: [f64; 3], memory: &str| {
        let text = format!(
            "[terrain]\ndatabase = {db:?}\nwindow = {window:?}\ncurved = true\n{memory}\n\
             [camera]\ngeodetic = {lla:?}\nheading = 20.0\npitch = -60.0\nfov = 60.0\n\
             [output]\nwidth = 160\nheight = 120\n"
        );
        let p = dir.join(format!("{name}.toml"));
        std::fs::write(&p, text).unwrap();
        p
    };
    let there = [51.0, 17.3, 6000.0];
    let served_scene = scene_at(
        "served",
        [48.0, 14.0, 50.0, 16.0],
        [49.0, 15.0, 6000.0],
        "memory = 8",
    );
    let served = dir.join("served");
    let reference = scene_at("reference", [50.0, 16.0, 52.0, 18.0], there, "");
    let b = render_frame(&reference, &dir.join("rendered"), &[]);
    let picture = |k: u32| {
        let png = served.join(format!("frame_{k:04}.png"));
        mean_diff(&image::open(png).unwrap().to_rgba8(), &b)
    };
    // The host flies on after the IG's 30th frame until the view's tiles are resident
    // (`serve`: the frame JSON's `paging.missing`; `view`, whose JSON has none: its picture
    // within 1/255 of the render there), at most `cap` frames: the pager reads them in the
    // background and never holds a frame, and on a loaded machine (tests running beside it)
    // that took more than 30 frames.
    let (frames, cap) = (30u32, 600u32);
    let settled = |k: u32| {
        // The JSON is written last, so the frame's files are all there once it is.
        let Some(j) = std::fs::read_to_string(served.join(format!("frame_{k:04}.json")))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        else {
            return false;
        };
        match command {
            "serve" => j["paging"]["missing"] == 0,
            _ => picture(k) <= 1.0,
        }
    };
    let n = cap.to_string();
    // Warnings only: a frame's info line a frame for up to `cap` frames would fill the stderr
    // pipe the test reads only at the end.
    let env: Vec<(&str, &str)> = env.iter().copied().chain([("RUST_LOG", "warn")]).collect();
    let mut ig = Ig::start_command(
        command,
        &served_scene,
        &with_size(&[
            "--cigi-sync",
            "--frames",
            &n,
            "--capture-frames",
            served.to_str().unwrap(),
        ]),
        host_socket(),
        &env,
    );
    let own = ownship(there, 20.0, -60.0, 0.0);
    let mut resident = None;
    for f in 0..cap {
        ig.exchange_raw(&message(f, &[own.into()]), f);
        // The IG wrote frame f - 1 before it took host frame f.
        if f >= frames && settled(f - 1) {
            resident = Some(f - 1);
            break;
        }
    }
    let shown = match resident {
        Some(k) => {
            ig.child.kill().unwrap();
            ig.child.wait().unwrap();
            k
        }
        None => {
            ig.finish();
            cap - 1
        }
    };
    let j = common::read_json(&served.join(format!("frame_{shown:04}.json")));
    let paging = &j["paging"];
    eprintln!("{command}: frame {shown}'s paging: {paging}");
    if command == "serve" {
        // The scene's window starts at (49664, 35328): 14E and 48N at 256 samples a degree.
        let window = [
            paging["window"][0].as_i64().unwrap(),
            paging["window"][1].as_i64().unwrap(),
        ];
        assert_ne!(window, [49664, 35328], "the window did not move");
        assert_eq!(
            paging["missing"], 0,
            "the view's tiles are resident within {cap} frames"
        );
    }
    let d = picture(shown);
    eprintln!("{command}: followed window vs in-memory render there: mean difference {d:.4}/255");
    assert!(d <= 1.0, "mean difference {d}/255");
}

fn hat_hot(id: u16, kind: u8, lat: f64, lon: f64, alt: f64) -> HatHotRequest {
    HatHotRequest {
        request_id: id,
        request_type: kind,
        entity_frame: false,
        update_period: 0,
        entity_id: 0,
        lat,
        lon,
        alt,
    }
}

#[test]
fn hat_and_hot_follow_the_dem_within_a_centimetre() {
    let dem = Dem::load();
    let dir = temp_dir("cigi-serve-hot");
    let scene = scene(&dir, [47.37, 9.31, 2300.0], 182.0, -6.0, 0.0);
    let ig = start_ig(&scene, &["--cigi-sync", "--frames", "1"], host_socket());
    // Säntis's flank, the Rhine valley, a point between samples near Lake Constance.
    let points = [
        (47.24937, 9.34331, 3000.0),
        (47.40123, 9.61877, 1000.0),
        (47.51234, 9.45678, 800.0),
    ];
    let mut packets = vec![ownship([47.37, 9.31, 2300.0], 0.0, 0.0, 0.0).into()];
    for (i, &(lat, lon, alt)) in points.iter().enumerate() {
        let id = 10 * i as u16;
        packets.push(hat_hot(id, 1, lat, lon, alt).into());
        packets.push(hat_hot(id + 1, 0, lat, lon, alt).into());
        packets.push(hat_hot(id + 2, 2, lat, lon, alt).into());
    }
    let (m, _) = ig.exchange_raw(&message(1, &packets), 1);
    ig.finish();
    let mut seen = 0;
    for p in &m.packets[1..] {
        let (id, hot, hat) = match *p {
            IgPacket::HatHotResponse(r) => {
                assert!(r.valid);
                assert_eq!(r.host_frame_lsn, 1);
                let (h, a) = if r.hot {
                    (Some(r.height), None)
                } else {
                    (None, Some(r.height))
                };
                (r.request_id, h, a)
            }
            IgPacket::HatHotExtendedResponse(r) => {
                assert!(r.valid);
                (r.request_id, Some(r.hot), Some(r.hat))
            }
            p => panic!("unexpected {p:?}"),
        };
        let (lat, lon, alt) = points[usize::from(id / 10)];
        let want = dem.height(lat, lon);
        if let Some(h) = hot {
            assert!(
                (h - want).abs() <= 0.01,
                "HOT at {lat}, {lon}: {h} vs DEM {want}"
            );
        }
        if let Some(a) = hat {
            assert!(
                (a - (alt - want)).abs() <= 0.01,
                "HAT at {lat}, {lon}: {a} vs {}",
                alt - want
            );
        }
        seen += 1;
    }
    assert_eq!(seen, 9);
}

/// WGS84 meridional radius of curvature (m) at latitude `lat` (degrees).
fn meridional_radius(lat: f64) -> f64 {
    let (a, f) = (6_378_137.0, 1.0 / 298.257_223_563);
    let e2 = f * (2.0 - f);
    let s = lat.to_radians().sin();
    a * (1.0 - e2) / (1.0 - e2 * s * s).powf(1.5)
}

#[test]
fn line_of_sight_across_the_saentis_ridge() {
    let dem = Dem::load();
    let dir = temp_dir("cigi-serve-los");
    let scene = scene(&dir, [47.37, 9.31, 2300.0], 182.0, -6.0, 0.0);
    let ig = start_ig(&scene, &["--cigi-sync", "--frames", "1"], host_socket());
    // North to south over the summit (2502 m), low and high.
    let lon = 9.34331;
    let (north, south) = (47.275, 47.225);
    let segment = |id: u16, alt: f64, extended: bool| {
        LosSegmentRequest::between(id, [north, lon, alt], [south, lon, alt], extended)
    };
    let vector = LosVectorRequest {
        request_id: 5,
        extended: true,
        source_entity_frame: false,
        response_entity_frame: false,
        alpha_threshold: 0,
        entity_id: 0,
        azimuth: 180.0,
        elevation: 0.0,
        min_range: 0.0,
        max_range: 10_000.0,
        source_lat: north,
        source_lon: lon,
        source_alt: 2300.0,
        material_mask: 0,
        update_period: 0,
    };
    let packets = vec![
        ownship([47.37, 9.31, 2300.0], 0.0, 0.0, 0.0).into(),
        segment(1, 2300.0, false).into(),
        segment(2, 2300.0, true).into(),
        segment(3, 2700.0, false).into(),
        segment(4, 2700.0, true).into(),
        vector.into(),
    ];
    let (m, _) = ig.exchange_raw(&message(2, &packets), 2);
    ig.finish();
    // Metres per degree of latitude here (WGS84), and the segment's length.
    let per_deg = meridional_radius(0.5 * (north + south)).to_radians();
    let length = (north - south) * per_deg;
    let low = dem
        .march(lon, (north, 2300.0), (south, 2300.0))
        .expect("the low segment meets the ridge");
    assert!(
        dem.march(lon, (north, 2700.0), (south, 2700.0)).is_none(),
        "the high one clears it"
    );
    let (s, step) = low;
    let want = s * length;
    let tol = step * length + 1e-3 * want;
    eprintln!(
        "march: low segment blocked at {want:.2} m (step {:.2} m)",
        step * length
    );
    let mut seen = 0;
    for p in &m.packets[1..] {
        match *p {
            IgPacket::LosResponse(r) => {
                assert!(r.valid);
                let low = r.request_id == 1;
                assert_eq!(r.visible, !low, "request {}", r.request_id);
                if low {
                    assert!(
                        (r.range - want).abs() <= tol,
                        "range {} vs march {want}",
                        r.range
                    );
                }
            }
            IgPacket::LosExtendedResponse(r) => {
                assert!(r.valid);
                let low = r.request_id != 4;
                if r.request_id != 5 {
                    assert_eq!(r.visible, !low, "request {}", r.request_id);
                }
                assert_eq!(r.range_valid, low, "request {}", r.request_id);
                if low {
                    assert!(
                        (r.range - want).abs() <= tol,
                        "{}: range {} vs march {want}",
                        r.request_id,
                        r.range
                    );
                    let lat = north + (south - north) * s;
                    assert!(
                        (r.lat - lat).abs() * per_deg <= tol,
                        "{}: lat {} vs {lat}",
                        r.request_id,
                        r.lat
                    );
                    assert!((r.lon - lon).abs() < 1e-9);
                    assert!((r.alt - 2300.0).abs() < 1e-6, "alt {}", r.alt);
                    assert!(
                        (r.alt - dem.height(r.lat, r.lon)).abs() < 0.05,
                        "the hit is on the DEM"
                    );
                }
            }
            p => panic!("unexpected {p:?}"),
        }
        seen += 1;
    }
    assert_eq!(seen, 5);
}

/// tshark's `(name, show)` of every CIGI field of each packet of a pdml document.
fn pdml(pdml: &str) -> Vec<Vec<(String, String)>> {
    let attr = |el: &str, name: &str| -> Option<String> {
        let key = format!(" {name}=\"");
        let start = el.find(&key)? + key.len();
        let len = el[start..].find('"')?;
        Some(el[start..start + len].to_string())
    };
    pdml.split("<packet>")
        .skip(1)
        .map(|p| {
            p.split("<field")
                .skip(1)
                .filter_map(|el| Some((attr(el, "name")?, attr(el, "show").unwrap_or_default())))
                .filter(|(n, _)| n.starts_with("cigi.") || n.starts_with("_ws."))
                .collect()
        })
        .collect()
}

#[test]
fn a_synchronous_host_gets_one_ig_frame_per_host_frame_decoded_by_tshark() {
    let dir = temp_dir("cigi-serve-sync");
    let scene = scene(&dir, [47.37, 9.31, 2300.0], 182.0, -6.0, 0.0);
    let frames = dir.join("frames");
    let ig = start_ig(
        &scene,
        &[
            "--cigi-sync",
            "--frames",
            "10",
            "--capture-frames",
            frames.to_str().unwrap(),
        ],
        host_socket(),
    );
    let host_addr = ig.host.local_addr().unwrap();
    let mut raw = Vec::new();
    for k in 0..10u32 {
        let hf = 1000 + 3 * k;
        let own = ownship(
            [47.37 - 0.001 * f64::from(k), 9.31, 2300.0],
            182.0,
            -6.0,
            0.0,
        );
        let mut packets = vec![own.into()];
        if k % 3 == 0 {
            packets.push(hat_hot(k as u16, 1, 47.3, 9.4, 0.0).into());
        }
        let (m, bytes) = ig.exchange_raw(&message(hf, &packets), hf);
        let s = sof(&m);
        assert_eq!(
            (s.ig_frame, s.last_host_frame, s.database, s.ig_mode),
            (k, hf, 0, 1)
        );
        assert_eq!(m.packets.len(), if k % 3 == 0 { 2 } else { 1 });
        raw.push(bytes);
    }
    ig.finish();
    for k in 0..10u32 {
        let j = common::read_json(&frames.join(format!("frame_{k:04}.json")));
        assert_eq!(j["cigi"]["host_frame"], 1000 + 3 * k, "IG frame {k}");
        assert_eq!(j["cigi"]["ig_frame"], k);
        let lat = j["camera"]["geodetic"][0].as_f64().unwrap();
        assert!(
            (lat - (47.37 - 0.001 * f64::from(k))).abs() < 1e-9,
            "frame {k}: lat {lat}"
        );
    }
    if std::process::Command::new("tshark")
        .arg("-v")
        .output()
        .is_err()
    {
        eprintln!("Skipping the tshark part: `tshark` is not installed (.ci/run installs it)");
        return;
    }
    let udp: Vec<relief::cigi::pcap::UdpFrame<'_>> = raw
        .iter()
        .enumerate()
        .map(|(i, d)| relief::cigi::pcap::UdpFrame {
            src: ([127, 0, 0, 2], 8005),
            dst: ([127, 0, 0, 1], host_addr.port().max(1)),
            time_us: 1_000_000 + 16_667 * i as u64,
            payload: d,
        })
        .collect();
    let pcap = dir.join("ig.pcap");
    std::fs::write(&pcap, relief::cigi::pcap::write_pcap(&udp).unwrap()).unwrap();
    let out = std::process::Command::new("tshark")
        .args(["-n", "-r"])
        .arg(&pcap)
        .args(["-d", "udp.port==8005,cigi", "-T", "pdml"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "tshark: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let packets = pdml(&String::from_utf8_lossy(&out.stdout));
    assert_eq!(packets.len(), 10);
    for (k, fields) in packets.iter().enumerate() {
        let get = |n: &str| -> Vec<&str> {
            fields
                .iter()
                .filter(|(f, _)| f == n)
                .map(|(_, v)| v.as_str())
                .collect()
        };
        assert!(
            !fields.iter().any(|(n, _)| n.starts_with("_ws.malformed")
                || n.starts_with("_ws.expert")
                || n == "cigi.unknown"),
            "frame {k}: {fields:?}"
        );
        let hf = (1000 + 3 * k).to_string();
        assert_eq!(
            get("cigi.sof.ig_frame_number"),
            [k.to_string().as_str()],
            "frame {k}"
        );
        assert_eq!(
            get("cigi.sof.last_host_frame_number"),
            [hf.as_str()],
            "frame {k}"
        );
        assert_eq!(get("cigi.sof.db_number"), ["0"], "frame {k}");
        assert_eq!(get("cigi.sof.ig_mode"), ["1"], "frame {k}");
        assert_eq!(get("cigi.sof.timestamp_valid"), ["1"], "frame {k}");
        let ids = get("cigi.packet_id");
        assert_eq!(
            ids,
            if k % 3 == 0 {
                vec!["101", "102"]
            } else {
                vec!["101"]
            },
            "frame {k}"
        );
    }
}

/// A hostile datagram: random bytes, a valid message with bytes changed, a valid header with
/// random packets, or a truncated valid message.
fn hostile(rng: &mut Rng, valid: &[u8]) -> Vec<u8> {
    let r = |rng: &mut Rng, n: usize| (rng.next_u64() % n as u64) as usize;
    match rng.next_u64() % 4 {
        0 => (0..r(rng, 300)).map(|_| rng.next_u64() as u8).collect(),
        1 => {
            let mut v = valid.to_vec();
            for _ in 0..=r(rng, 6) {
                let i = r(rng, v.len());
                v[i] = rng.next_u64() as u8;
            }
            v
        }
        2 => {
            let mut v = valid[..24].to_vec();
            v.extend((0..r(rng, 200)).map(|_| rng.next_u64() as u8));
            v
        }
        _ => valid[..r(rng, valid.len())].to_vec(),
    }
}

#[test]
fn twenty_thousand_hostile_datagrams_while_a_valid_host_flies() {
    let dir = temp_dir("cigi-serve-hostile");
    let scene = scene(&dir, [47.37, 9.31, 2300.0], 182.0, -6.0, 0.0);
    let host = host_socket();
    let host_addr = host.local_addr().unwrap().to_string();
    let ig = start_ig(
        &scene,
        &["--frames", "240", "--cigi-host", &host_addr],
        host,
    );
    ig.host
        .set_read_timeout(Some(Duration::from_millis(5)))
        .unwrap();
    let valid = |f: u32| {
        message(
            f,
            &[
                ownship([47.37, 9.31, 2300.0], 182.0, -6.0, 0.0).into(),
                hat_hot(1, 1, 47.3, 9.4, 0.0).into(),
            ],
        )
    };
    let stranger = host_socket();
    let mut rng = Rng::new(21);
    let (mut sent, mut strangers, mut host_frames, mut answers) = (0u32, 0u32, 0u32, 0u32);
    let mut buf = vec![0u8; 65536];
    let t0 = Instant::now();
    let mut last_answer_after_flood = None;
    while t0.elapsed() < Duration::from_secs(60) {
        if ig.exited() {
            break;
        }
        host_frames += 1;
        ig.send(&valid(host_frames));
        // 250 hostile datagrams per valid host frame from the host's own address, a few from
        // a stranger, until 20,000 are out.
        for _ in 0..250 {
            if sent < 20_000 {
                ig.send(&hostile(&mut rng, &valid(host_frames)));
                sent += 1;
            }
        }
        if strangers < 100 {
            stranger.send_to(&valid(host_frames), ig.addr).unwrap();
            strangers += 1;
        }
        while let Ok((n, _)) = ig.host.recv_from(&mut buf) {
            let m = read_ig_message(&buf[..n]).expect("the IG's datagrams stay valid");
            answers += 1;
            if sent == 20_000 {
                last_answer_after_flood = Some(sof(&m).last_host_frame);
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let elapsed = t0.elapsed();
    let out = ig.finish();
    eprintln!("{sent} hostile datagrams, {host_frames} host frames, {answers} IG datagrams in {elapsed:?}\n{out}");
    assert_eq!(sent, 20_000, "the IG ended before the flood did");
    assert!(answers >= 30, "frames kept coming: {answers}");
    assert!(last_answer_after_flood.is_some(), "answers after the flood");
    // "cigi: N IG frames, D datagrams in (A accepted, R refused, I from other senders, M malformed)"
    let summary = out
        .lines()
        .find(|l| l.starts_with("cigi: "))
        .expect("summary line");
    let nums: Vec<u64> = summary
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    let (frames, datagrams, accepted, refused, others) =
        (nums[0], nums[1], nums[2], nums[3], nums[4]);
    assert_eq!(frames, 240);
    assert_eq!(accepted + refused, datagrams);
    assert!(others >= 1 && others <= u64::from(strangers), "{summary}");
    // Loopback may drop datagrams under the flood (the IG asks for a 4 MiB receive buffer);
    // most arrive and a good part of them are refused.
    let offered = u64::from(sent + host_frames + strangers);
    assert!(
        datagrams <= offered && datagrams >= offered * 9 / 10,
        "{summary}"
    );
    assert!(refused >= (datagrams - others) / 3 + others, "{summary}");
}

#[test]
fn view_with_cigi_follows_a_synchronous_host() {
    let Some(x) = Xvfb::start() else { return };
    let dir = temp_dir("cigi-view");
    let scene = scene(&dir, [47.6, 9.6, 900.0], 45.0, 10.0, 0.0);
    // A template for entity type 7 (the sun, fog and entities from the host, as in serve).
    let mut text = std::fs::read_to_string(&scene).unwrap();
    text.push_str(
        "[[objects]]\nname = \"ball\"\nshape = \"sphere\"\nradius = 40.0\n\
         geodetic = [47.2, 9.2, 3000.0]\n[[cigi.entity]]\ntype = 7\nfreeform = \"ball\"\nmax = 2\n",
    );
    std::fs::write(&scene, text).unwrap();
    let frames = dir.join("frames");
    let ig = Ig::start_command(
        "view",
        &scene,
        &with_size(&[
            "--cigi-sync",
            "--frames",
            "3",
            "--capture-frames",
            frames.to_str().unwrap(),
        ]),
        host_socket(),
        &[("DISPLAY", x.display.as_str())],
    );
    for k in 0..3u32 {
        let own = ownship(
            [47.37 - 0.001 * f64::from(k), 9.31, 2300.0],
            182.0,
            -6.0,
            0.0,
        );
        let mut ball = ownship([47.33, 9.31, 2300.0], 0.0, 0.0, 0.0);
        (ball.entity_id, ball.entity_type) = (5, 7);
        let celestial = sun_at(6212024, 7, 40); // 21 June 2024 (MMDDYYYY), 07:40 UTC
        let mut atmosphere = AtmosphereControl::default();
        (atmosphere.model_enable, atmosphere.visibility) = (true, 15000.0);
        let packets = [own.into(), ball.into(), celestial.into(), atmosphere.into()];
        let (m, _) = ig.exchange_raw(&message(50 + k, &packets), 50 + k);
        assert_eq!(sof(&m).ig_frame, k);
    }
    ig.finish();
    for k in 0..3u32 {
        let j = common::read_json(&frames.join(format!("frame_{k:04}.json")));
        assert_eq!(j["cigi"]["host_frame"], 50 + k, "frame {k}");
        assert_eq!(j["cigi"]["drawn"], 1, "frame {k}: the entity drawn");
        assert_eq!(j["cigi"]["visibility"], 15000.0, "frame {k}");
        let sun = j["cigi"]["sun"][0].as_f64().unwrap();
        assert!((sun - 97.96).abs() < 0.1, "frame {k}: sun azimuth {sun}");
        let lat = j["camera"]["geodetic"][0].as_f64().unwrap();
        assert!(
            (lat - (47.37 - 0.001 * f64::from(k))).abs() < 1e-9,
            "frame {k}: lat {lat}"
        );
    }
}

/// `relief bench cigi` at 160x120 with short phases: the report's schema and figures a
/// working IG must give (every batch answered, frames reported, the flood sent).
#[test]
fn bench_cigi_reports_query_rates_latency_and_frame_period() {
    let o = relief_cli(
        &[
            "bench",
            "cigi",
            "terrains/alps.toml",
            "--size",
            "160x120",
            "--frames",
            "60",
            "--json",
        ],
        &[],
    );
    assert!(
        o.status.success(),
        "relief bench cigi failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    eprintln!("{}", r["rows"]);
    assert_eq!(r["bench"], "cigi");
    let names: Vec<_> = (r["rows"].as_array().unwrap().iter())
        .map(|row| row["name"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(
        names,
        [
            "quiet",
            "hat_hot",
            "los",
            "hat_hot_1000",
            "los_1000",
            "flood"
        ]
    );
    let d = &r["details"];
    assert_eq!(d["oracle_invalid"], 0);
    for k in ["oracle_hat_hot_per_s", "oracle_los_per_s"] {
        assert!(d[k].as_f64().unwrap() > 1000.0, "{k}");
    }
    let phases = d["phases"].as_array().unwrap();
    let f = |i: usize, k: &str| r["rows"][i][k].as_f64().unwrap();
    // 100 queries a host frame, 60 host frames a phase: 6,000 offered, every one answered
    // (the last frames' answers may arrive in the next phase).
    let answered = |i: usize| phases[i]["responses"].as_u64().unwrap();
    assert!((5700..=6000).contains(&answered(1)), "{}", answered(1));
    assert!((5700..=6300).contains(&answered(2)), "{}", answered(2));
    for (i, phase) in phases.iter().enumerate() {
        assert!(f(i, "latency_ms_p50") > 0.0 && f(i, "latency_ms_p99") < 500.0);
        assert!(f(i, "latency_frames_p50") >= 1.0);
        assert!(f(i, "sof_ms_p50") > 10.0 && f(i, "sof_ms_p50") < 100.0);
        assert!(phase["unreported"].as_u64().unwrap() <= 3);
    }
    // 1,000 a host frame: 60,000 offered, less what the session's cap of 1,024 waiting
    // queries dropped when two host datagrams fell in one IG frame.
    let dropped = d["dropped_queries"].as_u64().unwrap();
    for i in [3, 4] {
        assert!(
            answered(i) + dropped >= 54_000,
            "{} + {dropped}",
            answered(i)
        );
    }
    assert!(f(5, "flood_per_s") > 5000.0, "{}", f(5, "flood_per_s"));
}
