//! Reference model of the DC machine's observable contract (REQ-DC-110, REQ-DC-111,
//! REQ-DC-113; property P6 in `SPEC.md` §2), written plainly from the bring-up of `SPEC.md`
//! (ETG.1020 order) and not from the machine's code.
//!
//! It answers three questions:
//!
//! 1. [`allowed_request`]: which datagrams (command, register, length) the machine may send in
//!    which state;
//! 2. [`RefMachine::apply`]: for a line of `k` ideal DC slaves that all answer faithfully, which
//!    state and which events follow each abstract input ([`Input`]): a complete exchange, a
//!    lost frame, a stale reply before the real one, junk, `reset`, `start`;
//! 3. [`RefMachine::locked`]: whether cyclic operation is locked.
//!
//! The model is deterministic and assumes the configuration of the property runs (one latch
//! round, one retry, burst and convergence gate of one frame, lock after one good cycle, two
//! lost cycles tolerated, automatic restart, SYNC programmed, t_Diff measurement off: the
//! property runs' ring does not model forced port loops; harness/tests/tdiff.rs covers that
//! step on the emulator) — see [`ModelConfig`].

use ecdc_core::dc::State;
use ecdc_core::wire::Command;

/// Configuration values the model depends on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelConfig {
    /// Latch rounds per delay measurement.
    pub latch_rounds: u8,
    /// Retries of a request step after a timeout or error.
    pub retries: u8,
    /// Consecutive lost cycles that start a hold-over (REQ-DC-127; the property runs never
    /// reach its time limit, REQ-DC-129).
    pub max_lost_cycles: u16,
}

/// Kind of an event (the contract names events, not their numbers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EventKind {
    /// Slaves counted and addressed (`count`, `dc`).
    SlavesFound(u16, u16),
    /// t_Diff values resolved (with the measurement off: every slave's default).
    TdiffResolved,
    /// Delays measured.
    DelaysMeasured,
    /// Offsets written (`written`, `skipped_running`).
    OffsetsWritten(u16, u16),
    /// Drift gate passed.
    DriftConverged,
    /// SYNC programmed on this many slaves (those whose offset may be written).
    SyncStarted(u16),
    /// Cyclic lock reached.
    Locked,
    /// A timeout in this state.
    Timeout(State),
    /// Automatic restart scheduled.
    Restarting,
    /// Cyclic operation went silent: hold-over (REQ-DC-127).
    HoldoverStarted,
    /// The first complete cycle after a hold-over passed the resume check (REQ-DC-128).
    HoldoverEnded,
}

/// An abstract input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// The machine sends its next frame (time advances to its next deadline if it has nothing
    /// to send yet) and the faithful reply comes back.
    Exchange,
    /// As `Exchange`, but first a stale reply (to the previous frame) arrives: it must change
    /// nothing.
    StaleThenExchange,
    /// The machine sends its next frame and the reply is lost: time advances to the deadline.
    Lost,
    /// A junk frame arrives.
    Junk,
    /// `reset()`.
    Reset,
    /// `start()`.
    Start,
}

