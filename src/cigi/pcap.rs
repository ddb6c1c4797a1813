//! A minimal pcap writer for looking at CIGI traffic in Wireshark/tshark: each datagram as a
//! raw IPv4/UDP frame (link type 101, no Ethernet header) between two loopback addresses.
//! Test and debugging aid; no capture, no sockets.

use crate::error::{Error, Result};

/// The host's address in written captures (127.0.0.1); the IG is 127.0.0.2.
pub const HOST_ADDR: [u8; 4] = [127, 0, 0, 1];
/// The IG's address in written captures.
pub const IG_ADDR: [u8; 4] = [127, 0, 0, 2];

/// One UDP datagram of a capture.
#[derive(Clone, Debug)]
pub struct UdpFrame<'a> {
    pub src: ([u8; 4], u16),
    pub dst: ([u8; 4], u16),
    /// Capture time in microseconds.
    pub time_us: u64,
    pub payload: &'a [u8],
}

const LINKTYPE_RAW: u32 = 101;
const IP_HEADER: usize = 20;
const UDP_HEADER: usize = 8;

/// The pcap file (classic format, microsecond timestamps) holding `frames`. A payload too
/// large for one IPv4 datagram is an [`Error::Limit`].
pub fn write_pcap(frames: &[UdpFrame<'_>]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for v in [0xa1b2_c3d4u32.to_le_bytes(), [2, 0, 4, 0]] {
        out.extend_from_slice(&v);
    }
    out.extend_from_slice(&0i32.to_le_bytes()); // thiszone
    out.extend_from_slice(&0u32.to_le_bytes()); // sigfigs
    out.extend_from_slice(&65535u32.to_le_bytes()); // snaplen
    out.extend_from_slice(&LINKTYPE_RAW.to_le_bytes());
    for f in frames {
        let total = IP_HEADER + UDP_HEADER + f.payload.len();
        if total > usize::from(u16::MAX) {
            return Err(Error::Limit {
                what: "pcap UDP payload".into(),
                msg: format!(
                    "{} bytes; an IPv4 datagram holds at most 65507",
                    f.payload.len()
                ),
            });
        }
        out.extend_from_slice(&((f.time_us / 1_000_000) as u32).to_le_bytes());
        out.extend_from_slice(&((f.time_us % 1_000_000) as u32).to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&ipv4_header(f, total as u16));
        out.extend_from_slice(&f.src.1.to_be_bytes());
        out.extend_from_slice(&f.dst.1.to_be_bytes());
        out.extend_from_slice(&((UDP_HEADER + f.payload.len()) as u16).to_be_bytes());
        out.extend_from_slice(&[0, 0]); // no UDP checksum (allowed over IPv4)
        out.extend_from_slice(f.payload);
    }
    Ok(out)
}

fn ipv4_header(f: &UdpFrame<'_>, total: u16) -> [u8; IP_HEADER] {
    let mut h = [0u8; IP_HEADER];
    h[0] = 0x45; // version 4, 5 words
    h[2..4].copy_from_slice(&total.to_be_bytes());
    h[6] = 0x40; // don't fragment
    h[8] = 64; // TTL
    h[9] = 17; // UDP
    h[12..16].copy_from_slice(&f.src.0);
    h[16..20].copy_from_slice(&f.dst.0);
    let mut sum: u32 = h
        .chunks(2)
        .map(|c| u32::from(u16::from_be_bytes([c[0], c[1]])))
        .sum();
    while sum > 0xffff {
        sum = (sum & 0xffff) + (sum >> 16);
    }
    h[10..12].copy_from_slice(&(!(sum as u16)).to_be_bytes());
    h
}
