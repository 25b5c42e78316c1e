//! Hold-over (REQ-DC-127..130): a silence of the wire or a stall of the master during cyclic
//! operation is not a fault of the slaves' clocks (docs/background/holdover.md §1): the ESC's
//! time-control loop takes a sample only from a write covering 0x0910, so without FRMW each
//! clock keeps the rate it learnt; the offsets in 0x0920, the delays in 0x0928 and the
//! programmed SYNC0 start stay valid. What stops is the
//! distribution of the reference time and the master's view of it.
//!
//! So instead of re-initialising after `max_lost_cycles`, the cyclic phase enters a hold-over
//! sub-state: it keeps sending its cycle (that is how it notices the wire is back), counts the
//! time since the last complete cycle, and re-initialises only when that exceeds
//! `Config::holdover_ns`. The first complete cycle after a hold-over is the resume check,
//! made of the cycle's own datagrams, so it writes nothing but the FRMW every cycle writes
//! (never 0x0920, REQ-DC-030):
//! - BRD 0x0130's working counter is the slave count of the bring-up (same topology);
//! - the FRMW's and BRD 0x092C's working counters are the DC slave count (reference alive);
//! - the OR of every AL status (BRD 0x0130 data) shows no INIT where there was none before: an
//!   ESC that lost power restarts in INIT (docs/background/holdover.md §2), while a slave
//!   fallen back to SAFEOP by its watchdog is no clock fault;
//! - every round-robin FPRD answers at its station address (a power-cycled ESC lost it);
//! - the BRD 0x092C bound, written by this very cycle's FRMW, is at most
//!   `Config::holdover_check_ns`: a reset ESC's system time restarted at 0 with offset 0, so
//!   its difference to the reference is essentially a random 32-bit value, not the residual
//!   drift of a clock that kept its rate (docs/background/holdover.md §2, §3).
//!
//! A failed check is a typed fault ([`Error::ResumeCheckFailed`]) and the usual
//! re-initialisation; a passed one resumes monitoring and lock detection where they were.

use crate::dc::cyclic::CyclicCx;
use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::Machine;
use crate::dc::remeasure::{Remeasure, RemeasureRun};
use crate::time::SystemTime;

/// Why a hold-over began.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Event, HoldoverCause};
///
/// fn log(ev: &Event) -> Option<&'static str> {
///     match ev {
///         Event::HoldoverStarted {
///             cause: HoldoverCause::Silence,
///             ..
///         } => Some("network silent"),
///         Event::HoldoverStarted {
///             cause: HoldoverCause::Stall,
///             ..
///         } => Some("master stalled"),
///         _ => None,
///     }
/// }
/// let ev = Event::HoldoverStarted {
///     since: ecdc_core::time::SystemTime::from_nanos(5_000_000),
///     cause: HoldoverCause::Stall,
/// };
/// assert_eq!(log(&ev), Some("master stalled"));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HoldoverCause {
    /// `max_lost_cycles` cycles in a row came back incomplete or not at all (wire silence, a
    /// stopped peer, a burst of loss).
    Silence,
    /// The master did not send for more than `max_lost_cycles` cycle periods (its `now` jumped:
    /// a stalled host or process).
    Stall,
}

/// What the resume check saw when it passed.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Event, ResumeCheck};
///
/// // The machine reports this when cyclic operation resumes after a hold-over.
/// let ev = Event::HoldoverEnded {
///     after_ns: 250_000_000,
///     check: ResumeCheck {
///         slaves: 12,
///         al_status: 0x0008,
///         bound_ns: 1_800,
///     },
/// };
/// if let Event::HoldoverEnded { check, .. } = ev {
///     assert_eq!(check.slaves, 12);
///     assert!(check.bound_ns < 100_000); // within the default `holdover_check_ns`
/// }
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ResumeCheck {
    /// Slaves answering BRD 0x0130 (equal to the bring-up's count).
    pub slaves: u16,
    /// OR of every slave's AL status (low byte of 0x0130).
    pub al_status: u16,
    /// BRD 0x092C upper bound of |Δt| in the resume cycle, ns.
    pub bound_ns: u32,
}

