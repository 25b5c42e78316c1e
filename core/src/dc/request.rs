//! The datagrams the machine sends and the table that matches replies to them by index.
//!
//! A request is an [`Op`]: command, address, length and a small payload. Reads carry zeros;
//! writes carry at most 8 bytes, always exactly the width of the register written
//! (REQ-CONV-003). A reply is accepted only if its index is one the machine has in flight *and*
//! its command, register (ADO), station (for FP commands) and length equal the request's
//! (REQ-DC-113); anything else in a frame is someone else's datagram and is counted, not used.

use crate::wire::{Address, Command, Datagram, FrameBuilder};

/// Most datagrams of the machine in one frame. Per-slave steps on bigger networks take several
/// frames. ecdc choice: 32 datagrams of up to 44 bytes fit one 1 498-byte EtherCAT payload.
pub const MAX_INFLIGHT: usize = 32;

/// Payload of a request: zeros (reads, the latch trigger) or the first `len` bytes of a
/// little-endian integer (writes of exactly the register's width).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Payload {
    /// `len` zero bytes.
    Zero,
    /// The low `len` bytes of the value, little-endian (`len` ≤ 8).
    Le(u64),
}

/// One datagram the machine wants to send.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Op {
    /// Command.
    pub command: Command,
    /// Address (position, configured or broadcast; ADO = register).
    pub address: Address,
    /// Data length in bytes.
    pub len: u16,
    /// Data.
    pub payload: Payload,
}

impl Op {
    /// A read of `len` bytes at `reg` of the slave with station address `station`.
    pub const fn fprd(station: u16, reg: u16, len: u16) -> Op {
        Op {
            command: Command::Fprd,
            address: Address::configured(station, reg),
            len,
            payload: Payload::Zero,
        }
    }
    /// A write of the low `len` bytes of `value` at `reg` of `station`.
    pub const fn fpwr(station: u16, reg: u16, len: u16, value: u64) -> Op {
        Op {
            command: Command::Fpwr,
            address: Address::configured(station, reg),
            len,
            payload: Payload::Le(value),
        }
    }
    /// A broadcast read of `len` bytes at `reg`.
    pub const fn brd(reg: u16, len: u16) -> Op {
        Op {
            command: Command::Brd,
            address: Address::broadcast(reg),
            len,
            payload: Payload::Zero,
        }
    }
    /// A broadcast write of `len` zero bytes at `reg`.
    pub const fn bwr_zero(reg: u16, len: u16) -> Op {
        Op {
            command: Command::Bwr,
            address: Address::broadcast(reg),
            len,
            payload: Payload::Zero,
        }
    }
    /// FRMW of `len` bytes at `reg` of the reference `station`, payload pre-filled with `value`
    /// (slaves in front of the reference compare with it, KickCAT `sendDriftCompensation`).
    pub const fn frmw(station: u16, reg: u16, len: u16, value: u64) -> Op {
        Op {
            command: Command::Frmw,
            address: Address::configured(station, reg),
            len,
            payload: Payload::Le(value),
        }
    }

    /// Station address for FP commands, else 0.
    pub const fn station(&self) -> u16 {
        match self.address {
            Address::Configured { station, .. } => station,
            _ => 0,
        }
    }

    /// Register (ADO), 0 for logical addresses.
    pub fn register(&self) -> u16 {
        self.address.ado().unwrap_or(0)
    }

    /// Writes the datagram into `b` with `index`. Fails (frame unchanged) if it does not fit.
    pub fn emit(&self, b: &mut FrameBuilder<'_>, index: u8) -> crate::wire::Result<()> {
        match self.payload {
            Payload::Zero => b
                .push_zeroed(self.command, index, self.address, self.len)
                .map(|_| ()),
            Payload::Le(v) => {
                let bytes = v.to_le_bytes();
                let n = usize::from(self.len).min(bytes.len());
                let data = bytes.get(..n).unwrap_or(&[]);
                b.push(self.command, index, self.address, data).map(|_| ())
            }
        }
    }
}

/// What a reply belongs to, inside the current step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tag {
    /// Item number of the current request step.
    Item(u16),
    /// The FRMW that leads every drift-check frame and every cyclic frame.
    Frmw,
    /// Cyclic BRD 0x092C (upper bound; WKC = slaves with a system time).
    CycBound,
    /// Cyclic BRD 0x0130 (AL status): its WKC counts every slave, the topology check.
    CycTopology,
    /// Cyclic FPRD 0x092C of the slave at this table position.
    CycDiff(u16),
    /// Cyclic delay re-measurement item.
    CycRemeasure(u16),
}

/// A datagram in flight: enough to match its reply and route it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pending {
    /// Index sent.
    pub index: u8,
    /// Command sent.
    pub command: Command,
    /// Register (ADO) sent.
    pub register: u16,
    /// Station (FP commands) or 0.
    pub station: u16,
    /// Data length sent.
    pub len: u16,
    /// Where the reply goes.
    pub tag: Tag,
}

impl Pending {
    /// REQ-DC-113: a reply matches only if index, command, register, length and (for FP
    /// commands) station are those sent. Position/broadcast ADP is changed by the slaves and is
    /// therefore not compared.
    pub fn matches<T: AsRef<[u8]>>(&self, d: &Datagram<T>) -> bool {
        d.index() == self.index
            && d.command_raw() == self.command.code()
            && d.ado() == self.register
            && d.data_len() == self.len
            && (!matches!(
                self.command,
                Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw
            ) || d.adp() == self.station)
    }
}

/// The datagrams of one transmission still waiting for their reply.
#[derive(Debug, Clone)]
pub(crate) struct Inflight {
    pub(crate) entries: [Option<Pending>; MAX_INFLIGHT],
    pub(crate) deadline: u64,
}

impl Inflight {
    pub(crate) const fn new() -> Self {
        Inflight {
            entries: [None; MAX_INFLIGHT],
            deadline: 0,
        }
    }
    pub(crate) fn is_empty(&self) -> bool {
        self.entries.iter().all(Option::is_none)
    }
    pub(crate) fn has_room(&self) -> bool {
        self.entries.iter().any(Option::is_none)
    }
    pub(crate) fn insert(&mut self, p: Pending) -> bool {
        match self.entries.iter_mut().find(|e| e.is_none()) {
            Some(slot) => {
                *slot = Some(p);
                true
            }
            None => false,
        }
    }
    pub(crate) fn clear(&mut self) {
        self.entries = [None; MAX_INFLIGHT];
    }
    /// Removes and returns the pending entry matching `d`, if any.
    pub(crate) fn take_match<T: AsRef<[u8]>>(&mut self, d: &Datagram<T>) -> Option<Pending> {
        let slot = self
            .entries
            .iter_mut()
            .find(|e| e.is_some_and(|p| p.matches(d)))?;
        slot.take()
    }
}

/// Reads a little-endian unsigned integer of up to 8 bytes; `None` if `data` is not exactly
/// `len` bytes long.
pub(crate) fn le(data: &[u8], len: usize) -> Option<u64> {
    if data.len() != len || len > 8 {
        return None;
    }
    let mut b = [0u8; 8];
    b.get_mut(..len)?.copy_from_slice(data);
    Some(u64::from_le_bytes(b))
}
