//! What the machine tells its caller, through [`crate::dc::Machine::poll_event`], and the
//! bounded queue that holds it.

use crate::dc::error::Error;
use crate::dc::holdover::{HoldoverCause, ResumeCheck};
use crate::time::SystemTime;

/// Something the caller may want to know or act on. Events are queued in order; when the queue
/// is full the oldest event is dropped and counted in `Stats::events_dropped`.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, Error, Event, Machine};
/// use ecdc_core::time::SystemTime;
/// use ecdc_core::wire::MAC_PROCESSED_BIT;
///
/// let mut dc = Machine::<8>::new(Config::default())?;
/// let now = SystemTime::from_nanos(1_000_000_000);
/// dc.start(now);
/// let mut frame = [0u8; 1514];
/// let len = dc
///     .poll_transmit(now, &mut frame)
///     .expect("the slave count to send");
/// // The count comes back with working counter 0: no slave on the wire.
/// frame[6] |= MAC_PROCESSED_BIT;
/// dc.handle_frame(now, &frame[..len]);
/// assert_eq!(dc.poll_event(), Some(Event::Error(Error::NoSlaves)));
/// assert_eq!(dc.poll_event(), Some(Event::Restarting)); // `auto_restart` is on
/// assert_eq!(dc.poll_event(), None);
/// # Ok::<(), ecdc_core::dc::ConfigError>(())
/// ```
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Event {
    /// The network was counted and addressed.
    SlavesFound {
        /// All slaves (BRD working counter).
        count: u16,
        /// Slaves with DC and a system time (the FRMW working counter).
        dc: u16,
    },
    /// Every slave's t_Diff is known (REQ-DC-126); the per-slave values and sources are in
    /// [`crate::dc::Machine::slaves`].
    TdiffResolved {
        /// Slaves measured themselves, in this bring-up or (while the slaves run) an earlier one.
        measured: u16,
        /// Slaves given the value of a measured slave of the same ESC type and revision.
        same_type: u16,
        /// Slaves with a user-supplied value.
        configured: u16,
        /// Slaves whose measurement was wanted but not used (running network, implausible).
        fallback: u16,
    },
    /// Propagation delays measured (after `latch_rounds` latches).
    DelaysMeasured {
        /// Largest delay from the reference, ns.
        max_delay_ns: u32,
    },
    /// Offsets and delays written.
    OffsetsWritten {
        /// Slaves whose 0x0920 was written.
        written: u16,
        /// Slaves in SAFEOP/OP (or with an unreadable AL status) whose 0x0920 was left alone.
        skipped_running: u16,
    },
    /// Static drift compensation converged.
    DriftConverged {
        /// FRMW frames it took.
        frames: u32,
        /// Worst |Δt| at the last check, ns.
        max_diff_ns: u32,
    },
    /// SYNC units programmed; the first SYNC0 pulse is at `start`.
    SyncStarted {
        /// System time of the first SYNC0 pulse (64-bit; 32-bit slaves got its low half).
        start: SystemTime,
        /// Slaves programmed.
        slaves: u16,
    },
    /// Cyclic operation reached lock (|0x092C| bound ≤ `lock_ns` for `lock_cycles` cycles).
    Locked {
        /// Frames sent since `start` (or since the last re-initialisation).
        frames: u64,
        /// BRD 0x092C upper bound at lock, ns.
        bound_ns: u32,
    },
    /// The bound stayed above `unlock_ns` for `unlock_cycles` cycles.
    LockLost {
        /// BRD 0x092C upper bound, ns.
        bound_ns: u32,
    },
    /// A requested delay re-measurement finished and 0x0928 was rewritten.
    DelaysUpdated {
        /// Largest change of any slave's delay, ns.
        max_change_ns: u32,
    },
    /// A fault; see [`Error`]. With `auto_restart` a `Restarting` follows.
    Error(Error),
    /// The machine re-initialises from `CountSlaves` after `restart_delay_ns`, doubled for
    /// every re-initialisation without a lock in between up to `restart_backoff_max_ns`
    /// ([`crate::dc::Machine::restart_at`] tells when).
    Restarting,
    /// Cyclic operation went silent (no complete cycle) or the master stalled: the machine
    /// holds over instead of re-initialising (REQ-DC-127).
    HoldoverStarted {
        /// Master time of the first missed cycle: one period after the last complete cycle's
        /// transmission.
        since: SystemTime,
        /// What was seen.
        cause: HoldoverCause,
    },
    /// The first complete cycle after a hold-over passed the resume check (REQ-DC-128); the
    /// reference time distribution and monitoring go on, nothing was rewritten.
    HoldoverEnded {
        /// Time from `since` to the end of the resume cycle, ns.
        after_ns: u64,
        /// What the check saw.
        check: ResumeCheck,
    },
}