/// Why the resume check after a hold-over failed.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Error, ResumeFailure};
///
/// let e = Error::ResumeCheckFailed {
///     failure: ResumeFailure::SlaveCount {
///         expected: 12,
///         found: 11,
///     },
/// };
/// assert!(!e.is_retryable()); // the network changed: a new bring-up follows
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ResumeFailure {
    /// BRD 0x0130 (or BRD 0x092C) counted a different number of slaves.
    SlaveCount {
        /// Slaves of the bring-up.
        expected: u16,
        /// Slaves answering now.
        found: u16,
    },
    /// The FRMW's working counter is not the number of slaves with a system time (the
    /// reference or a DC slave is gone or reset).
    ReferenceWkc {
        /// Expected working counter.
        expected: u16,
        /// Working counter received.
        actual: u16,
    },
    /// A slave no longer answers at its station address (an ESC reset loses it).
    SlaveLost {
        /// Station address that did not answer.
        station: u16,
    },
    /// A slave is in INIT (or BOOT) although none was before the hold-over: it was reset.
    SlaveReset {
        /// OR of every AL status now.
        al_status: u16,
        /// OR of every AL status in the last complete cycle before the hold-over.
        before: u16,
    },
    /// The BRD 0x092C bound after the first FRMW exceeds `Config::holdover_check_ns`.
    Bound {
        /// Bound read, ns (`u32::MAX` when the read carried no value).
        bound_ns: u32,
    },
}

/// The hold-over sub-state of `Cyclic` and its own data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct Holdover {
    /// Master time the silence is counted from: one period after the last complete cycle's
    /// transmission (or, before any, the first cycle's transmission).
    pub(crate) since: SystemTime,
    pub(crate) cause: HoldoverCause,
    /// OR of the AL status of every slave in the last complete cycle (`None`: never read).
    pub(crate) al_before: Option<u16>,
}

/// AL status bit 0: set in INIT (1) and BOOT (3), the AL state codes of 0x0130 bits 3..0.
const AL_INIT_BIT: u16 = 0x0001;

impl<const N: usize> CyclicCx<'_, N> {
    /// Whether hold-over replaces the re-initialisation on silence (`holdover_ns` > 0).
    #[inline]
    pub(crate) fn holdover_enabled(&self) -> bool {
        self.sh.cfg.holdover_ns > 0
    }

    /// Enters hold-over (idempotent): reports it and suspends what needs every cycle.
    pub(crate) fn holdover_start(&mut self, since: SystemTime, cause: HoldoverCause) {
        if self.c.holdover.is_some() {
            return;
        }
        self.c.holdover = Some(Holdover {
            since,
            cause,
            al_before: self.c.al_ok,
        });
        // A delay re-measurement cut by the silence is run again from its first step once
        // the wire is back (some 0x0928 may already be rewritten: the rerun rewrites all).
        if self.c.remeasure.step != Remeasure::Idle {
            self.c.remeasure = RemeasureRun {
                requested: true,
                ..RemeasureRun::default()
            };
        }
        self.sh.push_event(Event::HoldoverStarted { since, cause });
    }

    /// In hold-over and silent for longer than `holdover_ns` at `now`: re-initialise.
    /// Returns whether it did. The silence is counted from the first cycle that was missed,
    /// and the first cycle after a silence can leave up to one period after it ended: one
    /// period more is allowed, so that a silence of exactly `holdover_ns` is held over.
    pub(crate) fn holdover_expired(&mut self, now: SystemTime) -> bool {
        let Some(h) = self.c.holdover else {
            return false;
        };
        let silent_ns = now.saturating_since(h.since);
        let limit = self
            .sh
            .cfg
            .holdover_ns
            .saturating_add(self.sh.cfg.monitor.cycle_ns);
        if silent_ns <= limit {
            return false;
        }
        self.fail(Error::HoldoverExpired { silent_ns });
        true
    }

    /// The first complete cycle after a hold-over: the resume check. Returns true when it
    /// passed (monitoring continues with this cycle), false after a fault.
    pub(crate) fn resume_check(&mut self, now: SystemTime, h: Holdover) -> bool {
        let result = self.resume_result(h);
        match result {
            Ok(check) => {
                self.c.holdover = None;
                self.c.topo_streak = 0;
                self.c.wkc_streak = 0;
                self.sh.stats.holdovers = self.sh.stats.holdovers.saturating_add(1);
                self.sh.push_event(Event::HoldoverEnded {
                    after_ns: now.saturating_since(h.since),
                    check,
                });
                true
            }
            Err(failure) => {
                self.fail(Error::ResumeCheckFailed { failure });
                false
            }
        }
    }

    fn resume_result(&self, h: Holdover) -> Result<ResumeCheck, ResumeFailure> {
        let c = &*self.c;
        let found = c.replies.topo_wkc.unwrap_or(0);
        if found != self.sh.line.count {
            return Err(ResumeFailure::SlaveCount {
                expected: self.sh.line.count,
                found,
            });
        }
        let frmw = c.replies.frmw_wkc.unwrap_or(0);
        if frmw != self.sh.line.sys_count {
            return Err(ResumeFailure::ReferenceWkc {
                expected: self.sh.line.sys_count,
                actual: frmw,
            });
        }
        let bound_wkc = c.replies.bound_wkc.unwrap_or(0);
        if bound_wkc != self.sh.line.sys_count {
            return Err(ResumeFailure::SlaveCount {
                expected: self.sh.line.count,
                found: self
                    .sh
                    .line
                    .count
                    .saturating_sub(self.sh.line.sys_count)
                    .saturating_add(bound_wkc),
            });
        }
        if let Some(station) = c.replies.lost_station {
            return Err(ResumeFailure::SlaveLost { station });
        }
        let al_status = c.replies.al_status.unwrap_or(0);
        if let Some(before) = h.al_before {
            if al_status & AL_INIT_BIT != 0 && before & AL_INIT_BIT == 0 {
                return Err(ResumeFailure::SlaveReset { al_status, before });
            }
        }
        // The bound is taken from this cycle only: `bound_ns` still holds the last value
        // from before the silence when this cycle's read carried none.
        let bound_ns = c.replies.bound_ns.unwrap_or(u32::MAX);
        if bound_ns > self.sh.cfg.holdover_check_ns {
            return Err(ResumeFailure::Bound { bound_ns });
        }
        Ok(ResumeCheck {
            slaves: found,
            al_status,
            bound_ns,
        })
    }
}

