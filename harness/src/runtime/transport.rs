//! Request/response matching over a [`Link`]: every frame we send is remembered by the index
//! of its first datagram; a received frame is a reply only if a slave processed it (source
//! MAC bit 0x02 set), it came from our own source address, and its first index is in flight.
//! Everything else is counted by kind and dropped, so the summary can say *why* frames
//! were ignored (a second master on the segment is a configuration error, a stale reply is
//! a timing problem, an unprocessed own frame means no slave is on the wire).
//!
//! Fixed-size slot table, no allocation: at most [`MAX_IN_FLIGHT`] frames outstanding
//! (SOEM uses 16 as well).

use std::io;

use super::clock;
use super::socket::{Link, ETHERTYPE_ECAT};

/// Frames that may be in flight at once.
pub const MAX_IN_FLIGHT: usize = 16;

/// Offsets of the few header fields the transport looks at (Ethernet II, no VLAN tag; the
/// kernel strips an offloaded tag before the packet socket sees the frame).
mod field {
    pub const SRC: core::ops::Range<usize> = 6..12;
    pub const ETHERTYPE: core::ops::Range<usize> = 12..14;
    pub const ECAT_HEADER: core::ops::Range<usize> = 14..16;
    /// Index byte of the first datagram (EtherCAT header 2 bytes, then cmd, idx).
    pub const FIRST_INDEX: usize = 17;
}

/// What a received frame is, from the master's point of view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// Not an EtherCAT command frame (wrong EtherType or type, or too short).
    Foreign,
    /// Our own frame, not processed by any slave (nothing on the wire, or a loop/switch).
    OwnUnprocessed,
    /// A frame (request or processed reply) belonging to another master with this MAC.
    OtherMaster([u8; 6]),
    /// A slave-processed reply to one of our frames; carries the first datagram index and
    /// the EtherCAT header length field.
    Reply {
        /// First datagram's index.
        index: u8,
        /// EtherCAT header length (11 bits).
        ecat_len: u16,
    },
}

/// Classifies a frame relative to our source MAC `mac` (whose bit 0x02 must be clear).
pub fn classify(frame: &[u8], mac: &[u8; 6]) -> Class {
    let (Some(src), Some(et), Some(hdr), Some(&index)) = (
        frame.get(field::SRC),
        frame.get(field::ETHERTYPE),
        frame.get(field::ECAT_HEADER),
        frame.get(field::FIRST_INDEX),
    ) else {
        return Class::Foreign;
    };
    if u16::from_be_bytes([et[0], et[1]]) != ETHERTYPE_ECAT {
        return Class::Foreign;
    }
    let header = u16::from_le_bytes([hdr[0], hdr[1]]);
    if header >> 12 != 1 {
        return Class::Foreign;
    }
    let mut origin = [0u8; 6];
    origin.copy_from_slice(src);
    let processed = origin[0] & 0x02 != 0;
    origin[0] &= !0x02;
    if &origin != mac {
        return Class::OtherMaster(origin);
    }
    if !processed {
        return Class::OwnUnprocessed;
    }
    Class::Reply {
        index,
        ecat_len: header & 0x07FF,
    }
}

/// Frame accounting, one counter per outcome. Every received frame lands in exactly one of
/// `matched`, `stale`, `mismatched`, `foreign`, `own_unprocessed`, `other_master`, `truncated`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counters {
    /// Frames sent.
    pub sent: u64,
    /// Frames received (any kind).
    pub received: u64,
    /// Replies matched to an in-flight frame.
    pub matched: u64,
    /// Frames whose reply never came before its deadline.
    pub lost: u64,
    /// Replies whose index was not in flight (arrived after their deadline, or duplicated).
    pub stale: u64,
    /// Replies with an in-flight index but a different EtherCAT length (corrupted or reused index).
    pub mismatched: u64,
    /// Non-EtherCAT or unparsable frames.
    pub foreign: u64,
    /// Our own frames that came back unprocessed.
    pub own_unprocessed: u64,
    /// Frames from or for another master.
    pub other_master: u64,
    /// Frames longer than the receive buffer.
    pub truncated: u64,
    /// The other master's MAC, if any was seen.
    #[serde(skip)]
    pub other_master_mac: Option<[u8; 6]>,
}

impl Counters {
    /// Received frames that were not matched replies.
    pub fn ignored(&self) -> u64 {
        self.received.saturating_sub(self.matched)
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct Slot {
    used: bool,
    index: u8,
    ecat_len: u16,
    sent_at: u64,
    deadline: u64,
}

/// A matched reply; the frame bytes are in the caller's buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reply {
    /// Length of the reply in the buffer.
    pub len: usize,
    /// First datagram index.
    pub index: u8,
    /// Monotonic time the request was handed to the kernel (just before `send`).
    pub sent_at: u64,
    /// Monotonic time the reply was read.
    pub received_at: u64,
    /// Monotonic time the kernel received it (socket timestamp), when the link records one.
    pub rx_stamp: Option<u64>,
}

impl Reply {
    /// Round trip as seen by user space, ns.
    pub fn rtt_ns(&self) -> u64 {
        self.received_at.saturating_sub(self.sent_at)
    }
}

/// Why a frame was not sent.
#[derive(Debug)]
pub enum SendError {
    /// The frame is not an EtherCAT frame from our MAC (a caller bug).
    NotOurFrame,
    /// A frame with the same first index is still in flight.
    IndexInFlight(u8),
    /// [`MAX_IN_FLIGHT`] frames are outstanding.
    TooManyInFlight,
    /// The kernel refused the frame.
    Io(io::Error),
}

impl std::fmt::Display for SendError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SendError::NotOurFrame => write!(
                f,
                "frame to send is not an EtherCAT frame with our source MAC"
            ),
            SendError::IndexInFlight(i) => write!(f, "datagram index {i} is still in flight"),
            SendError::TooManyInFlight => write!(f, "{MAX_IN_FLIGHT} frames already in flight"),
            SendError::Io(e) => write!(f, "send failed: {e}"),
        }
    }
}

