//! IG-to-host packets (CIGI 3.3 ICD, section 4.2), big-endian offsets. The `host_frame_lsn`
//! fields are the four least significant bits of the host frame the answer belongs to.

use super::wire::MAGIC;

cigi_packet! {
    /// Start of Frame (ID 101, 24 bytes): the first packet of every IG message. Version 3
    /// (byte 2), minor version 3 (byte 5, bits 4–7) and the magic number (bytes 6–7) are
    /// written by the encoder.
    StartOfFrame = StartOfFrame {
        /// The database loaded (negative: loading failed).
        database: i8 = 3,
        /// 0 normal; anything else an IG-defined error code.
        ig_status: u8 = 4,
        /// 0 reset/standby, 1 operate, 2 debug, 3 offline maintenance.
        ig_mode: u8 = 5 [0; 2],
        timestamp_valid: bool = 5 [2; 1],
        /// false WGS84, true host-defined earth reference model.
        earth_reference: bool = 5 [3; 1],
        ig_frame: u32 = 8,
        /// IG timestamp, ticks of 10 µs.
        timestamp: u32 = 12,
        last_host_frame: u32 = 16,
    }
    fixed { 2: u8 = 3, 5: u8 = 3 << 4, 6: u16 = MAGIC }
}

cigi_packet! {
    /// HAT/HOT Response (ID 102, 16 bytes).
    HatHotResponse = HatHotResponse {
        request_id: u16 = 2,
        valid: bool = 4 [0; 1],
        /// false HAT, true HOT.
        hot: bool = 4 [1; 1],
        host_frame_lsn: u8 = 4 [4; 4],
        height: f64 = 8,
    }
}

cigi_packet! {
    /// HAT/HOT Extended Response (ID 103, 40 bytes).
    HatHotExtendedResponse = HatHotExtendedResponse {
        request_id: u16 = 2,
        valid: bool = 4 [0; 1],
        host_frame_lsn: u8 = 4 [4; 4],
        hat: f64 = 8,
        hot: f64 = 16,
        material: u32 = 24,
        normal_azimuth: f32 = 28,
        normal_elevation: f32 = 32,
    }
}

cigi_packet! {
    /// Line of Sight Response (ID 104, 16 bytes).
    LosResponse = LosResponse {
        request_id: u16 = 2,
        valid: bool = 4 [0; 1],
        entity_valid: bool = 4 [1; 1],
        visible: bool = 4 [2; 1],
        host_frame_lsn: u8 = 4 [4; 4],
        /// Number of responses to this request this frame.
        count: u8 = 5,
        entity_id: u16 = 6,
        range: f64 = 8,
    }
}

cigi_packet! {
    /// Line of Sight Extended Response (ID 105, 56 bytes).
    LosExtendedResponse = LosExtendedResponse {
        request_id: u16 = 2,
        valid: bool = 4 [0; 1],
        entity_valid: bool = 4 [1; 1],
        range_valid: bool = 4 [2; 1],
        visible: bool = 4 [3; 1],
        host_frame_lsn: u8 = 4 [4; 4],
        count: u8 = 5,
        entity_id: u16 = 6,
        range: f64 = 8,
        lat: f64 = 16,
        lon: f64 = 24,
        alt: f64 = 32,
        red: u8 = 40,
        green: u8 = 41,
        blue: u8 = 42,
        alpha: u8 = 43,
        material: u32 = 44,
        normal_azimuth: f32 = 48,
        normal_elevation: f32 = 52,
    }
}

cigi_packet! {
    /// Position Response (ID 108, 48 bytes).
    PositionResponse = PositionResponse {
        object_id: u16 = 2,
        part_id: u8 = 4,
        /// 0 entity, 1 articulated part, 2 view, 3 view group, 4 motion tracker.
        object_class: u8 = 5 [0; 3],
        /// 0 geodetic, 1 parent entity, 2 submodel.
        coordinate_system: u8 = 5 [3; 2],
        lat: f64 = 8,
        lon: f64 = 16,
        alt: f64 = 24,
        roll: f32 = 32,
        pitch: f32 = 36,
        yaw: f32 = 40,
    }
}

cigi_packet! {
    /// Collision Detection Segment Notification (ID 113, 16 bytes): a segment of `entity_id`
    /// met a surface this frame, `distance` metres from its first point.
    CollisionSegmentNotification = CollisionSegmentNotification {
        entity_id: u16 = 2,
        segment_id: u8 = 4,
        /// false: the terrain (or another non-entity surface); true: `contacted_entity_id`.
        entity_contact: bool = 5 [0; 1],
        contacted_entity_id: u16 = 6,
        material_code: u32 = 8,
        distance: f32 = 12,
    }
}

cigi_packet! {
    /// Collision Detection Volume Notification (ID 114, 16 bytes): volume `volume_id` of
    /// `entity_id` overlaps volume `contacted_volume_id` of `contacted_entity_id` this frame.
    CollisionVolumeNotification = CollisionVolumeNotification {
        entity_id: u16 = 2,
        volume_id: u8 = 4,
        /// false: the terrain; true: `contacted_entity_id`'s volume `contacted_volume_id`.
        entity_contact: bool = 5 [0; 1],
        contacted_entity_id: u16 = 6,
        contacted_volume_id: u8 = 8,
    }
}