impl<const N: usize> Machine<N> {
    /// Whether the cyclic phase is in hold-over.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    ///
    /// // Only a running cyclic phase can hold over.
    /// let dc = Machine::<8>::new(Config::default())?;
    /// assert!(!dc.in_holdover());
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn in_holdover(&self) -> bool {
        self.phase.cyclic().is_some_and(|c| c.holdover.is_some())
    }

    /// Master time at which the running re-initialisation pause ends (`RestartWait` only).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine, State};
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
    /// frame[6] |= MAC_PROCESSED_BIT; // came back with no slave counted
    /// dc.handle_frame(now, &frame[..len]);
    /// assert_eq!(dc.state(), State::RestartWait);
    /// // The first pause is `restart_delay_ns` (10 ms).
    /// assert_eq!(dc.restart_at(), Some(now.wrapping_add(10_000_000)));
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn restart_at(&self) -> Option<crate::time::SystemTime> {
        self.sh.timers.get(crate::dc::timer::Timer::Restart)
    }
}

#[cfg(test)]
mod tests {
    //! Hold-over's own rules on a machine put straight into `Cyclic`: when it replaces the
    //! re-initialisation, when it expires, and what the resume check refuses (REQ-DC-127,
    //! REQ-DC-128). End-to-end hold-over against the emulator: `harness/tests`.
    use super::*;
    use crate::dc::slave::DcKind;
    use crate::dc::{Config, State};

    const T: u64 = 800_000_000_000_000_000;

    /// Two 64-bit DC slaves in `Cyclic`, with `holdover_ns` (0: hold-over off).
    fn cyclic(holdover_ns: u64) -> Machine<4> {
        let cfg = Config {
            holdover_ns,
            auto_restart: false,
            ..Config::default()
        };
        let mut m = Machine::<4>::new(cfg).unwrap();
        m.phase = m.phase.enter(State::Cyclic);
        m.sh.line.count = 2;
        m.sh.line.sys_count = 2;
        for (i, s) in m.sh.line.slaves.iter_mut().take(2).enumerate() {
            s.station = 0x1001 + i as u16;
            s.dc = DcKind::Bits64;
        }
        m
    }

    fn events(m: &mut Machine<4>) -> std::vec::Vec<Event> {
        core::iter::from_fn(|| m.poll_event()).collect()
    }

    /// `max_lost_cycles` lost cycles in a row at 1 ms each, the first sent at `T`.
    fn lose_cycles(m: &mut Machine<4>) {
        let lost = m.sh.cfg.monitor.max_lost_cycles;
        for k in 0..u64::from(lost) {
            let now = SystemTime(T + k * 1_000_000);
            m.in_cyclic(now, |cx| {
                cx.c.sent_at = now;
                cx.cyclic_lost(now);
            });
        }
    }

    // verifies: REQ-DC-127
    #[test]
    fn silence_holds_over_only_when_enabled() {
        let mut m = cyclic(0);
        lose_cycles(&mut m);
        assert_eq!(m.state(), State::Failed);
        assert_eq!(
            events(&mut m),
            [Event::Error(Error::Timeout {
                state: State::Cyclic
            })]
        );
        let mut m = cyclic(1);
        lose_cycles(&mut m);
        assert_eq!(m.state(), State::Cyclic);
        assert!(m.in_holdover());
        assert!(matches!(
            events(&mut m)[..],
            [Event::HoldoverStarted {
                cause: HoldoverCause::Silence,
                ..
            }]
        ));
    }

