//! The CIGI 3.3 wire layer (issue 21, first part): every packet round trip in both byte
//! orders, hostile datagrams, the session's state and interpolation, and Wireshark's CIGI
//! dissector (tshark) as the independent decoder of what relief writes.

mod common;

use common::{temp_dir, Rng};
use relief::cigi::pcap::{write_pcap, UdpFrame, HOST_ADDR, IG_ADDR};
use relief::cigi::*;
use std::net::SocketAddr;
use std::process::Command;
use std::time::Instant;

// ---------------------------------------------------------------------------------------------
// Sample packets: every field a distinct value; `k` (0 or 1) flips every flag and moves every
// number, so two samples of a kind together set and clear each bit.

fn b(k: u32, i: u32) -> bool {
    (k + i) % 2 == 1
}

fn ig_control(k: u32) -> IgControl {
    IgControl {
        database: 7 - 9 * k as i8,
        ig_mode: 1 + k as u8,
        timestamp_valid: b(k, 1),
        extrapolation: b(k, 0),
        host_frame: 123_456 + k,
        timestamp: 987_654_321 + k,
        last_ig_frame: 4_000_000_000 + k,
    }
}

fn entity_control(k: u32) -> EntityControl {
    EntityControl {
        entity_id: 65_000 + k as u16,
        entity_state: 1 + k as u8,
        attach: b(k, 1),
        collision_detection: b(k, 0),
        inherit_alpha: b(k, 1),
        ground_clamp: 2 - k as u8,
        animation_direction: b(k, 0),
        animation_loop: b(k, 1),
        animation_state: 2 + k as u8,
        extrapolation: b(k, 0),
        alpha: 200 + k as u8,
        entity_type: 1234 + k as u16,
        parent_id: 42 + k as u16,
        roll: -12.5 + k as f32,
        pitch: 3.25 + k as f32,
        yaw: 271.75 + k as f32,
        lat: 47.25 + f64::from(k),
        lon: 9.375 + f64::from(k),
        alt: 2502.5 + f64::from(k),
    }
}

fn conformal_clamped(k: u32) -> ConformalClampedEntityControl {
    ConformalClampedEntityControl {
        entity_id: 5 + k as u16,
        yaw: 123.25 + k as f32,
        lat: -33.125 + f64::from(k),
        lon: 151.0625 + f64::from(k),
    }
}

fn rate_control(k: u32) -> RateControl {
    RateControl {
        entity_id: 3 + k as u16,
        part_id: 17 + k as u8,
        apply_to_part: b(k, 0),
        body_frame: b(k, 1),
        x_rate: 100.5 + k as f32,
        y_rate: -2.25 + k as f32,
        z_rate: 0.125 + k as f32,
        roll_rate: 5.5 + k as f32,
        pitch_rate: -1.5 + k as f32,
        yaw_rate: 3.0 + k as f32,
    }
}

fn celestial(k: u32) -> CelestialSphereControl {
    CelestialSphereControl {
        hour: 13 + k as u8,
        minute: 45 + k as u8,
        ephemeris: b(k, 1),
        sun: b(k, 0),
        moon: b(k, 1),
        stars: b(k, 0),
        date_time_valid: b(k, 1),
        date: 6_212_026 + k,
        star_intensity: 62.5 + k as f32,
    }
}

fn atmosphere(k: u32) -> AtmosphereControl {
    AtmosphereControl {
        model_enable: b(k, 1),
        humidity: 55 + k as u8,
        air_temperature: 15.5 + k as f32,
        visibility: 25_000.0 + k as f32,
        horizontal_wind: 7.25 + k as f32,
        vertical_wind: -0.5 + k as f32,
        wind_direction: 270.0 + k as f32,
        pressure: 1013.25 + k as f32,
    }
}

fn weather(k: u32) -> WeatherControl {
    WeatherControl {
        entity_region_id: 513 + k as u16,
        layer_id: 2 + k as u8,
        humidity: 80 + k as u8,
        enable: b(k, 1),
        scud: b(k, 0),
        random_winds: b(k, 1),
        random_lightning: b(k, 0),
        cloud_type: 9 + k as u8,
        scope: 1 + k as u8,
        severity: 3 + k as u8,
        air_temperature: -5.5 + k as f32,
        visibility: 1500.0 + k as f32,
        scud_frequency: 12.5 + k as f32,
        coverage: 75.0 + k as f32,
        base_elevation: 1200.0 + k as f32,
        thickness: 300.5 + k as f32,
        transition_band: 50.25 + k as f32,
        horizontal_wind: 11.0 + k as f32,
        vertical_wind: 0.75 + k as f32,
        wind_direction: 135.0 + k as f32,
        pressure: 990.5 + k as f32,
        aerosol: 0.25 + k as f32,
    }
}

fn view_control(k: u32) -> ViewControl {
    ViewControl {
        view_id: 300 + k as u16,
        group_id: 4 + k as u8,
        x_enable: b(k, 1),
        y_enable: b(k, 0),
        z_enable: b(k, 1),
        roll_enable: b(k, 0),
        pitch_enable: b(k, 1),
        yaw_enable: b(k, 0),
        entity_id: 77 + k as u16,
        x: 1.5 + k as f32,
        y: -0.25 + k as f32,
        z: -1.125 + k as f32,
        roll: 2.5 + k as f32,
        pitch: -7.5 + k as f32,
        yaw: 45.0 + k as f32,
    }
}

fn view_definition(k: u32) -> ViewDefinition {
    ViewDefinition {
        view_id: 301 + k as u16,
        group_id: 5 + k as u8,
        near_enable: b(k, 1),
        far_enable: b(k, 0),
        left_enable: b(k, 1),
        right_enable: b(k, 0),
        top_enable: b(k, 1),
        bottom_enable: b(k, 0),
        mirror: 2 + k as u8,
        pixel_replication: 3 + k as u8,
        orthographic: b(k, 1),
        reorder: b(k, 0),
        view_type: 5 + k as u8,
        near: 0.5 + k as f32,
        far: 40_000.0 + k as f32,
        left: -30.0 + k as f32,
        right: 30.5 + k as f32,
        top: 20.25 + k as f32,
        bottom: -18.75 + k as f32,
    }
}

fn hat_hot_request(k: u32) -> HatHotRequest {
    HatHotRequest {
        request_id: 900 + k as u16,
        request_type: 1 + k as u8,
        entity_frame: b(k, 1),
        update_period: 6 + k as u8,
        entity_id: 12 + k as u16,
        lat: 46.5 + f64::from(k),
        lon: -121.75 + f64::from(k),
        alt: 4392.125 + f64::from(k),
    }
}

fn los_segment_request(k: u32) -> LosSegmentRequest {
    LosSegmentRequest {
        request_id: 901 + k as u16,
        extended: b(k, 1),
        source_entity_frame: b(k, 0),
        destination_entity_frame: b(k, 1),
        response_entity_frame: b(k, 0),
        destination_entity_valid: b(k, 1),
        alpha_threshold: 128 + k as u8,
        entity_id: 13 + k as u16,
        source_lat: 47.5 + f64::from(k),
        source_lon: 9.25 + f64::from(k),
        source_alt: 3000.5 + f64::from(k),
        destination_lat: 47.625 + f64::from(k),
        destination_lon: 9.5 + f64::from(k),
        destination_alt: 1500.25 + f64::from(k),
        material_mask: 0xdead_beef - k,
        update_period: 2 + k as u8,
        destination_entity_id: 4321 + k as u16,
    }
}

fn los_vector_request(k: u32) -> LosVectorRequest {
    LosVectorRequest {
        request_id: 902 + k as u16,
        extended: b(k, 0),
        source_entity_frame: b(k, 1),
        response_entity_frame: b(k, 0),
        alpha_threshold: 64 + k as u8,
        entity_id: 14 + k as u16,
        azimuth: 123.5 + k as f32,
        elevation: -10.25 + k as f32,
        min_range: 5.5 + k as f32,
        max_range: 20_000.0 + k as f32,
        source_lat: -33.75 + f64::from(k),
        source_lon: 151.125 + f64::from(k),
        source_alt: 120.5 + f64::from(k),
        material_mask: 0x0123_4567 + k,
        update_period: 1 + k as u8,
    }
}

fn position_request(k: u32) -> PositionRequest {
    PositionRequest {
        object_id: 15 + k as u16,
        part_id: 3 + k as u8,
        continuous: b(k, 1),
        object_class: 2 + k as u8,
        coordinate_system: 1 + k as u8,
    }
}

fn start_of_frame(k: u32) -> StartOfFrame {
    StartOfFrame {
        database: -3 + 5 * k as i8,
        ig_status: 9 + k as u8,
        ig_mode: 1 + k as u8,
        timestamp_valid: b(k, 1),
        earth_reference: b(k, 0),
        ig_frame: 555_555 + k,
        timestamp: 123_456_789 + k,
        last_host_frame: 123_455 + k,
    }
}

fn hat_hot_response(k: u32) -> HatHotResponse {
    HatHotResponse {
        request_id: 900 + k as u16,
        valid: b(k, 1),
        hot: b(k, 0),
        host_frame_lsn: 0xb + k as u8,
        height: 1234.5 + f64::from(k),
    }
}

