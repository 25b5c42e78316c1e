//! Propagation-delay measurement (REQ-DC-101, REQ-DC-102): read the latches, trigger a new
//! latch with one BWR 0x0900 (master time sampled just before it leaves), read the port and
//! EPU receive times, and turn them into delays with the pure DC maths. Repeated
//! `latch_rounds` times and averaged exactly (one rounding, REQ-DC-019). A port counts as
//! latched only if its time changed across the trigger (stale-latch detection, Lambert's IgH
//! patch).

use crate::dc::delay::Delays;
use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::{Item, Machine};
use crate::dc::request::{le, Op, Reply};
use crate::dc::state::State;
use crate::wire::register::reg;

/// Bytes of one full latch read: 0x0900..0x091F (4 port times, system time, EPU time).
const LATCH_BLOCK: u16 = 32;

/// The bring-up's delay measurement rounds.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct LatchRounds<const N: usize> {
    /// Rounds completed in this bring-up.
    pub(crate) round: u8,
    /// Exact sum of the rounds so far (REQ-DC-019); cleared (no rounds) when they are done.
    pub(crate) sum: Delays<N>,
    /// Master time sampled just before sending the latch trigger (REQ-DC-102).
    pub(crate) trigger_time: u64,
}

impl<const N: usize> LatchRounds<N> {
    /// No round measured.
    pub(crate) const fn new() -> Self {
        LatchRounds {
            round: 0,
            sum: Delays::new(),
            trigger_time: 0,
        }
    }

    /// Back to [`LatchRounds::new`], in place (no temporary of size `N`).
    pub(crate) fn clear(&mut self) {
        self.round = 0;
        self.sum.clear();
        self.trigger_time = 0;
    }
}

impl<const N: usize> Machine<N> {
    pub(crate) fn measure_item(&self, i: u16) -> Item {
        match self.state() {
            State::LatchTrigger => Item::Send(Op::bwr_zero(reg::RECEIVE_TIME_PORT0, 4)),
            State::LatchReadBefore => match self.slave(i) {
                Some(s) if s.dc.has_latches() => {
                    Item::Send(Op::fprd(s.station, reg::RECEIVE_TIME_PORT0, 16))
                }
                _ => Item::Skip,
            },
            State::LatchReadAfter => match self.slave(i) {
                Some(s) if s.dc.has_latches() => {
                    Item::Send(Op::fprd(s.station, reg::RECEIVE_TIME_PORT0, LATCH_BLOCK))
                }
                _ => Item::Skip,
            },
            _ => Item::Skip,
        }
    }

    pub(crate) fn measure_reply(&mut self, r: Reply<'_>) -> Result<(), Error> {
        let (i, p, wkc, data) = r.parts();
        let bad = p.out_of_range();
        match self.state() {
            State::LatchTrigger => {
                p.check_latch_wkc(wkc, self.sh.line.latching_count(), self.sh.line.count)
            }
            State::LatchReadBefore | State::LatchReadAfter => {
                self.expect_wkc(p, 1, wkc)?;
                let t = port_times(data).ok_or(bad)?;
                let after = self.state() == State::LatchReadAfter;
                let epu = if after {
                    data.get(24..32).and_then(|d| le(d, 8)).ok_or(bad)?
                } else {
                    0
                };
                if let Some(s) = self.slave_mut(i) {
                    if after {
                        s.times_after = t;
                        s.epu_time = epu;
                    } else {
                        s.times_before = t;
                    }
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    pub(crate) fn measure_done(&mut self) -> Result<State, Error> {
        match self.state() {
            State::LatchReadBefore => Ok(State::LatchTrigger),
            State::LatchTrigger => Ok(State::LatchReadAfter),
            State::LatchReadAfter => {
                self.sh.add_latch_round()?;
                self.sh.latch.round = self.sh.latch.round.saturating_add(1);
                if self.sh.latch.round < self.sh.cfg.latch_rounds {
                    return Ok(State::LatchReadBefore);
                }
                self.finish_delays()?;
                Ok(State::ReadAlStatus)
            }
            _ => Ok(self.state()),
        }
    }

    /// REQ-DC-019, REQ-DC-101: the 0x0928 values from the exact sum of the K rounds (one
    /// rounding), range-checked, then the offsets from the last round (REQ-DC-102).
    fn finish_delays(&mut self) -> Result<(), Error> {
        // The sum is used once: dropped whatever the outcome.
        let applied = self.apply_delays();
        self.sh.latch.sum.clear();
        let max_seen = applied?;
        self.sh.compute_offsets()?;
        self.push_event(Event::DelaysMeasured {
            max_delay_ns: max_seen,
        });
        Ok(())
    }

    /// The 0x0928 value of every slave with a system time from the sum of the rounds; the
    /// largest one.
    fn apply_delays(&mut self) -> Result<u32, Error> {
        let delays = &self.sh.latch.sum;
        if !delays.has_rounds() {
            return Err(Error::Measurement { station: 0 });
        }
        let max_delay = self.sh.cfg.max_delay_ns;
        let mut max_seen = 0u32;
        let count = self.sh.line.count;
        for (i, s) in self
            .sh
            .line
            .slaves
            .iter_mut()
            .enumerate()
            .take(usize::from(count))
        {
            if !s.dc.has_system_time() {
                continue;
            }
            let station = s.station;
            let d = delays
                .register_value(i)
                .map_err(|_| Error::Measurement { station })?;
            if d > max_delay {
                return Err(Error::OutOfRange {
                    station,
                    register: reg::SYSTEM_TIME_DELAY,
                });
            }
            s.delay_ns = d;
            max_seen = max_seen.max(d);
        }
        Ok(max_seen)
    }
}

/// The four 32-bit port receive times 0x0900..0x090F (ports 0..3) at the start of a latch
/// read's data, little-endian (REQ-DC-020); `None` when fewer than 16 bytes came back.
pub(crate) fn port_times(data: &[u8]) -> Option<[u32; 4]> {
    let mut t = [0u32; 4];
    for (k, slot) in t.iter_mut().enumerate() {
        let at = k.saturating_mul(4);
        let v = data.get(at..at.saturating_add(4)).and_then(|d| le(d, 4))?;
        *slot = u32::try_from(v).ok()?;
    }
    Some(t)
}
