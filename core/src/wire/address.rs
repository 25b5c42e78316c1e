//! The 4 address bytes of a datagram, typed by the command's addressing kind.
//!
//! On the wire the bytes are ADP (LE u16 at offset 2) then ADO (LE u16 at offset 4); a logical
//! address is the same 4 bytes read as one LE u32, so ADP is its low half (REQ-WIRE-031).

use super::{Addressing, Command, Error, Result};

/// A typed datagram address. Convert to/from the raw LE u32 with [`Address::to_raw`] and
/// [`Address::from_raw`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Address {
    /// Auto-increment (APxx, ARMW): `adp` is the two's complement of the position
    /// (0 = first slave, 0xFFFF = second, ...). Use [`Address::position`].
    Position {
        /// Auto-increment position field as on the wire.
        adp: u16,
        /// Register (physical memory) offset.
        ado: u16,
    },
    /// Configured station address (FPxx, FRMW).
    Configured {
        /// Configured station address or alias.
        station: u16,
        /// Register offset.
        ado: u16,
    },
    /// Broadcast (Bxx). `adp` is what is on the wire: a master sends 0 and every ESC
    /// increments it, so a reply carries the number of slaves passed.
    Broadcast {
        /// Position field as on the wire (0 when sent).
        adp: u16,
        /// Register offset.
        ado: u16,
    },
    /// Logical address (Lxx).
    Logical(u32),
    /// The 4 bytes uninterpreted: what NOP carries. Accepted for any command on emit (an
    /// escape hatch for tests and forwarding), produced by `parse` only for NOP.
    Raw(u32),
}

impl Address {
    /// Auto-increment address of the slave at 0-based `position`: ADP = −position.
    pub const fn position(position: u16, ado: u16) -> Address {
        Address::Position {
            adp: 0u16.wrapping_sub(position),
            ado,
        }
    }

    /// Configured-station address.
    pub const fn configured(station: u16, ado: u16) -> Address {
        Address::Configured { station, ado }
    }

    /// Broadcast address as a master sends it (ADP 0).
    pub const fn broadcast(ado: u16) -> Address {
        Address::Broadcast { adp: 0, ado }
    }

    /// Logical address.
    pub const fn logical(addr: u32) -> Address {
        Address::Logical(addr)
    }

    /// The 0-based position an auto-increment ADP designates (inverse of [`Address::position`]).
    pub const fn position_of_adp(adp: u16) -> u16 {
        0u16.wrapping_sub(adp)
    }

    /// Interprets the raw LE u32 (ADP in the low half) for `command`.
    pub const fn from_raw(command: Command, raw: u32) -> Address {
        let [a0, a1, o0, o1] = raw.to_le_bytes();
        let adp = u16::from_le_bytes([a0, a1]);
        let ado = u16::from_le_bytes([o0, o1]);
        match command.addressing() {
            Addressing::Position => Address::Position { adp, ado },
            Addressing::Configured => Address::Configured { station: adp, ado },
            Addressing::Broadcast => Address::Broadcast { adp, ado },
            Addressing::Logical => Address::Logical(raw),
            Addressing::None => Address::Raw(raw),
        }
    }

    /// The raw LE u32 as on the wire (ADP in the low half, ADO in the high half).
    pub const fn to_raw(self) -> u32 {
        match self {
            Address::Position { adp, ado }
            | Address::Configured { station: adp, ado }
            | Address::Broadcast { adp, ado } => (adp as u32) | ((ado as u32) << 16),
            Address::Logical(raw) | Address::Raw(raw) => raw,
        }
    }

    /// The addressing kind of this address (`None` for [`Address::Raw`]).
    pub const fn kind(self) -> Addressing {
        match self {
            Address::Position { .. } => Addressing::Position,
            Address::Configured { .. } => Addressing::Configured,
            Address::Broadcast { .. } => Addressing::Broadcast,
            Address::Logical(_) => Addressing::Logical,
            Address::Raw(_) => Addressing::None,
        }
    }

    /// The register offset, if this is a physical (non-logical) address.
    pub const fn ado(self) -> Option<u16> {
        match self {
            Address::Position { ado, .. }
            | Address::Configured { ado, .. }
            | Address::Broadcast { ado, .. } => Some(ado),
            Address::Logical(_) | Address::Raw(_) => None,
        }
    }

    /// Checks that this address may be sent with `command`: same addressing kind, or `Raw`.
    /// REQ-WIRE-031
    pub fn check_for(self, command: Command) -> Result<()> {
        match self {
            Address::Raw(_) => Ok(()),
            a if a.kind() == command.addressing() => Ok(()),
            _ => Err(Error::AddressMismatch),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn position_is_twos_complement() {
        assert_eq!(Address::position(0, 0x10).to_raw(), 0x0010_0000);
        assert_eq!(Address::position(1, 0x10).to_raw(), 0x0010_FFFF);
        assert_eq!(Address::position(2, 0).to_raw(), 0x0000_FFFE);
        for p in [0u16, 1, 2, 100, 0xFFFF] {
            let Address::Position { adp, .. } = Address::position(p, 0) else {
                panic!()
            };
            assert_eq!(Address::position_of_adp(adp), p);
        }
    }

    /// REQ-WIRE-031: ADP is the low half of the logical address (tshark: ADP 0, ADO 1 shows as
    /// lad 0x00010000).
    // verifies: REQ-WIRE-031
    #[test]
    fn raw_roundtrip_all_kinds() {
        let raw = 0x0001_0000;
        assert_eq!(
            Address::from_raw(Command::Fprd, raw),
            Address::Configured { station: 0, ado: 1 }
        );
        assert_eq!(Address::from_raw(Command::Lrw, raw), Address::Logical(raw));
        for c in Command::ALL {
            for raw in [0u32, 1, 0xFFFF, 0x1234_5678, u32::MAX] {
                let a = Address::from_raw(c, raw);
                assert_eq!(a.to_raw(), raw);
                assert!(a.check_for(c).is_ok());
            }
        }
        assert_eq!(
            Address::position(0, 0).check_for(Command::Fprd),
            Err(Error::AddressMismatch)
        );
        assert!(Address::Raw(7).check_for(Command::Fprd).is_ok());
    }
}