fn hat_hot_extended_response(k: u32) -> HatHotExtendedResponse {
    HatHotExtendedResponse {
        request_id: 903 + k as u16,
        valid: b(k, 1),
        host_frame_lsn: 0x5 + k as u8,
        hat: 250.75 + f64::from(k),
        hot: 1890.25 + f64::from(k),
        material: 77_000 + k,
        normal_azimuth: 210.5 + k as f32,
        normal_elevation: 80.25 + k as f32,
    }
}

fn los_response(k: u32) -> LosResponse {
    LosResponse {
        request_id: 901 + k as u16,
        valid: b(k, 1),
        entity_valid: b(k, 0),
        visible: b(k, 1),
        host_frame_lsn: 0xc + k as u8,
        count: 3 + k as u8,
        entity_id: 2222 + k as u16,
        range: 8765.5 + f64::from(k),
    }
}

fn los_extended_response(k: u32) -> LosExtendedResponse {
    LosExtendedResponse {
        request_id: 902 + k as u16,
        valid: b(k, 1),
        entity_valid: b(k, 0),
        range_valid: b(k, 1),
        visible: b(k, 0),
        host_frame_lsn: 0x9 + k as u8,
        count: 2 + k as u8,
        entity_id: 3333 + k as u16,
        range: 4321.25 + f64::from(k),
        lat: 47.125 + f64::from(k),
        lon: 9.0625 + f64::from(k),
        alt: 812.5 + f64::from(k),
        red: 10 + k as u8,
        green: 20 + k as u8,
        blue: 30 + k as u8,
        alpha: 250 + k as u8,
        material: 99 + k,
        normal_azimuth: 33.5 + k as f32,
        normal_elevation: 66.25 + k as f32,
    }
}

fn segment_definition(k: u32) -> CollisionSegmentDefinition {
    CollisionSegmentDefinition {
        entity_id: 21 + k as u16,
        segment_id: 4 + k as u8,
        enabled: b(k, 0),
        x1: 1.5 + k as f32,
        y1: -2.25 + k as f32,
        z1: 3.125 + k as f32,
        x2: -14.5 + k as f32,
        y2: 6.75 + k as f32,
        z2: 8.0 + k as f32,
        material_mask: 0x0102_0304 + k,
    }
}

fn volume_definition(k: u32) -> CollisionVolumeDefinition {
    CollisionVolumeDefinition {
        entity_id: 23 + k as u16,
        volume_id: 6 + k as u8,
        enabled: b(k, 0),
        cuboid: b(k, 1),
        x: 2.5 + k as f32,
        y: -1.25 + k as f32,
        z: 0.75 + k as f32,
        radius_height: 4.5 + k as f32,
        width: 3.25 + k as f32,
        depth: 11.5 + k as f32,
        roll: 5.0 + k as f32,
        pitch: -7.5 + k as f32,
        yaw: 123.0 + k as f32,
    }
}

fn volume_notification(k: u32) -> CollisionVolumeNotification {
    CollisionVolumeNotification {
        entity_id: 33 + k as u16,
        volume_id: 2 + k as u8,
        entity_contact: b(k, 1),
        contacted_entity_id: 4343 + k as u16,
        contacted_volume_id: 8 + k as u8,
    }
}

fn collision_notification(k: u32) -> CollisionSegmentNotification {
    CollisionSegmentNotification {
        entity_id: 31 + k as u16,
        segment_id: 9 + k as u8,
        entity_contact: b(k, 0),
        contacted_entity_id: 4242 + k as u16,
        material_code: 77 + k,
        distance: 12.375 + k as f32,
    }
}

fn position_response(k: u32) -> PositionResponse {
    PositionResponse {
        object_id: 15 + k as u16,
        part_id: 3 + k as u8,
        object_class: 2 + k as u8,
        coordinate_system: 1 + k as u8,
        lat: 46.75 + f64::from(k),
        lon: 8.5 + f64::from(k),
        alt: 3100.5 + f64::from(k),
        roll: 1.5 + k as f32,
        pitch: -2.5 + k as f32,
        yaw: 359.5 - k as f32,
    }
}

/// Every host-to-IG packet but IG Control.
fn host_body(k: u32) -> Vec<HostPacket> {
    vec![
        entity_control(k).into(),
        conformal_clamped(k).into(),
        rate_control(k).into(),
        celestial(k).into(),
        atmosphere(k).into(),
        weather(k).into(),
        view_control(k).into(),
        view_definition(k).into(),
        segment_definition(k).into(),
        volume_definition(k).into(),
        hat_hot_request(k).into(),
        los_segment_request(k).into(),
        los_vector_request(k).into(),
        position_request(k).into(),
    ]
}

/// Every IG-to-host packet but Start of Frame.
fn ig_body(k: u32) -> Vec<IgPacket> {
    vec![
        hat_hot_response(k).into(),
        hat_hot_extended_response(k).into(),
        los_response(k).into(),
        los_extended_response(k).into(),
        position_response(k).into(),
        collision_notification(k).into(),
        volume_notification(k).into(),
    ]
}

fn host_datagram(k: u32, order: ByteOrder) -> Vec<u8> {
    let mut m = MessageBuilder::host(&ig_control(k), order);
    for p in host_body(k) {
        m.push_any(&p);
    }
    m.finish()
}

fn ig_datagram(k: u32, order: ByteOrder) -> Vec<u8> {
    let mut m = MessageBuilder::ig(&start_of_frame(k), order);
    for p in ig_body(k) {
        m.push_any(&p);
    }
    m.finish()
}

const ORDERS: [ByteOrder; 2] = [ByteOrder::Big, ByteOrder::Little];
const CIGI_PORT: u16 = 8004;
const IG_PORT: u16 = 8005;

/// A capture of host and IG datagrams of both samples in `order`.
fn capture(order: ByteOrder) -> Vec<u8> {
    let datagrams: Vec<(bool, Vec<u8>)> = (0..2)
        .flat_map(|k| {
            [
                (true, host_datagram(k, order)),
                (false, ig_datagram(k, order)),
            ]
        })
        .collect();
    let frames: Vec<UdpFrame<'_>> = datagrams
        .iter()
        .enumerate()
        .map(|(i, (from_host, d))| {
            let (host, ig) = ((HOST_ADDR, CIGI_PORT), (IG_ADDR, IG_PORT));
            let (src, dst) = if *from_host { (host, ig) } else { (ig, host) };
            UdpFrame {
                src,
                dst,
                time_us: 1_000_000 + 16_667 * i as u64,
                payload: d,
            }
        })
        .collect();
    write_pcap(&frames).unwrap()
}

// ---------------------------------------------------------------------------------------------
// Round trips

fn round_trip<P: Packet + PartialEq + std::fmt::Debug>(p: &P, order: ByteOrder) {
    let bytes = p.encode(order);
    assert_eq!(bytes.len(), P::KIND.size(), "{:?}", P::KIND);
    assert_eq!(bytes[0], P::KIND.id());
    assert_eq!(usize::from(bytes[1]), P::KIND.size());
    assert_eq!(
        P::decode(&bytes, order).as_ref(),
        Some(p),
        "{:?} {order:?}",
        P::KIND
    );
    // One byte short, or another kind's ID: no packet.
    assert!(P::decode(&bytes[..bytes.len() - 1], order).is_none());
    let mut other = bytes.clone();
    other[0] ^= 0x40;
    assert!(P::decode(&other, order).is_none());
}

#[test]
fn every_packet_round_trips_in_both_byte_orders() {
    for k in 0..2 {
        for order in ORDERS {
            round_trip(&ig_control(k), order);
            round_trip(&entity_control(k), order);
            round_trip(&conformal_clamped(k), order);
            round_trip(&rate_control(k), order);
            round_trip(&celestial(k), order);
            round_trip(&atmosphere(k), order);
            round_trip(&weather(k), order);
            round_trip(&view_control(k), order);
            round_trip(&view_definition(k), order);
            round_trip(&segment_definition(k), order);
            round_trip(&collision_notification(k), order);
            round_trip(&volume_definition(k), order);
            round_trip(&volume_notification(k), order);
            round_trip(&hat_hot_request(k), order);
            round_trip(&los_segment_request(k), order);
            round_trip(&los_vector_request(k), order);
            round_trip(&position_request(k), order);
            round_trip(&start_of_frame(k), order);
            round_trip(&hat_hot_response(k), order);
            round_trip(&hat_hot_extended_response(k), order);
            round_trip(&los_response(k), order);
            round_trip(&los_extended_response(k), order);
            round_trip(&position_response(k), order);
        }
    }
    // Every kind is covered above, host and IG sets included.
    let kinds: Vec<Kind> = host_body(0)
        .iter()
        .map(|p| p.kind())
        .chain(ig_body(0).iter().map(|p| p.kind()))
        .collect();
    assert_eq!(kinds.len() + 2, Kind::ALL.len());
}

