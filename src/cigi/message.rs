//! Messages: one datagram, a header packet (IG Control from the host, Start of Frame from
//! the IG) followed by packets, each read by its size byte.
//!
//! Rules for what comes off the wire (none of them panics, loops or allocates by a claimed
//! size; the packet list grows only with bytes actually present):
//! * the first packet must be the header of the direction, at least 24 bytes and inside the
//!   datagram, with version 3, minor version 2 or 3 and the magic number 0x8000 in either byte
//!   order; otherwise the whole datagram is refused ([`Rejection`]) and none of it is read:
//!   without the header neither byte order nor version is known;
//! * after it, each packet is taken by its size byte: a size below 2 (0 is the classic
//!   endless loop) or past the end of the datagram stops the walk there ([`Stop`]), the packets
//!   before it stand;
//! * an ID relief does not handle is skipped by its size ([`Walk::unknown`]); a handled ID
//!   whose size is below its layout is skipped ([`Walk::short`]); a larger size is read by the
//!   layout and the rest skipped (a later minor version's additions); a second header is
//!   skipped ([`Walk::misplaced_header`]).

use super::host::*;
use super::ig::*;
use super::packet::{Direction, Kind, Packet};
use super::wire::{ByteOrder, Reader};

/// Why a datagram was refused as a whole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    /// Fewer than 8 bytes, or a header packet whose size byte is below 24 or past the end.
    Short,
    /// The first packet is not the direction's header (its ID given).
    NoHeader(u8),
    /// CIGI version other than 3.
    Version(u8),
    /// Minor version other than 2 or 3.
    MinorVersion(u8),
    /// The magic number is neither 0x8000 nor 0x0080.
    Magic([u8; 2]),
}

impl std::fmt::Display for Rejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rejection::Short => write!(f, "datagram or header packet too short"),
            Rejection::NoHeader(id) => write!(f, "first packet has ID {id}, not the header"),
            Rejection::Version(v) => write!(f, "CIGI version {v}, relief reads 3"),
            Rejection::MinorVersion(v) => {
                write!(f, "CIGI minor version {v}, relief reads 3.2 and 3.3")
            }
            Rejection::Magic(b) => {
                write!(f, "magic number {b:02x?}, not 0x8000 in either byte order")
            }
        }
    }
}

/// Why the walk of a datagram's packets stopped before its end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// A size byte of 0 or 1.
    SizeBelowTwo,
    /// A size byte reaching past the end of the datagram.
    PastEnd,
    /// One byte left over: no room for ID and size.
    Trailing,
}

/// What walking one accepted datagram found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Walk {
    /// Packets taken by their size byte, the header included
    /// (`= decoded + unknown + short + misplaced_header`).
    pub packets: u32,
    /// Packets decoded, the header included.
    pub decoded: u32,
    /// IDs relief does not handle in this direction, skipped.
    pub unknown: u32,
    /// Handled IDs with a size below their layout, skipped.
    pub short: u32,
    /// A second header packet, skipped.
    pub misplaced_header: u32,
    /// Where the walk ended early, if it did.
    pub stop: Option<Stop>,
}

/// The packets of one direction: an enum over the packet structs.
pub trait PacketSet: Sized {
    const DIRECTION: Direction;
    const HEADER: Kind;
    /// The byte of the header holding the minor version in bits 4–7.
    const MINOR_BYTE: usize;
    /// Decodes packet bytes of a handled kind (at least its size long).
    fn decode(kind: Kind, bytes: &[u8], order: ByteOrder) -> Option<Self>;
    fn kind(&self) -> Kind;
    fn encode_into(&self, order: ByteOrder, out: &mut Vec<u8>);
}

