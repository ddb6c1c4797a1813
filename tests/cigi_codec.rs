//! The CIGI 3.3 wire layer (issue 21, first part): every packet round trip in both byte
//! orders, hostile datagrams, the session's state and interpolation, and Wireshark's CIGI
//! dissector (tshark) as the independent decoder of what relief writes.

mod common;

use common::{temp_dir, Rng};
use relief::cigi::pcap::{write_pcap, UdpFrame, HOST_ADDR, IG_ADDR};
use relief::cigi::*;
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
        rate_control(k).into(),
        celestial(k).into(),
        atmosphere(k).into(),
        weather(k).into(),
        view_control(k).into(),
        view_definition(k).into(),
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
        .flat_map(|k| [(true, host_datagram(k, order)), (false, ig_datagram(k, order))])
        .collect();
    let frames: Vec<UdpFrame<'_>> = datagrams
        .iter()
        .enumerate()
        .map(|(i, (from_host, d))| {
            let (host, ig) = ((HOST_ADDR, CIGI_PORT), (IG_ADDR, IG_PORT));
            let (src, dst) = if *from_host { (host, ig) } else { (ig, host) };
            UdpFrame { src, dst, time_us: 1_000_000 + 16_667 * i as u64, payload: d }
        })
        .collect();
    write_pcap(&frames).unwrap()
}

#[test]
fn write_capture_for_inspection() {
    let dir = temp_dir("cigi-capture");
    for order in ORDERS {
        std::fs::write(dir.join(format!("{order:?}.pcap")), capture(order)).unwrap();
    }
    eprintln!("{}", dir.display());
}
