//! [`Phase`]: which phase the machine is in and the data that belongs to that phase alone.
//! [`State`] (`dc/state.rs`) is its observable projection: the diagram, `State::can_go` and
//! the model checkers work on states, the code on phases.
//!
//! A phase's data exists only while the machine is in it: entering a phase from another one
//! starts it afresh, and leaving it drops its data, so no phase can read what another one left
//! behind. Within a phase, moving from one step to the next keeps the data (the drift gate
//! counts across its bursts and checks).

use crate::dc::cyclic::CyclicState;
use crate::dc::drift::DriftGate;
use crate::dc::state::State;

/// The discovery steps (`dc/discovery.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum DiscoveryStep {
    CountSlaves,
    AssignAddresses,
    ReadInfo,
    ProbeSystemTime,
}

/// The t_Diff measurement's steps (`dc/tdiff.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum TdiffStep {
    Read,
    Latch,
    Trigger,
    Close,
    Restore,
}

/// The delay measurement's steps (`dc/measure.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum MeasureStep {
    ReadBefore,
    Trigger,
    ReadAfter,
}

/// The offset write's steps (`dc/adjust.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum AdjustStep {
    ReadAlStatus,
    WriteOffsets,
    ResetLoops,
}

/// The static drift compensation's steps (`dc/drift.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum DriftStep {
    Burst,
    Check,
}

/// The SYNC activation's steps (`dc/activation.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum ActivationStep {
    ReadReferenceTime,
    ClearActivation,
    ProgramSync,
    ActivateSync,
}

/// The machine's phase, holding that phase's own data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Phase {
    Idle,
    Discovery(DiscoveryStep),
    Tdiff(TdiffStep),
    Measure(MeasureStep),
    Adjust(AdjustStep),
    /// The convergence gate lives as long as the drift compensation.
    Drift(DriftStep, DriftGate),
    Activation(ActivationStep),
    /// Cyclic operation's bookkeeping, hold-over and re-measurement (`dc/cyclic.rs`).
    Cyclic(CyclicState),
    RestartWait,
    Failed,
}

impl Phase {
    /// The observable state.
    pub(crate) const fn state(&self) -> State {
        match self {
            Phase::Idle => State::Idle,
            Phase::Discovery(s) => match s {
                DiscoveryStep::CountSlaves => State::CountSlaves,
                DiscoveryStep::AssignAddresses => State::AssignAddresses,
                DiscoveryStep::ReadInfo => State::ReadInfo,
                DiscoveryStep::ProbeSystemTime => State::ProbeSystemTime,
            },
            Phase::Tdiff(s) => match s {
                TdiffStep::Read => State::TdiffRead,
                TdiffStep::Latch => State::TdiffLatch,
                TdiffStep::Trigger => State::TdiffTrigger,
                TdiffStep::Close => State::TdiffClose,
                TdiffStep::Restore => State::TdiffRestore,
            },
            Phase::Measure(s) => match s {
                MeasureStep::ReadBefore => State::LatchReadBefore,
                MeasureStep::Trigger => State::LatchTrigger,
                MeasureStep::ReadAfter => State::LatchReadAfter,
            },
            Phase::Adjust(s) => match s {
                AdjustStep::ReadAlStatus => State::ReadAlStatus,
                AdjustStep::WriteOffsets => State::WriteOffsets,
                AdjustStep::ResetLoops => State::ResetLoops,
            },
            Phase::Drift(s, _) => match s {
                DriftStep::Burst => State::DriftBurst,
                DriftStep::Check => State::DriftCheck,
            },
            Phase::Activation(s) => match s {
                ActivationStep::ReadReferenceTime => State::ReadReferenceTime,
                ActivationStep::ClearActivation => State::ClearActivation,
                ActivationStep::ProgramSync => State::ProgramSync,
                ActivationStep::ActivateSync => State::ActivateSync,
            },
            Phase::Cyclic(_) => State::Cyclic,
            Phase::RestartWait => State::RestartWait,
            Phase::Failed => State::Failed,
        }
    }