    /// A delay re-measurement the silence cuts is dropped, with its progress and error, and
    /// asked for again, so it runs from its first step once the wire is back; one that is not
    /// running is left alone.
    #[test]
    fn holdover_reruns_a_cut_remeasurement() {
        let cut = RemeasureRun {
            requested: false,
            step: Remeasure::After,
            cursor: 1,
            sent_to: 2,
            error: Some(Error::NoReferenceClock),
        };
        for (before, after) in [
            (
                cut,
                RemeasureRun {
                    requested: true,
                    ..RemeasureRun::default()
                },
            ),
            (RemeasureRun::default(), RemeasureRun::default()),
        ] {
            let mut m = cyclic(1);
            let after_start = m.in_cyclic(SystemTime(T), |cx| {
                cx.c.remeasure = before;
                cx.holdover_start(SystemTime(T), HoldoverCause::Silence);
                cx.c.remeasure
            });
            assert_eq!(after_start, Some(after));
        }
    }

    /// Hold-over ends in a re-initialisation once the silence is longer than `holdover_ns`
    /// plus one period; a silence of exactly that is still held over.
    // verifies: REQ-DC-127
    #[test]
    fn holdover_expires_after_its_limit() {
        let mut m = cyclic(10_000_000);
        let since = SystemTime(T);
        m.in_cyclic(since, |cx| cx.holdover_start(since, HoldoverCause::Silence));
        let limit = 10_000_000 + 1_000_000;
        let at_limit = since.wrapping_add(limit);
        assert_eq!(
            m.in_cyclic(at_limit, |cx| cx.holdover_expired(at_limit)),
            Some(false)
        );
        assert_eq!(m.state(), State::Cyclic);
        let after = at_limit.wrapping_add(1);
        assert_eq!(
            m.in_cyclic(after, |cx| cx.holdover_expired(after)),
            Some(true)
        );
        assert_eq!(m.state(), State::Failed);
        assert_eq!(
            events(&mut m).last(),
            Some(&Event::Error(Error::HoldoverExpired {
                silent_ns: limit + 1
            }))
        );
    }

    /// `restart_at` is the end of the pause while one runs, and `None` otherwise.
    // verifies: REQ-DC-130
    #[test]
    fn restart_at_is_the_end_of_the_pause() {
        let mut m = cyclic(0);
        assert_eq!(m.restart_at(), None);
        m.sh.cfg.auto_restart = true;
        lose_cycles(&mut m);
        assert_eq!(m.state(), State::RestartWait);
        let at = m.restart_at().unwrap();
        assert!(at.is_after(SystemTime(T)), "{at:?}");
        assert_eq!(
            at.saturating_since(SystemTime(T)),
            m.sh.cfg.restart_delay_ns
                + (u64::from(m.sh.cfg.monitor.max_lost_cycles) - 1) * 1_000_000
        );
    }

    /// The resume check on a complete cycle: every count right, AL status `al`, bound `bound`.
    fn resume(al: u16, before: Option<u16>, bound: u32) -> Result<ResumeCheck, ResumeFailure> {
        let mut m = cyclic(1_000_000_000);
        let c = m.phase.cyclic_mut().unwrap();
        c.replies.topo_wkc = Some(2);
        c.replies.frmw_wkc = Some(2);
        c.replies.bound_wkc = Some(2);
        c.replies.al_status = Some(al);
        c.replies.bound_ns = Some(bound);
        let h = Holdover {
            since: SystemTime(T),
            cause: HoldoverCause::Silence,
            al_before: before,
        };
        m.in_cyclic(SystemTime(T), |cx| cx.resume_result(h))
            .unwrap()
    }

    /// A slave back in INIT that was not before the silence was reset (its SYNC and offsets
    /// are gone); one in INIT already, or in any state without the INIT bit, was not.
    // verifies: REQ-DC-128
    #[test]
    fn resume_check_refuses_a_slave_reset_to_init() {
        const OP: u16 = 0x08;
        const INIT: u16 = 0x01;
        const PREOP: u16 = 0x02;
        let check = Config::default().holdover_check_ns;
        assert_eq!(
            resume(INIT, Some(OP), 10),
            Err(ResumeFailure::SlaveReset {
                al_status: INIT,
                before: OP
            })
        );
        for (al, before) in [
            (OP, Some(OP)),
            (INIT, Some(INIT)),
            (PREOP, Some(OP)),
            (INIT, None),
        ] {
            assert_eq!(
                resume(al, before, check),
                Ok(ResumeCheck {
                    slaves: 2,
                    al_status: al,
                    bound_ns: check
                }),
                "{al:#x} after {before:?}"
            );
        }
        // The bound may equal `holdover_check_ns`, not exceed it.
        assert_eq!(
            resume(OP, Some(OP), check + 1),
            Err(ResumeFailure::Bound {
                bound_ns: check + 1
            })
        );
    }
}
