//! Clock servos: the loops that turn phase measurements into rate or deadline commands.
//!
//! All integer / fixed-point (Q32 gains and commands, see [`gains`]), `no_std`, no allocation,
//! deterministic, and total: every function returns a bounded value or a typed error for every
//! input (REQ-CONV-008). Requirement ids REQ-SERVO-NNN are in `spec/req/servo.md`; the bounds
//! are property P5 (`proofs/src/servo.rs`).
//!
//! Layout (one concept per file):
//! - [`gains`]: pole placement → Q32 gains, stability-region refusal;
//! - [`pi`]: the PI kernel with output/integrator clamps and conditional integration (P5 core);
//! - [`carry`]: error-feedback quantiser (fractional remainder carried);
//! - [`gate`]: median/MAD outlier gate; [`lock`]: lock detector with hysteresis; `run`: the
//!   same-sign run both the gate and the engine's step policy confirm with;
//! - [`engine`]: the generic mode machine (acquire → track, steps, blanking, holdover);
//! - [`master`]: master-follows-reference (wake-up deadline correction, whole-period steps);
//! - `refclock` (feature `refclock`): reference-follows-master (value and schedule of the FPWR
//!   to 0x0910), for masters that distribute their own time instead of the reference's;
//! - [`ieee1588`]: offset, mean path delay, rate ratio (seed 004 eq. 1–6);
//! - [`filter`]: the seed 004 two-pole offset filter (eq. 7–9);
//! - [`counter`]: counter self-compensation with carry (seed 004 eq. 15–18);
//! - `ptp` (feature `ptp`): an IEEE 1588 slave-clock servo built from the above.
//!
//! The two feature-gated modules are not needed to run DC: the machine uses [`master`]'s
//! direction (the master follows the reference) and its own drift compensation.

pub mod carry;
pub mod counter;
pub mod engine;
pub mod filter;
pub mod gains;
pub mod gate;
#[cfg(test)]
mod golden;
pub mod ieee1588;
pub mod lock;
pub mod master;
pub mod pi;
#[cfg(any(test, feature = "ptp"))]
pub mod ptp;
#[cfg(any(test, feature = "refclock"))]
pub mod refclock;
mod run;
#[cfg(test)]
mod test_rng;

pub use engine::{ConfigError, Counters, Input, Mode, Output, Servo, ServoConfig, Verdict};
pub use gains::{GainError, PiGains, Pole};
pub use master::{MasterConfig, MasterInput, MasterOutput, MasterServo};
pub use pi::{PiLimits, PiStep};
