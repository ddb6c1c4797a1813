//! The CIGI 3.3 wire layer of relief's image generator (issue 21, first part): the packets a
//! host sends an IG and the IG's answers, read and written in either byte order, and a pure
//! [`Session`] holding the host's state. No sockets and no rendering here
//! ([docs/cigi.md](../../docs/cigi.md)).
//!
//! * [`wire`]: byte order (from the magic number) and the bounded field reader and writer;
//! * [`packet`]: the kinds, their IDs and sizes, the [`Packet`] trait;
//! * [`host`], [`ig`]: the packet structs of each direction;
//! * [`message`]: a datagram read packet by packet by the size bytes (the rules for malformed
//!   input), and the builder of outgoing datagrams;
//! * [`session`], [`entity`]: the host state a stream of datagrams leaves, with counters, the
//!   query queue and entity poses at a given time;
//! * [`clock`]: local time → host time, without steps;
//! * [`pcap`]: a capture writer so Wireshark/tshark can decode relief's traffic.

#[macro_use]
pub mod packet;
pub mod clock;
pub mod entity;
pub mod host;
pub mod ig;
pub mod message;
pub mod pcap;
pub mod session;
pub mod wire;

pub use entity::{Entity, EntityState, Pose, Rates};
pub use host::*;
pub use ig::*;
pub use message::{
    read_host_message, read_ig_message, HostMessage, HostPacket, IgMessage, IgPacket,
    MessageBuilder, PacketSet, Rejection, Stop, Walk, DATAGRAM_LIMIT,
};
pub use packet::{Direction, Kind, Packet};
pub use session::{Counters, Query, Session};
pub use wire::{ByteOrder, MAGIC};
