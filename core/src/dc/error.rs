//! Typed faults of the DC machine. They reach the caller as [`crate::dc::Event::Error`], never
//! as a panic or a return value of a `poll_*` (REQ-DC-111).

use crate::dc::holdover::ResumeFailure;
use crate::dc::state::State;
use crate::wire::Command;

/// A fault seen by the machine. Each variant carries what a user needs to find the cause.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Error, State};
///
/// // Faults arrive as `Event::Error`; a caller decides what to report.
/// fn advice(e: &Error) -> &'static str {
///     match e {
///         Error::NoSlaves => "check the cable and the interface",
///         Error::TooManySlaves { .. } => "raise the machine's capacity N",
///         _ if e.is_retryable() => "transient: the machine retries",
///         _ => "see the error text",
///     }
/// }
/// assert_eq!(
///     advice(&Error::Timeout {
///         state: State::CountSlaves
///     }),
///     "transient: the machine retries"
/// );
/// assert_eq!(Error::NoSlaves.to_string(), "no slave answered");
/// ```
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Error {
    /// A reply came back with the wrong working counter.
    Wkc {
        /// Command of the datagram.
        command: Command,
        /// Station address (FP commands), or 0 for broadcast / position addressing.
        station: u16,
        /// Register (ADO) addressed.
        register: u16,
        /// Working counter the machine expected.
        expected: u16,
        /// Working counter that came back.
        actual: u16,
    },
    /// A request step got no (valid) reply within `response_timeout_ns`, after all retries.
    Timeout {
        /// The step that timed out.
        state: State,
    },
    /// The number of slaves (BRD working counter) differs from the one brought up.
    TopologyChanged {
        /// Slaves found at bring-up.
        expected: u16,
        /// Slaves answering now.
        found: u16,
    },
    /// A slave stopped answering at its station address (link lost, or power-cycled: a reset
    /// ESC has lost its station address).
    SlaveLost {
        /// Station address that no longer answers.
        station: u16,
    },
    /// The static drift compensation did not converge within `drift.max_frames`. The per-slave
    /// report is available through [`crate::dc::Machine::slaves`] (`last_diff_ns`).
    NotConverged {
        /// FRMW frames sent.
        frames: u32,
        /// Slaves still above the threshold at the last check.
        slaves_over: u16,
        /// Worst slave's station address (0 when only the broadcast bound was read).
        worst_station: u16,
        /// Worst |Δt| in ns.
        worst_diff_ns: u32,
    },
    /// Cyclic operation did not reach lock within `monitor.lock_timeout_cycles`.
    NotLocked {
        /// Cycles spent trying.
        cycles: u32,
        /// Last BRD 0x092C upper bound, ns.
        bound_ns: u32,
    },
    /// A register value read back is outside its plausible range; nothing derived from it is
    /// written (REQ-DC-112).
    OutOfRange {
        /// Station address of the slave (0 = broadcast / not slave specific).
        station: u16,
        /// Register the value came from (or would have been written to).
        register: u16,
    },
    /// The receive times could not be turned into delays (inconsistent topology or latches).
    Measurement {
        /// Station address of the first slave the computation rejected (0 = whole network).
        station: u16,
    },
    /// More slaves than the capacity `N` of the machine.
    TooManySlaves {
        /// Slaves found.
        found: u16,
        /// Capacity.
        capacity: u16,
    },
    /// No slave answered the count.
    NoSlaves,
    /// No slave supports DC with a system time, so there is no reference clock.
    NoReferenceClock,
    /// The caller's buffer cannot hold even one of the machine's datagrams.
    BufferTooSmall,
    /// A hold-over lasted longer than `Config::holdover_ns` (REQ-DC-129).
    HoldoverExpired {
        /// Time since the last complete cycle, ns.
        silent_ns: u64,
    },
    /// The check on the first complete cycle after a hold-over failed (REQ-DC-128).
    ResumeCheckFailed {
        /// What did not match.
        failure: ResumeFailure,
    },
    /// An internal consistency check of the machine failed in `state` (a transition outside
    /// [`State::can_go`], or a cyclic block whose layout did not add up). The machine stops
    /// there instead of panicking (REQ-CONV-008); no input is known to reach it.
    Internal {
        /// The state the machine was in when the check failed.
        state: State,
    },
}

