//! Dispatch of the request steps: for the current [`State`], which datagrams make up the step,
//! how each reply is checked and stored, and where the step goes when done. The per-step logic
//! lives in `discovery.rs`, `measure.rs`, `adjust.rs`, `drift.rs` and `activation.rs`.

use crate::dc::config::DriftCommand;
use crate::dc::error::Error;
use crate::dc::machine::{Item, Machine};
use crate::dc::phase::{AdjustStep, DiscoveryStep, DriftStep, MeasureStep, Phase};
use crate::dc::request::{Op, Pending, Reply};
use crate::dc::shared::{expect_wkc, Shared};
use crate::dc::state::State;
use crate::dc::timer::Timer;
use crate::time::SystemTime;

impl<const N: usize> Machine<N> {
    /// Number of items of the current step.
    pub(crate) fn item_count(&self) -> u16 {
        match self.phase {
            Phase::Discovery(step) => self.discovery_count(step),
            Phase::Tdiff(_) => self.tdiff_count(),
            Phase::Measure(step) => self.measure_count(step),
            Phase::Adjust(step) => self.adjust_count(step),
            Phase::Drift(step, _) => self.drift_count(step),
            Phase::Activation(step) => self.activation_count(step),
            Phase::Idle | Phase::Cyclic(_) | Phase::RestartWait | Phase::Failed => 0,
        }
    }

    /// Most items per frame: one FRMW per frame in a burst (each frame is one loop sample).
    pub(crate) fn max_per_frame(&self) -> usize {
        match self.phase {
            // The count is one datagram; the restore of an interrupted t_Diff measurement that
            // may come before it goes alone.
            Phase::Discovery(DiscoveryStep::CountSlaves) => 1,
            Phase::Drift(DriftStep::Burst, _) => 1,
            // REQ-DC-131: the 0x0920 reads depend on the AL states, so no frame mixes the two:
            // a frame from the AL half ends with its last AL read.
            Phase::Adjust(AdjustStep::ReadAlStatus) if self.sh.step.cursor < self.sh.line.count => {
                self.slaves()
                    .iter()
                    .skip(usize::from(self.sh.step.cursor))
                    .filter(|s| s.dc.has_system_time())
                    .count()
                    .max(1)
            }
            // One entry stays free for the FRMW that closes every check frame.
            Phase::Drift(DriftStep::Check, _) => crate::dc::request::MAX_INFLIGHT.saturating_sub(1),
            _ => usize::MAX,
        }
    }

    pub(crate) fn item(&self, now: SystemTime, i: u16) -> Item {
        if self.phase == Phase::Discovery(DiscoveryStep::CountSlaves) && self.sh.tdiff.recovering {
            return match i {
                0 => self.tdiff_recover_item(),
                _ => self.discovery_item(0),
            };
        }
        match self.phase {
            Phase::Discovery(_) => self.discovery_item(i),
            Phase::Tdiff(_) => self.tdiff_item(i),
            Phase::Measure(_) => self.measure_item(i),
            Phase::Adjust(_) => self.adjust_item(i),
            Phase::Drift(..) => self.drift_item(now, i),
            Phase::Activation(_) => self.activation_item(i),
            Phase::Idle | Phase::Cyclic(_) | Phase::RestartWait | Phase::Failed => Item::Skip,
        }
    }

    /// Hook right before an item goes out (the latch trigger samples master time here).
    pub(crate) fn before_send(&mut self, now: SystemTime) {
        if self.phase == Phase::Measure(MeasureStep::Trigger) {
            // REQ-DC-102: master time sampled *before* the latching BWR leaves.
            self.sh.latch.trigger_time = now;
        }
        if let Phase::Drift(DriftStep::Burst, gate) = &mut self.phase {
            // One FRMW per burst frame: one loop sample in every slave.
            gate.frames = gate.frames.saturating_add(1);
        }
    }

    pub(crate) fn on_item(&mut self, now: SystemTime, r: Reply<'_>) -> Result<(), Error> {
        if self.phase == Phase::Discovery(DiscoveryStep::CountSlaves) && self.sh.tdiff.recovering {
            return match r.item {
                0 => {
                    self.tdiff_recover_reply();
                    Ok(())
                }
                // The count's reply: its handler does not read the item number.
                _ => self.discovery_reply(r),
            };
        }
        match self.phase {
            Phase::Discovery(_) => self.discovery_reply(r),
            Phase::Tdiff(_) => self.tdiff_reply(r),
            Phase::Measure(_) => self.measure_reply(r),
            Phase::Adjust(_) => self.adjust_reply(r),
            Phase::Drift(..) => self.drift_reply(r),
            Phase::Activation(_) => self.activation_reply(now, r),
            Phase::Idle | Phase::Cyclic(_) | Phase::RestartWait | Phase::Failed => Ok(()),
        }
    }

    /// Per-state initialisation when a state is entered.
    pub(crate) fn on_enter(&mut self, to: State) {
        match to {
            State::CountSlaves => {
                self.sh.line.forget_found();
                self.sh.latch.round = 0;
                self.tdiff_reset();
            }
            State::Cyclic => self.sh.scratch.monitor.invalidate(),
            _ => {}
        }
    }

    /// The step's items are all sent and answered: validate the whole step and move on.
    pub(crate) fn step_done(&mut self, now: SystemTime) {
        let next = match self.phase {
            Phase::Discovery(_) => self.discovery_done(),
            Phase::Tdiff(_) => self.tdiff_done(),
            Phase::Measure(_) => self.measure_done(),
            Phase::Adjust(_) => self.adjust_done(),
            Phase::Drift(..) => self.drift_done(),
            Phase::Activation(_) => self.activation_done(),
            Phase::Idle | Phase::Cyclic(_) | Phase::RestartWait | Phase::Failed => return,
        };
        match next {
            Ok(s) => {
                self.enter(s);
                if self.phase.is_cyclic() {
                    // The first cycle is due at once: the cycle grid starts where the
                    // bring-up ends.
                    self.sh.timers.set(Timer::Cycle, now);
                }
            }
            Err(e) => self.fault(now, e),
        }
    }
}

impl<const N: usize> Shared<N> {
    /// The drift-compensation datagram to the reference's 0x0910, of the reference's width:
    /// FRMW by station address or ARMW by position (`Config::drift_command`).
    pub(crate) fn frmw_op(&self, now: SystemTime) -> Op {
        let (station, width) = self
            .line
            .slave(self.line.reference)
            .map_or((0, 8), |s| (s.station, s.dc.time_width()));
        let reg = crate::wire::register::reg::SYSTEM_TIME;
        match self.cfg.drift_command {
            DriftCommand::Frmw => Op::frmw(station, reg, width, now.as_nanos()),
            DriftCommand::Armw => Op {
                command: crate::wire::Command::Armw,
                address: crate::wire::Address::position(self.line.reference, reg),
                len: width,
                payload: crate::dc::request::Payload::Le(now.as_nanos()),
            },
        }
    }

    /// FRMW working counter: every slave with a system time reads or writes it once.
    pub(crate) fn check_frmw(&self, p: Pending, wkc: u16) -> Result<(), Error> {
        expect_wkc(p, self.line.sys_count, wkc)
    }
}
