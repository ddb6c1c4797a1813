//! Host-to-IG packets (CIGI 3.3 ICD, section 4.1), big-endian offsets. Angles in degrees,
//! lengths in metres, timestamps in ticks of 10 µs. Multi-bit codes are kept as the raw
//! `u8` of the wire (the ICD's meaning in each field's comment); the session interprets them.

use super::wire::MAGIC;

cigi_packet! {
    /// IG Control (ID 1, 24 bytes): the first packet of every host message. Version 3
    /// (byte 2), minor version 3 (byte 4, bits 4–7) and the magic number (bytes 6–7) are
    /// written by the encoder.
    IgControl = IgControl {
        /// Database number to load (0: none requested; negative: the IG reports a failure).
        database: i8 = 3,
        /// IG mode change request: 0 reset/standby, 1 operate, 2 debug, 3 offline maintenance.
        ig_mode: u8 = 4 [0; 2],
        timestamp_valid: bool = 4 [2; 1],
        /// Entity extrapolation/interpolation enabled globally.
        extrapolation: bool = 4 [3; 1],
        host_frame: u32 = 8,
        /// Host timestamp, ticks of 10 µs.
        timestamp: u32 = 12,
        /// The last IG frame number the host received.
        last_ig_frame: u32 = 16,
    }
    fixed { 2: u8 = 3, 4: u8 = 3 << 4, 6: u16 = MAGIC }
}

cigi_packet! {
    /// Entity Control (ID 2, 48 bytes): an entity's state, type, parent and pose. Unattached,
    /// `lat`/`lon`/`alt` are geodetic (degrees, degrees, metres above MSL); attached, they are
    /// x/y/z offsets (m) in the parent's body frame.
    EntityControl = EntityControl {
        entity_id: u16 = 2,
        /// 0 inactive/standby, 1 active, 2 destroyed.
        entity_state: u8 = 4 [0; 2],
        /// Attached to `parent_id`.
        attach: bool = 4 [2; 1],
        collision_detection: bool = 4 [3; 1],
        inherit_alpha: bool = 4 [4; 1],
        /// 0 no clamp, 1 non-conformal, 2 conformal.
        ground_clamp: u8 = 4 [5; 2],
        animation_direction: bool = 5 [0; 1],
        animation_loop: bool = 5 [1; 1],
        /// 0 stop, 1 pause, 2 play, 3 continue.
        animation_state: u8 = 5 [2; 2],
        /// Linear extrapolation/interpolation of this entity.
        extrapolation: bool = 5 [4; 1],
        alpha: u8 = 6,
        entity_type: u16 = 8,
        parent_id: u16 = 10,
        roll: f32 = 12,
        pitch: f32 = 16,
        yaw: f32 = 20,
        lat: f64 = 24,
        lon: f64 = 32,
        alt: f64 = 40,
    }
}

cigi_packet! {
    /// Conformal Clamped Entity Control (ID 3, 24 bytes): a new heading and geodetic position
    /// for an entity that exists; its altitude, pitch and roll (offsets when it is clamped
    /// conformally) stay those of its last Entity Control.
    ConformalClampedEntityControl = ConformalClampedEntityControl {
        entity_id: u16 = 2,
        yaw: f32 = 4,
        lat: f64 = 8,
        lon: f64 = 16,
    }
}

cigi_packet! {
    /// Collision Detection Segment Definition (ID 22, 40 bytes): a segment fixed to an entity,
    /// between two points given as body offsets (x forward, y right, z down, metres), that the
    /// IG tests against the terrain and the other entities each frame while the entity's
    /// collision detection is on.
    CollisionSegmentDefinition = CollisionSegmentDefinition {
        entity_id: u16 = 2,
        segment_id: u8 = 4,
        enabled: bool = 5 [0; 1],
        x1: f32 = 8,
        y1: f32 = 12,
        z1: f32 = 16,
        x2: f32 = 20,
        y2: f32 = 24,
        z2: f32 = 28,
        material_mask: u32 = 32,
    }
}

cigi_packet! {
    /// Collision Detection Volume Definition (ID 23, 48 bytes): a sphere or a cuboid fixed to
    /// an entity (centre at body offsets x forward, y right, z down, metres; a cuboid turned by
    /// yaw, pitch and roll from the body's axes, `depth` along its x, `width` along y,
    /// `radius_height` along z) that the IG tests against the other entities' volumes.
    CollisionVolumeDefinition = CollisionVolumeDefinition {
        entity_id: u16 = 2,
        volume_id: u8 = 4,
        enabled: bool = 5 [0; 1],
        /// false a sphere, true a cuboid.
        cuboid: bool = 5 [1; 1],
        x: f32 = 8,
        y: f32 = 12,
        z: f32 = 16,
        /// A sphere's radius, a cuboid's height.
        radius_height: f32 = 20,
        width: f32 = 24,
        depth: f32 = 28,
        roll: f32 = 32,
        pitch: f32 = 36,
        yaw: f32 = 40,
    }
}

