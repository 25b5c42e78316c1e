//! The explicit states of the DC machine and its one transition table.
//!
//! ```text
//!  Idle ──start──▶ CountSlaves ─▶ AssignAddresses ─▶ ReadInfo ─▶ ProbeSystemTime
//!                      ▲   (first: restore of a port an                        │
//!                      │    interrupted t_Diff step left closed)               ▼
//!                      │      TdiffRead ─(mode Off, or a slave running)────────────┐
//!                      │          ▼                                                │
//!                      │     TdiffLatch ◀─▶ TdiffTrigger ◀── TdiffClose ◀─┐        │
//!                      │  (all-open rounds, then per target closed rounds; │        │
//!                      │   TdiffLatch ⟲ while its last frame carries the   │        │
//!                      │   next round's trigger)                           │        │
//!                      │          ▼                                        │        │
//!                      │     TdiffRestore ──(next target)──────────────────┘        │
//!                      │          │ (no target left; TdiffLatch too if none at all) │
//!                      │          ▼                                                 │
//!                 RestartWait  ┌──── LatchReadBefore ◀───────────────────────────────┘
//!                      ▲       ▼                        ▲
//!                      │  LatchTrigger ─▶ LatchReadAfter ┘ (K rounds)
//!            (any fault, auto_restart)         │
//!                      │                       ▼
//!                   Failed ◀──(fault, no restart)       ReadAlStatus ─▶ WriteOffsets ─▶ ResetLoops
//!                                                                                   │
//!                                 ┌─────────────────────────────────────────────────┘
//!                                 ▼
//!                            DriftBurst ◀─▶ DriftCheck ─(K checks below threshold)─┐
//!                                                                                  ▼
//!   Cyclic ◀─ ActivateSync ◀─ ProgramSync ◀─ ClearActivation ◀─ ReadReferenceTime ◀┘
//!     (`sync: None` goes from DriftCheck straight to Cyclic)
//! ```
//!
//! Every state except `Idle`, `RestartWait`, `Failed` and `Cyclic` is a *request step*: a list of
//! datagrams (usually one per slave) sent in as few frames as fit, whose replies are all
//! validated before the next step starts. Invalid transitions are refused by [`State::can_go`]
//! and never panic (REQ-DC-110).

/// One state of [`crate::dc::Machine`].
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, Machine, State};
/// use ecdc_core::time::SystemTime;
///
/// let mut dc = Machine::<8>::new(Config::default())?;
/// assert_eq!(dc.state(), State::Idle);
/// dc.start(SystemTime::from_nanos(1_000_000_000));
/// assert_eq!(dc.state(), State::CountSlaves);
/// # Ok::<(), ecdc_core::dc::ConfigError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum State {
    /// Not started; `start` begins the bring-up.
    Idle,
    /// BRD 0x0000: the working counter is the number of slaves.
    CountSlaves,
    /// APWR 0x0010 per position: station addresses.
    AssignAddresses,
    /// FPRD 0x0008 (features), 0x0110 (DL status) per slave.
    ReadInfo,
    /// FPRD 0x0910 per DC slave: WKC 1 = has system time, WKC 0 = delay-only ESC.
    ProbeSystemTime,
    /// FPRD 0x0000 (type, revision) and 0x0130 per slave, 0x0100 per possible
    /// t_Diff target (REQ-DC-120, REQ-DC-123).
    TdiffRead,
    /// FPRD 0x0900..0x090F: the port times of a t_Diff latch (every DC slave with all ports
    /// open; only the upstream DC slave while a target is closed), followed by the BWR of
    /// the next latch when one of the same kind follows (one frame per round).
    TdiffLatch,
    /// BWR 0x0900 of a t_Diff latch; slaves behind a closed port do not count (REQ-DC-125).
    TdiffTrigger,
    /// FPWR 0x0100: force the target's downstream ports closed (loop bits 0b11).
    TdiffClose,
    /// FPWR 0x0100: the target's DL control as read in `TdiffRead`.
    TdiffRestore,
    /// FPRD 0x0900..0x090F per DC slave: latches before the trigger (stale-latch detection).
    LatchReadBefore,
    /// BWR 0x0900: latch receive times everywhere; master time sampled just before sending.
    LatchTrigger,
    /// FPRD 0x0900..0x091F per DC slave: port times and the EPU time of the trigger frame.
    LatchReadAfter,
    /// FPRD 0x0130 per DC slave: AL status, to never step 0x0920 of a running slave; then
    /// FPRD 0x0920 of each slave that may be running, whose domain the others join
    /// (REQ-DC-131).
    ReadAlStatus,
    /// FPWR 0x0920 (exact width) on non-running slaves and 0x0928 on every DC slave.
    WriteOffsets,
    /// FPWR 0x0934 then 0x0930 on every slave whose offset was written: loop reset.
    ResetLoops,
    /// FRMW 0x0910 frames back to back.
    DriftBurst,
    /// FRMW plus 0x092C reads: the convergence gate.
    DriftCheck,
    /// FPRD 0x0910 of the reference: the one time all SYNC start times derive from.
    ReadReferenceTime,
    /// FPWR 0x0981 = 0 on every SYNC slave.
    ClearActivation,
    /// FPWR 0x0990 (exact width), 0x09A0, 0x09A4 on every SYNC slave.
    ProgramSync,
    /// FPWR 0x0980 (2 bytes) = AssignActivate on every SYNC slave.
    ActivateSync,
    /// One FRMW per cycle, 0x092C monitoring, lock detection, delay re-measurement.
    Cyclic,
    /// Waiting `restart_delay_ns` before re-initialising after a fault.
    RestartWait,
    /// Stopped after a fault with `auto_restart` off; `start` tries again.
    Failed,
}

