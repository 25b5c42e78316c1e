//! Propagation-delay measurement (REQ-DC-101, REQ-DC-102): read the latches, trigger a new
//! latch with one BWR 0x0900 (master time sampled just before it leaves), read the port and
//! EPU receive times, and turn them into delays with the pure DC maths. Repeated
//! `latch_rounds` times and averaged exactly (one rounding, REQ-DC-019). A port counts as
//! latched only if its time changed across the trigger (stale-latch detection, Lambert's IgH
//! patch).

use crate::dc::delay::Delays;
use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::line::Line;
use crate::dc::machine::{Item, Machine};
use crate::dc::phase::{MeasureStep, Phase};
use crate::dc::request::{Op, Reply};
use crate::dc::shared::expect_wkc;
use crate::dc::slave::{LatchRead, SlaveInfo};
use crate::dc::state::State;
use crate::time::SystemTime;
use crate::wire::register::reg;

/// The bring-up's delay measurement rounds.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct LatchRounds<const N: usize> {
    /// Rounds completed in this bring-up.
    pub(crate) round: u8,
    /// Exact sum of the rounds so far (REQ-DC-019); cleared (no rounds) when they are done.
    pub(crate) sum: Delays<N>,
    /// Master time sampled just before sending the latch trigger (REQ-DC-102).
    pub(crate) trigger_time: SystemTime,
}

impl<const N: usize> LatchRounds<N> {
    /// No round measured.
    pub(crate) const fn new() -> Self {
        LatchRounds {
            round: 0,
            sum: Delays::new(),
            trigger_time: SystemTime::EPOCH,
        }
    }

    /// Back to [`LatchRounds::new`], in place (no temporary of size `N`).
    pub(crate) fn clear(&mut self) {
        self.round = 0;
        self.sum.clear();
        self.trigger_time = SystemTime::EPOCH;
    }
}

impl<const N: usize> Machine<N> {
    /// Items of a delay measurement step.
    pub(crate) fn measure_count(&self, step: MeasureStep) -> u16 {
        match step {
            MeasureStep::Trigger => 1,
            MeasureStep::ReadBefore | MeasureStep::ReadAfter => self.sh.line.count,
        }
    }

    fn latch_item(&self, i: u16, read: LatchRead) -> Item {
        self.sh
            .line
            .slave(i)
            .and_then(|s| latch_read(s, read))
            .map_or(Item::Skip, Item::Send)
    }

    pub(crate) fn measure_item(&self, i: u16) -> Item {
        match self.phase {
            Phase::Measure(MeasureStep::Trigger) => Item::Send(LATCH_TRIGGER),
            Phase::Measure(MeasureStep::ReadBefore) => self.latch_item(i, LatchRead::Before),
            Phase::Measure(MeasureStep::ReadAfter) => self.latch_item(i, LatchRead::After),
            _ => Item::Skip,
        }
    }

    pub(crate) fn measure_reply(&mut self, r: Reply<'_>) -> Result<(), Error> {
        match self.phase {
            Phase::Measure(MeasureStep::Trigger) => {
                let line = &self.sh.line;
                r.sent
                    .check_latch_wkc(r.wkc, line.latching_count(), line.count)
            }
            Phase::Measure(MeasureStep::ReadBefore) => {
                store_latch_reply(&mut self.sh.line, r, LatchRead::Before)
            }
            Phase::Measure(MeasureStep::ReadAfter) => {
                store_latch_reply(&mut self.sh.line, r, LatchRead::After)
            }
            _ => Ok(()),
        }
    }

    pub(crate) fn measure_done(&mut self) -> Result<State, Error> {
        match self.phase {
            Phase::Measure(MeasureStep::ReadBefore) => Ok(State::LatchTrigger),
            Phase::Measure(MeasureStep::Trigger) => Ok(State::LatchReadAfter),
            Phase::Measure(MeasureStep::ReadAfter) => {
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
        self.sh.push_event(Event::DelaysMeasured {
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

/// The latching write: BWR 0x0900 (REQ-DC-101), 4 bytes of zeros.
pub(crate) const LATCH_TRIGGER: Op = Op::bwr_zero(reg::RECEIVE_TIME_PORT0, 4);

/// The read of `s`'s receive-time block, for a slave with latches.
pub(crate) fn latch_read(s: &SlaveInfo, read: LatchRead) -> Option<Op> {
    s.dc.has_latches()
        .then(|| Op::fprd(s.station, reg::RECEIVE_TIME_PORT0, read.len()))
}

/// A reply to [`latch_read`] (working counter 1), stored into the slave's entry (REQ-DC-020).
pub(crate) fn store_latch_reply<const N: usize>(
    line: &mut Line<N>,
    r: Reply<'_>,
    read: LatchRead,
) -> Result<(), Error> {
    expect_wkc(r.sent, 1, r.wkc)?;
    match line.slave_mut(r.item) {
        Some(s) => s.store_latches(read, r.data).ok_or(r.sent.out_of_range()),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    //! The latch round's own checks on a machine put straight into its step.
    use crate::dc::slave::DcKind;
    use crate::dc::testing;
    use crate::dc::{Config, Machine, State};
    use crate::time::SystemTime;
    use crate::wire::Command;

    /// A line of a 64-bit DC slave, a slave without DC and another 64-bit DC slave.
    fn line() -> Machine<4> {
        testing::line(&[DcKind::Bits64, DcKind::None, DcKind::Bits64])
    }

    /// The latch trigger (BWR 0x0900) is counted by every slave it reaches, and at least by
    /// every slave with latches: a working counter outside that range is not accepted, and
    /// the round starts over from the reads before the trigger instead of reading latches
    /// that may not have been taken.
    // verifies: REQ-DC-101
    #[test]
    fn latch_trigger_wkc_between_latching_and_all_slaves() {
        for (wkc, next) in [
            (0, State::LatchReadBefore),
            (1, State::LatchReadBefore),
            (2, State::LatchReadAfter),
            (3, State::LatchReadAfter),
            (4, State::LatchReadBefore),
        ] {
            let mut m = line();
            m.phase = m.phase.enter(State::LatchTrigger);
            let mut buf = [0u8; 1514];
            let now = SystemTime(1_000_000);
            let n = m.poll_transmit(now, &mut buf).unwrap();
            let reply = testing::answer(&buf[..n], |cmd| {
                assert_eq!(cmd, Command::Bwr);
                wkc
            });
            m.handle_frame(now, &reply);
            assert_eq!(m.state(), next, "WKC {wkc}");
        }
    }

    /// `configure` forgets a measurement in progress: its round count and trigger time.
    #[test]
    fn configure_forgets_the_latch_rounds() {
        let mut m = line();
        m.sh.latch.round = 2;
        m.sh.latch.trigger_time = SystemTime(5_000);
        m.configure(Config::default()).unwrap();
        assert_eq!(m.sh.latch.round, 0);
        assert_eq!(m.sh.latch.trigger_time, SystemTime::EPOCH);
    }
}
