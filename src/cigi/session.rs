//! The IG side of a CIGI session as a pure state machine: datagrams `(bytes, now)` in, the
//! host's state, a queue of queries and counters out. No sockets, no clock of its own.
//!
//! Each datagram goes through [`super::message::read_message`]'s rules; an accepted one is
//! applied packet by packet in order. Values that cannot be applied (non-finite numbers, a
//! reserved entity state, a parent that does not exist or would make a cycle) drop that packet
//! and count [`Counters::invalid_values`]. Entities live in a map (IDs are u16, at most
//! [`MAX_ENTITIES`] of them); views, weather layers and queries are capped as well, so no
//! stream of datagrams makes the session grow without bound.

use super::clock::HostClock;
use super::entity::{Entity, EntityState, Pose, Rates, Sample};
use super::host::*;
use super::ig::StartOfFrame;
use super::message::{
    read_host_message, HostPacket, MessageBuilder, PacketSet, Rejection, Stop, Walk,
};
use super::packet::Kind;
use super::wire::ByteOrder;
use std::collections::{BTreeMap, VecDeque};
use std::net::SocketAddr;

/// Most entities held at once; Entity Control for a new ID beyond it is refused.
pub const MAX_ENTITIES: usize = 4096;
/// Most views (View Control / View Definition IDs) held.
pub const MAX_VIEWS: usize = 256;
/// Weather Control's cloud layers (CIGI 3.3: 1, 2 and 3; 0 is ground fog, 4–9 precipitation
/// and particles).
pub const CLOUD_LAYER_IDS: std::ops::RangeInclusive<u8> = 1..=3;

/// Most weather layers (scope, region or entity, layer) held.
pub const MAX_WEATHER: usize = 256;
/// Most queries waiting for the IG's answers.
pub const MAX_QUERIES: usize = 1024;
/// Collision detection segments kept (across every entity).
pub const MAX_SEGMENTS: usize = 1024;
/// Seconds per timestamp tick (CIGI 3: 10 µs).
pub const TICK: f64 = 1e-5;

/// What the session has counted since it started.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Every datagram offered
    /// (`= accepted + short + no_header + refused_version + bad_magic + ignored_sender`).
    pub datagrams: u64,
    pub accepted: u64,
    /// Too short for a header, or a header whose size byte is wrong.
    pub short: u64,
    /// The first packet was not IG Control.
    pub no_header: u64,
    /// Version ≠ 3 or minor version not 2 or 3.
    pub refused_version: u64,
    /// Magic number neither 0x8000 nor 0x0080.
    pub bad_magic: u64,
    /// From another address than the session's host.
    pub ignored_sender: u64,
    /// Packets of accepted datagrams taken by their size byte
    /// (`= Σ by_kind + unknown + short_packets + misplaced_header`).
    pub packets: u64,
    /// Decoded packets per kind ([`Kind::index`]).
    pub by_kind: [u64; Kind::ALL.len()],
    /// Unknown or unsupported IDs, skipped.
    pub unknown: u64,
    /// Handled IDs with a size below their layout, skipped.
    pub short_packets: u64,
    /// IG Control other than first, skipped.
    pub misplaced_header: u64,
    /// Walks stopped by a size byte of 0 or 1.
    pub size_below_two: u64,
    /// Walks stopped by a size past the datagram's end.
    pub past_end: u64,
    /// Walks ending with one stray byte.
    pub trailing: u64,
    /// Decoded packets not applied: non-finite values, reserved codes, bad parents.
    pub invalid_values: u64,
    /// New entities refused at [`MAX_ENTITIES`] (views and weather at their caps too).
    pub refused_capacity: u64,
    /// Queries dropped because [`MAX_QUERIES`] were waiting.
    pub dropped_queries: u64,
    /// Entities removed (destroyed, with their children, or by a reset).
    pub destroyed: u64,
}

impl Counters {
    /// Decoded packets of kind `k`.
    pub fn of_kind(&self, k: Kind) -> u64 {
        self.by_kind[k.index()]
    }

    /// Datagrams refused as a whole for their contents, and walks cut short or packets
    /// skipped for a wrong size: everything a well-behaved host never sends.
    pub fn malformed(&self) -> u64 {
        self.short
            + self.no_header
            + self.bad_magic
            + self.size_below_two
            + self.past_end
            + self.trailing
            + self.short_packets
            + self.misplaced_header
    }
}