impl State {
    /// All states, in bring-up order (for tables, tests and the dot graph).
    pub const ALL: [State; 25] = [
        State::Idle,
        State::CountSlaves,
        State::AssignAddresses,
        State::ReadInfo,
        State::ProbeSystemTime,
        State::TdiffRead,
        State::TdiffLatch,
        State::TdiffTrigger,
        State::TdiffClose,
        State::TdiffRestore,
        State::LatchReadBefore,
        State::LatchTrigger,
        State::LatchReadAfter,
        State::ReadAlStatus,
        State::WriteOffsets,
        State::ResetLoops,
        State::DriftBurst,
        State::DriftCheck,
        State::ReadReferenceTime,
        State::ClearActivation,
        State::ProgramSync,
        State::ActivateSync,
        State::Cyclic,
        State::RestartWait,
        State::Failed,
    ];

    /// True for the states that send a request list and wait for all replies.
    pub(crate) const fn is_request_step(self) -> bool {
        !matches!(
            self,
            State::Idle | State::Cyclic | State::RestartWait | State::Failed
        )
    }

    /// The transition table. `RestartWait`/`Failed` are reachable from every state (faults);
    /// `Idle` from every state (`reset`); `CountSlaves` from `Idle`, `RestartWait`, `Failed`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::State;
    ///
    /// assert!(State::Idle.can_go(State::CountSlaves));
    /// assert!(State::DriftCheck.can_go(State::Cyclic));
    /// // Faults and `reset` are always possible; skipping steps is not.
    /// assert!(State::Cyclic.can_go(State::RestartWait));
    /// assert!(!State::CountSlaves.can_go(State::Cyclic));
    /// ```
    pub const fn can_go(self, to: State) -> bool {
        use State::*;
        matches!(
            (self, to),
            (_, Idle)
                | (_, RestartWait)
                | (_, Failed)
                | (Idle | RestartWait | Failed, CountSlaves)
                | (CountSlaves, AssignAddresses)
                | (AssignAddresses, ReadInfo)
                | (ReadInfo, ProbeSystemTime)
                | (ProbeSystemTime, TdiffRead)
                | (TdiffRead, TdiffLatch)
                | (TdiffRead, LatchReadBefore)
                | (TdiffLatch, TdiffLatch)
                | (TdiffLatch, TdiffTrigger)
                | (TdiffLatch, TdiffClose)
                | (TdiffLatch, TdiffRestore)
                | (TdiffLatch, LatchReadBefore)
                | (TdiffTrigger, TdiffLatch)
                | (TdiffTrigger, TdiffTrigger)
                | (TdiffClose, TdiffTrigger)
                | (TdiffRestore, TdiffClose)
                | (TdiffRestore, LatchReadBefore)
                | (LatchReadBefore, LatchTrigger)
                | (LatchTrigger, LatchReadAfter)
                | (LatchTrigger, LatchReadBefore)
                | (LatchReadAfter, LatchReadBefore)
                | (LatchReadAfter, ReadAlStatus)
                | (ReadAlStatus, WriteOffsets)
                | (WriteOffsets, ResetLoops)
                | (ResetLoops, DriftBurst)
                | (DriftBurst, DriftCheck)
                | (DriftCheck, DriftBurst)
                | (DriftCheck, ReadReferenceTime)
                | (DriftCheck, Cyclic)
                | (ReadReferenceTime, ClearActivation)
                | (ClearActivation, ProgramSync)
                | (ProgramSync, ActivateSync)
                | (ActivateSync, Cyclic)
        )
    }

