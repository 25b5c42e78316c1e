//! The 15 EtherCAT commands, their addressing kind and working-counter rules
//! (ESC datasheet Section I Tables 5 and 7; docs/background/wire-format.md §1.4).

use super::{Error, Result};
use core::fmt;

/// How a command interprets the 4 address bytes of a datagram. REQ-WIRE-031
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Addressing {
    /// Auto-increment: ADP = −position, every ESC increments it, the one that sees 0 acts.
    Position,
    /// Configured station address (or alias) in ADP; ADP is not modified.
    Configured,
    /// Every ESC acts; ADP is incremented by each ESC (so a reply carries the slave count).
    Broadcast,
    /// One 32-bit logical address mapped by FMMUs.
    Logical,
    /// NOP: the address bytes carry nothing.
    None,
}

/// An EtherCAT command code (0..=14). Codes above 14 are rejected with
/// [`Error::UnknownCommand`] (REQ-WIRE-017); a view still exposes the raw byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Command {
    /// No operation: slaves ignore the datagram.
    Nop = 0,
    /// Auto-increment physical read.
    Aprd = 1,
    /// Auto-increment physical write.
    Apwr = 2,
    /// Auto-increment physical read-write.
    Aprw = 3,
    /// Configured-address physical read.
    Fprd = 4,
    /// Configured-address physical write.
    Fpwr = 5,
    /// Configured-address physical read-write.
    Fprw = 6,
    /// Broadcast read (data = data_in OR memory of every slave).
    Brd = 7,
    /// Broadcast write.
    Bwr = 8,
    /// Broadcast read-write.
    Brw = 9,
    /// Logical memory read.
    Lrd = 10,
    /// Logical memory write.
    Lwr = 11,
    /// Logical memory read-write.
    Lrw = 12,
    /// Auto-increment read, multiple write (the addressed slave reads, all others write).
    Armw = 13,
    /// Configured-address read, multiple write (the addressed slave reads, all others write).
    Frmw = 14,
}

impl Command {
    /// Every command, in code order (handy for exhaustive tests and the tshark check).
    pub const ALL: [Command; 15] = [
        Command::Nop,
        Command::Aprd,
        Command::Apwr,
        Command::Aprw,
        Command::Fprd,
        Command::Fpwr,
        Command::Fprw,
        Command::Brd,
        Command::Bwr,
        Command::Brw,
        Command::Lrd,
        Command::Lwr,
        Command::Lrw,
        Command::Armw,
        Command::Frmw,
    ];

    /// Decodes a command byte. REQ-WIRE-017
    pub fn from_u8(code: u8) -> Result<Command> {
        match Command::ALL.get(usize::from(code)) {
            Some(c) => Ok(*c),
            None => Err(Error::UnknownCommand { code }),
        }
    }