/// IG mode (IG Control's request, Start of Frame's report).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum IgMode {
    #[default]
    Standby,
    Operate,
    Debug,
    OfflineMaintenance,
}

impl IgMode {
    pub fn from_code(v: u8) -> IgMode {
        match v & 3 {
            0 => IgMode::Standby,
            1 => IgMode::Operate,
            2 => IgMode::Debug,
            _ => IgMode::OfflineMaintenance,
        }
    }
    pub fn code(self) -> u8 {
        self as u8
    }
}

/// A query from the host the IG has to answer, with the host frame it came in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Query {
    HatHot(HatHotRequest, u32),
    LosSegment(LosSegmentRequest, u32),
    LosVector(LosVectorRequest, u32),
    Position(PositionRequest, u32),
}

/// What the host said about one view ID.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct View {
    pub control: Option<ViewControl>,
    pub definition: Option<ViewDefinition>,
}

/// View Control `new` over what the view held: an offset whose enable bit is clear keeps its
/// earlier value (and enable bit), as the ICD says the IG ignores it; a new entity starts
/// afresh.
fn merge_view_control(old: Option<ViewControl>, new: ViewControl) -> ViewControl {
    let Some(o) = old.filter(|o| o.entity_id == new.entity_id) else {
        return new;
    };
    let pick =
        |on: bool, n: f32, was_on: bool, was: f32| if on { (true, n) } else { (was_on, was) };
    let mut m = new;
    (m.x_enable, m.x) = pick(new.x_enable, new.x, o.x_enable, o.x);
    (m.y_enable, m.y) = pick(new.y_enable, new.y, o.y_enable, o.y);
    (m.z_enable, m.z) = pick(new.z_enable, new.z, o.z_enable, o.z);
    (m.roll_enable, m.roll) = pick(new.roll_enable, new.roll, o.roll_enable, o.roll);
    (m.pitch_enable, m.pitch) = pick(new.pitch_enable, new.pitch, o.pitch_enable, o.pitch);
    (m.yaw_enable, m.yaw) = pick(new.yaw_enable, new.yaw, o.yaw_enable, o.yaw);
    m
}

/// The IG's view of a CIGI host.
#[derive(Clone, Debug, Default)]
pub struct Session {
    pub counters: Counters,
    /// The host's address once known; datagrams from others are ignored.
    pub host: Option<SocketAddr>,
    pub ig_mode: IgMode,
    pub database: i8,
    pub order: ByteOrder,
    pub minor_version: u8,
    /// IG Control's last host frame number.
    pub host_frame: Option<u32>,
    /// IG Control's last valid timestamp (ticks).
    pub host_timestamp: Option<u32>,
    /// IG Control's extrapolation/interpolation bit.
    pub extrapolation: bool,
    /// The last IG frame the host says it received.
    pub last_ig_frame: u32,
    /// Host time (s) of the last accepted datagram: its timestamp unwrapped, or its arrival
    /// time when the timestamp is not valid.
    pub host_time: f64,
    /// Arrival time (`now`) of the last accepted datagram.
    pub arrival: f64,
    /// Local → host time ([`HostClock`]).
    pub clock: HostClock,
    wraps: u64,
    entities: BTreeMap<u16, Entity>,
    pub views: BTreeMap<u16, View>,
    pub celestial: Option<CelestialSphereControl>,
    pub atmosphere: Option<AtmosphereControl>,
    /// Weather layers by (scope, entity or region ID, layer ID).
    pub weather: BTreeMap<(u8, u16, u8), WeatherControl>,
    /// Enabled collision detection segments by (entity ID, segment ID).
    segments: BTreeMap<(u16, u8), CollisionSegmentDefinition>,
    /// Enabled collision detection volumes by (entity ID, volume ID).
    volumes: BTreeMap<(u16, u8), CollisionVolumeDefinition>,
    queries: VecDeque<Query>,
}

impl Session {
    pub fn new() -> Self {
        Self::default()
    }

    /// A session that only listens to `host`.
    pub fn with_host(host: SocketAddr) -> Self {
        Session {
            host: Some(host),
            ..Self::default()
        }
    }