    /// Short lower-case name, for logs and the CLI.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::State;
    ///
    /// assert_eq!(State::CountSlaves.name(), "count-slaves");
    /// assert_eq!(State::Cyclic.name(), "cyclic");
    /// ```
    pub const fn name(self) -> &'static str {
        match self {
            State::Idle => "idle",
            State::CountSlaves => "count-slaves",
            State::AssignAddresses => "assign-addresses",
            State::ReadInfo => "read-info",
            State::ProbeSystemTime => "probe-system-time",
            State::TdiffRead => "tdiff-read",
            State::TdiffLatch => "tdiff-latch",
            State::TdiffTrigger => "tdiff-trigger",
            State::TdiffClose => "tdiff-close",
            State::TdiffRestore => "tdiff-restore",
            State::LatchReadBefore => "latch-read-before",
            State::LatchTrigger => "latch-trigger",
            State::LatchReadAfter => "latch-read-after",
            State::ReadAlStatus => "read-al-status",
            State::WriteOffsets => "write-offsets",
            State::ResetLoops => "reset-loops",
            State::DriftBurst => "drift-burst",
            State::DriftCheck => "drift-check",
            State::ReadReferenceTime => "read-reference-time",
            State::ClearActivation => "clear-activation",
            State::ProgramSync => "program-sync",
            State::ActivateSync => "activate-sync",
            State::Cyclic => "cyclic",
            State::RestartWait => "restart-wait",
            State::Failed => "failed",
        }
    }
}

impl core::fmt::Display for State {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The display name is the state's name: the variant's name in lower case with hyphens
    /// between its words, one name per state.
    #[test]
    fn display_is_the_name() {
        let mut names = std::collections::BTreeSet::new();
        for state in State::ALL {
            let name = state.name();
            assert_eq!(std::format!("{state}"), name);
            let variant = std::format!("{state:?}").to_lowercase();
            assert_eq!(name.replace('-', ""), variant, "{state:?}");
            assert!(names.insert(name), "{name} twice");
        }
        assert_eq!(names.len(), State::ALL.len());
    }

    /// The bring-up path is a chain of allowed transitions, and nothing jumps over the offset
    /// write or the drift gate.
    #[test]
    fn bring_up_path_is_allowed_and_no_shortcuts() {
        use State::*;
        let path = [
            Idle,
            CountSlaves,
            AssignAddresses,
            ReadInfo,
            ProbeSystemTime,
            TdiffRead,
            TdiffLatch,
            TdiffTrigger,
            TdiffLatch,
            TdiffClose,
            TdiffTrigger,
            TdiffLatch,
            TdiffRestore,
            LatchReadBefore,
            LatchTrigger,
            LatchReadAfter,
            ReadAlStatus,
            WriteOffsets,
            ResetLoops,
            DriftBurst,
            DriftCheck,
            ReadReferenceTime,
            ClearActivation,
            ProgramSync,
            ActivateSync,
            Cyclic,
        ];
        for w in path.windows(2) {
            assert!(w[0].can_go(w[1]), "{} -> {}", w[0], w[1]);
        }
        assert!(!LatchReadAfter.can_go(WriteOffsets));
        // The delay measurement always follows the t_Diff step, which ends with every port
        // restored.
        assert!(!ProbeSystemTime.can_go(LatchReadBefore));
        assert!(!TdiffClose.can_go(LatchReadBefore));
        assert!(!TdiffTrigger.can_go(LatchReadBefore));
        assert!(!ResetLoops.can_go(Cyclic));
        assert!(!DriftBurst.can_go(Cyclic));
        assert!(!Idle.can_go(Cyclic));
        for s in State::ALL {
            assert!(s.can_go(RestartWait));
        }
    }
}