/// May the machine send `command` to `register` with `len` data bytes in `state`?
/// (`Cyclic` includes the datagrams of a delay re-measurement.)
pub fn allowed_request(state: State, command: Command, register: u16, len: u16) -> bool {
    use Command::*;
    match state {
        State::Idle | State::RestartWait | State::Failed => false,
        // Before the count: the restore of a port an interrupted t_Diff step left closed.
        State::CountSlaves => {
            (command == Brd && register == 0x0000)
                || (command == Fpwr && register == 0x0100 && len == 2)
        }
        State::AssignAddresses => command == Apwr && register == 0x0010 && len == 2,
        State::ReadInfo => command == Fprd && matches!(register, 0x0008 | 0x0110),
        State::ProbeSystemTime | State::ReadReferenceTime => {
            command == Fprd && register == 0x0910 && matches!(len, 4 | 8)
        }
        State::TdiffRead => {
            command == Fprd && matches!(register, 0x0000 | 0x0130 | 0x0100) && len == 2
        }
        State::TdiffLatch => command == Fprd && register == 0x0900 && len == 16,
        State::TdiffTrigger => command == Bwr && register == 0x0900,
        State::TdiffClose | State::TdiffRestore => {
            command == Fpwr && register == 0x0100 && len == 2
        }
        State::LatchReadBefore => command == Fprd && register == 0x0900 && len == 16,
        State::LatchTrigger => command == Bwr && register == 0x0900,
        State::LatchReadAfter => command == Fprd && register == 0x0900 && len == 32,
        // 0x0920 of the slaves found running (REQ-DC-131).
        State::ReadAlStatus => {
            command == Fprd
                && ((register == 0x0130 && len == 2)
                    || (register == 0x0920 && matches!(len, 4 | 8)))
        }
        State::WriteOffsets => {
            command == Fpwr
                && ((register == 0x0920 && matches!(len, 4 | 8))
                    || (register == 0x0928 && len == 4))
        }
        State::ResetLoops => command == Fpwr && matches!(register, 0x0930 | 0x0934) && len == 2,
        State::DriftBurst => matches!(command, Frmw | Armw) && register == 0x0910,
        State::DriftCheck => {
            (matches!(command, Frmw | Armw) && register == 0x0910)
                || (matches!(command, Brd | Fprd) && register == 0x092C && len == 4)
        }
        State::ClearActivation => command == Fpwr && register == 0x0981 && len == 1,
        State::ProgramSync => {
            command == Fpwr
                && ((register == 0x0990 && matches!(len, 4 | 8))
                    || (matches!(register, 0x09A0 | 0x09A4) && len == 4))
        }
        State::ActivateSync => command == Fpwr && register == 0x0980 && len == 2,
        State::Cyclic => {
            (matches!(command, Frmw | Armw) && register == 0x0910)
                || (matches!(command, Brd | Fprd) && register == 0x092C && len == 4)
                || (command == Brd && register == 0x0130 && len == 2)
                || (command == Fprd && register == 0x0900 && matches!(len, 16 | 32))
                || (command == Bwr && register == 0x0900)
                || (command == Fpwr && register == 0x0928 && len == 4)
        }
    }
}

/// The reference machine: a line of `k` ideal DC slaves, `writable` of them in INIT, PRE-OP
/// or BOOT (the others running).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RefMachine {
    /// Configuration.
    pub cfg: ModelConfig,
    /// Slaves on the line (all with a system time).
    pub k: u16,
    /// Slaves whose offset may be written.
    pub writable: u16,
    /// Current state.
    pub state: State,
    /// Failed attempts of the current request step.
    pub tries: u8,
    /// Latch rounds done in this measurement.
    pub rounds: u8,
    /// Consecutive lost cycles.
    pub lost: u16,
    /// Cyclic lock.
    pub locked: bool,
    /// In hold-over (cyclic operation silent for `max_lost_cycles` cycles).
    pub holdover: bool,
    /// The AL states of this `ReadAlStatus` step are in; its 0x0920 reads of the running
    /// slaves follow in a frame of their own (REQ-DC-131).
    pub al_read: bool,
}

impl RefMachine {
    /// A machine in `Idle` for a line of `k` slaves.
    pub fn new(cfg: ModelConfig, k: u16, writable: u16) -> RefMachine {
        RefMachine {
            cfg,
            k,
            writable,
            state: State::Idle,
            tries: 0,
            rounds: 0,
            lost: 0,
            locked: false,
            holdover: false,
            al_read: false,
        }
    }

    /// Whether cyclic operation is locked.
    pub fn locked(&self) -> bool {
        self.state == State::Cyclic && self.locked && !self.holdover
    }

    fn enter(&mut self, s: State) {
        self.state = s;
        self.tries = 0;
        if s == State::CountSlaves {
            self.rounds = 0;
        }
        if s == State::Cyclic {
            self.lost = 0;
            self.locked = false;
        }
        self.holdover = false;
        self.al_read = false;
    }