    /// A datagram from `from` at `now` (s, any monotonic clock); the first accepted
    /// datagram fixes the host's address unless [`Session::with_host`] did. `None`: ignored,
    /// another sender.
    pub fn receive_from(
        &mut self,
        from: SocketAddr,
        bytes: &[u8],
        now: f64,
    ) -> Option<Result<Walk, Rejection>> {
        if self.host.is_some_and(|h| h != from) {
            self.counters.datagrams += 1;
            self.counters.ignored_sender += 1;
            log::debug!(
                "CIGI datagram from {from} ignored: the host is {:?}",
                self.host
            );
            return None;
        }
        let r = self.receive(bytes, now);
        if r.is_ok() && self.host.is_none() {
            self.host = Some(from);
        }
        Some(r)
    }

    /// A datagram from the host at `now` (s, any monotonic clock): refused as a whole
    /// (counted) or applied packet by packet.
    pub fn receive(&mut self, bytes: &[u8], now: f64) -> Result<Walk, Rejection> {
        let c = &mut self.counters;
        c.datagrams += 1;
        let msg = match read_host_message(bytes) {
            Ok(m) => m,
            Err(r) => {
                match r {
                    Rejection::Short => c.short += 1,
                    Rejection::NoHeader(_) => c.no_header += 1,
                    Rejection::Version(_) | Rejection::MinorVersion(_) => c.refused_version += 1,
                    Rejection::Magic(_) => c.bad_magic += 1,
                }
                log::debug!("CIGI datagram of {} bytes refused: {r}", bytes.len());
                return Err(r);
            }
        };
        c.accepted += 1;
        let w = msg.walk;
        c.packets += u64::from(w.packets);
        c.unknown += u64::from(w.unknown);
        c.short_packets += u64::from(w.short);
        c.misplaced_header += u64::from(w.misplaced_header);
        match w.stop {
            Some(Stop::SizeBelowTwo) => c.size_below_two += 1,
            Some(Stop::PastEnd) => c.past_end += 1,
            Some(Stop::Trailing) => c.trailing += 1,
            None => {}
        }
        self.order = msg.order;
        self.minor_version = msg.minor_version;
        for p in &msg.packets {
            self.counters.by_kind[p.kind().index()] += 1;
            self.apply(p, now);
        }
        Ok(w)
    }

    fn apply(&mut self, p: &HostPacket, now: f64) {
        match p {
            HostPacket::IgControl(p) => self.ig_control(p, now),
            HostPacket::EntityControl(p) => self.entity_control(p),
            HostPacket::ConformalClampedEntityControl(p) => self.conformal_clamped(p),
            HostPacket::RateControl(p) => self.rate_control(p),
            HostPacket::CelestialSphereControl(p) => self.celestial = Some(*p),
            HostPacket::AtmosphereControl(p) => self.atmosphere = Some(*p),
            HostPacket::WeatherControl(p) => {
                let key = (p.scope, p.entity_region_id, p.layer_id);
                if self.weather.len() < MAX_WEATHER || self.weather.contains_key(&key) {
                    self.weather.insert(key, *p);
                } else {
                    self.counters.refused_capacity += 1;
                }
            }
            HostPacket::ViewControl(p) => {
                let offsets = [p.x, p.y, p.z, p.roll, p.pitch, p.yaw];
                if !offsets.iter().all(|v| v.is_finite()) {
                    self.counters.invalid_values += 1;
                } else if let Some(v) = self.view_mut(p.view_id) {
                    v.control = Some(merge_view_control(v.control, *p));
                }
            }
            HostPacket::CollisionSegmentDefinition(p) => self.segment_definition(p),
            HostPacket::CollisionVolumeDefinition(p) => self.volume_definition(p),
            HostPacket::ViewDefinition(p) => {
                if let Some(v) = self.view_mut(p.view_id) {
                    v.definition = Some(*p);
                }
            }
            HostPacket::HatHotRequest(p) => self.query(Query::HatHot(*p, self.frame())),
            HostPacket::LosSegmentRequest(p) => self.query(Query::LosSegment(*p, self.frame())),
            HostPacket::LosVectorRequest(p) => self.query(Query::LosVector(*p, self.frame())),
            HostPacket::PositionRequest(p) => self.query(Query::Position(*p, self.frame())),
        }
    }

    fn frame(&self) -> u32 {
        self.host_frame.unwrap_or(0)
    }

    fn view_mut(&mut self, id: u16) -> Option<&mut View> {
        if self.views.len() >= MAX_VIEWS && !self.views.contains_key(&id) {
            self.counters.refused_capacity += 1;
            return None;
        }
        Some(self.views.entry(id).or_default())
    }