    /// The phase of state `to`, entered from `self`: a step of the same phase keeps the
    /// phase's data, any other phase starts afresh. A new drift check starts without a bound
    /// read. (`Cyclic` has one step and is never re-entered from itself, `State::can_go`.)
    pub(crate) fn enter(self, to: State) -> Phase {
        match to {
            State::Idle => Phase::Idle,
            State::CountSlaves => Phase::Discovery(DiscoveryStep::CountSlaves),
            State::AssignAddresses => Phase::Discovery(DiscoveryStep::AssignAddresses),
            State::ReadInfo => Phase::Discovery(DiscoveryStep::ReadInfo),
            State::ProbeSystemTime => Phase::Discovery(DiscoveryStep::ProbeSystemTime),
            State::TdiffRead => Phase::Tdiff(TdiffStep::Read),
            State::TdiffLatch => Phase::Tdiff(TdiffStep::Latch),
            State::TdiffTrigger => Phase::Tdiff(TdiffStep::Trigger),
            State::TdiffClose => Phase::Tdiff(TdiffStep::Close),
            State::TdiffRestore => Phase::Tdiff(TdiffStep::Restore),
            State::LatchReadBefore => Phase::Measure(MeasureStep::ReadBefore),
            State::LatchTrigger => Phase::Measure(MeasureStep::Trigger),
            State::LatchReadAfter => Phase::Measure(MeasureStep::ReadAfter),
            State::ReadAlStatus => Phase::Adjust(AdjustStep::ReadAlStatus),
            State::WriteOffsets => Phase::Adjust(AdjustStep::WriteOffsets),
            State::ResetLoops => Phase::Adjust(AdjustStep::ResetLoops),
            State::DriftBurst | State::DriftCheck => {
                let mut gate = match self {
                    Phase::Drift(_, gate) => gate,
                    _ => DriftGate::IDLE,
                };
                let step = if matches!(to, State::DriftBurst) {
                    DriftStep::Burst
                } else {
                    gate.bound = None;
                    DriftStep::Check
                };
                Phase::Drift(step, gate)
            }
            State::ReadReferenceTime => Phase::Activation(ActivationStep::ReadReferenceTime),
            State::ClearActivation => Phase::Activation(ActivationStep::ClearActivation),
            State::ProgramSync => Phase::Activation(ActivationStep::ProgramSync),
            State::ActivateSync => Phase::Activation(ActivationStep::ActivateSync),
            State::Cyclic => Phase::Cyclic(CyclicState::default()),
            State::RestartWait => Phase::RestartWait,
            State::Failed => Phase::Failed,
        }
    }

    /// In `Cyclic` (cheaper than comparing [`Phase::state`], on the per-cycle path).
    #[inline(always)]
    pub(crate) const fn is_cyclic(&self) -> bool {
        matches!(self, Phase::Cyclic(_))
    }

    /// The drift gate, in the drift compensation.
    pub(crate) fn drift_gate(&self) -> Option<&DriftGate> {
        match self {
            Phase::Drift(_, gate) => Some(gate),
            _ => None,
        }
    }

    /// The drift gate, in the drift compensation.
    pub(crate) fn drift_gate_mut(&mut self) -> Option<&mut DriftGate> {
        match self {
            Phase::Drift(_, gate) => Some(gate),
            _ => None,
        }
    }

    /// Cyclic operation's data, in `Cyclic`.
    pub(crate) fn cyclic(&self) -> Option<&CyclicState> {
        match self {
            Phase::Cyclic(c) => Some(c),
            _ => None,
        }
    }

    /// Cyclic operation's data, in `Cyclic`.
    pub(crate) fn cyclic_mut(&mut self) -> Option<&mut CyclicState> {
        match self {
            Phase::Cyclic(c) => Some(c),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every state is the projection of the phase entered for it, from any phase.
    #[test]
    fn enter_projects_back_to_the_state() {
        for from in State::ALL {
            let p = Phase::Idle.enter(from);
            for to in State::ALL {
                assert_eq!(p.enter(to).state(), to, "{from} -> {to}");
            }
        }
    }

    /// The drift gate survives its own steps and starts afresh from any other phase.
    #[test]
    fn drift_gate_lives_as_long_as_the_drift_compensation() {
        let mut p = Phase::Adjust(AdjustStep::ResetLoops).enter(State::DriftBurst);
        if let Some(g) = p.drift_gate_mut() {
            g.frames = 5;
            g.bound = Some(3);
        }
        let p = p.enter(State::DriftCheck);
        assert_eq!(p.drift_gate().map(|g| (g.frames, g.bound)), Some((5, None)));
        let p = p.enter(State::DriftBurst).enter(State::Failed);
        assert_eq!(p.drift_gate(), None);
        let p = p.enter(State::DriftBurst);
        assert_eq!(p.drift_gate(), Some(&DriftGate::IDLE));
    }

    /// The cyclic getters read the phase's data, and see none outside `Cyclic`.
    #[test]
    fn cyclic_data_is_read_in_cyclic_only() {
        use crate::dc::{Config, Machine};
        use crate::time::SystemTime;
        let mut m = Machine::<4>::new(Config::default()).unwrap();
        let mut c = CyclicState {
            bound_ns: Some(5),
            ref_time: Some(crate::time::SystemTime(7)),
            ..CyclicState::default()
        };
        c.lock.locked = true;
        m.phase = Phase::Cyclic(c);
        assert!(m.is_locked() && !m.in_holdover());
        assert_eq!(m.diff_bound_ns(), Some(5));
        assert_eq!(m.reference_time(), Some(SystemTime(7)));
        m.phase = m.phase.enter(State::Failed);
        assert!(!m.is_locked());
        assert_eq!((m.diff_bound_ns(), m.reference_time()), (None, None));
    }
}