impl Error {
    /// Whether resending the same requests may help (lost frame, transient WKC) rather than the
    /// network being unusable as it is.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Error, State};
    ///
    /// assert!(Error::Timeout {
    ///     state: State::ReadInfo
    /// }
    /// .is_retryable());
    /// assert!(!Error::NoReferenceClock.is_retryable());
    /// ```
    pub const fn is_retryable(&self) -> bool {
        matches!(
            self,
            Error::Wkc { .. }
                | Error::Timeout { .. }
                | Error::OutOfRange { .. }
                | Error::Measurement { .. }
        )
    }
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Error::Wkc { command, station, register, expected, actual } => write!(
                f,
                "{} station {station:#06x} register {register:#06x}: working counter {actual}, expected {expected}",
                command.name()
            ),
            Error::Timeout { state } => write!(f, "no reply in step {state}"),
            Error::TopologyChanged { expected, found } => {
                write!(f, "topology changed: {found} slaves answer, {expected} were configured")
            }
            Error::SlaveLost { station } => write!(f, "slave {station:#06x} lost"),
            Error::NotConverged { frames, slaves_over, worst_station, worst_diff_ns } => write!(
                f,
                "static drift compensation not converged after {frames} frames: {slaves_over} slaves over threshold, worst {worst_station:#06x} at {worst_diff_ns} ns"
            ),
            Error::NotLocked { cycles, bound_ns } => {
                write!(f, "not locked after {cycles} cycles (|0x092C| bound {bound_ns} ns)")
            }
            Error::OutOfRange { station, register } => {
                write!(f, "station {station:#06x} register {register:#06x}: value out of range")
            }
            Error::Measurement { station } => {
                write!(f, "receive times inconsistent (first rejected station {station:#06x})")
            }
            Error::TooManySlaves { found, capacity } => {
                write!(f, "{found} slaves found, capacity is {capacity}")
            }
            Error::NoSlaves => f.write_str("no slave answered"),
            Error::NoReferenceClock => f.write_str("no DC slave with a system time"),
            Error::BufferTooSmall => f.write_str("transmit buffer too small"),
            Error::HoldoverExpired { silent_ns } => {
                write!(f, "no complete cycle for {silent_ns} ns, beyond the hold-over limit")
            }
            Error::ResumeCheckFailed { failure } => match failure {
                ResumeFailure::SlaveCount { expected, found } => write!(
                    f,
                    "resume check: {found} slaves answer, {expected} before the hold-over"
                ),
                ResumeFailure::ReferenceWkc { expected, actual } => write!(
                    f,
                    "resume check: FRMW working counter {actual}, expected {expected}"
                ),
                ResumeFailure::SlaveLost { station } => {
                    write!(f, "resume check: slave {station:#06x} lost its address")
                }
                ResumeFailure::SlaveReset { al_status, before } => write!(
                    f,
                    "resume check: a slave is in INIT (AL status OR {al_status:#06x}, before {before:#06x})"
                ),
                ResumeFailure::Bound { bound_ns } => {
                    write!(f, "resume check: |0x092C| bound {bound_ns} ns")
                }
            },
            Error::Internal { state } => write!(f, "internal consistency check failed in {state}"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Error {}

#[cfg(test)]
mod tests {
    use super::*;

    /// Errors name the datagram or slave they concern.
    #[test]
    fn error_messages() {
        let e = Error::SlaveLost { station: 0x1002 };
        assert_eq!(std::format!("{e}"), "slave 0x1002 lost");
        assert_eq!(
            std::format!(
                "{}",
                Error::Timeout {
                    state: State::ReadInfo
                }
            ),
            std::format!("no reply in step {}", State::ReadInfo)
        );
    }
}