    fn query(&mut self, q: Query) {
        if self.queries.len() >= MAX_QUERIES {
            self.counters.dropped_queries += 1;
        } else {
            self.queries.push_back(q);
        }
    }

    fn ig_control(&mut self, p: &IgControl, now: f64) {
        let mode = IgMode::from_code(p.ig_mode);
        if mode == IgMode::Standby && self.ig_mode != IgMode::Standby {
            self.reset();
        }
        self.ig_mode = mode;
        self.database = p.database;
        self.host_frame = Some(p.host_frame);
        self.last_ig_frame = p.last_ig_frame;
        self.extrapolation = p.extrapolation;
        self.arrival = now;
        if p.timestamp_valid {
            if let Some(prev) = self.host_timestamp {
                // A step back of more than half the range is the 32-bit counter wrapping.
                if p.timestamp < prev && prev - p.timestamp > u32::MAX / 2 {
                    self.wraps += 1;
                }
            }
            self.host_timestamp = Some(p.timestamp);
            let t = ((self.wraps << 32) + u64::from(p.timestamp)) as f64 / 100_000.0;
            if t < self.host_time - super::clock::RESET {
                // Timestamps went back (not a wrap): a restarted host, a new clock.
                self.clock.restart();
            }
            self.host_time = t;
        } else {
            self.host_time = now;
        }
        self.clock.observe(now, self.host_time);
    }

    /// Entering reset/standby: every entity but the ownship (0) and every pending query go.
    fn reset(&mut self) {
        let before = self.entities.len();
        self.entities.retain(|&id, _| id == 0);
        self.counters.destroyed += (before - self.entities.len()) as u64;
        self.queries.clear();
        self.segments.retain(|&(id, _), _| id == 0);
        self.volumes.retain(|&(id, _), _| id == 0);
    }

    /// Collision Detection Volume Definition: kept, dropped and counted as segments are
    /// ([`MAX_SEGMENTS`] volumes at most); a negative or non-finite size is invalid.
    fn volume_definition(&mut self, p: &CollisionVolumeDefinition) {
        let v = [p.x, p.y, p.z, p.roll, p.pitch, p.yaw];
        let sizes = [p.radius_height, p.width, p.depth];
        let sizes_ok = sizes.iter().all(|s| s.is_finite() && *s >= 0.0);
        if !v.iter().all(|x| x.is_finite()) || !sizes_ok {
            self.counters.invalid_values += 1;
            return;
        }
        let key = (p.entity_id, p.volume_id);
        let enabled = p.enabled.then_some(*p);
        keep(&mut self.volumes, key, enabled, &mut self.counters);
    }

    /// The collision detection volumes of active entities: `(volume, whether its entity's
    /// collision detection is on)` — those with it on are tested against every other
    /// entity's.
    pub fn collision_volumes(&self) -> impl Iterator<Item = (&CollisionVolumeDefinition, bool)> {
        self.volumes.values().filter_map(|v| {
            let e = self.entities.get(&v.entity_id)?;
            (e.state == EntityState::Active).then_some((v, e.collision_detection))
        })
    }

    /// Collision Detection Segment Definition: an enabled segment is kept (replacing the
    /// entity's segment of that ID; new ones refused at [`MAX_SEGMENTS`]), a disabled one
    /// dropped; non-finite offsets are counted (`invalid_values`).
    fn segment_definition(&mut self, p: &CollisionSegmentDefinition) {
        let v = [p.x1, p.y1, p.z1, p.x2, p.y2, p.z2];
        if !v.iter().all(|x| x.is_finite()) {
            self.counters.invalid_values += 1;
            return;
        }
        let key = (p.entity_id, p.segment_id);
        let enabled = p.enabled.then_some(*p);
        keep(&mut self.segments, key, enabled, &mut self.counters);
    }

    /// The collision detection segments to test this frame: enabled, of an active entity
    /// whose collision detection is on (Entity Control's bit).
    pub fn collision_segments(&self) -> impl Iterator<Item = &CollisionSegmentDefinition> {
        self.segments.values().filter(|s| {
            self.entities
                .get(&s.entity_id)
                .is_some_and(|e| e.state == EntityState::Active && e.collision_detection)
        })
    }

