//! [`Shared`]: the machine's parts that every phase reads and uses, around the phase
//! (`dc/phase.rs`): configuration, the line, the in-flight and timer tables, events and
//! counters, the request-step runner's progress, restart bookkeeping and the working tables.

use crate::dc::config::Config;
use crate::dc::error::Error;
use crate::dc::event::{Event, EventQueue};
use crate::dc::line::Line;
use crate::dc::machine::Stats;
use crate::dc::measure::LatchRounds;
use crate::dc::request::{Inflight, Op, Pending, Tag, MAX_INFLIGHT};
use crate::dc::scratch::Scratch;
use crate::dc::tdiff::Tdiff;
use crate::dc::timer::{Timer, TimerTable};
use crate::time::SystemTime;
use crate::wire::FrameBuilder;

/// The machine's parts that outlive a phase: configuration, the line, the in-flight and timer
/// tables, events and counters, and the working tables.
#[derive(Debug, Clone)]
pub(crate) struct Shared<const N: usize> {
    pub(crate) cfg: Config,
    /// The slave table and the line's facts (`dc/line.rs`).
    pub(crate) line: Line<N>,
    pub(crate) inflight: Inflight,
    /// Every deadline (`dc/timer.rs`); `Timer::Reply` is armed exactly while a frame is
    /// awaited.
    pub(crate) timers: TimerTable,
    /// Where the current request step stands (its items, retries, deferred error).
    pub(crate) step: StepProgress,
    pub(crate) events: EventQueue,
    pub(crate) stats: Stats,
    /// Master time of the last transmission of a request step.
    pub(crate) last_sent: SystemTime,
    /// Re-initialisation bookkeeping.
    pub(crate) restarts: Restarts,
    /// The delay measurement's rounds (`dc/measure.rs`).
    pub(crate) latch: LatchRounds<N>,
    /// The t_Diff measurement's own data (`dc/tdiff.rs`).
    pub(crate) tdiff: Tdiff<N>,
    /// Working tables of the computations (`dc/scratch.rs`).
    pub(crate) scratch: Scratch<N>,
}

impl<const N: usize> Shared<N> {
    /// Gives up the frame in flight: its datagrams are forgotten (a late reply is foreign)
    /// and the reply timer stops.
    pub(crate) fn stop_awaiting(&mut self) {
        self.inflight.clear();
        self.timers.stop(Timer::Reply);
    }

    /// The next datagram index of the configured range.
    pub(crate) fn alloc_index(&mut self) -> u8 {
        let i = self.inflight.next_index;
        self.inflight.next_index = index_after(i, self.cfg.index_first, self.cfg.index_count);
        i
    }

    /// Emits `op` into `b` and records it in flight; false if it did not fit.
    pub(crate) fn push_op(&mut self, b: &mut FrameBuilder<'_>, op: Op, tag: Tag) -> bool {
        if !self.inflight.has_room() {
            return false;
        }
        let index = self.alloc_index();
        if op.emit(b, index).is_err() {
            return false;
        }
        self.inflight.insert(Pending {
            index,
            command: op.command,
            register: op.register(),
            station: op.station(),
            len: op.len,
            tag,
        })
    }

    /// Queues an event, counting it in `Stats::events_dropped` when the queue is full.
    pub(crate) fn push_event(&mut self, e: Event) {
        if !self.events.push(e) {
            self.stats.events_dropped = self.stats.events_dropped.saturating_add(1);
        }
    }
}

/// Where a request step stands: its items are numbered `0..item_count`, sent in frames of
/// consecutive items and answered before the next frame goes out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct StepProgress {
    /// The next item to send.
    pub(crate) cursor: u16,
    /// The first item of the frame in flight (a retry sends from there again).
    pub(crate) chunk_start: u16,
    /// Retries of the step so far (`Config::retries`).
    pub(crate) tries: u8,
    /// An error found in a reply, reported if the step then times out instead of completing.
    pub(crate) error: Option<Error>,
}

impl StepProgress {
    /// A step not started.
    pub(crate) const START: StepProgress = StepProgress {
        cursor: 0,
        chunk_start: 0,
        tries: 0,
        error: None,
    };
}

/// Re-initialisation bookkeeping: the backoff's exponent and where `Stats::lock_frames` counts
/// from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct Restarts {
    /// Re-initialisations since the last lock (or `start`): the backoff's exponent.
    pub(crate) streak: u8,
    /// `Stats::frames_sent` at the last `start` or re-initialisation.
    pub(crate) frames_at_start: u64,
}

impl Restarts {
    /// None yet.
    pub(crate) const NONE: Restarts = Restarts {
        streak: 0,
        frames_at_start: 0,
    };
}

/// The datagram index handed out after `i` in the range of `count` indexes from `first`.
#[inline]
pub(crate) fn index_after(i: u8, first: u8, count: u8) -> u8 {
    let off = i.wrapping_sub(first).wrapping_add(1);
    if off >= count {
        first
    } else {
        first.wrapping_add(off)
    }
}

/// Compile-time guard: the index range must be able to hold two frames' worth of datagrams.
const _: () = assert!(MAX_INFLIGHT <= 64);

/// Expected-WKC check shared by every step.
pub(crate) fn expect_wkc(p: Pending, expected: u16, actual: u16) -> Result<(), Error> {
    if expected == actual {
        Ok(())
    } else {
        Err(Error::Wkc {
            command: p.command,
            station: p.station,
            register: p.register,
            expected,
            actual,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dc::event::EVENT_QUEUE_LEN;
    use crate::dc::Machine;
    use crate::wire::Command;

    /// Indexes run through `first..first + count` and wrap to `first`, also across 0xFF.
    #[test]
    fn indexes_cycle_through_their_range() {
        let walk = |first: u8, count: u8, from: u8, n: usize| {
            let mut i = from;
            let mut seen = std::vec::Vec::new();
            for _ in 0..n {
                i = index_after(i, first, count);
                seen.push(i);
            }
            seen
        };
        assert_eq!(walk(0x80, 3, 0x80, 4), [0x81, 0x82, 0x80, 0x81]);
        assert_eq!(walk(0xFE, 4, 0xFE, 4), [0xFF, 0x00, 0x01, 0xFE]);
        assert_eq!(walk(0, 1, 0, 2), [0, 0]);
    }

    #[test]
    fn expect_wkc_names_the_datagram() {
        let p = Pending {
            command: Command::Fprd,
            index: 3,
            station: 0x1001,
            register: 0x0130,
            len: 2,
            tag: Tag::Item(0),
        };
        assert_eq!(expect_wkc(p, 1, 1), Ok(()));
        assert_eq!(
            expect_wkc(p, 1, 0),
            Err(Error::Wkc {
                command: Command::Fprd,
                station: 0x1001,
                register: 0x0130,
                expected: 1,
                actual: 0,
            })
        );
    }

    /// A full event queue counts what it drops; events that fit are not counted.
    #[test]
    fn dropped_events_are_counted() {
        let mut m = Machine::<2>::new(crate::dc::Config::default()).unwrap();
        for _ in 0..EVENT_QUEUE_LEN {
            m.sh.push_event(Event::Restarting);
        }
        assert_eq!(m.sh.stats.events_dropped, 0);
        m.sh.push_event(Event::Restarting);
        assert_eq!(m.sh.stats.events_dropped, 1);
    }
}