#[test]
fn whole_messages_read_back_in_both_byte_orders() {
    for k in 0..2 {
        for order in ORDERS {
            let m = read_host_message(&host_datagram(k, order)).unwrap();
            assert_eq!((m.order, m.minor_version), (order, 3));
            let mut want: Vec<HostPacket> = vec![ig_control(k).into()];
            want.extend(host_body(k));
            assert_eq!(m.packets, want);
            assert_eq!(
                m.walk,
                Walk {
                    packets: 15,
                    decoded: 15,
                    ..Walk::default()
                }
            );
            let m = read_ig_message(&ig_datagram(k, order)).unwrap();
            assert_eq!(m.order, order);
            let mut want: Vec<IgPacket> = vec![start_of_frame(k).into()];
            want.extend(ig_body(k));
            assert_eq!(m.packets, want);
            assert_eq!(m.walk.decoded, 8);
        }
    }
}

/// The byte order on the wire, checked against the standard library's conversions rather than
/// the codec's own reader.
#[test]
fn byte_orders_put_each_field_where_the_icd_says() {
    let e = entity_control(0);
    for (order, magic) in [
        (ByteOrder::Big, [0x80, 0x00]),
        (ByteOrder::Little, [0x00, 0x80]),
    ] {
        let be = order == ByteOrder::Big;
        let ig = ig_control(0).encode(order);
        assert_eq!(ig[2], 3, "version");
        assert_eq!(ig[4] >> 4, 3, "minor version");
        assert_eq!(&ig[6..8], &magic);
        let host_frame = if be {
            123_456u32.to_be_bytes()
        } else {
            123_456u32.to_le_bytes()
        };
        assert_eq!(&ig[8..12], &host_frame);
        let bytes = e.encode(order);
        let id = if be {
            e.entity_id.to_be_bytes()
        } else {
            e.entity_id.to_le_bytes()
        };
        assert_eq!(&bytes[2..4], &id);
        let lat = if be {
            e.lat.to_be_bytes()
        } else {
            e.lat.to_le_bytes()
        };
        assert_eq!(&bytes[24..32], &lat);
        let yaw = if be {
            e.yaw.to_be_bytes()
        } else {
            e.yaw.to_le_bytes()
        };
        assert_eq!(&bytes[20..24], &yaw);
        // State 1, attached, no collision detection, inherit alpha, conformal clamp (2).
        assert_eq!(bytes[4], 0b0101_0101);
        let sof = start_of_frame(0).encode(order);
        assert_eq!((sof[2], sof[5] >> 4, [sof[6], sof[7]]), (3, 3, magic));
        assert_eq!(ByteOrder::from_magic(magic), Some(order));
    }
    assert_eq!(ByteOrder::from_magic([0x80, 0x80]), None);
}