    fn entity_control(&mut self, p: &EntityControl) {
        let pose = Pose {
            lat: p.lat,
            lon: p.lon,
            alt: p.alt,
            roll: f64::from(p.roll),
            pitch: f64::from(p.pitch),
            yaw: f64::from(p.yaw),
        };
        let v = [
            pose.lat, pose.lon, pose.alt, pose.roll, pose.pitch, pose.yaw,
        ];
        let geodetic_ok = p.attach || (pose.lat.abs() <= 90.0 && pose.lon.abs() <= 360.0);
        if p.entity_state > 2 || !v.iter().all(|x| x.is_finite()) || !geodetic_ok {
            self.counters.invalid_values += 1;
            return;
        }
        if p.entity_state == 2 {
            self.destroy(p.entity_id);
            return;
        }
        let parent = p.attach.then_some(p.parent_id);
        if let Some(parent) = parent {
            if !self.can_attach(p.entity_id, parent) {
                self.counters.invalid_values += 1;
                return;
            }
        }
        let state = if p.entity_state == 1 {
            EntityState::Active
        } else {
            EntityState::Inactive
        };
        let sample = Sample {
            time: self.host_time,
            pose,
        };
        if let Some(e) = self.entities.get_mut(&p.entity_id) {
            if e.entity_type != p.entity_type || e.parent != parent {
                // A new type or parent is a new entity as far as motion goes.
                e.previous = None;
                e.rates = Rates::default();
            }
            e.entity_type = p.entity_type;
            e.state = state;
            e.parent = parent;
            e.alpha = p.alpha;
            e.ground_clamp = p.ground_clamp;
            e.collision_detection = p.collision_detection;
            e.extrapolation = p.extrapolation;
            e.push_sample(sample);
        } else if self.entities.len() >= MAX_ENTITIES {
            self.counters.refused_capacity += 1;
        } else {
            self.entities.insert(
                p.entity_id,
                Entity {
                    id: p.entity_id,
                    entity_type: p.entity_type,
                    state,
                    parent,
                    alpha: p.alpha,
                    ground_clamp: p.ground_clamp,
                    collision_detection: p.collision_detection,
                    extrapolation: p.extrapolation,
                    previous: None,
                    latest: sample,
                    rates: Rates::default(),
                },
            );
        }
    }

    /// Whether `id` may hang below `parent`: the parent exists and `id` is not among its
    /// ancestors (the walk up is bounded by the entity count).
    fn can_attach(&self, id: u16, parent: u16) -> bool {
        let mut at = parent;
        for _ in 0..=self.entities.len() {
            if at == id {
                return false;
            }
            match self.entities.get(&at) {
                None => return false,
                Some(e) => match e.parent {
                    None => return true,
                    Some(p) => at = p,
                },
            }
        }
        false
    }

    /// Removes `id` and everything attached below it.
    fn destroy(&mut self, id: u16) {
        let mut gone = vec![id];
        let mut k = 0;
        while k < gone.len() {
            let at = gone[k];
            if self.entities.remove(&at).is_some() {
                self.counters.destroyed += 1;
            }
            let children = self.entities.iter().filter(|(_, e)| e.parent == Some(at));
            gone.extend(children.map(|(&c, _)| c));
            k += 1;
        }
        self.segments.retain(|&(id, _), _| !gone.contains(&id));
        self.volumes.retain(|&(id, _), _| !gone.contains(&id));
    }

    /// Conformal Clamped Entity Control: a new sample of an existing top-level entity with
    /// the packet's latitude, longitude and yaw, its altitude, pitch and roll kept from its
    /// latest sample (offsets from the terrain when it is clamped conformally; as they are
    /// otherwise, as the ICD says). An unknown or attached entity, or a value out of range,
    /// is counted (`invalid_values`) and ignored.
    fn conformal_clamped(&mut self, p: &ConformalClampedEntityControl) {
        let (lat, lon, yaw) = (p.lat, p.lon, f64::from(p.yaw));
        let ok = [lat, lon, yaw].iter().all(|v| v.is_finite())
            && lat.abs() <= 90.0
            && lon.abs() <= 360.0;
        let time = self.host_time;
        match self.entities.get_mut(&p.entity_id) {
            Some(e) if ok && e.parent.is_none() => {
                let pose = Pose {
                    lat,
                    lon,
                    yaw,
                    ..e.latest.pose
                };
                e.push_sample(Sample { time, pose });
            }
            _ => self.counters.invalid_values += 1,
        }
    }