macro_rules! packet_set {
    ($(#[$m:meta])* $name:ident, $dir:ident, $header:ident, $minor:literal { $($kind:ident),* $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub enum $name { $($kind($kind),)* }

        impl PacketSet for $name {
            const DIRECTION: Direction = Direction::$dir;
            const HEADER: Kind = Kind::$header;
            const MINOR_BYTE: usize = $minor;
            fn decode(kind: Kind, bytes: &[u8], order: ByteOrder) -> Option<Self> {
                match kind {
                    $(Kind::$kind => $kind::decode(bytes, order).map(Self::$kind),)*
                    _ => None,
                }
            }
            fn kind(&self) -> Kind {
                match self { $(Self::$kind(_) => Kind::$kind,)* }
            }
            fn encode_into(&self, order: ByteOrder, out: &mut Vec<u8>) {
                match self { $(Self::$kind(p) => p.encode_into(order, out),)* }
            }
        }
        $(impl From<$kind> for $name {
            fn from(p: $kind) -> Self { Self::$kind(p) }
        })*
    };
}

packet_set! {
    /// A host-to-IG packet.
    HostPacket, HostToIg, IgControl, 4 {
        IgControl, EntityControl, ConformalClampedEntityControl, RateControl,
        CelestialSphereControl, AtmosphereControl,
        WeatherControl, ViewControl, ViewDefinition, CollisionSegmentDefinition,
        CollisionVolumeDefinition, HatHotRequest,
        LosSegmentRequest,
        LosVectorRequest, PositionRequest,
    }
}

packet_set! {
    /// An IG-to-host packet.
    IgPacket, IgToHost, StartOfFrame, 5 {
        StartOfFrame, HatHotResponse, HatHotExtendedResponse, LosResponse, LosExtendedResponse,
        PositionResponse, CollisionSegmentNotification, CollisionVolumeNotification,
    }
}

/// One accepted datagram.
#[derive(Clone, Debug, PartialEq)]
pub struct Message<P> {
    pub order: ByteOrder,
    pub minor_version: u8,
    /// The decoded packets in order; the first is the header.
    pub packets: Vec<P>,
    pub walk: Walk,
}

/// A host-to-IG message.
pub type HostMessage = Message<HostPacket>;
/// An IG-to-host message.
pub type IgMessage = Message<IgPacket>;

/// Checks the header packet; its byte order, minor version and size.
fn header<P: PacketSet>(bytes: &[u8]) -> Result<(ByteOrder, u8, usize), Rejection> {
    if bytes.len() < 8 {
        return Err(Rejection::Short);
    }
    if bytes[0] != P::HEADER.id() {
        return Err(Rejection::NoHeader(bytes[0]));
    }
    let size = usize::from(bytes[1]);
    if size < P::HEADER.size() || size > bytes.len() {
        return Err(Rejection::Short);
    }
    if bytes[2] != 3 {
        return Err(Rejection::Version(bytes[2]));
    }
    let order = ByteOrder::from_magic([bytes[6], bytes[7]])
        .ok_or(Rejection::Magic([bytes[6], bytes[7]]))?;
    let minor = Reader::new(bytes, order).bits(P::MINOR_BYTE, 4, 4);
    if !(2..=3).contains(&minor) {
        return Err(Rejection::MinorVersion(minor));
    }
    Ok((order, minor, size))
}

/// Reads one datagram of direction `P` (see the module's rules).
pub fn read_message<P: PacketSet>(bytes: &[u8]) -> Result<Message<P>, Rejection> {
    let (order, minor_version, header_size) = header::<P>(bytes)?;
    let mut packets = Vec::new();
    let mut walk = Walk::default();
    packets.extend(P::decode(P::HEADER, bytes, order));
    walk.packets = 1;
    walk.decoded = packets.len() as u32;
    let mut rest = &bytes[header_size..];
    while !rest.is_empty() {
        if rest.len() < 2 {
            walk.stop = Some(Stop::Trailing);
            break;
        }
        let size = usize::from(rest[1]);
        if size < 2 {
            walk.stop = Some(Stop::SizeBelowTwo);
            break;
        }
        let Some(p) = rest.get(..size) else {
            walk.stop = Some(Stop::PastEnd);
            break;
        };
        walk.packets += 1;
        match Kind::from_id(p[0], P::DIRECTION) {
            None => walk.unknown += 1,
            Some(k) if k == P::HEADER => walk.misplaced_header += 1,
            Some(k) => match P::decode(k, p, order) {
                Some(packet) => {
                    packets.push(packet);
                    walk.decoded += 1;
                }
                None => walk.short += 1,
            },
        }
        rest = &rest[size..];
    }
    Ok(Message {
        order,
        minor_version,
        packets,
        walk,
    })
}

/// Reads a host-to-IG datagram.
pub fn read_host_message(bytes: &[u8]) -> Result<HostMessage, Rejection> {
    read_message(bytes)
}

/// Reads an IG-to-host datagram.
pub fn read_ig_message(bytes: &[u8]) -> Result<IgMessage, Rejection> {
    read_message(bytes)
}

/// Assembles a datagram: the header first, then packets, in one byte order.
#[derive(Clone, Debug)]
pub struct MessageBuilder {
    order: ByteOrder,
    bytes: Vec<u8>,
}

/// The most bytes one UDP datagram carries over IPv4 (65,535 less the IP and UDP headers): a
/// message past it cannot be sent.
pub const DATAGRAM_LIMIT: usize = 65_507;

impl MessageBuilder {
    /// A host message starting with `ig_control`.
    pub fn host(ig_control: &IgControl, order: ByteOrder) -> Self {
        let mut bytes = Vec::with_capacity(256);
        ig_control.encode_into(order, &mut bytes);
        MessageBuilder { order, bytes }
    }

    /// An IG message starting with `start_of_frame`.
    pub fn ig(start_of_frame: &StartOfFrame, order: ByteOrder) -> Self {
        let mut bytes = Vec::with_capacity(256);
        start_of_frame.encode_into(order, &mut bytes);
        MessageBuilder { order, bytes }
    }

    /// Appends one packet.
    pub fn push(&mut self, p: &impl Packet) -> &mut Self {
        p.encode_into(self.order, &mut self.bytes);
        self
    }

    /// Appends one packet of either direction's enum.
    pub fn push_any(&mut self, p: &impl PacketSet) -> &mut Self {
        p.encode_into(self.order, &mut self.bytes);
        self
    }

    /// Whether `bytes` more still fit in one datagram ([`DATAGRAM_LIMIT`]).
    pub fn fits(&self, bytes: usize) -> bool {
        self.bytes.len() + bytes <= DATAGRAM_LIMIT
    }

    /// Bytes so far.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Drops the packets pushed after the first `len` bytes (a [`Self::len`] taken before).
    pub fn truncate(&mut self, len: usize) {
        self.bytes.truncate(len);
    }

    /// The datagram.
    pub fn finish(self) -> Vec<u8> {
        self.bytes
    }
}