/// Capacity of the event queue.
pub const EVENT_QUEUE_LEN: usize = 32;

/// Fixed-size FIFO of events.
#[derive(Debug, Clone)]
pub(crate) struct EventQueue {
    buf: [Option<Event>; EVENT_QUEUE_LEN],
    head: usize,
    len: usize,
}

impl EventQueue {
    pub(crate) const fn new() -> Self {
        EventQueue {
            buf: [None; EVENT_QUEUE_LEN],
            head: 0,
            len: 0,
        }
    }

    /// Pushes an event; returns false if the oldest had to be dropped.
    pub(crate) fn push(&mut self, e: Event) -> bool {
        let mut kept = true;
        if self.len >= EVENT_QUEUE_LEN {
            self.head = (self.head.wrapping_add(1)) % EVENT_QUEUE_LEN;
            self.len = EVENT_QUEUE_LEN.saturating_sub(1);
            kept = false;
        }
        let at = (self.head.wrapping_add(self.len)) % EVENT_QUEUE_LEN;
        if let Some(slot) = self.buf.get_mut(at) {
            *slot = Some(e);
        }
        self.len = self.len.saturating_add(1);
        kept
    }

    pub(crate) fn pop(&mut self) -> Option<Event> {
        if self.len == 0 {
            return None;
        }
        let e = self.buf.get_mut(self.head).and_then(Option::take);
        self.head = (self.head.wrapping_add(1)) % EVENT_QUEUE_LEN;
        self.len = self.len.saturating_sub(1);
        e
    }

    /// The waiting events, oldest first.
    fn waiting(&self) -> impl Iterator<Item = &Event> + '_ {
        (0..self.len).filter_map(move |k| {
            let at = self.head.wrapping_add(k) % EVENT_QUEUE_LEN;
            self.buf.get(at).and_then(Option::as_ref)
        })
    }
}

/// Queues are equal when the same events wait in the same order, wherever their rings start.
impl PartialEq for EventQueue {
    fn eq(&self, other: &Self) -> bool {
        self.len == other.len && self.waiting().eq(other.waiting())
    }
}

impl Eq for EventQueue {}

impl core::hash::Hash for EventQueue {
    fn hash<H: core::hash::Hasher>(&self, state: &mut H) {
        self.len.hash(state);
        for e in self.waiting() {
            e.hash(state);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fifo_and_overflow_drops_oldest() {
        let mut q = EventQueue::new();
        for i in 0..(EVENT_QUEUE_LEN as u16 + 3) {
            q.push(Event::LockLost {
                bound_ns: u32::from(i),
            });
        }
        assert_eq!(q.pop(), Some(Event::LockLost { bound_ns: 3 }));
        let mut n = 1;
        while q.pop().is_some() {
            n += 1;
        }
        assert_eq!(n, EVENT_QUEUE_LEN);
        assert_eq!(q.pop(), None);
    }

    #[test]
    fn queues_compare_by_waiting_events_not_ring_position() {
        let e = |b| Event::LockLost { bound_ns: b };
        let (mut a, mut b) = (EventQueue::new(), EventQueue::new());
        a.push(e(9));
        a.pop();
        a.push(e(1));
        b.push(e(1));
        assert_eq!(a, b);
        b.push(e(2));
        assert_ne!(a, b);
        a.push(e(3));
        assert_ne!(a, b, "same length, other event");
        assert_ne!(EventQueue::new(), b);
    }
}