    /// The state in which the next frame is built: a restart pause ends, and steps with
    /// nothing to send are passed. Loop reset and SYNC programming concern only slaves whose
    /// offset may be written (REQ-DC-103): with none, they are empty.
    fn sending_state(&mut self, ev: &mut Vec<EventKind>) {
        if self.state == State::RestartWait {
            self.enter(State::CountSlaves);
        }
        // The model runs with the t_Diff measurement off (`TdiffMode::Off`): the step sends
        // nothing and goes straight on to the delay measurement.
        if self.state == State::TdiffRead {
            ev.push(EventKind::TdiffResolved);
            self.enter(State::LatchReadBefore);
        }
        if self.state == State::ResetLoops && self.writable == 0 {
            self.enter(State::DriftBurst);
        }
        if self.writable == 0
            && matches!(
                self.state,
                State::ClearActivation | State::ProgramSync | State::ActivateSync
            )
        {
            ev.push(EventKind::SyncStarted(0));
            self.enter(State::Cyclic);
        }
    }

    /// Successor of a request step whose frame was answered faithfully, with its events.
    fn after_reply(&mut self, ev: &mut Vec<EventKind>) {
        use State::*;
        let next = match self.state {
            CountSlaves => AssignAddresses,
            AssignAddresses => ReadInfo,
            ReadInfo => ProbeSystemTime,
            ProbeSystemTime => {
                ev.push(EventKind::SlavesFound(self.k, self.k));
                TdiffRead
            }
            LatchReadBefore => LatchTrigger,
            LatchTrigger => LatchReadAfter,
            LatchReadAfter => {
                self.rounds = self.rounds.saturating_add(1);
                if self.rounds < self.cfg.latch_rounds {
                    LatchReadBefore
                } else {
                    ev.push(EventKind::DelaysMeasured);
                    ReadAlStatus
                }
            }
            ReadAlStatus if self.writable < self.k && !self.al_read => {
                self.al_read = true;
                ReadAlStatus
            }
            ReadAlStatus => WriteOffsets,
            WriteOffsets => {
                ev.push(EventKind::OffsetsWritten(
                    self.writable,
                    self.k.saturating_sub(self.writable),
                ));
                ResetLoops
            }
            ResetLoops => DriftBurst,
            DriftBurst => DriftCheck,
            DriftCheck => {
                // Ideal slaves: |Δt| = 0 at the first check.
                ev.push(EventKind::DriftConverged);
                ReadReferenceTime
            }
            ReadReferenceTime => ClearActivation,
            ClearActivation => ProgramSync,
            ProgramSync => ActivateSync,
            ActivateSync => {
                ev.push(EventKind::SyncStarted(self.writable));
                Cyclic
            }
            Cyclic => {
                self.lost = 0;
                // Ideal slaves that kept running: the resume check passes, the lock (if
                // reached before) is kept.
                if self.holdover {
                    self.holdover = false;
                    ev.push(EventKind::HoldoverEnded);
                }
                if !self.locked {
                    // Ideal slaves: bound 0 ≤ lock threshold at the first cycle.
                    self.locked = true;
                    ev.push(EventKind::Locked);
                }
                Cyclic
            }
            s => s,
        };
        if next != self.state {
            self.enter(next);
        } else {
            self.tries = 0;
        }
    }

    fn after_loss(&mut self, ev: &mut Vec<EventKind>) {
        let fault = |m: &mut RefMachine, ev: &mut Vec<EventKind>| {
            ev.push(EventKind::Timeout(m.state));
            ev.push(EventKind::Restarting);
            m.locked = false;
            m.enter(State::RestartWait);
        };
        if self.state == State::Cyclic {
            self.lost = self.lost.saturating_add(1);
            if self.lost >= self.cfg.max_lost_cycles && !self.holdover {
                self.holdover = true;
                ev.push(EventKind::HoldoverStarted);
            }
        } else if self.tries < self.cfg.retries {
            let tries = self.tries.saturating_add(1);
            if matches!(self.state, State::LatchTrigger | State::LatchReadAfter) {
                // The trigger may or may not have latched: the round starts again.
                self.enter(State::LatchReadBefore);
            }
            self.tries = tries;
        } else {
            fault(self, ev);
        }
    }