/// Random packet bytes decode to a packet whose encoding decodes to itself again: reading
/// and writing agree on every field's place and width, for any bits.
#[test]
fn decode_and_encode_agree_on_random_bytes() {
    let mut rng = Rng::new(21);
    for &kind in Kind::ALL {
        for order in ORDERS {
            for _ in 0..200 {
                let mut bytes: Vec<u8> = (0..kind.size()).map(|_| rng.next_u64() as u8).collect();
                bytes[0] = kind.id();
                bytes[1] = kind.size() as u8;
                let (a, b) = match kind.direction() {
                    Direction::HostToIg => {
                        let p = HostPacket::decode(kind, &bytes, order).unwrap();
                        let mut e = Vec::new();
                        p.encode_into(order, &mut e);
                        let q = HostPacket::decode(kind, &e, order).unwrap();
                        let mut f = Vec::new();
                        q.encode_into(order, &mut f);
                        (e, f)
                    }
                    Direction::IgToHost => {
                        let p = IgPacket::decode(kind, &bytes, order).unwrap();
                        let mut e = Vec::new();
                        p.encode_into(order, &mut e);
                        let q = IgPacket::decode(kind, &e, order).unwrap();
                        let mut f = Vec::new();
                        q.encode_into(order, &mut f);
                        (e, f)
                    }
                };
                assert_eq!(a, b, "{kind:?} {order:?}");
                // Every non-reserved bit survives: the re-encoding keeps the random bits of
                // the fields (at least half of the packet's bytes are field bytes).
                let same = a.iter().zip(&bytes).filter(|(x, y)| x == y).count();
                assert!(
                    same * 2 >= kind.size(),
                    "{kind:?}: {same} of {} bytes kept",
                    kind.size()
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Hostile input

/// Appends one packet's bytes (valid or not) to a datagram.
type Put<'a> = &'a dyn Fn(&mut Vec<u8>);

fn host_msg(frame: u32, packets: &[Put<'_>]) -> Vec<u8> {
    let mut bytes = ig_control_at(frame, None).encode(ByteOrder::Big);
    for p in packets {
        p(&mut bytes);
    }
    bytes
}

fn ig_control_at(frame: u32, timestamp: Option<u32>) -> IgControl {
    IgControl {
        ig_mode: 1,
        host_frame: frame,
        timestamp_valid: timestamp.is_some(),
        timestamp: timestamp.unwrap_or(0),
        extrapolation: true,
        ..IgControl::default()
    }
}

fn entity(id: u16) -> EntityControl {
    EntityControl {
        entity_id: id,
        entity_state: 1,
        extrapolation: true,
        lat: 47.0,
        lon: 9.0,
        alt: 1000.0,
        ..EntityControl::default()
    }
}

fn push_entity(id: u16) -> impl Fn(&mut Vec<u8>) {
    move |b: &mut Vec<u8>| entity(id).encode_into(ByteOrder::Big, b)
}

/// The counters' identities (the session's own bookkeeping must add up).
fn assert_counters_add_up(c: &Counters) {
    assert_eq!(
        c.datagrams,
        c.accepted + c.short + c.no_header + c.refused_version + c.bad_magic + c.ignored_sender,
        "{c:?}"
    );
    assert_eq!(
        c.packets,
        c.by_kind.iter().sum::<u64>() + c.unknown + c.short_packets + c.misplaced_header,
        "{c:?}"
    );
}

#[test]
fn size_zero_and_sizes_past_the_end_stop_the_walk() {
    let mut s = Session::new();
    let zero = |b: &mut Vec<u8>| b.extend_from_slice(&[2, 0, 0, 0, 0, 0, 0, 0]);
    let w = s
        .receive(
            &host_msg(1, &[&push_entity(1), &zero, &push_entity(2)]),
            0.0,
        )
        .unwrap();
    assert_eq!(w.stop, Some(Stop::SizeBelowTwo));
    let one = |b: &mut Vec<u8>| b.extend_from_slice(&[2, 1, 0, 0]);
    s.receive(&host_msg(2, &[&one, &push_entity(3)]), 0.0)
        .unwrap();
    let past = |b: &mut Vec<u8>| b.extend_from_slice(&[2, 200, 0, 0, 0, 0, 0, 0]);
    let w = s
        .receive(&host_msg(3, &[&push_entity(4), &past]), 0.0)
        .unwrap();
    assert_eq!(w.stop, Some(Stop::PastEnd));
    let stray = |b: &mut Vec<u8>| b.push(2);
    let w = s
        .receive(&host_msg(4, &[&push_entity(5), &stray]), 0.0)
        .unwrap();
    assert_eq!(w.stop, Some(Stop::Trailing));
    // Entities before the stop stand; after it, none.
    let ids: Vec<u16> = s.entities().map(|e| e.id).collect();
    assert_eq!(ids, vec![1, 4, 5]);
    let c = &s.counters;
    assert_eq!((c.size_below_two, c.past_end, c.trailing), (2, 1, 1));
    assert_eq!(c.of_kind(Kind::EntityControl), 3);
    assert_eq!(c.packets, 4 + 3);
    assert_counters_add_up(c);
}

#[test]
fn unknown_short_and_misplaced_packets_are_skipped_and_counted() {
    let mut s = Session::new();
    // Component Control (ID 4, 32 bytes): a CIGI packet relief does not handle yet.
    let unknown = |b: &mut Vec<u8>| {
        b.extend_from_slice(&{
            let mut p = [0u8; 32];
            p[0] = 4;
            p[1] = 32;
            p
        })
    };
    // An Entity Control claiming 16 bytes: shorter than its layout.
    let short = |b: &mut Vec<u8>| {
        let mut p = entity(9).encode(ByteOrder::Big);
        p[1] = 16;
        b.extend_from_slice(&p[..16]);
    };
    // Start of Frame from the host, and a second IG Control.
    let sof = |b: &mut Vec<u8>| start_of_frame(0).encode_into(ByteOrder::Big, b);
    let igc = |b: &mut Vec<u8>| ig_control(0).encode_into(ByteOrder::Big, b);
    let d = host_msg(
        7,
        &[
            &unknown,
            &short,
            &push_entity(1),
            &sof,
            &igc,
            &push_entity(2),
        ],
    );
    let w = s.receive(&d, 0.0).unwrap();
    assert_eq!(
        w,
        Walk {
            packets: 7,
            decoded: 3,
            unknown: 2,
            short: 1,
            misplaced_header: 1,
            stop: None
        }
    );
    assert_eq!(s.entity_count(), 2);
    assert_eq!(
        s.host_frame,
        Some(7),
        "the second IG Control is not applied"
    );
    // Longer than the layout: read by the layout, the rest skipped.
    let long = |b: &mut Vec<u8>| {
        let mut p = entity(3).encode(ByteOrder::Big);
        p[1] = 56;
        p.extend_from_slice(&[0xff; 8]);
        b.extend_from_slice(&p);
    };
    s.receive(&host_msg(8, &[&long, &push_entity(4)]), 0.0)
        .unwrap();
    assert_eq!(s.entity(3).unwrap().latest.pose.alt, 1000.0);
    assert!(s.entity(4).is_some());
    assert_counters_add_up(&s.counters);
}

#[test]
fn wrong_versions_magic_numbers_and_headers_are_refused() {
    let good = host_msg(1, &[&push_entity(1)]);
    let mut s = Session::new();
    let with = |at: usize, v: u8| {
        let mut d = good.clone();
        d[at] = v;
        d
    };
    for v in [0u8, 1, 2, 4, 255] {
        assert_eq!(s.receive(&with(2, v), 0.0), Err(Rejection::Version(v)));
    }
    for minor in [0u8, 1, 4, 15] {
        let r = s.receive(&with(4, (minor << 4) | 1), 0.0);
        assert_eq!(r, Err(Rejection::MinorVersion(minor)));
    }
    assert_eq!(
        s.receive(&with(6, 0x81), 0.0),
        Err(Rejection::Magic([0x81, 0]))
    );
    assert_eq!(s.receive(&with(1, 16), 0.0), Err(Rejection::Short));
    assert_eq!(s.receive(&with(1, 255), 0.0), Err(Rejection::Short));
    assert_eq!(s.receive(&good[..7], 0.0), Err(Rejection::Short));
    assert_eq!(s.receive(&[], 0.0), Err(Rejection::Short));
    // No IG Control first: nothing of the datagram is applied.
    let headless = entity(1).encode(ByteOrder::Big);
    assert_eq!(s.receive(&headless, 0.0), Err(Rejection::NoHeader(2)));
    assert_eq!(s.entity_count(), 0);
    let c = s.counters.clone();
    assert_eq!(
        (c.refused_version, c.bad_magic, c.short, c.no_header),
        (9, 1, 4, 1)
    );
    assert_eq!((c.accepted, c.packets), (0, 0));
    // Minor version 2 is read; a byte-swapped message is read as such.
    assert!(s.receive(&with(4, (2 << 4) | 1), 0.0).is_ok());
    assert_eq!(s.minor_version, 2);
    let mut m = MessageBuilder::host(&ig_control_at(2, None), ByteOrder::Little);
    m.push(&entity(700));
    s.receive(&m.finish(), 0.0).unwrap();
    assert_eq!(s.order, ByteOrder::Little);
    assert_eq!(s.entity(700).unwrap().latest.pose.lat, 47.0);
    assert_counters_add_up(&s.counters);
}

#[test]
fn huge_entity_ids_live_in_a_map_and_the_count_is_capped() {
    let mut s = Session::new();
    let cap = relief::cigi::session::MAX_ENTITIES;
    let per = 250; // Entity Controls per datagram (12 kB)
    let total = cap + 904;
    let ids: Vec<u16> = (0..total).map(|i| 65_535 - i as u16).collect();
    for chunk in ids.chunks(per) {
        let mut m = MessageBuilder::host(&ig_control_at(1, None), ByteOrder::Big);
        for &id in chunk {
            m.push(&entity(id));
        }
        s.receive(&m.finish(), 0.0).unwrap();
    }
    assert_eq!(s.entity_count(), cap);
    assert_eq!(s.counters.refused_capacity, 904);
    assert!(s.entity(65_535).is_some());
    assert_eq!(s.counters.of_kind(Kind::EntityControl), total as u64);
    // Updates of held entities still pass at the cap; destroying one makes room.
    let mut destroy = entity(65_535);
    destroy.entity_state = 2;
    let d = host_msg(
        2,
        &[
            &|b: &mut Vec<u8>| destroy.encode_into(ByteOrder::Big, b),
            &push_entity(7),
        ],
    );
    s.receive(&d, 0.0).unwrap();
    assert!(s.entity(65_535).is_none() && s.entity(7).is_some());
    assert_counters_add_up(&s.counters);
}

#[test]
fn values_that_cannot_be_applied_are_dropped() {
    let mut s = Session::new();
    let bad = |f: fn(&mut EntityControl)| {
        move |b: &mut Vec<u8>| {
            let mut e = entity(5);
            f(&mut e);
            e.encode_into(ByteOrder::Big, b)
        }
    };
    let d = host_msg(
        1,
        &[
            &bad(|e| e.lat = f64::NAN),
            &bad(|e| e.yaw = f32::INFINITY),
            &bad(|e| e.lat = 91.0),
            &bad(|e| e.entity_state = 3),
            &bad(|e| {
                e.attach = true;
                e.parent_id = 77; // no such entity
            }),
            &bad(|e| {
                e.attach = true;
                e.parent_id = 5; // itself
            }),
        ],
    );
    s.receive(&d, 0.0).unwrap();
    assert_eq!(s.entity_count(), 0);
    assert_eq!(s.counters.invalid_values, 6);
}

/// A stream of hostile datagrams: random bytes, mutated valid messages, valid headers with
/// random tails. No panic, no hang, bounded state, counters adding up, within the budget.
#[test]
fn a_hundred_thousand_hostile_datagrams() {
    const N: usize = 100_000;
    // The issue asks for 100,000 in 10 s; relief's budget is a tenth of that, on a loaded
    // 2-core machine in the test profile.
    const BUDGET_S: f64 = 1.0;
    let mut rng = Rng::new(2026);
    let valid = [
        host_datagram(0, ByteOrder::Big),
        host_datagram(1, ByteOrder::Little),
    ];
    let mut datagrams = Vec::with_capacity(N);
    for i in 0..N {
        let r = rng.next_u64();
        let d: Vec<u8> = match i % 4 {
            // Random bytes, 0..600 long.
            0 => (0..r % 600).map(|_| rng.next_u64() as u8).collect(),
            // A valid message with a few random bytes changed (size bytes included).
            1 => {
                let mut d = valid[(r & 1) as usize].clone();
                for _ in 0..1 + (r >> 8) % 6 {
                    let at = (rng.next_u64() as usize) % d.len();
                    d[at] = rng.next_u64() as u8;
                }
                d
            }
            // A valid header, then random packets with plausible IDs and any sizes.
            2 => {
                let mut d = ig_control_at(i as u32, Some(i as u32)).encode(ByteOrder::Big);
                for _ in 0..(r % 12) {
                    let x = rng.next_u64();
                    let id = [1u8, 2, 8, 9, 10, 12, 16, 21, 24, 25, 26, 27, 101, 0, 255]
                        [(x % 15) as usize];
                    let len = ((x >> 8) % 70) as usize;
                    d.push(id);
                    d.push((x >> 16) as u8);
                    d.extend((0..len).map(|_| rng.next_u64() as u8));
                }
                d
            }
            // A valid message cut anywhere.
            _ => {
                let d = &valid[(r & 1) as usize];
                d[..(r >> 1) as usize % d.len()].to_vec()
            }
        };
        datagrams.push(d);
    }
    let mut s = Session::new();
    let t = Instant::now();
    for (i, d) in datagrams.iter().enumerate() {
        let _ = s.receive(d, i as f64 * 1e-4);
    }
    let secs = t.elapsed().as_secs_f64();
    let c = &s.counters;
    println!(
        "{N} hostile datagrams in {:.1} ms ({:.2} µs each): {c:?}",
        secs * 1e3,
        secs * 1e6 / N as f64
    );
    assert!(
        secs < BUDGET_S,
        "{secs:.3} s for {N} datagrams (budget {BUDGET_S} s)"
    );
    assert_eq!(c.datagrams, N as u64);
    assert_counters_add_up(c);
    // Each kind of damage was met.
    assert!(c.accepted > 0 && c.no_header > 0 && c.refused_version > 0 && c.bad_magic > 0);
    assert!(c.size_below_two > 0 && c.past_end > 0 && c.unknown > 0 && c.short_packets > 0);
    assert!(s.entity_count() <= relief::cigi::session::MAX_ENTITIES);
    assert!(s.pending_queries() <= relief::cigi::session::MAX_QUERIES);
}

// ---------------------------------------------------------------------------------------------
// Session

fn pose_msg(frame: u32, ticks: Option<u32>, entities: &[EntityControl]) -> Vec<u8> {
    let mut m = MessageBuilder::host(&ig_control_at(frame, ticks), ByteOrder::Big);
    for e in entities {
        m.push(e);
    }
    m.finish()
}

fn at(id: u16, lat: f64, lon: f64, alt: f64, rpy: [f32; 3]) -> EntityControl {
    EntityControl {
        lat,
        lon,
        alt,
        roll: rpy[0],
        pitch: rpy[1],
        yaw: rpy[2],
        ..entity(id)
    }
}

#[test]
fn ownship_is_interpolated_between_two_host_samples() {
    let mut s = Session::new();
    // Host times 1.0 s and 1.5 s (ticks of 10 µs); arrival times deliberately different.
    let a = at(0, 47.0, 9.0, 1000.0, [-10.0, 2.0, 350.0]);
    let b = at(0, 47.5, 9.25, 1100.0, [10.0, 4.0, 10.0]);
    let wrap_a = at(1, -10.0, 179.75, 0.0, [170.0, 0.0, 0.0]);
    let wrap_b = at(1, -10.0, -179.75, 0.0, [-170.0, 0.0, 0.0]);
    s.receive(&pose_msg(1, Some(100_000), &[a, wrap_a]), 50.0)
        .unwrap();
    s.receive(&pose_msg(2, Some(150_000), &[b, wrap_b]), 50.7)
        .unwrap();
    assert_eq!(s.host_time, 1.5);
    let mid = s.pose_at(0, 1.25).unwrap();
    assert_eq!(
        (mid.lat, mid.lon, mid.alt, mid.roll, mid.pitch, mid.yaw),
        (47.25, 9.125, 1050.0, 0.0, 3.0, 0.0)
    );
    // Longitude and roll the short way round the date line.
    let w = s.pose_at(1, 1.25).unwrap();
    assert_eq!((w.lon, w.roll), (-180.0, -180.0));
    // At the samples, the samples; extrapolated a quarter interval on; held two intervals past.
    assert_eq!(s.pose_at(0, 1.0).unwrap().alt, 1000.0);
    assert_eq!(s.pose_at(0, 1.5).unwrap().alt, 1100.0);
    assert_eq!(s.pose_at(0, 1.625).unwrap().alt, 1125.0);
    assert_eq!(s.pose_at(0, 2.5).unwrap().alt, 1300.0);
    assert_eq!(s.pose_at(0, 99.0).unwrap().alt, 1300.0);
    assert_eq!(s.pose_at(0, 0.0).unwrap().alt, 1000.0);
    // Local time → host time: the lowest arrival − host time (50.0 − 1.0 = 49.0; the second
    // datagram measured 49.2, later by 0.2 s) is the offset: local 50.8 is host time 1.8.
    assert!((s.host_time_at(50.8) - 1.8).abs() < 1e-12);
    // Interpolation off (the entity's bit): the latest sample.
    let mut c = b;
    c.extrapolation = false;
    s.receive(&pose_msg(3, Some(200_000), &[c]), 51.0).unwrap();
    assert_eq!(s.pose_at(0, 1.75).unwrap().alt, 1100.0);
}

#[test]
fn host_time_follows_timestamps_through_their_wrap_or_the_arrival_clock() {
    let mut s = Session::new();
    s.receive(&pose_msg(1, Some(u32::MAX - 49_999), &[entity(0)]), 0.0)
        .unwrap();
    let t0 = s.host_time;
    s.receive(&pose_msg(2, Some(50_000), &[entity(0)]), 0.0)
        .unwrap();
    assert!(
        (s.host_time - t0 - 1.0).abs() < 1e-6,
        "{} {}",
        s.host_time,
        t0
    );
    // Without valid timestamps the arrival times are the samples' times.
    let mut s = Session::new();
    s.receive(&pose_msg(1, None, &[at(0, 0.0, 0.0, 0.0, [0.0; 3])]), 10.0)
        .unwrap();
    s.receive(&pose_msg(2, None, &[at(0, 0.0, 0.0, 20.0, [0.0; 3])]), 12.0)
        .unwrap();
    assert_eq!(s.pose_at(0, 11.0).unwrap().alt, 10.0);
}

/// Conformal Clamped Entity Control moves an existing top-level entity: latitude, longitude
/// and yaw from the packet, altitude, pitch and roll (the clamp's offsets) kept from its
/// Entity Control; an unknown or attached entity, or a latitude past 90°, is counted and
/// ignored.
#[test]
fn conformal_clamped_entity_control_moves_an_entity_and_keeps_its_offsets() {
    let mut s = Session::new();
    let clamped = EntityControl {
        ground_clamp: 2,
        ..at(7, 47.4, 9.4, 12.0, [-3.0, 4.0, 80.0])
    };
    let child = EntityControl {
        attach: true,
        parent_id: 7,
        ..entity(8)
    };
    s.receive(&pose_msg(1, Some(100_000), &[clamped, child]), 0.0)
        .unwrap();
    let moved = |id: u16, lat: f64| ConformalClampedEntityControl {
        entity_id: id,
        yaw: 95.5,
        lat,
        lon: 9.45,
    };
    let mut m = MessageBuilder::host(&ig_control_at(2, Some(150_000)), ByteOrder::Big);
    m.push(&moved(7, 47.42))
        .push(&moved(9, 47.42))
        .push(&moved(8, 47.42))
        .push(&moved(7, 91.0));
    s.receive(&m.finish(), 0.5).unwrap();
    let p = s.pose_at(7, 1.5).unwrap();
    let off = [p.lat - 47.42, p.lon - 9.45, p.yaw - 95.5];
    assert!(off.iter().all(|d| d.abs() < 1e-9), "{p:?}");
    assert!(
        (p.alt - 12.0).abs() < 1e-9 && (p.pitch - 4.0).abs() < 1e-9,
        "{p:?}"
    );
    assert!((p.roll + 3.0).abs() < 1e-9, "{p:?}");
    let e = s.entity(7).unwrap();
    assert_eq!((e.ground_clamp, e.entity_type), (2, clamped.entity_type));
    // Between the samples it moves as from one Entity Control to the next.
    let half = s.pose_at(7, 1.25).unwrap();
    assert!((half.lat - 47.41).abs() < 1e-9, "{half:?}");
    // Unknown (9), attached (8), latitude 91°: three counted, none applied.
    assert_eq!(s.counters.invalid_values, 3);
    assert_eq!(s.pose_at(8, 1.5).unwrap().lat, 47.0);
    assert_counters_add_up(&s.counters);
}

/// Collision Detection Segment Definitions are kept per entity and segment; the frame tests
/// those of active entities whose collision detection is on; a disabled definition drops its
/// segment, non-finite offsets are counted, a destroyed entity's segments go with it.
#[test]
fn collision_segments_are_kept_per_entity_and_tested_only_where_detection_is_on() {
    let mut s = Session::new();
    let on = EntityControl {
        collision_detection: true,
        ..entity(7)
    };
    let seg = |entity_id: u16, segment_id: u8, enabled: bool| CollisionSegmentDefinition {
        entity_id,
        segment_id,
        enabled,
        z2: 10.0,
        ..CollisionSegmentDefinition::default()
    };
    let mut m = MessageBuilder::host(&ig_control_at(1, None), ByteOrder::Big);
    m.push(&on)
        .push(&entity(8))
        .push(&seg(7, 1, true))
        .push(&seg(7, 2, true))
        .push(&seg(7, 3, true))
        .push(&seg(8, 1, true))
        .push(&seg(7, 3, false))
        .push(&CollisionSegmentDefinition {
            x1: f32::NAN,
            ..seg(7, 4, true)
        });
    s.receive(&m.finish(), 0.0).unwrap();
    let ids: Vec<(u16, u8)> = s
        .collision_segments()
        .map(|d| (d.entity_id, d.segment_id))
        .collect();
    assert_eq!(
        ids,
        [(7, 1), (7, 2)],
        "entity 8's detection is off; 3 was disabled"
    );
    assert_eq!(s.counters.invalid_values, 1, "the NaN offset");
    let gone = EntityControl {
        entity_state: 2,
        ..on
    };
    s.receive(&pose_msg(2, None, &[gone, on]), 0.1).unwrap();
    assert_eq!(s.collision_segments().count(), 0, "destroyed with entity 7");
    assert_counters_add_up(&s.counters);
}

#[test]
fn rate_control_dead_reckons_from_the_latest_sample() {
    let mut s = Session::new();
    let e = at(0, 0.0, 0.0, 100.0, [0.0, 0.0, 90.0]);
    let rate = RateControl {
        entity_id: 0,
        body_frame: true,
        x_rate: 10.0,
        z_rate: -1.0,
        yaw_rate: 3.0,
        ..RateControl::default()
    };
    let mut m = MessageBuilder::host(&ig_control_at(1, Some(0)), ByteOrder::Big);
    m.push(&e).push(&rate);
    s.receive(&m.finish(), 0.0).unwrap();
    let p = s.pose_at(0, 2.0).unwrap();
    // Heading east at the equator, 20 m on a circle of radius a + h; 2 m up; yaw +6°.
    let lon = (20.0f64 / (6_378_137.0 + 100.0)).to_degrees();
    assert!((p.lon - lon).abs() < 1e-12, "{} {lon}", p.lon);
    assert!(p.lat.abs() < 1e-12);
    assert!((p.alt - 102.0).abs() < 1e-9);
    assert!((p.yaw - 96.0).abs() < 1e-9);
}

#[test]
fn entities_attach_detach_and_are_destroyed_with_their_children() {
    let mut s = Session::new();
    let child = |id: u16, parent: u16| EntityControl {
        attach: true,
        parent_id: parent,
        ..entity(id)
    };
    s.receive(
        &pose_msg(
            1,
            None,
            &[entity(10), child(11, 10), child(12, 11), entity(13)],
        ),
        0.0,
    )
    .unwrap();
    assert_eq!(s.entity(12).unwrap().parent, Some(11));
    // A cycle is refused.
    s.receive(&pose_msg(2, None, &[child(10, 12)]), 0.0)
        .unwrap();
    assert_eq!(
        (s.entity(10).unwrap().parent, s.counters.invalid_values),
        (None, 1)
    );
    let destroy = EntityControl {
        entity_state: 2,
        ..entity(10)
    };
    s.receive(&pose_msg(3, None, &[destroy]), 0.0).unwrap();
    let ids: Vec<u16> = s.entities().map(|e| e.id).collect();
    assert_eq!((ids, s.counters.destroyed), (vec![13], 3));
    // Reset/standby clears all but the ownship.
    s.receive(&pose_msg(4, None, &[entity(0), entity(1)]), 0.0)
        .unwrap();
    let mut standby = MessageBuilder::host(
        &IgControl {
            ig_mode: 0,
            ..ig_control_at(5, None)
        },
        ByteOrder::Big,
    );
    standby.push(&HatHotRequest::default());
    s.receive(&standby.finish(), 0.0).unwrap();
    assert_eq!(s.entities().map(|e| e.id).collect::<Vec<_>>(), vec![0]);
}

#[test]
fn queries_queue_with_their_host_frame_up_to_the_cap() {
    let mut s = Session::new();
    let mut m = MessageBuilder::host(&ig_control_at(42, None), ByteOrder::Big);
    m.push(&hat_hot_request(0)).push(&los_segment_request(0));
    m.push(&los_vector_request(0)).push(&position_request(0));
    s.receive(&m.finish(), 0.0).unwrap();
    let q = s.take_queries();
    assert_eq!(
        q,
        vec![
            Query::HatHot(hat_hot_request(0), 42),
            Query::LosSegment(los_segment_request(0), 42),
            Query::LosVector(los_vector_request(0), 42),
            Query::Position(position_request(0), 42),
        ]
    );
    let cap = relief::cigi::session::MAX_QUERIES;
    for f in 0..(cap / 100 + 1) as u32 {
        let mut m = MessageBuilder::host(&ig_control_at(f, None), ByteOrder::Big);
        for _ in 0..100 {
            m.push(&position_request(0));
        }
        s.receive(&m.finish(), 0.0).unwrap();
    }
    assert_eq!(s.pending_queries(), cap);
    assert_eq!(
        s.counters.dropped_queries,
        (cap / 100 + 1) as u64 * 100 - cap as u64
    );
}

#[test]
fn environment_views_and_the_start_of_frame_message() {
    let mut s = Session::new();
    let mut m = MessageBuilder::host(
        &IgControl {
            database: 4,
            ..ig_control_at(77, None)
        },
        ByteOrder::Big,
    );
    m.push(&celestial(0))
        .push(&weather(0))
        .push(&view_control(0))
        .push(&view_definition(0));
    m.push(&WeatherControl {
        scope: 0,
        enable: true,
        visibility: 800.0,
        layer_id: 0,
        ..weather(1)
    });
    // A cloud layer's visibility is the one inside the cloud, not the global one.
    m.push(&WeatherControl {
        scope: 0,
        enable: true,
        visibility: 50.0,
        layer_id: 1,
        ..weather(1)
    });
    s.receive(&m.finish(), 0.0).unwrap();
    assert_eq!(s.celestial, Some(celestial(0)));
    assert_eq!(s.views[&300].control, Some(view_control(0)));
    assert_eq!(s.views[&301].definition, Some(view_definition(0)));
    // No atmosphere model: the enabled global weather layer's visibility (ground fog, not
    // the cloud layer's 50 m).
    assert_eq!(s.visibility(), Some(800.0));
    let mut m = MessageBuilder::host(&ig_control_at(78, None), ByteOrder::Big);
    m.push(&atmosphere(0));
    s.receive(&m.finish(), 0.0).unwrap();
    assert_eq!(s.visibility(), Some(25_000.0));
    // The IG's answer: Start of Frame first, then the responses, read back.
    let mut out = s.start_of_frame(9, Some(1234));
    out.push(&hat_hot_response(0)).push(&los_response(1));
    let back = read_ig_message(&out.finish()).unwrap();
    let IgPacket::StartOfFrame(sof) = back.packets[0] else {
        panic!("{:?}", back.packets[0])
    };
    assert_eq!(
        (sof.ig_frame, sof.last_host_frame, sof.database, sof.ig_mode),
        (9, 78, 0, 1)
    );
    assert_eq!((sof.timestamp_valid, sof.timestamp), (true, 1234));
    assert_eq!(
        back.packets[1..],
        [hat_hot_response(0).into(), los_response(1).into()]
    );
}

#[test]
fn other_senders_are_ignored_once_the_host_is_known() {
    let host: SocketAddr = "127.0.0.1:8004".parse().unwrap();
    let other: SocketAddr = "127.0.0.9:8004".parse().unwrap();
    let mut s = Session::new();
    assert!(
        s.receive_from(other, &[1, 2, 3], 0.0).unwrap().is_err(),
        "refused: no host yet"
    );
    assert!(s
        .receive_from(host, &pose_msg(1, None, &[entity(1)]), 0.0)
        .unwrap()
        .is_ok());
    assert_eq!(s.host, Some(host));
    assert!(s
        .receive_from(other, &pose_msg(2, None, &[entity(2)]), 0.0)
        .is_none());
    assert!(s.entity(2).is_none());
    assert_eq!(s.counters.ignored_sender, 1);
    assert_counters_add_up(&s.counters);
}

// ---------------------------------------------------------------------------------------------
// Wireshark's CIGI dissector as the independent decoder

/// tshark's name for a field and the value it must show (numbers compared as numbers).
type Expect = Vec<(String, String)>;

fn fields(prefix: &str, list: &[(&str, f64)]) -> Expect {
    list.iter()
        .map(|(n, v)| {
            let name = if n.starts_with("cigi.") {
                n.to_string()
            } else {
                format!("{prefix}.{n}")
            };
            (name, v.to_string())
        })
        .collect()
}

fn f(v: bool) -> f64 {
    f64::from(u8::from(v))
}

fn byte_swap(order: ByteOrder) -> (String, String) {
    let show = if order == ByteOrder::Big {
        "0x8000"
    } else {
        "0x0080"
    };
    ("cigi.byte_swap".into(), show.into())
}

fn expect_host(p: &HostPacket, order: ByteOrder) -> Expect {
    let mut e = fields(
        "",
        &[
            ("cigi.packet_id", f64::from(p.kind().id())),
            ("cigi.packet_size", p.kind().size() as f64),
        ],
    );
    let more = match *p {
        HostPacket::IgControl(p) => {
            let mut h = vec![("cigi.version".to_string(), "3".to_string())];
            h.extend(fields(
                "cigi.ig_control",
                &[
                    ("db_number", f64::from(p.database)),
                    ("ig_mode", f64::from(p.ig_mode)),
                    ("timestamp_valid", f(p.timestamp_valid)),
                    ("extrapolation_enable", f(p.extrapolation)),
                    ("minor_version", 3.0),
                ],
            ));
            h.push(byte_swap(order));
            h.extend(fields(
                "cigi.ig_control",
                &[
                    ("host_frame_number", f64::from(p.host_frame)),
                    ("timestamp", f64::from(p.timestamp)),
                    ("last_ig_frame_number", f64::from(p.last_ig_frame)),
                ],
            ));
            h
        }
        HostPacket::EntityControl(p) => fields(
            "cigi.entity_control",
            &[
                ("entity_id", f64::from(p.entity_id)),
                ("entity_state", f64::from(p.entity_state)),
                ("attach_state", f(p.attach)),
                ("coll_det_request", f(p.collision_detection)),
                ("inherit_alpha", f(p.inherit_alpha)),
                ("ground_ocean_clamp", f64::from(p.ground_clamp)),
                ("animation_dir", f(p.animation_direction)),
                ("animation_loop_mode", f(p.animation_loop)),
                ("animation_state", f64::from(p.animation_state)),
                ("extrapolation_enable", f(p.extrapolation)),
                ("alpha", f64::from(p.alpha)),
                ("entity_type", f64::from(p.entity_type)),
                ("parent_id", f64::from(p.parent_id)),
                ("roll", f64::from(p.roll)),
                ("pitch", f64::from(p.pitch)),
                ("yaw", f64::from(p.yaw)),
                ("lat_xoff", p.lat),
                ("lon_yoff", p.lon),
                ("alt_zoff", p.alt),
            ],
        ),
        HostPacket::ConformalClampedEntityControl(p) => fields(
            "cigi.conformal_clamped_entity_control",
            &[
                ("entity_id", f64::from(p.entity_id)),
                ("yaw", f64::from(p.yaw)),
                ("lat", p.lat),
                ("lon", p.lon),
            ],
        ),
        HostPacket::RateControl(p) => fields(
            "cigi.rate_control",
            &[
                ("entity_id", f64::from(p.entity_id)),
                ("part_id", f64::from(p.part_id)),
                ("apply_to_part", f(p.apply_to_part)),
                ("coordinate_system", f(p.body_frame)),
                ("x_rate", f64::from(p.x_rate)),
                ("y_rate", f64::from(p.y_rate)),
                ("z_rate", f64::from(p.z_rate)),
                ("roll_rate", f64::from(p.roll_rate)),
                ("pitch_rate", f64::from(p.pitch_rate)),
                ("yaw_rate", f64::from(p.yaw_rate)),
            ],
        ),
        HostPacket::CelestialSphereControl(p) => fields(
            "cigi.celestial_sphere_control",
            &[
                ("hour", f64::from(p.hour)),
                ("minute", f64::from(p.minute)),
                ("ephemeris_enable", f(p.ephemeris)),
                ("sun_enable", f(p.sun)),
                ("moon_enable", f(p.moon)),
                ("star_enable", f(p.stars)),
                ("date_time_valid", f(p.date_time_valid)),
                ("date", f64::from(p.date)),
                ("star_intensity", f64::from(p.star_intensity)),
            ],
        ),
        HostPacket::AtmosphereControl(p) => fields(
            "cigi.atmosphere_control",
            &[
                ("atmospheric_model_enable", f(p.model_enable)),
                ("humidity", f64::from(p.humidity)),
                ("air_temp", f64::from(p.air_temperature)),
                ("visibility_range", f64::from(p.visibility)),
                ("horiz_wind", f64::from(p.horizontal_wind)),
                ("vert_wind", f64::from(p.vertical_wind)),
                ("wind_direction", f64::from(p.wind_direction)),
                ("barometric_pressure", f64::from(p.pressure)),
            ],
        ),
        HostPacket::WeatherControl(p) => fields(
            "cigi.weather_control",
            &[
                ("entity_region_id", f64::from(p.entity_region_id)),
                ("layer_id", f64::from(p.layer_id)),
                ("humidity", f64::from(p.humidity)),
                ("weather_enable", f(p.enable)),
                ("scud_enable", f(p.scud)),
                ("random_winds_enable", f(p.random_winds)),
                ("random_lightning_enable", f(p.random_lightning)),
                ("cloud_type", f64::from(p.cloud_type)),
                ("scope", f64::from(p.scope)),
                ("severity", f64::from(p.severity)),
                ("air_temp", f64::from(p.air_temperature)),
                ("visibility_range", f64::from(p.visibility)),
                ("scud_frequency", f64::from(p.scud_frequency)),
                ("coverage", f64::from(p.coverage)),
                ("base_elevation", f64::from(p.base_elevation)),
                ("thickness", f64::from(p.thickness)),
                ("transition_band", f64::from(p.transition_band)),
                ("horiz_wind", f64::from(p.horizontal_wind)),
                ("vert_wind", f64::from(p.vertical_wind)),
                ("wind_direction", f64::from(p.wind_direction)),
                ("barometric_pressure", f64::from(p.pressure)),
                ("aerosol_concentration", f64::from(p.aerosol)),
            ],
        ),
        HostPacket::ViewControl(p) => fields(
            "cigi.view_control",
            &[
                ("view_id", f64::from(p.view_id)),
                ("group_id", f64::from(p.group_id)),
                ("xoff_enable", f(p.x_enable)),
                ("yoff_enable", f(p.y_enable)),
                ("zoff_enable", f(p.z_enable)),
                ("roll_enable", f(p.roll_enable)),
                ("pitch_enable", f(p.pitch_enable)),
                ("yaw_enable", f(p.yaw_enable)),
                ("entity_id", f64::from(p.entity_id)),
                ("xoff", f64::from(p.x)),
                ("yoff", f64::from(p.y)),
                ("zoff", f64::from(p.z)),
                ("roll", f64::from(p.roll)),
                ("pitch", f64::from(p.pitch)),
                ("yaw", f64::from(p.yaw)),
            ],
        ),
        HostPacket::CollisionSegmentDefinition(p) => fields(
            "cigi.coll_det_seg_def",
            &[
                ("entity_id", f64::from(p.entity_id)),
                ("segment_id", f64::from(p.segment_id)),
                ("segment_enable", f(p.enabled)),
                ("x1", f64::from(p.x1)),
                ("y1", f64::from(p.y1)),
                ("z1", f64::from(p.z1)),
                ("x2", f64::from(p.x2)),
                ("y2", f64::from(p.y2)),
                ("z2", f64::from(p.z2)),
                ("material_mask", f64::from(p.material_mask)),
            ],
        ),
        HostPacket::CollisionVolumeDefinition(p) => fields(
            "cigi.coll_det_vol_def",
            &[
                ("entity_id", f64::from(p.entity_id)),
                ("volume_id", f64::from(p.volume_id)),
                ("volume_enable", f(p.enabled)),
                ("volume_type", f(p.cuboid)),
                ("x", f64::from(p.x)),
                ("y", f64::from(p.y)),
                ("z", f64::from(p.z)),
                ("radius_height", f64::from(p.radius_height)),
                ("width", f64::from(p.width)),
                ("depth", f64::from(p.depth)),
                ("roll", f64::from(p.roll)),
                ("pitch", f64::from(p.pitch)),
                ("yaw", f64::from(p.yaw)),
            ],
        ),
        HostPacket::ViewDefinition(p) => fields(
            "cigi.view_def",
            &[
                ("view_id", f64::from(p.view_id)),
                ("group_id", f64::from(p.group_id)),
                ("near_enable", f(p.near_enable)),
                ("far_enable", f(p.far_enable)),
                ("left_enable", f(p.left_enable)),
                ("right_enable", f(p.right_enable)),
                ("top_enable", f(p.top_enable)),
                ("bottom_enable", f(p.bottom_enable)),
                ("mirror_mode", f64::from(p.mirror)),
                ("pixel_replication", f64::from(p.pixel_replication)),
                ("projection_type", f(p.orthographic)),
                ("reorder", f(p.reorder)),
                ("view_type", f64::from(p.view_type)),
                ("near", f64::from(p.near)),
                ("far", f64::from(p.far)),
                ("left", f64::from(p.left)),
                ("right", f64::from(p.right)),
                ("top", f64::from(p.top)),
                ("bottom", f64::from(p.bottom)),
            ],
        ),
        HostPacket::HatHotRequest(p) => fields(
            "cigi.hat_hot_request",
            &[
                ("hat_hot_id", f64::from(p.request_id)),
                ("type", f64::from(p.request_type)),
                ("coordinate_system", f(p.entity_frame)),
                ("update_period", f64::from(p.update_period)),
                ("entity_id", f64::from(p.entity_id)),
                ("lat_xoff", p.lat),
                ("lon_yoff", p.lon),
                ("alt_zoff", p.alt),
            ],
        ),
        HostPacket::LosSegmentRequest(p) => fields(
            "cigi.los_segment_request",
            &[
                ("los_id", f64::from(p.request_id)),
                ("type", f(p.extended)),
                ("source_coord", f(p.source_entity_frame)),
                ("destination_coord", f(p.destination_entity_frame)),
                ("response_coord", f(p.response_entity_frame)),
                ("destination_entity_id_valid", f(p.destination_entity_valid)),
                ("alpha_threshold", f64::from(p.alpha_threshold)),
                ("entity_id", f64::from(p.entity_id)),
                ("source_lat_xoff", p.source_lat),
                ("source_lon_yoff", p.source_lon),
                ("source_alt_zoff", p.source_alt),
                ("destination_lat_xoff", p.destination_lat),
                ("destination_lon_yoff", p.destination_lon),
                ("destination_alt_zoff", p.destination_alt),
                ("material_mask", f64::from(p.material_mask)),
                ("update_period", f64::from(p.update_period)),
                ("destination_entity_id", f64::from(p.destination_entity_id)),
            ],
        ),
        HostPacket::LosVectorRequest(p) => fields(
            "cigi.los_vector_request",
            &[
                ("los_id", f64::from(p.request_id)),
                ("type", f(p.extended)),
                ("source_coord", f(p.source_entity_frame)),
                ("response_coord", f(p.response_entity_frame)),
                ("alpha", f64::from(p.alpha_threshold)),
                ("entity_id", f64::from(p.entity_id)),
                ("azimuth", f64::from(p.azimuth)),
                ("elevation", f64::from(p.elevation)),
                ("min_range", f64::from(p.min_range)),
                ("max_range", f64::from(p.max_range)),
                ("source_lat_xoff", p.source_lat),
                ("source_lon_yoff", p.source_lon),
                ("source_alt_zoff", p.source_alt),
                ("material_mask", f64::from(p.material_mask)),
                ("update_period", f64::from(p.update_period)),
            ],
        ),
        HostPacket::PositionRequest(p) => fields(
            "cigi.pos_request",
            &[
                ("object_id", f64::from(p.object_id)),
                ("part_id", f64::from(p.part_id)),
                ("update_mode", f(p.continuous)),
                ("object_class", f64::from(p.object_class)),
                ("coord_system", f64::from(p.coordinate_system)),
            ],
        ),
    };
    e.extend(more);
    e
}

fn expect_ig(p: &IgPacket, order: ByteOrder) -> Expect {
    let mut e = fields(
        "",
        &[
            ("cigi.packet_id", f64::from(p.kind().id())),
            ("cigi.packet_size", p.kind().size() as f64),
        ],
    );
    let more = match *p {
        IgPacket::StartOfFrame(p) => {
            let mut h = vec![("cigi.version".to_string(), "3".to_string())];
            h.extend(fields(
                "cigi.sof",
                &[
                    ("db_number", f64::from(p.database)),
                    ("ig_status", f64::from(p.ig_status)),
                    ("ig_mode", f64::from(p.ig_mode)),
                    ("timestamp_valid", f(p.timestamp_valid)),
                    ("earth_reference_model", f(p.earth_reference)),
                    ("minor_version", 3.0),
                ],
            ));
            h.push(byte_swap(order));
            h.extend(fields(
                "cigi.sof",
                &[
                    ("ig_frame_number", f64::from(p.ig_frame)),
                    ("timestamp", f64::from(p.timestamp)),
                    ("last_host_frame_number", f64::from(p.last_host_frame)),
                ],
            ));
            h
        }
        IgPacket::HatHotResponse(p) => fields(
            "cigi.hat_hot_response",
            &[
                ("hat_hot_id", f64::from(p.request_id)),
                ("valid", f(p.valid)),
                ("type", f(p.hot)),
                ("host_frame_number_lsn", f64::from(p.host_frame_lsn)),
                ("height", p.height),
            ],
        ),
        IgPacket::HatHotExtendedResponse(p) => fields(
            "cigi.hat_hot_ext_response",
            &[
                ("hat_hot_id", f64::from(p.request_id)),
                ("valid", f(p.valid)),
                ("host_frame_number_lsn", f64::from(p.host_frame_lsn)),
                ("hat", p.hat),
                ("hot", p.hot),
                ("material_code", f64::from(p.material)),
                ("normal_vector_azimuth", f64::from(p.normal_azimuth)),
                ("normal_vector_elevation", f64::from(p.normal_elevation)),
            ],
        ),
        IgPacket::LosResponse(p) => fields(
            "cigi.los_response",
            &[
                ("los_id", f64::from(p.request_id)),
                ("valid", f(p.valid)),
                ("entity_id_valid", f(p.entity_valid)),
                ("visible", f(p.visible)),
                ("host_frame_number_lsn", f64::from(p.host_frame_lsn)),
                ("count", f64::from(p.count)),
                ("entity_id", f64::from(p.entity_id)),
                ("range", p.range),
            ],
        ),
        IgPacket::LosExtendedResponse(p) => fields(
            "cigi.3_2_los_ext_response",
            &[
                ("los_id", f64::from(p.request_id)),
                ("valid", f(p.valid)),
                ("entity_id_valid", f(p.entity_valid)),
                ("range_valid", f(p.range_valid)),
                ("visible", f(p.visible)),
                ("host_frame_number_lsn", f64::from(p.host_frame_lsn)),
                ("response_count", f64::from(p.count)),
                ("entity_id", f64::from(p.entity_id)),
                ("range", p.range),
                ("lat_xoff", p.lat),
                ("lon_yoff", p.lon),
                ("alt_zoff", p.alt),
                ("red", f64::from(p.red)),
                ("green", f64::from(p.green)),
                ("blue", f64::from(p.blue)),
                ("alpha", f64::from(p.alpha)),
                ("material_code", f64::from(p.material)),
                ("normal_vector_azimuth", f64::from(p.normal_azimuth)),
                ("normal_vector_elevation", f64::from(p.normal_elevation)),
            ],
        ),
        IgPacket::CollisionSegmentNotification(p) => fields(
            "cigi.coll_det_seg_notification",
            &[
                ("entity_id", f64::from(p.entity_id)),
                ("segment_id", f64::from(p.segment_id)),
                ("type", f(p.entity_contact)),
                ("contacted_entity_id", f64::from(p.contacted_entity_id)),
                ("material_code", f64::from(p.material_code)),
                ("intersection_distance", f64::from(p.distance)),
            ],
        ),
        IgPacket::CollisionVolumeNotification(p) => fields(
            "cigi.coll_det_vol_notification",
            &[
                ("entity_id", f64::from(p.entity_id)),
                ("volume_id", f64::from(p.volume_id)),
                ("type", f(p.entity_contact)),
                ("contacted_entity_id", f64::from(p.contacted_entity_id)),
                ("contacted_volume_id", f64::from(p.contacted_volume_id)),
            ],
        ),
        IgPacket::PositionResponse(p) => fields(
            "cigi.pos_response",
            &[
                ("object_id", f64::from(p.object_id)),
                ("part_id", f64::from(p.part_id)),
                ("object_class", f64::from(p.object_class)),
                ("coord_system", f64::from(p.coordinate_system)),
                ("lat_xoff", p.lat),
                ("lon_yoff", p.lon),
                ("alt_zoff", p.alt),
                ("roll", f64::from(p.roll)),
                ("pitch", f64::from(p.pitch)),
                ("yaw", f64::from(p.yaw)),
            ],
        ),
    };
    e.extend(more);
    e
}

/// The value of XML attribute `name` in a PDML element's text.
fn attr<'a>(el: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let start = el.find(&key)? + key.len();
    let len = el[start..].find('"')?;
    Some(&el[start..start + len])
}

/// Per frame, the CIGI fields tshark shows (name, show), containers and hidden fields left
/// out; and every field name of the whole output (for the malformed/expert check).
fn pdml_fields(pdml: &str) -> (Vec<Expect>, Vec<String>) {
    let mut frames = Vec::new();
    let mut all = Vec::new();
    for packet in pdml.split("<packet>").skip(1) {
        let mut frame = Vec::new();
        for el in packet.split("<field").skip(1) {
            let Some(name) = attr(el, "name") else {
                continue;
            };
            all.push(name.to_string());
            let show = attr(el, "show").unwrap_or("");
            if !name.starts_with("cigi.") || attr(el, "hide") == Some("yes") || show.is_empty() {
                continue;
            }
            frame.push((name.to_string(), show.to_string()));
        }
        frames.push(frame);
    }
    (frames, all)
}

fn same_value(a: &str, b: &str) -> bool {
    match (a.parse::<f64>(), b.parse::<f64>()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

#[test]
fn tshark_decodes_every_packet_as_sent() {
    if Command::new("tshark").arg("-v").output().is_err() {
        eprintln!("Skipping the tshark test: `tshark` is not installed (Debian: apt-get install tshark; .ci/run installs it)");
        return;
    }
    let dir = temp_dir("cigi-tshark");
    for order in ORDERS {
        let pcap = dir.join(format!("cigi-{order:?}.pcap"));
        std::fs::write(&pcap, capture(order)).unwrap();
        let t = Instant::now();
        let out = Command::new("tshark")
            .args(["-n", "-r"])
            .arg(&pcap)
            .args(["-d", &format!("udp.port=={CIGI_PORT},cigi"), "-T", "pdml"])
            .output()
            .unwrap();
        let pdml = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "tshark: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let (frames, all) = pdml_fields(&pdml);
        let bad: Vec<&String> = all
            .iter()
            .filter(|n| {
                n.starts_with("_ws.malformed")
                    || n.starts_with("_ws.expert")
                    || *n == "cigi.unknown"
                    || *n == "cigi.invalid_len"
            })
            .collect();
        assert!(
            bad.is_empty(),
            "{order:?}: tshark reports {bad:?} ({})",
            pcap.display()
        );
        // Frames alternate host (sample 0), IG (sample 0), host (1), IG (1).
        let mut want = Vec::new();
        for k in 0..2 {
            let mut host: Vec<HostPacket> = vec![ig_control(k).into()];
            host.extend(host_body(k));
            want.push(
                host.iter()
                    .flat_map(|p| expect_host(p, order))
                    .collect::<Expect>(),
            );
            let mut ig: Vec<IgPacket> = vec![start_of_frame(k).into()];
            ig.extend(ig_body(k));
            want.push(
                ig.iter()
                    .flat_map(|p| expect_ig(p, order))
                    .collect::<Expect>(),
            );
        }
        assert_eq!(frames.len(), 4, "{order:?}");
        let mut compared = 0;
        for (i, (got, want)) in frames.iter().zip(&want).enumerate() {
            for (j, (g, w)) in got.iter().zip(want).enumerate() {
                assert!(
                    g.0 == w.0 && same_value(&g.1, &w.1),
                    "{order:?} frame {}, field {j}: tshark shows {} = {}, relief sent {} = {}",
                    i + 1,
                    g.0,
                    g.1,
                    w.0,
                    w.1
                );
            }
            assert_eq!(
                got.len(),
                want.len(),
                "{order:?} frame {}: field count",
                i + 1
            );
            compared += got.len();
        }
        println!(
            "tshark ({order:?}): {compared} CIGI fields in 4 datagrams decoded as sent, no malformed or expert entries ({:.0} ms)",
            t.elapsed().as_secs_f64() * 1e3
        );
    }
}
