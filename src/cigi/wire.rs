//! Byte order and the bounded field reader and writer the packets are built on.
//!
//! A CIGI message is written in the sender's native byte order; the receiver learns it from
//! the magic number 0x8000 in the first packet (IG Control or Start of Frame): read back as
//! 0x0080 it says the message is byte-swapped. Packet ID and size are single bytes, and so are
//! the bit fields, so only the multi-byte fields differ between the two orders.
//!
//! Readers and writers never index past their slice: a read past the end gives zero bytes and
//! a write past the end is dropped (the packet layer checks lengths first; this is the second
//! line of defence that keeps a layout mistake from ever becoming a panic).

/// The byte order of a CIGI message.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ByteOrder {
    /// Network order: what relief sends, and the ICD's reference order.
    #[default]
    Big,
    /// Byte-swapped: a little-endian host that does not swap.
    Little,
}

/// The value of the byte-swap magic number of IG Control and Start of Frame.
pub const MAGIC: u16 = 0x8000;

impl ByteOrder {
    /// The order a magic-number field's two bytes say: 0x80 0x00 is big-endian, 0x00 0x80
    /// little-endian; anything else is no CIGI 3 message.
    pub fn from_magic(bytes: [u8; 2]) -> Option<ByteOrder> {
        match bytes {
            [0x80, 0x00] => Some(ByteOrder::Big),
            [0x00, 0x80] => Some(ByteOrder::Little),
            _ => None,
        }
    }
}

/// A fixed-size value of the wire: how it is put into and read from a packet.
pub trait Field: Sized {
    fn put(self, w: &mut Writer<'_>, off: usize);
    fn get(r: &Reader<'_>, off: usize) -> Self;
}

/// A value held in a few bits of one byte.
pub trait Bits: Sized {
    fn to_bits(self) -> u8;
    fn from_bits(v: u8) -> Self;
}

impl Bits for u8 {
    fn to_bits(self) -> u8 {
        self
    }
    fn from_bits(v: u8) -> Self {
        v
    }
}

impl Bits for bool {
    fn to_bits(self) -> u8 {
        self as u8
    }
    fn from_bits(v: u8) -> Self {
        v != 0
    }
}

/// Writes fields into one packet's bytes in one byte order.
pub struct Writer<'a> {
    buf: &'a mut [u8],
    order: ByteOrder,
}

impl<'a> Writer<'a> {
    pub fn new(buf: &'a mut [u8], order: ByteOrder) -> Self {
        Writer { buf, order }
    }

    fn put_bytes<const N: usize>(&mut self, off: usize, be: [u8; N]) {
        let mut b = be;
        if self.order == ByteOrder::Little {
            b.reverse();
        }
        if let Some(dst) = self.buf.get_mut(off..off.saturating_add(N)) {
            dst.copy_from_slice(&b);
        }
    }

    /// ORs `v` (masked to `bits` bits) into byte `off` at bit `shift` (bit 0 the least
    /// significant).
    pub fn bits(&mut self, off: usize, shift: u32, bits: u32, v: u8) {
        let mask = ((1u16 << bits) - 1) as u8;
        if let Some(b) = self.buf.get_mut(off) {
            *b |= (v & mask) << shift;
        }
    }
}

/// Reads fields from one packet's bytes in one byte order.
pub struct Reader<'a> {
    buf: &'a [u8],
    order: ByteOrder,
}

impl<'a> Reader<'a> {
    pub fn new(buf: &'a [u8], order: ByteOrder) -> Self {
        Reader { buf, order }
    }

    fn get_bytes<const N: usize>(&self, off: usize) -> [u8; N] {
        let mut b = [0u8; N];
        if let Some(src) = self.buf.get(off..off.saturating_add(N)) {
            b.copy_from_slice(src);
        }
        if self.order == ByteOrder::Little {
            b.reverse();
        }
        b
    }

    /// Bits `shift..shift + bits` of byte `off`.
    pub fn bits(&self, off: usize, shift: u32, bits: u32) -> u8 {
        let mask = ((1u16 << bits) - 1) as u8;
        self.buf.get(off).map_or(0, |b| (b >> shift) & mask)
    }
}

macro_rules! wire_field {
    ($t:ty, $n:literal) => {
        impl Field for $t {
            fn put(self, w: &mut Writer<'_>, off: usize) {
                w.put_bytes::<$n>(off, self.to_be_bytes());
            }
            fn get(r: &Reader<'_>, off: usize) -> Self {
                <$t>::from_be_bytes(r.get_bytes::<$n>(off))
            }
        }
    };
}

wire_field!(u8, 1);
wire_field!(i8, 1);
wire_field!(u16, 2);
wire_field!(i16, 2);
wire_field!(u32, 4);
wire_field!(i32, 4);
wire_field!(f32, 4);
wire_field!(f64, 8);
