//! How an ESC finds the datagrams in a frame: the way the hardware does, not the way a strict
//! codec does. The processing unit follows the M (more) bit from datagram to datagram and does
//! not check the EtherCAT header length; frames shorter than 60 bytes are accepted (veth and
//! host captures are unpadded). A datagram that runs past the end of the frame makes the frame
//! invalid: the ESC forwards it but commits nothing (as for an FCS error). REQ-ESC-001.
//!
//! This is deliberately independent of `ecdc_core::wire`, whose job is to *reject* malformed
//! frames; an emulator must process whatever a master sends, exactly like a slave would.

/// EtherType of EtherCAT frames.
pub const ETHERTYPE_ECAT: u16 = 0x88A4;
const ETHERTYPE_VLAN: u16 = 0x8100;
/// Datagram header length.
pub const DG_HEADER: usize = 10;

/// Command codes (docs/background/wire-format.md §1.4), in wire-code order from 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cmd {
    /// No operation.
    Nop,
    /// Auto-increment physical read, write, read-write.
    Aprd,
    Apwr,
    Aprw,
    /// Configured-address physical read, write, read-write.
    Fprd,
    Fpwr,
    Fprw,
    /// Broadcast read, write, read-write.
    Brd,
    Bwr,
    Brw,
    /// Logical read, write, read-write.
    Lrd,
    Lwr,
    Lrw,
    /// Auto-increment / configured-address read, multiple write.
    Armw,
    Frmw,
}

impl Cmd {
    /// The command with wire code `code`; `None` for the reserved codes (15 and above), which
    /// an ESC passes on untouched.
    pub fn from_code(code: u8) -> Option<Cmd> {
        use Cmd::*;
        const BY_CODE: [Cmd; 15] = [
            Nop, Aprd, Apwr, Aprw, Fprd, Fpwr, Fprw, Brd, Bwr, Brw, Lrd, Lwr, Lrw, Armw, Frmw,
        ];
        BY_CODE.get(usize::from(code)).copied()
    }
}

/// Where one datagram sits in the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DgSpan {
    /// Offset of the 10-byte header.
    pub start: usize,
    /// Data length (11-bit field).
    pub len: usize,
}

impl DgSpan {
    /// Offset of the data.
    pub fn data(&self) -> usize {
        self.start + DG_HEADER
    }
    /// Offset of the working counter.
    pub fn wkc(&self) -> usize {
        self.start + DG_HEADER + self.len
    }
}

/// Result of looking at a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameClass {
    /// An EtherCAT type-1 frame whose datagrams are in the span list.
    Ecat,
    /// Forwarded without processing (not EtherCAT, other frame type, or malformed).
    Forward(ForwardReason),
}

/// Why a frame is forwarded without processing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForwardReason {
    /// Shorter than an Ethernet + EtherCAT header.
    Runt,
    /// EtherType is not 0x88A4.
    NotEtherCat,
    /// EtherCAT header type is not 1 (DLPDU).
    NotDlpdu,
    /// A datagram runs past the end of the frame.
    Truncated,
}

/// Finds the datagrams of `frame`, writing their spans into `spans` (cleared first).
pub fn walk(frame: &[u8], spans: &mut Vec<DgSpan>) -> FrameClass {
    spans.clear();
    if frame.len() < 14 {
        return FrameClass::Forward(ForwardReason::Runt);
    }
    let mut et = u16::from_be_bytes([frame[12], frame[13]]);
    let mut off = 14;
    if et == ETHERTYPE_VLAN {
        if frame.len() < 18 {
            return FrameClass::Forward(ForwardReason::Runt);
        }
        et = u16::from_be_bytes([frame[16], frame[17]]);
        off = 18;
    }
    if et != ETHERTYPE_ECAT {
        return FrameClass::Forward(ForwardReason::NotEtherCat);
    }
    if frame.len() < off + 2 {
        return FrameClass::Forward(ForwardReason::Runt);
    }
    let hdr = u16::from_le_bytes([frame[off], frame[off + 1]]);
    if hdr >> 12 != 1 {
        return FrameClass::Forward(ForwardReason::NotDlpdu);
    }
    off += 2;
    loop {
        if off + DG_HEADER + 2 > frame.len() {
            spans.clear();
            return FrameClass::Forward(ForwardReason::Truncated);
        }
        let lf = u16::from_le_bytes([frame[off + 6], frame[off + 7]]);
        let len = usize::from(lf & 0x07FF);
        if off + DG_HEADER + len + 2 > frame.len() {
            spans.clear();
            return FrameClass::Forward(ForwardReason::Truncated);
        }
        spans.push(DgSpan { start: off, len });
        off += DG_HEADER + len + 2;
        if lf & 0x8000 == 0 {
            return FrameClass::Ecat;
        }
    }
}

/// Offset of the source MAC's first octet (its 0x02 bit is set by the first slave).
pub const SRC_MAC: usize = 6;
/// Circulating bit in the datagram length field (bit 14).
pub const CIRCULATING: u16 = 0x4000;

/// Frame duration on the wire in ns at 100 Mbit/s: preamble+SFD (8), frame padded to 60,
/// FCS (4), 80 ns per byte (docs/background/esc-registers.md §6; ESC datasheet Section I p.88).
pub fn wire_duration_ns(frame_len: usize) -> u64 {
    (8 + frame_len.max(60) + 4) as u64 * 80
}

/// Inter-frame gap: 96 bit times.
pub const IFG_NS: u64 = 960;

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn walks_by_more_bit_and_accepts_short_frames() {
        // 14 eth + 2 hdr + one 12-byte datagram (len 0) = 28 bytes, no padding.
        let mut f = vec![0u8; 28];
        f[12] = 0x88;
        f[13] = 0xA4;
        f[14] = 12;
        f[15] = 0x10;
        let mut s = Vec::new();
        assert_eq!(walk(&f, &mut s), FrameClass::Ecat);
        assert_eq!(s, vec![DgSpan { start: 16, len: 0 }]);
        // Set M on the only datagram: the next header would run past the end.
        f[16 + 7] = 0x80;
        assert_eq!(
            walk(&f, &mut s),
            FrameClass::Forward(ForwardReason::Truncated)
        );
        f[13] = 0x00;
        assert_eq!(
            walk(&f, &mut s),
            FrameClass::Forward(ForwardReason::NotEtherCat)
        );
        assert_eq!(
            walk(&f[..10], &mut s),
            FrameClass::Forward(ForwardReason::Runt)
        );
    }
}
