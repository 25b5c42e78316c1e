//! EtherCAT over UDP: an Ethernet II / IPv4 / UDP frame whose UDP payload is an EtherCAT header
//! plus datagrams (port 0x88A4 = 34980). Used to build test captures and to let `ecdc decode`
//! unwrap such frames; the EtherCAT part is then parsed by the same `ecdc_core::wire` views.

use ecdc_core::wire::UDP_PORT_ETHERCAT;

/// IPv4 EtherType.
pub const ETHERTYPE_IPV4: u16 = 0x0800;
/// IP protocol number of UDP.
pub const IPPROTO_UDP: u8 = 17;

/// Builds Ethernet + IPv4 (no options, checksum filled) + UDP (checksum 0 = none, allowed over
/// IPv4) around `ecat_payload`, from `src_ip:34980` to `dst_ip:34980`.
pub fn wrap(
    dst_mac: [u8; 6],
    src_mac: [u8; 6],
    src_ip: [u8; 4],
    dst_ip: [u8; 4],
    ecat_payload: &[u8],
) -> Vec<u8> {
    let udp_len = u16::try_from(8 + ecat_payload.len()).expect("payload fits a UDP datagram");
    let ip_len = udp_len + 20;
    let mut f = Vec::with_capacity(14 + usize::from(ip_len));
    f.extend_from_slice(&dst_mac);
    f.extend_from_slice(&src_mac);
    f.extend_from_slice(&ETHERTYPE_IPV4.to_be_bytes());
    let mut ip = [0u8; 20];
    ip[0] = 0x45; // version 4, IHL 5
    ip[2..4].copy_from_slice(&ip_len.to_be_bytes());
    ip[6] = 0x40; // don't fragment
    ip[8] = 64; // TTL
    ip[9] = IPPROTO_UDP;
    ip[12..16].copy_from_slice(&src_ip);
    ip[16..20].copy_from_slice(&dst_ip);
    let sum = ipv4_checksum(&ip);
    ip[10..12].copy_from_slice(&sum.to_be_bytes());
    f.extend_from_slice(&ip);
    f.extend_from_slice(&UDP_PORT_ETHERCAT.to_be_bytes());
    f.extend_from_slice(&UDP_PORT_ETHERCAT.to_be_bytes());
    f.extend_from_slice(&udp_len.to_be_bytes());
    f.extend_from_slice(&[0, 0]);
    f.extend_from_slice(ecat_payload);
    if f.len() < 60 {
        f.resize(60, 0);
    }
    f
}

/// The Internet checksum of an IPv4 header whose checksum field is zero.
pub fn ipv4_checksum(header: &[u8]) -> u16 {
    let mut sum: u32 = header
        .chunks(2)
        .map(|c| u32::from(u16::from_be_bytes([c[0], *c.get(1).unwrap_or(&0)])))
        .sum();
    while sum > 0xFFFF {
        sum = (sum & 0xFFFF) + (sum >> 16);
    }
    !(sum as u16)
}

/// Where the EtherCAT payload of a UDP frame is, and its IP endpoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UdpEcat {
    /// Offset of the EtherCAT header in the frame.
    pub offset: usize,
    /// Length of the UDP payload.
    pub len: usize,
    /// Source IPv4 address.
    pub src_ip: [u8; 4],
    /// Destination IPv4 address.
    pub dst_ip: [u8; 4],
}

/// If `frame` is Ethernet (optionally one 802.1Q tag) / IPv4 / UDP with source or destination
/// port 0x88A4, returns where its EtherCAT payload lies; `None` otherwise or if truncated.
pub fn unwrap(frame: &[u8]) -> Option<UdpEcat> {
    let mut at = 12;
    let mut ethertype = u16::from_be_bytes([*frame.get(at)?, *frame.get(at + 1)?]);
    if ethertype == ecdc_core::wire::ETHERTYPE_VLAN {
        at += 4;
        ethertype = u16::from_be_bytes([*frame.get(at)?, *frame.get(at + 1)?]);
    }
    if ethertype != ETHERTYPE_IPV4 {
        return None;
    }
    let ip = frame.get(at + 2..)?;
    let ihl = usize::from(ip.first()? & 0x0F) * 4;
    if ip.first()? >> 4 != 4 || ihl < 20 || *ip.get(9)? != IPPROTO_UDP {
        return None;
    }
    let src_ip = ip.get(12..16)?.try_into().ok()?;
    let dst_ip = ip.get(16..20)?.try_into().ok()?;
    let udp = ip.get(ihl..)?;
    let sport = u16::from_be_bytes([*udp.first()?, *udp.get(1)?]);
    let dport = u16::from_be_bytes([*udp.get(2)?, *udp.get(3)?]);
    let ulen = usize::from(u16::from_be_bytes([*udp.get(4)?, *udp.get(5)?]));
    if sport != UDP_PORT_ETHERCAT && dport != UDP_PORT_ETHERCAT {
        return None;
    }
    let len = ulen.checked_sub(8)?;
    let offset = at + 2 + ihl + 8;
    frame.get(offset..offset + len)?;
    Some(UdpEcat {
        offset,
        len,
        src_ip,
        dst_ip,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_unwrap() {
        let payload = [0x0e, 0x10, 7, 1, 0, 0, 0x30, 1, 2, 0, 0, 0, 0, 0, 0, 0];
        let f = wrap([0xff; 6], [0x10; 6], [10, 0, 0, 1], [10, 0, 0, 2], &payload);
        let u = unwrap(&f).unwrap();
        assert_eq!(&f[u.offset..u.offset + u.len], &payload);
        assert_eq!(u.src_ip, [10, 0, 0, 1]);
        // the IPv4 header checksum verifies (sum over the header with checksum is 0xFFFF)
        assert_eq!(ipv4_checksum(&f[14..34]), 0);
        assert!(unwrap(&f[..40]).is_none());
    }
}