    /// Applies an input; returns the events that must follow, in order.
    pub fn apply(&mut self, input: Input) -> Vec<EventKind> {
        let mut ev = Vec::new();
        match input {
            Input::Reset => self.enter(State::Idle),
            Input::Start => self.enter(State::CountSlaves),
            Input::Junk => {}
            Input::Exchange | Input::StaleThenExchange | Input::Lost => {
                if self.state == State::Idle || self.state == State::Failed {
                    return ev;
                }
                self.sending_state(&mut ev);
                if input == Input::Lost {
                    self.after_loss(&mut ev);
                } else {
                    self.after_reply(&mut ev);
                }
            }
        }
        ev
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A started model of `k` slaves, `writable` of them with a writable offset: one retry, a
    /// hold-over after two lost cycles.
    fn started(latch_rounds: u8, k: u16, writable: u16) -> RefMachine {
        let cfg = ModelConfig {
            latch_rounds,
            retries: 1,
            max_lost_cycles: 2,
        };
        let mut m = RefMachine::new(cfg, k, writable);
        m.apply(Input::Start);
        m
    }

    #[test]
    fn faithful_bringup_order() {
        let mut m = started(2, 3, 1);
        let mut seen = vec![m.state];
        let mut events = Vec::new();
        for _ in 0..30 {
            events.extend(m.apply(Input::Exchange));
            seen.push(m.state);
        }
        assert!(seen.contains(&State::ResetLoops));
        assert_eq!(m.state, State::Cyclic);
        assert!(m.locked());
        assert_eq!(
            events,
            vec![
                EventKind::SlavesFound(3, 3),
                EventKind::TdiffResolved,
                EventKind::DelaysMeasured,
                EventKind::OffsetsWritten(1, 2),
                EventKind::DriftConverged,
                EventKind::SyncStarted(1),
                EventKind::Locked
            ]
        );
        // Two latch rounds: LatchReadAfter is followed once by LatchReadBefore.
        let rounds = seen
            .windows(2)
            .filter(|w| w[0] == State::LatchReadAfter && w[1] == State::LatchReadBefore)
            .count();
        assert_eq!(rounds, 1);
        // Every transition is one the machine's table allows. TdiffRead sends nothing with the
        // measurement off: the exchange after it already is LatchReadBefore's.
        for w in seen.windows(2) {
            let through = w[0] == State::TdiffRead
                && w[0].can_go(State::LatchReadBefore)
                && State::LatchReadBefore.can_go(w[1]);
            assert!(w[0] == w[1] || w[0].can_go(w[1]) || through, "{:?}", w);
        }
    }

    /// REQ-DC-127, 128: lost cycles in `Cyclic` start a hold-over, not a restart; the next
    /// complete cycle ends it and the lock is back.
    // verifies: REQ-DC-127
    #[test]
    fn silence_in_cyclic_holds_over() {
        let mut m = started(1, 2, 2);
        for _ in 0..100 {
            if m.locked() {
                break;
            }
            m.apply(Input::Exchange);
        }
        assert!(m.locked());
        assert!(m.apply(Input::Lost).is_empty());
        assert_eq!(m.apply(Input::Lost), vec![EventKind::HoldoverStarted]);
        assert!(!m.locked());
        assert!(m.apply(Input::Lost).is_empty());
        assert_eq!(m.state, State::Cyclic);
        assert_eq!(m.apply(Input::Exchange), vec![EventKind::HoldoverEnded]);
        assert!(m.locked());
    }

    #[test]
    fn losses_retry_then_restart() {
        let mut m = started(1, 1, 1);
        assert!(m.apply(Input::Lost).is_empty());
        assert_eq!(m.state, State::CountSlaves);
        assert_eq!(
            m.apply(Input::Lost),
            vec![
                EventKind::Timeout(State::CountSlaves),
                EventKind::Restarting
            ]
        );
        assert_eq!(m.state, State::RestartWait);
        m.apply(Input::Exchange);
        assert_eq!(m.state, State::AssignAddresses);
        assert!(!allowed_request(State::Cyclic, Command::Fpwr, 0x0920, 8));
        assert!(allowed_request(
            State::WriteOffsets,
            Command::Fpwr,
            0x0920,
            8
        ));
    }
}
