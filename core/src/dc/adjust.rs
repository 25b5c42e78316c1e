//! Offset and delay writes (REQ-DC-103): read AL status (and 0x0920 of the slaves that may be
//! running, to anchor the other offsets on their domain, REQ-DC-131), write 0x0920 with the
//! slave's exact width only to slaves that are provably not running, write 0x0928 to every slave with a
//! system time, then reset the loop of every slave whose offset changed (0x0934, then 0x0930,
//! ETG1020 §22.2.4 order as ethercrab and KickCAT; REQ-DC-031).

use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::{Item, Machine};
use crate::dc::phase::{AdjustStep, Phase};
use crate::dc::request::{le, Op, Reply};
use crate::dc::shared::expect_wkc;
use crate::dc::state::State;
use crate::dc::work::PerSlave;
use crate::wire::register::{reg, typed};

/// The writes of `WriteOffsets`, per slave with a system time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum DcWrite {
    /// 0x0920 (exact width), only where the offset may be stepped.
    Offset,
    /// 0x0928.
    Delay,
}

impl PerSlave for DcWrite {
    const ALL: &'static [Self] = &[DcWrite::Offset, DcWrite::Delay];
}

/// The writes of `ResetLoops`, per slave whose offset was written (0x0934 before 0x0930).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum LoopReset {
    /// 0x0934.
    FilterDepths,
    /// 0x0930.
    SpeedCounterStart,
}

impl PerSlave for LoopReset {
    const ALL: &'static [Self] = &[LoopReset::FilterDepths, LoopReset::SpeedCounterStart];
}

impl<const N: usize> Machine<N> {
    /// Items of an offset step.
    pub(crate) fn adjust_count(&self, step: AdjustStep) -> u16 {
        let n = self.sh.line.count;
        match step {
            // AL status of every slave, then 0x0920 of the running ones.
            AdjustStep::ReadAlStatus => n.saturating_mul(2),
            AdjustStep::WriteOffsets => DcWrite::items(n),
            AdjustStep::ResetLoops => LoopReset::items(n),
        }
    }

    pub(crate) fn adjust_item(&self, i: u16) -> Item {
        match self.phase {
            Phase::Adjust(AdjustStep::ReadAlStatus) if i < self.sh.line.count => {
                match self.sh.line.slave(i) {
                    Some(s) if s.dc.has_system_time() => {
                        Item::Send(Op::fprd(s.station, reg::AL_STATUS, 2))
                    }
                    _ => Item::Skip,
                }
            }
            // REQ-DC-131: the offset of every slave whose offset stays, after every AL status
            // of the step is in (`max_per_frame` keeps the two halves in separate frames).
            Phase::Adjust(AdjustStep::ReadAlStatus) => {
                match self.sh.line.slave(i.saturating_sub(self.sh.line.count)) {
                    Some(s) if s.dc.has_system_time() && s.al_status.is_some() => {
                        if s.may_step_offset() {
                            Item::Skip
                        } else {
                            let w = s.dc.time_width();
                            Item::Send(Op::fprd(s.station, reg::SYSTEM_TIME_OFFSET, w))
                        }
                    }
                    _ => Item::Skip,
                }
            }
            Phase::Adjust(AdjustStep::WriteOffsets) => match DcWrite::of(i) {
                Some((pos, write)) => match self.sh.line.slave(pos) {
                    Some(s) if s.dc.has_system_time() => match write {
                        // REQ-DC-103: never step the system time of a (possibly) running slave.
                        DcWrite::Offset if s.may_step_offset() => {
                            let w = s.dc.time_width();
                            Item::Send(Op::fpwr(s.station, reg::SYSTEM_TIME_OFFSET, w, s.offset))
                        }
                        DcWrite::Offset => Item::Skip,
                        DcWrite::Delay => Item::Send(Op::fpwr(
                            s.station,
                            reg::SYSTEM_TIME_DELAY,
                            4,
                            u64::from(s.delay_ns),
                        )),
                    },
                    _ => Item::Skip,
                },
                None => Item::Skip,
            },
            Phase::Adjust(AdjustStep::ResetLoops) => match LoopReset::of(i) {
                Some((pos, write)) => match self.sh.line.slave(pos) {
                    Some(s) if s.offset_written => {
                        let (register, v) = match write {
                            LoopReset::FilterDepths => (
                                reg::SYSTEM_TIME_DIFF_FILTER_DEPTH,
                                self.sh.cfg.filter_depths,
                            ),
                            LoopReset::SpeedCounterStart => {
                                (reg::SPEED_COUNTER_START, self.sh.cfg.speed_counter_start)
                            }
                        };
                        Item::Send(Op::fpwr(s.station, register, 2, u64::from(v)))
                    }
                    _ => Item::Skip,
                },
                None => Item::Skip,
            },
            _ => Item::Skip,
        }
    }

    pub(crate) fn adjust_reply(&mut self, r: Reply<'_>) -> Result<(), Error> {
        let (i, p, wkc, data) = r.parts();
        expect_wkc(p, 1, wkc)?;
        match self.phase {
            Phase::Adjust(AdjustStep::ReadAlStatus) if i >= self.sh.line.count => {
                let v = le(data, usize::from(p.len)).ok_or(p.out_of_range())?;
                if let Some(s) = self.sh.line.slave_mut(i.saturating_sub(self.sh.line.count)) {
                    s.running_offset = Some(v);
                }
            }
            Phase::Adjust(AdjustStep::ReadAlStatus) => {
                let v = typed::AL_STATUS
                    .decode(data)
                    .map_err(|_| p.out_of_range())?;
                if let Some(s) = self.sh.line.slave_mut(i) {
                    s.al_status = Some(v);
                }
            }
            Phase::Adjust(AdjustStep::WriteOffsets) => {
                if let Some((pos, DcWrite::Offset)) = DcWrite::of(i) {
                    if let Some(s) = self.sh.line.slave_mut(pos) {
                        s.offset_written = true;
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }

    pub(crate) fn adjust_done(&mut self) -> Result<State, Error> {
        match self.phase {
            Phase::Adjust(AdjustStep::ReadAlStatus) => {
                self.sh.anchor_on_running_domain()?;
                for s in self.sh.line.slaves.iter_mut() {
                    s.offset_written = false;
                    s.sync_programmed = false;
                }
                Ok(State::WriteOffsets)
            }
            Phase::Adjust(AdjustStep::WriteOffsets) => {
                let mut written = 0u16;
                let mut skipped = 0u16;
                for s in self.slaves().iter().filter(|s| s.dc.has_system_time()) {
                    if s.offset_written {
                        written = written.saturating_add(1);
                    } else {
                        skipped = skipped.saturating_add(1);
                    }
                }
                self.sh.push_event(Event::OffsetsWritten {
                    written,
                    skipped_running: skipped,
                });
                Ok(State::ResetLoops)
            }
            Phase::Adjust(AdjustStep::ResetLoops) => Ok(State::DriftBurst),
            _ => Ok(self.state()),
        }
    }
}