    fn rate_control(&mut self, p: &RateControl) {
        let v = [
            p.x_rate,
            p.y_rate,
            p.z_rate,
            p.roll_rate,
            p.pitch_rate,
            p.yaw_rate,
        ];
        if !v.iter().all(|x| x.is_finite()) {
            self.counters.invalid_values += 1;
            return;
        }
        if p.apply_to_part {
            // Articulated parts are not modelled yet: decoded, counted, not applied.
            return;
        }
        match self.entities.get_mut(&p.entity_id) {
            Some(e) => {
                e.rates = Rates {
                    linear: [v[0], v[1], v[2]].map(f64::from),
                    angular: [v[3], v[4], v[5]].map(f64::from),
                    body_frame: p.body_frame,
                }
            }
            None => self.counters.invalid_values += 1,
        }
    }

    /// The entity with ID `id`.
    pub fn entity(&self, id: u16) -> Option<&Entity> {
        self.entities.get(&id)
    }

    /// Every entity, by ID.
    pub fn entities(&self) -> impl Iterator<Item = &Entity> {
        self.entities.values()
    }

    pub fn entity_count(&self) -> usize {
        self.entities.len()
    }

    /// The ownship (entity 0).
    pub fn ownship(&self) -> Option<&Entity> {
        self.entities.get(&0)
    }

    /// The host time (s) at local time `now`: `now` minus the clock offset [`HostClock`]
    /// estimates (the lowest `arrival − host time` of the last 2 s, slewed); before any
    /// datagram, `now`.
    pub fn host_time_at(&self, now: f64) -> f64 {
        self.clock.host_time_at(now).unwrap_or(now)
    }

    /// Entity `id`'s pose at host time `t` ([`Entity::pose_at`]).
    pub fn pose_at(&self, id: u16, t: f64) -> Option<Pose> {
        let e = self.entities.get(&id)?;
        Some(e.pose_at(t, self.extrapolation))
    }

    /// Queries waiting for answers.
    pub fn pending_queries(&self) -> usize {
        self.queries.len()
    }

    /// Takes every waiting query, oldest first.
    pub fn take_queries(&mut self) -> Vec<Query> {
        self.queries.drain(..).collect()
    }

    /// The global visibility (m): Atmosphere Control's when the atmospheric model is on,
    /// else the lowest of the enabled global weather layers other than the cloud layers
    /// ([`CLOUD_LAYER_IDS`], whose visibility is the one inside the cloud), else `None`.
    pub fn visibility(&self) -> Option<f32> {
        if let Some(a) = self.atmosphere.filter(|a| a.model_enable) {
            return Some(a.visibility);
        }
        self.weather
            .values()
            .filter(|w| w.enable && w.scope == 0 && w.visibility.is_finite())
            .filter(|w| !CLOUD_LAYER_IDS.contains(&w.layer_id))
            .map(|w| w.visibility)
            .reduce(f32::min)
    }

    /// The IG's answer datagram for IG frame `ig_frame`: Start of Frame (the session's mode,
    /// database and last host frame; `timestamp` in ticks if given), big-endian; push the
    /// responses onto it and [`MessageBuilder::finish`].
    pub fn start_of_frame(&self, ig_frame: u32, timestamp: Option<u32>) -> MessageBuilder {
        let sof = StartOfFrame {
            database: self.database,
            ig_status: 0,
            ig_mode: self.ig_mode.code(),
            timestamp_valid: timestamp.is_some(),
            earth_reference: false,
            ig_frame,
            timestamp: timestamp.unwrap_or(0),
            last_host_frame: self.host_frame.unwrap_or(0),
        };
        MessageBuilder::ig(&sof, ByteOrder::Big)
    }
}

/// A collision definition under `key`: kept where `value` is given (an enabled definition,
/// replacing the one of that key; a new key refused at [`MAX_SEGMENTS`], counted), dropped
/// where it is not (disabled).
fn keep<T>(
    map: &mut BTreeMap<(u16, u8), T>,
    key: (u16, u8),
    value: Option<T>,
    counters: &mut Counters,
) {
    match value {
        None => {
            map.remove(&key);
        }
        Some(v) if map.len() < MAX_SEGMENTS || map.contains_key(&key) => {
            map.insert(key, v);
        }
        Some(_) => counters.refused_capacity += 1,
    }
}