cigi_packet! {
    /// Rate Control (ID 8, 32 bytes): linear (m/s) and angular (°/s) rates of an entity or
    /// of one of its articulated parts.
    RateControl = RateControl {
        entity_id: u16 = 2,
        part_id: u8 = 4,
        apply_to_part: bool = 5 [0; 1],
        /// false: world/parent frame, true: the entity's body frame.
        body_frame: bool = 5 [1; 1],
        x_rate: f32 = 8,
        y_rate: f32 = 12,
        z_rate: f32 = 16,
        roll_rate: f32 = 20,
        pitch_rate: f32 = 24,
        yaw_rate: f32 = 28,
    }
}

cigi_packet! {
    /// Celestial Sphere Control (ID 9, 16 bytes): time of day and date for sun, moon, stars.
    CelestialSphereControl = CelestialSphereControl {
        hour: u8 = 2,
        minute: u8 = 3,
        ephemeris: bool = 4 [0; 1],
        sun: bool = 4 [1; 1],
        moon: bool = 4 [2; 1],
        stars: bool = 4 [3; 1],
        date_time_valid: bool = 4 [4; 1],
        /// MMDDYYYY as a decimal number.
        date: u32 = 8,
        /// Star field intensity (%).
        star_intensity: f32 = 12,
    }
}

cigi_packet! {
    /// Atmosphere Control (ID 10, 32 bytes): the global atmosphere.
    AtmosphereControl = AtmosphereControl {
        model_enable: bool = 2 [0; 1],
        /// Global humidity (%).
        humidity: u8 = 3,
        air_temperature: f32 = 4,
        /// Global visibility range (m).
        visibility: f32 = 8,
        horizontal_wind: f32 = 12,
        vertical_wind: f32 = 16,
        wind_direction: f32 = 20,
        /// mb (= hPa).
        pressure: f32 = 24,
    }
}

cigi_packet! {
    /// Weather Control (ID 12, 56 bytes): one weather layer, global, regional or attached to
    /// an entity.
    WeatherControl = WeatherControl {
        /// Entity ID (scope entity) or region ID (scope regional).
        entity_region_id: u16 = 2,
        layer_id: u8 = 4,
        humidity: u8 = 5,
        enable: bool = 6 [0; 1],
        scud: bool = 6 [1; 1],
        random_winds: bool = 6 [2; 1],
        random_lightning: bool = 6 [3; 1],
        cloud_type: u8 = 6 [4; 4],
        /// 0 global, 1 regional, 2 entity.
        scope: u8 = 7 [0; 2],
        severity: u8 = 7 [2; 3],
        air_temperature: f32 = 8,
        visibility: f32 = 12,
        scud_frequency: f32 = 16,
        coverage: f32 = 20,
        base_elevation: f32 = 24,
        thickness: f32 = 28,
        transition_band: f32 = 32,
        horizontal_wind: f32 = 36,
        vertical_wind: f32 = 40,
        wind_direction: f32 = 44,
        pressure: f32 = 48,
        aerosol: f32 = 52,
    }
}

cigi_packet! {
    /// View Control (ID 16, 32 bytes): a view's (or view group's) eye offset and attitude
    /// relative to its entity.
    ViewControl = ViewControl {
        view_id: u16 = 2,
        group_id: u8 = 4,
        x_enable: bool = 5 [0; 1],
        y_enable: bool = 5 [1; 1],
        z_enable: bool = 5 [2; 1],
        roll_enable: bool = 5 [3; 1],
        pitch_enable: bool = 5 [4; 1],
        yaw_enable: bool = 5 [5; 1],
        entity_id: u16 = 6,
        x: f32 = 8,
        y: f32 = 12,
        z: f32 = 16,
        roll: f32 = 20,
        pitch: f32 = 24,
        yaw: f32 = 28,
    }
}

cigi_packet! {
    /// View Definition (ID 21, 32 bytes): a view's frustum (near/far in metres, the four
    /// half-angles in degrees).
    ViewDefinition = ViewDefinition {
        view_id: u16 = 2,
        group_id: u8 = 4,
        near_enable: bool = 5 [0; 1],
        far_enable: bool = 5 [1; 1],
        left_enable: bool = 5 [2; 1],
        right_enable: bool = 5 [3; 1],
        top_enable: bool = 5 [4; 1],
        bottom_enable: bool = 5 [5; 1],
        /// 0 none, 1 horizontal, 2 vertical, 3 both.
        mirror: u8 = 5 [6; 2],
        pixel_replication: u8 = 6 [0; 3],
        /// false perspective, true orthographic.
        orthographic: bool = 6 [3; 1],
        reorder: bool = 6 [4; 1],
        view_type: u8 = 6 [5; 3],
        near: f32 = 8,
        far: f32 = 12,
        left: f32 = 16,
        right: f32 = 20,
        top: f32 = 24,
        bottom: f32 = 28,
    }
}