    /// The command byte.
    #[inline]
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// Short upper-case name as Wireshark prints it ("FRMW").
    pub const fn name(self) -> &'static str {
        match self {
            Command::Nop => "NOP",
            Command::Aprd => "APRD",
            Command::Apwr => "APWR",
            Command::Aprw => "APRW",
            Command::Fprd => "FPRD",
            Command::Fpwr => "FPWR",
            Command::Fprw => "FPRW",
            Command::Brd => "BRD",
            Command::Bwr => "BWR",
            Command::Brw => "BRW",
            Command::Lrd => "LRD",
            Command::Lwr => "LWR",
            Command::Lrw => "LRW",
            Command::Armw => "ARMW",
            Command::Frmw => "FRMW",
        }
    }

    /// How this command reads the 4 address bytes. REQ-WIRE-031
    pub const fn addressing(self) -> Addressing {
        match self {
            Command::Nop => Addressing::None,
            Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => Addressing::Position,
            Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => Addressing::Configured,
            Command::Brd | Command::Bwr | Command::Brw => Addressing::Broadcast,
            Command::Lrd | Command::Lwr | Command::Lrw => Addressing::Logical,
        }
    }

    /// True if an addressed slave may read its memory into the datagram (xxRD, xxRW, xRMW).
    pub const fn is_read(self) -> bool {
        matches!(
            self,
            Command::Aprd
                | Command::Aprw
                | Command::Fprd
                | Command::Fprw
                | Command::Brd
                | Command::Brw
                | Command::Lrd
                | Command::Lrw
                | Command::Armw
                | Command::Frmw
        )
    }

    /// True if a slave may write the datagram data into its memory (xxWR, xxRW, xRMW).
    pub const fn is_write(self) -> bool {
        matches!(
            self,
            Command::Apwr
                | Command::Aprw
                | Command::Fpwr
                | Command::Fprw
                | Command::Bwr
                | Command::Brw
                | Command::Lwr
                | Command::Lrw
                | Command::Armw
                | Command::Frmw
        )
    }

    /// True for APRW, FPRW, BRW and LRW, whose WKC counts reads +1 and writes +2.
    pub const fn is_read_write(self) -> bool {
        matches!(
            self,
            Command::Aprw | Command::Fprw | Command::Brw | Command::Lrw
        )
    }

    /// True if every ESC increments ADP as the datagram passes (position and broadcast
    /// addressing, including ARMW). REQ-WIRE-032
    pub const fn increments_adp(self) -> bool {
        matches!(
            self.addressing(),
            Addressing::Position | Addressing::Broadcast
        )
    }

    /// What one slave adds to the WKC, given whether it read and/or wrote at least one byte of
    /// this datagram (ESC datasheet Table 5). REQ-WIRE-050
    ///
    /// - read-only commands: +1 if read; write-only: +1 if written;
    /// - APRW/FPRW/BRW/LRW: +1 read, +2 write, +3 both;
    /// - ARMW/FRMW: +1 if the slave read (the addressed one) or wrote (every other one);
    /// - NOP: 0.
    pub const fn wkc_increment(self, did_read: bool, did_write: bool) -> u16 {
        match self {
            Command::Nop => 0,
            Command::Armw | Command::Frmw => (did_read || did_write) as u16,
            c if c.is_read_write() => (did_read as u16) | ((did_write as u16) << 1),
            c if c.is_read() => did_read as u16,
            _ => did_write as u16,
        }
    }

    /// Expected WKC when `addressed_slaves` slaves each fully take part (each one reads and/or
    /// writes as the command allows). Saturates at `u16::MAX`. REQ-WIRE-051
    ///
    /// - NOP: 0;
    /// - APxx/FPxx: `addressed_slaves` is 0 or 1 in practice (one station per address);
    /// - read-only / write-only / ARMW / FRMW: `addressed_slaves`
    ///   (FRMW to 0x0910 → number of DC slaves; BRD → number of slaves);
    /// - APRW/FPRW/BRW/LRW: `3 × addressed_slaves` (each reads and writes).
    ///
    /// For LRW with slaves that only have inputs or only outputs use [`Command::lrw_expected_wkc`].
    pub const fn expected_wkc(self, addressed_slaves: u16) -> u16 {
        let per = self.wkc_increment(true, true);
        per.saturating_mul(addressed_slaves)
    }

    /// Expected WKC of a logical datagram: +2 per slave whose write (output) FMMU it hits, +1
    /// per slave whose read (input) FMMU it hits; a slave with both counts 3. Saturates.
    /// REQ-WIRE-051
    pub const fn lrw_expected_wkc(write_slaves: u16, read_slaves: u16) -> u16 {
        write_slaves.saturating_mul(2).saturating_add(read_slaves)
    }
}

impl From<Command> for u8 {
    fn from(c: Command) -> u8 {
        c.code()
    }
}