impl std::error::Error for SendError {}

/// Index-matched request/response over a link.
#[derive(Debug)]
pub struct Transport<L: Link> {
    link: L,
    mac: [u8; 6],
    slots: [Slot; MAX_IN_FLIGHT],
    counters: Counters,
}

impl<L: Link> Transport<L> {
    /// A transport sending as `mac` (bit 0x02 of the first octet must be clear so the slaves'
    /// "processed" marker is visible).
    pub fn new(link: L, mac: [u8; 6]) -> Self {
        Transport {
            link,
            mac,
            slots: [Slot::default(); MAX_IN_FLIGHT],
            counters: Counters::default(),
        }
    }

    /// Our source MAC.
    pub fn mac(&self) -> [u8; 6] {
        self.mac
    }

    /// Frame accounting so far.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Starts a fresh accounting period (e.g. between two benchmark phases).
    pub fn reset_counters(&mut self) {
        self.counters = Counters::default();
    }

    /// The link underneath.
    pub fn link(&self) -> &L {
        &self.link
    }

    /// The link underneath, mutably (e.g. to flush a capture).
    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }

    /// Frames awaiting a reply.
    pub fn in_flight(&self) -> usize {
        self.slots.iter().filter(|s| s.used).count()
    }

    /// Sends `frame` and remembers it until a reply arrives or `deadline_ns` passes.
    pub fn send(&mut self, frame: &[u8], deadline_ns: u64) -> Result<u64, SendError> {
        let Class::OwnUnprocessed = classify(frame, &self.mac) else {
            return Err(SendError::NotOurFrame);
        };
        let (Some(&index), Some(hdr)) =
            (frame.get(field::FIRST_INDEX), frame.get(field::ECAT_HEADER))
        else {
            return Err(SendError::NotOurFrame);
        };
        let ecat_len = u16::from_le_bytes([hdr[0], hdr[1]]) & 0x07FF;
        if self.slots.iter().any(|s| s.used && s.index == index) {
            return Err(SendError::IndexInFlight(index));
        }
        let Some(slot) = self.slots.iter_mut().find(|s| !s.used) else {
            return Err(SendError::TooManyInFlight);
        };
        let sent_at = clock::now_ns();
        self.link.send(frame).map_err(SendError::Io)?;
        *slot = Slot {
            used: true,
            index,
            ecat_len,
            sent_at,
            deadline: deadline_ns,
        };
        self.counters.sent += 1;
        Ok(sent_at)
    }

    /// Forgets in-flight frames whose deadline is before `now`, counting them as lost.
    /// Returns how many expired.
    pub fn expire(&mut self, now: u64) -> usize {
        let mut n = 0;
        for s in self
            .slots
            .iter_mut()
            .filter(|s| s.used && s.deadline <= now)
        {
            s.used = false;
            n += 1;
        }
        self.counters.lost += n as u64;
        n
    }

    /// Forgets every in-flight frame (counted as lost).
    pub fn abandon_all(&mut self) {
        self.expire(u64::MAX);
    }

    /// Receives until a reply to an in-flight frame arrives or `deadline_ns` passes; other
    /// frames are counted and dropped. On `Ok(None)`, in-flight frames past their own
    /// deadlines have been expired.
    pub fn recv(&mut self, buf: &mut [u8], deadline_ns: u64) -> io::Result<Option<Reply>> {
        loop {
            let Some(full) = self.link.recv(buf, deadline_ns)? else {
                self.expire(clock::now_ns());
                return Ok(None);
            };
            let received_at = clock::now_ns();
            self.counters.received += 1;
            if full > buf.len() {
                self.counters.truncated += 1;
                continue;
            }
            let frame = buf.get(..full).unwrap_or_default();
            match classify(frame, &self.mac) {
                Class::Foreign => self.counters.foreign += 1,
                Class::OwnUnprocessed => self.counters.own_unprocessed += 1,
                Class::OtherMaster(m) => {
                    self.counters.other_master += 1;
                    self.counters.other_master_mac.get_or_insert(m);
                }
                Class::Reply { index, ecat_len } => {
                    match self.slots.iter_mut().find(|s| s.used && s.index == index) {
                        None => self.counters.stale += 1,
                        Some(s) if s.ecat_len != ecat_len => {
                            self.counters.mismatched += 1;
                        }
                        Some(s) if received_at > s.deadline => {
                            // Too late: the caller has already given up on it.
                            s.used = false;
                            self.counters.lost += 1;
                            self.counters.stale += 1;
                        }
                        Some(s) => {
                            s.used = false;
                            self.counters.matched += 1;
                            let rx_stamp = self.link.last_rx_time().filter(|t| *t <= received_at);
                            return Ok(Some(Reply {
                                len: full,
                                index,
                                sent_at: s.sent_at,
                                received_at,
                                rx_stamp,
                            }));
                        }
                    }
                }
            }
        }
    }
}