cigi_packet! {
    /// HAT/HOT Request (ID 24, 32 bytes): height above / of terrain at a point.
    HatHotRequest = HatHotRequest {
        request_id: u16 = 2,
        /// 0 HAT, 1 HOT, 2 extended.
        request_type: u8 = 4 [0; 2],
        /// false geodetic, true entity offset.
        entity_frame: bool = 4 [2; 1],
        /// 0: once; n: every n IG frames.
        update_period: u8 = 5,
        entity_id: u16 = 6,
        lat: f64 = 8,
        lon: f64 = 16,
        alt: f64 = 24,
    }
}

cigi_packet! {
    /// Line of Sight Segment Request (ID 25, 64 bytes): the first intersection on a segment.
    LosSegmentRequest = LosSegmentRequest {
        request_id: u16 = 2,
        /// false basic, true extended response.
        extended: bool = 4 [0; 1],
        source_entity_frame: bool = 4 [1; 1],
        destination_entity_frame: bool = 4 [2; 1],
        response_entity_frame: bool = 4 [3; 1],
        destination_entity_valid: bool = 4 [4; 1],
        alpha_threshold: u8 = 5,
        entity_id: u16 = 6,
        source_lat: f64 = 8,
        source_lon: f64 = 16,
        source_alt: f64 = 24,
        destination_lat: f64 = 32,
        destination_lon: f64 = 40,
        destination_alt: f64 = 48,
        material_mask: u32 = 56,
        update_period: u8 = 60,
        destination_entity_id: u16 = 62,
    }
}

cigi_packet! {
    /// Line of Sight Vector Request (ID 26, 56 bytes): the first intersection along a ray
    /// between two ranges.
    LosVectorRequest = LosVectorRequest {
        request_id: u16 = 2,
        extended: bool = 4 [0; 1],
        source_entity_frame: bool = 4 [1; 1],
        response_entity_frame: bool = 4 [2; 1],
        alpha_threshold: u8 = 5,
        entity_id: u16 = 6,
        azimuth: f32 = 8,
        elevation: f32 = 12,
        min_range: f32 = 16,
        max_range: f32 = 20,
        source_lat: f64 = 24,
        source_lon: f64 = 32,
        source_alt: f64 = 40,
        material_mask: u32 = 48,
        update_period: u8 = 52,
    }
}

cigi_packet! {
    /// Position Request (ID 27, 8 bytes): where an object (entity, part, view, …) is.
    PositionRequest = PositionRequest {
        object_id: u16 = 2,
        part_id: u8 = 4,
        /// false one-shot, true every frame.
        continuous: bool = 5 [0; 1],
        /// 0 entity, 1 articulated part, 2 view, 3 view group, 4 motion tracker.
        object_class: u8 = 5 [1; 3],
        /// 0 geodetic, 1 parent entity, 2 submodel.
        coordinate_system: u8 = 5 [4; 2],
    }
}

impl EntityControl {
    /// An active, opaque top-level entity `id` of `entity_type` at geodetic `lla` (degrees,
    /// metres) with attitude `ypr` (yaw, pitch, roll; degrees); every other field off.
    pub fn placed(id: u16, entity_type: u16, lla: [f64; 3], ypr: [f32; 3]) -> EntityControl {
        EntityControl {
            entity_id: id,
            entity_state: 1,
            alpha: 255,
            entity_type,
            yaw: ypr[0],
            pitch: ypr[1],
            roll: ypr[2],
            lat: lla[0],
            lon: lla[1],
            alt: lla[2],
            ..EntityControl::default()
        }
    }
}

impl LosSegmentRequest {
    /// A line of sight from geodetic `from` to `to` (degrees, metres), neither end in an
    /// entity's frame; a basic or (`extended`) extended response.
    pub fn between(request_id: u16, from: [f64; 3], to: [f64; 3], extended: bool) -> Self {
        LosSegmentRequest {
            request_id,
            extended,
            source_lat: from[0],
            source_lon: from[1],
            source_alt: from[2],
            destination_lat: to[0],
            destination_lon: to[1],
            destination_alt: to[2],
            ..LosSegmentRequest::default()
        }
    }
}