impl TryFrom<u8> for Command {
    type Error = Error;
    fn try_from(code: u8) -> Result<Command> {
        Command::from_u8(code)
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A command displays as its name.
    #[test]
    fn display_is_the_name() {
        assert_eq!(std::format!("{}", Command::Frmw), "FRMW");
    }

    /// REQ-WIRE-017: codes 0..=14 decode to the command with that code, 15..=255 are errors.
    // verifies: REQ-WIRE-017
    #[test]
    fn every_code() {
        for code in 0..=255u8 {
            match Command::from_u8(code) {
                Ok(c) => {
                    assert!(code <= 14);
                    assert_eq!(c.code(), code);
                }
                Err(e) => {
                    assert!(code > 14);
                    assert_eq!(e, Error::UnknownCommand { code });
                }
            }
        }
    }

    /// REQ-WIRE-031: the addressing table, written out independently of `addressing()`.
    // verifies: REQ-WIRE-031
    #[test]
    fn addressing_table() {
        use Addressing::*;
        let expected = [
            None, Position, Position, Position, Configured, Configured, Configured, Broadcast,
            Broadcast, Broadcast, Logical, Logical, Logical, Position, Configured,
        ];
        for (c, a) in Command::ALL.iter().zip(expected) {
            assert_eq!(c.addressing(), a, "{c}");
        }
        let names = [
            "NOP", "APRD", "APWR", "APRW", "FPRD", "FPWR", "FPRW", "BRD", "BWR", "BRW", "LRD",
            "LWR", "LRW", "ARMW", "FRMW",
        ];
        for (c, n) in Command::ALL.iter().zip(names) {
            assert_eq!(c.name(), n);
        }
    }

    /// REQ-WIRE-050/051: WKC rules from ESC datasheet Table 5.
    // verifies: REQ-WIRE-050
    #[test]
    fn wkc_rules() {
        assert_eq!(Command::Nop.expected_wkc(5), 0);
        assert_eq!(Command::Brd.expected_wkc(5), 5);
        assert_eq!(Command::Bwr.expected_wkc(5), 5);
        assert_eq!(Command::Brw.expected_wkc(5), 15);
        assert_eq!(Command::Fprd.expected_wkc(1), 1);
        assert_eq!(Command::Fpwr.expected_wkc(1), 1);
        assert_eq!(Command::Aprw.expected_wkc(1), 3);
        assert_eq!(Command::Frmw.expected_wkc(4), 4);
        assert_eq!(Command::Armw.expected_wkc(4), 4);
        assert_eq!(Command::Lrw.expected_wkc(2), 6);
        assert_eq!(Command::lrw_expected_wkc(2, 3), 7);
        assert_eq!(Command::Brd.expected_wkc(u16::MAX), u16::MAX);
        assert_eq!(Command::Brw.expected_wkc(u16::MAX), u16::MAX);
        // per-slave increments
        assert_eq!(Command::Lrw.wkc_increment(true, false), 1);
        assert_eq!(Command::Lrw.wkc_increment(false, true), 2);
        assert_eq!(Command::Lrw.wkc_increment(true, true), 3);
        assert_eq!(Command::Lrd.wkc_increment(false, true), 0);
        assert_eq!(Command::Lwr.wkc_increment(true, false), 0);
        assert_eq!(Command::Frmw.wkc_increment(false, true), 1);
        assert_eq!(Command::Frmw.wkc_increment(true, false), 1);
        assert_eq!(Command::Nop.wkc_increment(true, true), 0);
        for c in Command::ALL {
            assert_eq!(c.wkc_increment(false, false), 0);
        }
    }

    /// Which commands read, write or both (the classes REQ-WIRE-050's WKC rules are stated
    /// over), written out per code independently of the `matches!` lists: R = read, W = write.
    // verifies: REQ-WIRE-050
    #[test]
    fn read_write_classes() {
        let expected = [
            "", "R", "W", "RW", "R", "W", "RW", "R", "W", "RW", "R", "W", "RW", "RW*", "RW*",
        ];
        for (c, e) in Command::ALL.iter().zip(expected) {
            assert_eq!(c.is_read(), e.contains('R'), "{c} read");
            assert_eq!(c.is_write(), e.contains('W'), "{c} write");
            // ARMW/FRMW read on one slave and write on the others: not an RW command.
            assert_eq!(c.is_read_write(), e == "RW", "{c} read-write");
        }
    }

    /// REQ-WIRE-032: exactly the position (APxx, ARMW) and broadcast (Bxx) commands have their
    /// ADP incremented; table by code, independent of `addressing()`.
    // verifies: REQ-WIRE-032
    #[test]
    fn adp_increment_table() {
        let expected = [
            false, true, true, true, false, false, false, true, true, true, false, false, false,
            true, false,
        ];
        for (c, e) in Command::ALL.iter().zip(expected) {
            assert_eq!(c.increments_adp(), e, "{c}");
        }
    }

    /// REQ-WIRE-017: the `u8` conversions carry the wire code both ways.
    // verifies: REQ-WIRE-017
    #[test]
    fn u8_conversions() {
        for (code, c) in (0u8..).zip(Command::ALL) {
            assert_eq!(u8::from(c), code, "{c}");
            assert_eq!(Command::try_from(code), Ok(c));
        }
        assert_eq!(
            Command::try_from(15),
            Err(Error::UnknownCommand { code: 15 })
        );
    }

    /// REQ-WIRE-050: every command and every (read, wrote) pair against a table written from
    /// ESC datasheet Table 5.
    // verifies: REQ-WIRE-050
    #[test]
    fn wkc_increment_every_case() {
        for c in Command::ALL {
            // [neither, read only, write only, both]
            let expected: [u16; 4] = match c {
                Command::Nop => [0, 0, 0, 0],
                Command::Aprw | Command::Fprw | Command::Brw | Command::Lrw => [0, 1, 2, 3],
                Command::Armw | Command::Frmw => [0, 1, 1, 1],
                Command::Aprd | Command::Fprd | Command::Brd | Command::Lrd => [0, 1, 0, 1],
                Command::Apwr | Command::Fpwr | Command::Bwr | Command::Lwr => [0, 0, 1, 1],
            };
            let got = [
                c.wkc_increment(false, false),
                c.wkc_increment(true, false),
                c.wkc_increment(false, true),
                c.wkc_increment(true, true),
            ];
            assert_eq!(got, expected, "{c}");
        }
    }
}
