//! The packet kinds relief reads and writes, their IDs and sizes, and the [`Packet`] trait
//! every packet struct implements through the `cigi_packet!` macro (one line per field: its
//! byte offset and, for a bit field, its first bit and width).

use super::wire::{ByteOrder, Reader, Writer};

/// Who sends a packet kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    HostToIg,
    IgToHost,
}

macro_rules! kinds {
    ($($kind:ident = $id:literal, $size:literal, $dir:ident, $name:literal;)*) => {
        /// A CIGI 3.3 packet kind relief handles.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum Kind { $($kind,)* }

        impl Kind {
            /// Every kind, in the order of [`Kind::index`].
            pub const ALL: &'static [Kind] = &[$(Kind::$kind,)*];
            /// Packet ID (byte 0).
            pub const fn id(self) -> u8 {
                match self { $(Kind::$kind => $id,)* }
            }
            /// Packet size in bytes (byte 1) of the CIGI 3.3 layout.
            pub const fn size(self) -> usize {
                match self { $(Kind::$kind => $size,)* }
            }
            /// Who sends it.
            pub const fn direction(self) -> Direction {
                match self { $(Kind::$kind => Direction::$dir,)* }
            }
            /// The ICD's name.
            pub const fn name(self) -> &'static str {
                match self { $(Kind::$kind => $name,)* }
            }
        }
    };
}

kinds! {
    IgControl = 1, 24, HostToIg, "IG Control";
    EntityControl = 2, 48, HostToIg, "Entity Control";
    ConformalClampedEntityControl = 3, 24, HostToIg, "Conformal Clamped Entity Control";
    RateControl = 8, 32, HostToIg, "Rate Control";
    CelestialSphereControl = 9, 16, HostToIg, "Celestial Sphere Control";
    AtmosphereControl = 10, 32, HostToIg, "Atmosphere Control";
    WeatherControl = 12, 56, HostToIg, "Weather Control";
    ViewControl = 16, 32, HostToIg, "View Control";
    ViewDefinition = 21, 32, HostToIg, "View Definition";
    CollisionSegmentDefinition = 22, 40, HostToIg, "Collision Detection Segment Definition";
    CollisionVolumeDefinition = 23, 48, HostToIg, "Collision Detection Volume Definition";
    HatHotRequest = 24, 32, HostToIg, "HAT/HOT Request";
    LosSegmentRequest = 25, 64, HostToIg, "LOS Segment Request";
    LosVectorRequest = 26, 56, HostToIg, "LOS Vector Request";
    PositionRequest = 27, 8, HostToIg, "Position Request";
    StartOfFrame = 101, 24, IgToHost, "Start of Frame";
    HatHotResponse = 102, 16, IgToHost, "HAT/HOT Response";
    HatHotExtendedResponse = 103, 40, IgToHost, "HAT/HOT Extended Response";
    LosResponse = 104, 16, IgToHost, "LOS Response";
    LosExtendedResponse = 105, 56, IgToHost, "LOS Extended Response";
    PositionResponse = 108, 48, IgToHost, "Position Response";
    CollisionSegmentNotification = 113, 16, IgToHost, "Collision Detection Segment Notification";
    CollisionVolumeNotification = 114, 16, IgToHost, "Collision Detection Volume Notification";
}

impl Kind {
    /// Position in [`Kind::ALL`] (an index for per-kind counters).
    pub fn index(self) -> usize {
        Kind::ALL.iter().position(|&k| k == self).unwrap_or(0)
    }

    /// The kind of packet ID `id` sent in direction `dir`, if relief handles it.
    pub fn from_id(id: u8, dir: Direction) -> Option<Kind> {
        Kind::ALL
            .iter()
            .copied()
            .find(|k| k.id() == id && k.direction() == dir)
    }
}

/// A CIGI packet with a fixed layout.
pub trait Packet: Sized {
    const KIND: Kind;
    /// Writes the fields (not ID and size) into the zeroed packet bytes.
    fn write(&self, w: &mut Writer<'_>);
    /// Reads the fields from packet bytes at least [`Kind::size`] long.
    fn read(r: &Reader<'_>) -> Self;

    /// Appends the packet (ID, size, fields) in `order`. Bit-field values are masked to their
    /// width.
    fn encode_into(&self, order: ByteOrder, out: &mut Vec<u8>) {
        let start = out.len();
        let size = Self::KIND.size();
        out.resize(start + size, 0);
        let bytes = &mut out[start..];
        bytes[0] = Self::KIND.id();
        bytes[1] = size as u8;
        self.write(&mut Writer::new(bytes, order));
    }

    /// The packet alone, in `order`.
    fn encode(&self, order: ByteOrder) -> Vec<u8> {
        let mut out = Vec::with_capacity(Self::KIND.size());
        self.encode_into(order, &mut out);
        out
    }

    /// The packet read from `bytes` in `order`; `None` when the ID is not this kind's or the
    /// bytes (or the size byte) are shorter than the layout. Longer is accepted: the extra
    /// bytes are a later minor version's and ignored.
    fn decode(bytes: &[u8], order: ByteOrder) -> Option<Self> {
        let size = Self::KIND.size();
        let ok =
            bytes.len() >= size && bytes[0] == Self::KIND.id() && usize::from(bytes[1]) >= size;
        ok.then(|| Self::read(&Reader::new(bytes, order)))
    }
}

/// Declares a packet struct and its [`Packet`] impl. Each field is `name: type = offset`, a
/// bit field `name: u8|bool = offset [first_bit; width]`; `fixed { offset: type = value }`
/// are written on encode and not read back (version, magic number: the datagram reader checks
/// them).
macro_rules! cigi_packet {
    (
        $(#[$meta:meta])*
        $name:ident = $kind:ident {
            $( $(#[$fmeta:meta])* $field:ident : $ty:ty = $off:literal $([$shift:literal ; $width:literal])? ),* $(,)?
        }
        $( fixed { $( $foff:literal : $fty:ty = $fval:expr ),* $(,)? } )?
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, Default, PartialEq)]
        pub struct $name { $( $(#[$fmeta])* pub $field: $ty, )* }

        impl $crate::cigi::packet::Packet for $name {
            const KIND: $crate::cigi::packet::Kind = $crate::cigi::packet::Kind::$kind;
            fn write(&self, w: &mut $crate::cigi::wire::Writer<'_>) {
                $( $( $crate::cigi::wire::Field::put::<>(($fval) as $fty, w, $foff); )* )?
                $( cigi_packet!(@put w, self.$field, $off $(, $shift, $width)?); )*
            }
            fn read(r: &$crate::cigi::wire::Reader<'_>) -> Self {
                Self { $( $field: cigi_packet!(@get r, $ty, $off $(, $shift, $width)?), )* }
            }
        }
    };
    (@put $w:ident, $v:expr, $off:literal) => {
        $crate::cigi::wire::Field::put($v, $w, $off)
    };
    (@put $w:ident, $v:expr, $off:literal, $shift:literal, $width:literal) => {
        $w.bits($off, $shift, $width, $crate::cigi::wire::Bits::to_bits($v))
    };
    (@get $r:ident, $ty:ty, $off:literal) => {
        <$ty as $crate::cigi::wire::Field>::get($r, $off)
    };
    (@get $r:ident, $ty:ty, $off:literal, $shift:literal, $width:literal) => {
        <$ty as $crate::cigi::wire::Bits>::from_bits($r.bits($off, $shift, $width))
    };
}
