//! The generic servo engine: mode machine, time sanity, step policy, blanking, holdover, outlier
//! gate, lock detector and gain switch around the PI kernel (REQ-SERVO-050..090).
//!
//! One engine serves every loop; adapters turn their measurement into an error θ (ns,
//! REQ-CONV-007: measured − target, positive = the controlled clock is ahead) and turn the
//! engine's command back into their actuator's units ([`super::master`], `servo::ptp`).
//! [`Servo::update`] is a pure function of (state, input, config): no clock reads, no
//! allocation, no floating point, so a log replays bit-exactly (REQ-SERVO-090).
//!
//! ```text
//!            first sample                 |θ| < gear_ns for gear_count samples
//!   Init ─────────────────▶ Acquire ─────────────────────────────────────────▶ Tracking
//!                            ▲   ▲   gate: confirm same-side rejections             │
//!                            │   └──────────────────────────────────────────────────┘
//!                            │        any step (first-step or confirmed step)
//!                            └── holdover_max missing samples (Holdover while missing)
//! ```
//! The command is always bounded by y_max: it is either the PI output (clamped) or the held
//! integrator (|I| ≤ I_max ≤ y_max) — REQ-SERVO-012.

use super::gains::PiGains;
use super::gate::{Gate, GateConfig, GateVerdict};
use super::lock::{LockConfig, LockDetector};
use super::pi::{hold, pi_step, PiLimits};
use super::run::SignRun;
use crate::num::wrapping_diff;

/// Engine configuration (validated by [`Servo::new`]).
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::MasterConfig;
/// use ecdc_core::servo::{Input, Servo, ServoConfig, Verdict};
///
/// // The master loop's defaults for a 1 ms interval, but allow one phase step on the first
/// // sample when the error exceeds 1 µs.
/// let cfg = ServoConfig {
///     first_step_ns: 1_000,
///     ..MasterConfig::for_period(1_000_000)?.servo
/// };
/// let mut servo = Servo::new(cfg)?;
/// let out = servo.update(Input::Sample {
///     local_ns: 0,
///     theta_ns: 5_000,
/// });
/// assert_eq!((out.verdict, out.step_ns), (Verdict::Stepped, 5_000));
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ServoConfig {
    /// Nominal sample interval h₀, ns (> 0). Samples are accepted when the local interval since
    /// the previous one is in [h₀/2, 4·h₀] (REQ-SERVO-070).
    pub interval_ns: u32,
    /// Gains while acquiring (fast).
    pub acquire: PiGains,
    /// Gains while tracking (narrow band).
    pub track: PiGains,
    /// Output and integrator clamps.
    pub limits: PiLimits,
    /// On the first sample after (re)start, step when |θ| > this (ns); 0 = never.
    pub first_step_ns: u64,
    /// After the first sample, step when |θ| > this for `step_confirm` samples; 0 = never.
    pub step_ns: u64,
    /// Consecutive samples over `step_ns` (same side) before a step (N_c ≥ 1).
    pub step_confirm: u8,
    /// Samples ignored after a step (W): the measurement pipeline may still hold the old phase.
    pub blank: u8,
    /// Switch from acquire to track gains after `gear_count` samples with |θ| < `gear_ns`.
    pub gear_ns: u64,
    /// See `gear_ns` (≥ 1).
    pub gear_count: u16,
    /// Take the tracking gains anyway after this many accepted samples in Acquire (0 = never):
    /// with measurement noise larger than `gear_ns` the consecutive-run criterion may never be
    /// met, and the fast acquisition gains pass more of that noise through.
    pub acquire_max: u32,
    /// Outlier gate (armed in Tracking only: while acquiring, θ moves systematically and a
    /// median of past errors is not a prediction of the next one).
    pub gate: GateConfig,
    /// Lock detector thresholds.
    pub lock: LockConfig,
    /// Missing or invalid samples tolerated in holdover before re-acquiring (keeping I).
    pub holdover_max: u32,
    /// Raise [`Output::fault`] after this many consecutive saturated samples during which |θ|
    /// did not shrink (0 = never): the actuator is not acting (REQ-SERVO-086).
    pub fault_after: u32,
}

/// Why a configuration was refused.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::MasterConfig;
/// use ecdc_core::servo::{ConfigError, Servo, ServoConfig};
///
/// let cfg = ServoConfig {
///     interval_ns: 0,
///     ..MasterConfig::for_period(1_000_000)?.servo
/// };
/// assert_eq!(
///     Servo::new(cfg).map(|s| s.mode()),
///     Err(ConfigError::Interval)
/// );
/// # Ok::<(), ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ConfigError {
    /// interval_ns must be > 0.
    Interval,
    /// step_confirm and gear_count must be ≥ 1.
    Counts,
    /// Lock thresholds: low ≤ high, count ≥ 1.
    Lock,
    /// Gains refused (stability region).
    Gains(super::gains::GainError),
    /// Limits refused.
    Limits(super::pi::LimitError),
    /// Adapter-specific parameter (period, target, rate limit) out of range.
    Parameter,
}

/// Servo mode. A settled loop is Tracking with `locked == true`.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::MasterConfig;
/// use ecdc_core::servo::{Input, Mode, Servo};
///
/// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
/// assert_eq!(servo.mode(), Mode::Init);
/// servo.update(Input::Sample {
///     local_ns: 0,
///     theta_ns: 100,
/// });
/// assert_eq!(servo.mode(), Mode::Acquire);
/// servo.update(Input::Missing);
/// assert_eq!(servo.mode(), Mode::Holdover);
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// No sample yet.
    Init,
    /// Fast gains, gate disarmed.
    Acquire,
    /// Narrow gains, gate armed.
    Tracking,
    /// Samples missing or invalid: output the learned frequency (I) only.
    Holdover,
}

/// What the engine did with one input.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::MasterConfig;
/// use ecdc_core::servo::{Input, Servo, Verdict};
///
/// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
/// let first = servo.update(Input::Sample {
///     local_ns: 0,
///     theta_ns: 100,
/// });
/// assert_eq!(first.verdict, Verdict::Accepted);
/// // 10 µs later instead of ~1 ms: not a plausible sample interval.
/// let early = servo.update(Input::Sample {
///     local_ns: 10_000,
///     theta_ns: 100,
/// });
/// assert_eq!(early.verdict, Verdict::BadInterval);
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Verdict {
    /// Used by the PI.
    Accepted,
    /// Rejected by the outlier gate; held.
    Rejected,
    /// Ignored during post-step blanking; held.
    Blanked,
    /// No sample this interval; held.
    Missing,
    /// Sample time not after the previous one or interval out of [h₀/2, 4h₀]; held.
    BadInterval,
    /// Over the step threshold, waiting for confirmation; held.
    StepPending,
    /// A step was emitted (see [`Output::step_ns`]); held.
    Stepped,
}

/// One input per interval.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::MasterConfig;
/// use ecdc_core::servo::{Input, Servo, Verdict};
///
/// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
/// servo.update(Input::Sample {
///     local_ns: 0,
///     theta_ns: 100,
/// });
/// // The frame of the next cycle was lost.
/// assert_eq!(servo.update(Input::Missing).verdict, Verdict::Missing);
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Input {
    /// A measurement: local time of the sample (ns, wrapping) and the error θ (ns).
    Sample {
        /// Local monotonic time of the measurement.
        local_ns: u64,
        /// Phase error, measured − target.
        theta_ns: i64,
    },
    /// The measurement for this interval was lost (e.g. FRMW WKC 0, frame lost).
    Missing,
}

/// Engine output for one input.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::MasterConfig;
/// use ecdc_core::servo::{Input, Servo};
///
/// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
/// let out = servo.update(Input::Sample {
///     local_ns: 0,
///     theta_ns: 100,
/// });
/// // Ahead by 100 ns: retard (positive command), within ±y_max, no step.
/// assert!(out.command_q32 > 0 && out.command_q32 <= servo.config().limits.y_max());
/// assert_eq!((out.step_ns, out.theta_ns, out.locked), (0, 100, false));
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Output {
    /// Retard command, Q32 ns per interval, |·| ≤ y_max (REQ-SERVO-012).
    pub command_q32: i64,
    /// Phase step: the controlled clock must be moved back by this many ns (0 = none).
    pub step_ns: i64,
    /// Mode after this input.
    pub mode: Mode,
    /// Lock flag after this input.
    pub locked: bool,
    /// What happened to the input.
    pub verdict: Verdict,
    /// The PI output was clamped.
    pub saturated: bool,
    /// Saturated for `fault_after` samples without the error shrinking: the command is not
    /// reaching the clock (escalate; the servo keeps running). Clears when saturation ends.
    pub fault: bool,
    /// The error used (clamped to ±2^62 for diagnostics), 0 when there was none.
    pub theta_ns: i64,
    /// Integrator after this input, Q32.
    pub integrator_q32: i64,
}

/// Event counters (diagnostics, ptp4l-style summaries).
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::MasterConfig;
/// use ecdc_core::servo::{Input, Servo};
///
/// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
/// servo.update(Input::Sample {
///     local_ns: 0,
///     theta_ns: 100,
/// });
/// servo.update(Input::Missing);
/// let c = servo.counters();
/// assert_eq!((c.inputs, c.accepted, c.held), (2, 1, 1));
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Counters {
    /// Inputs seen.
    pub inputs: u64,
    /// Samples used by the PI.
    pub accepted: u64,
    /// Gate rejections.
    pub rejected: u64,
    /// Steps emitted.
    pub steps: u64,
    /// PI outputs clamped.
    pub saturated: u64,
    /// Held intervals (missing, invalid).
    pub held: u64,
    /// Returns to Acquire (gate confirmation, holdover timeout).
    pub reacquired: u64,
    /// Rising edges of [`Output::fault`].
    pub faults: u64,
}

/// The servo engine state.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::carry::Carry;
/// use ecdc_core::servo::master::MasterConfig;
/// use ecdc_core::servo::{Input, Servo};
///
/// // Close the loop on a simulated clock that drifts 20 ns per interval: θ' = θ + 20 − command,
/// // the Q32 command applied in whole ns with its fraction carried.
/// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
/// let (mut theta, mut carry) = (0i64, Carry::new());
/// for k in 0..5_000u64 {
///     let out = servo.update(Input::Sample { local_ns: k * 1_000_000, theta_ns: theta });
///     theta += 20 - carry.quantize(out.command_q32);
/// }
/// assert!(servo.is_locked());
/// // The integrator has learned the drift.
/// assert_eq!((servo.integrator_q32() + (1 << 31)) >> 32, 20);
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Servo {
    cfg: ServoConfig,
    mode: Mode,
    resume: Mode,
    integrator: i64,
    last_t: Option<u64>,
    gate: Gate,
    lock: LockDetector,
    gear_run: u16,
    acquired: u32,
    step_run: SignRun,
    blank_left: u8,
    sat_run: u32,
    sat_start: u64,
    fault: bool,
    missing: u32,
    first: bool,
    counters: Counters,
}

impl Servo {
    /// Validate `cfg` and start in `Init` with integrator 0.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::{Mode, Servo};
    ///
    /// let servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
    /// assert_eq!((servo.mode(), servo.integrator_q32()), (Mode::Init, 0));
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub fn new(cfg: ServoConfig) -> Result<Self, ConfigError> {
        if cfg.interval_ns == 0 {
            return Err(ConfigError::Interval);
        }
        if cfg.step_confirm == 0 || cfg.gear_count == 0 {
            return Err(ConfigError::Counts);
        }
        cfg.lock.validate().map_err(|_| ConfigError::Lock)?;
        Ok(Servo {
            cfg,
            mode: Mode::Init,
            resume: Mode::Acquire,
            integrator: 0,
            last_t: None,
            gate: Gate::new(),
            lock: LockDetector::new(),
            gear_run: 0,
            acquired: 0,
            step_run: SignRun::new(),
            blank_left: 0,
            sat_run: 0,
            sat_start: 0,
            fault: false,
            missing: 0,
            first: true,
            counters: Counters::default(),
        })
    }

    /// Seed the integrator with a known frequency (Q32 ns per interval, clamped to ±I_max), e.g.
    /// the last learned value across a restart (linuxptp's `fadj`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::Servo;
    ///
    /// // Restart with the drift learned before: 12 ns per interval.
    /// let servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?.with_integrator(12 * ONE);
    /// assert_eq!(servo.integrator_q32(), 12 * ONE);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub fn with_integrator(mut self, i_q32: i64) -> Self {
        self.set_integrator(i_q32);
        self
    }

    /// Load a known frequency into the integrator (Q32 ns per interval, clamped to ±I_max), e.g.
    /// a rate measured before the loop starts: the PI then starts at its equilibrium instead of
    /// integrating the whole rate error through the phase.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::Servo;
    ///
    /// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
    /// servo.set_integrator(i64::MAX);
    /// // Clamped to I_max (1 µs per interval for a 1 ms cycle).
    /// assert_eq!(servo.integrator_q32(), 1_000 * ONE);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub fn set_integrator(&mut self, i_q32: i64) {
        self.integrator = hold(self.cfg.limits, i_q32);
    }

    /// Configuration in use.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::Servo;
    ///
    /// let servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
    /// assert_eq!(servo.config().interval_ns, 1_000_000);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn config(&self) -> &ServoConfig {
        &self.cfg
    }

    /// Current mode.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::{Input, Mode, Servo};
    ///
    /// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
    /// servo.update(Input::Sample {
    ///     local_ns: 0,
    ///     theta_ns: 0,
    /// });
    /// assert_eq!(servo.mode(), Mode::Acquire);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn mode(&self) -> Mode {
        self.mode
    }

    /// Current lock flag.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::{Input, Servo};
    ///
    /// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
    /// // Lock needs 32 consecutive samples within P/50 = 20 µs.
    /// for k in 0..32u64 {
    ///     assert!(!servo.is_locked());
    ///     servo.update(Input::Sample {
    ///         local_ns: k * 1_000_000,
    ///         theta_ns: 0,
    ///     });
    /// }
    /// assert!(servo.is_locked());
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn is_locked(&self) -> bool {
        self.lock.is_locked()
    }

    /// Integrator (learned frequency), Q32 ns per interval, |·| ≤ I_max.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::{Input, Servo};
    ///
    /// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
    /// let out = servo.update(Input::Sample {
    ///     local_ns: 0,
    ///     theta_ns: 100,
    /// });
    /// assert_eq!(servo.integrator_q32(), out.integrator_q32);
    /// assert!(servo.integrator_q32() > 0 && servo.integrator_q32() < 100 * ONE);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn integrator_q32(&self) -> i64 {
        self.integrator
    }

    /// Event counters.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::{Input, Servo};
    ///
    /// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
    /// servo.update(Input::Missing);
    /// assert_eq!(servo.counters().held, 1);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Back to `Init`, keeping the learned frequency (a restart does not change the crystal's rate).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::{Mode, Servo};
    ///
    /// let mut servo =
    ///     Servo::new(MasterConfig::for_period(1_000_000)?.servo)?.with_integrator(7 * ONE);
    /// servo.reset();
    /// // Back to Init, but the crystal's rate is still known.
    /// assert_eq!(
    ///     (servo.mode(), servo.integrator_q32()),
    ///     (Mode::Init, 7 * ONE)
    /// );
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub fn reset(&mut self) {
        let i = self.integrator;
        let counters = self.counters;
        if let Ok(s) = Servo::new(self.cfg) {
            *self = s;
        }
        self.integrator = i;
        self.counters = counters;
    }

    fn held(&self, verdict: Verdict, theta: i64) -> Output {
        Output {
            command_q32: hold(self.cfg.limits, self.integrator),
            step_ns: 0,
            mode: self.mode,
            locked: self.lock.is_locked(),
            verdict,
            saturated: false,
            fault: self.fault,
            theta_ns: theta,
            integrator_q32: self.integrator,
        }
    }

    /// Enter Acquire (keep I), forget gate window and gear progress.
    fn reacquire(&mut self) {
        self.mode = Mode::Acquire;
        self.resume = Mode::Acquire;
        self.gate.clear();
        self.gear_run = 0;
        self.acquired = 0;
        self.step_run.clear();
    }

    /// Count a missing/invalid interval; re-acquire after `holdover_max` of them.
    fn holdover(&mut self, verdict: Verdict, theta: i64) -> Output {
        self.counters.held = self.counters.held.saturating_add(1);
        self.missing = self.missing.saturating_add(1);
        if self.mode != Mode::Holdover && self.mode != Mode::Init {
            self.resume = self.mode;
            self.mode = Mode::Holdover;
        }
        if self.missing > self.cfg.holdover_max && self.mode == Mode::Holdover {
            // Long gap: the phase may have walked off. Keep I, re-acquire, allow a first step.
            self.reacquire();
            self.mode = Mode::Holdover;
            self.lock.unlock();
            self.first = true;
            self.last_t = None;
            self.counters.reacquired = self.counters.reacquired.saturating_add(1);
        }
        self.held(verdict, theta)
    }

    fn step(&mut self, theta: i64) -> Output {
        // REQ-SERVO-080: I is kept (the frequency is still valid), histories are cleared,
        // W samples are blanked, lock drops.
        self.counters.steps = self.counters.steps.saturating_add(1);
        self.reacquire();
        self.lock.unlock();
        self.blank_left = self.cfg.blank;
        self.first = false;
        let mut out = self.held(Verdict::Stepped, theta);
        out.step_ns = theta;
        out
    }

    /// REQ-SERVO-070..090: process one input.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::{Input, Servo, Verdict};
    ///
    /// let mut servo = Servo::new(MasterConfig::for_period(1_000_000)?.servo)?;
    /// let a = servo.update(Input::Sample {
    ///     local_ns: 0,
    ///     theta_ns: -400,
    /// });
    /// assert_eq!(a.verdict, Verdict::Accepted);
    /// assert!(a.command_q32 < 0); // behind: advance
    ///                             // A lost sample holds the learned rate: the integrator, no P term.
    /// let b = servo.update(Input::Missing);
    /// assert_eq!(b.command_q32, a.integrator_q32);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub fn update(&mut self, input: Input) -> Output {
        self.update_inline(input)
    }

    /// [`Servo::update`], always inlined: the master adapter calls it once per cycle with a
    /// sample whose variant is known there, so the call, the input and output copies and the
    /// `Missing` arm fold away.
    #[inline(always)]
    pub(crate) fn update_inline(&mut self, input: Input) -> Output {
        self.counters.inputs = self.counters.inputs.saturating_add(1);
        let (t, theta) = match input {
            Input::Missing => {
                // One nominal interval passed without a sample: advance the time anchor so the
                // next sample's interval check measures from where it is expected.
                self.last_t = self
                    .last_t
                    .map(|t| t.wrapping_add(u64::from(self.cfg.interval_ns)));
                return self.holdover(Verdict::Missing, 0);
            }
            Input::Sample { local_ns, theta_ns } => (local_ns, theta_ns),
        };
        let theta = theta.clamp(-(1 << 62), 1 << 62);
        // Time sanity (REQ-SERVO-070).
        if let Some(prev) = self.last_t {
            let h = wrapping_diff::<u64>(t, prev);
            let h0 = i64::from(self.cfg.interval_ns);
            if h <= 0 {
                return self.holdover(Verdict::BadInterval, theta);
            }
            self.last_t = Some(t);
            if h < h0 / 2 || h > h0.saturating_mul(4) {
                return self.holdover(Verdict::BadInterval, theta);
            }
        } else {
            self.last_t = Some(t);
        }
        self.missing = 0;
        match self.mode {
            Mode::Init => {
                self.mode = Mode::Acquire;
                self.resume = Mode::Acquire;
            }
            Mode::Holdover => self.mode = self.resume,
            Mode::Acquire | Mode::Tracking => {}
        }
        if self.blank_left > 0 {
            self.blank_left = self.blank_left.saturating_sub(1);
            return self.held(Verdict::Blanked, theta);
        }
        let mag = theta.unsigned_abs();
        // Step policy (REQ-SERVO-080).
        if self.first {
            self.first = false;
            if self.cfg.first_step_ns > 0 && mag > self.cfg.first_step_ns {
                return self.step(theta);
            }
        } else if self.cfg.step_ns > 0 && mag > self.cfg.step_ns {
            if self.step_run.push(theta > 0) >= self.cfg.step_confirm {
                return self.step(theta);
            }
            return self.held(Verdict::StepPending, theta);
        } else {
            self.step_run.clear();
        }
        // Outlier gate (Tracking only).
        if self.mode == Mode::Tracking {
            match self.gate.judge(&self.cfg.gate, theta) {
                GateVerdict::Accept => {}
                GateVerdict::Reject => {
                    self.counters.rejected = self.counters.rejected.saturating_add(1);
                    return self.held(Verdict::Rejected, theta);
                }
                GateVerdict::Confirmed => {
                    // A real change, not noise: fast gains take it from here.
                    self.reacquire();
                    self.counters.reacquired = self.counters.reacquired.saturating_add(1);
                }
            }
        }
        let gains = if self.mode == Mode::Tracking {
            self.cfg.track
        } else {
            self.cfg.acquire
        };
        let s = pi_step(gains, self.cfg.limits, self.integrator, theta);
        self.integrator = s.integrator;
        if s.saturated {
            self.counters.saturated = self.counters.saturated.saturating_add(1);
            if self.sat_run == 0 {
                self.sat_start = mag;
            }
            self.sat_run = self.sat_run.saturating_add(1);
            // REQ-SERVO-086: fault after `fault_after` saturated samples without |θ| shrinking
            // below its value at the start of the run; cleared when saturation ends.
            let stuck = self.cfg.fault_after > 0
                && self.sat_run >= self.cfg.fault_after
                && mag >= self.sat_start;
            if stuck && !self.fault {
                self.counters.faults = self.counters.faults.saturating_add(1);
            }
            self.fault = stuck;
        } else {
            self.sat_run = 0;
            self.fault = false;
        }
        self.counters.accepted = self.counters.accepted.saturating_add(1);
        self.gate.push(theta);
        self.lock.update(&self.cfg.lock, theta);
        if self.mode == Mode::Acquire {
            self.acquired = self.acquired.saturating_add(1);
            if mag < self.cfg.gear_ns {
                self.gear_run = self.gear_run.saturating_add(1);
            } else {
                self.gear_run = 0;
            }
            let timed_out = self.cfg.acquire_max > 0 && self.acquired >= self.cfg.acquire_max;
            if self.gear_run >= self.cfg.gear_count || timed_out {
                // Bumpless apart from ΔKp·θ: I carries over (REQ-SERVO-085).
                self.mode = Mode::Tracking;
                self.resume = Mode::Tracking;
                self.gate.clear();
            }
        }
        Output {
            command_q32: s.y,
            step_ns: 0,
            mode: self.mode,
            locked: self.lock.is_locked(),
            verdict: Verdict::Accepted,
            saturated: s.saturated,
            fault: self.fault,
            theta_ns: theta,
            integrator_q32: s.integrator,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::gains::Pole;
    use super::*;

    fn cfg() -> ServoConfig {
        let g = PiGains::double_pole(Pole::from_micro(500_000).unwrap()).unwrap();
        ServoConfig {
            interval_ns: 1000,
            acquire: g,
            track: g,
            limits: PiLimits::from_ns(100, 100).unwrap(),
            first_step_ns: 10_000,
            step_ns: 50_000,
            step_confirm: 3,
            blank: 2,
            gear_ns: 50,
            gear_count: 4,
            acquire_max: 0,
            gate: GateConfig::with_floor(100),
            lock: LockConfig {
                low_ns: 50,
                high_ns: 200,
                count: 4,
            },
            holdover_max: 3,
            fault_after: 5,
        }
    }

    fn sample(t: u64, theta: i64) -> Input {
        Input::Sample {
            local_ns: t,
            theta_ns: theta,
        }
    }

    // verifies: REQ-SERVO-070
    #[test]
    fn time_sanity_rejects_backwards_and_bad_intervals() {
        let mut s = Servo::new(cfg()).unwrap();
        assert_eq!(s.update(sample(10_000, 5)).verdict, Verdict::Accepted);
        let i = s.integrator_q32();
        // Same time, backwards, too short (< h0/2), too long (> 4 h0): all held, I untouched.
        for t in [10_000, 9_000, 10_400, 15_000] {
            let o = s.update(sample(t, 5));
            assert_eq!(o.verdict, Verdict::BadInterval, "t={t}");
            assert_eq!(s.integrator_q32(), i);
        }
        // 15_000 became the anchor (it was after the previous one): 16_000 is fine again.
        assert_eq!(s.update(sample(16_000, 5)).verdict, Verdict::Accepted);
    }

    // verifies: REQ-SERVO-080, REQ-SERVO-081
    #[test]
    fn first_step_then_blanking_then_confirmed_step() {
        let mut s = Servo::new(cfg()).unwrap();
        let o = s.update(sample(0, 30_000));
        assert_eq!((o.verdict, o.step_ns), (Verdict::Stepped, 30_000));
        assert_eq!(s.update(sample(1000, 7)).verdict, Verdict::Blanked);
        assert_eq!(s.update(sample(2000, 7)).verdict, Verdict::Blanked);
        assert_eq!(s.update(sample(3000, 7)).verdict, Verdict::Accepted);
        // Over step_ns: two pending, the third (same side) steps; an opposite side restarts.
        assert_eq!(s.update(sample(4000, 60_000)).verdict, Verdict::StepPending);
        assert_eq!(
            s.update(sample(5000, -60_000)).verdict,
            Verdict::StepPending
        );
        assert_eq!(
            s.update(sample(6000, -60_000)).verdict,
            Verdict::StepPending
        );
        let i = s.integrator_q32();
        let o = s.update(sample(7000, -61_000));
        assert_eq!((o.verdict, o.step_ns), (Verdict::Stepped, -61_000));
        assert_eq!(s.integrator_q32(), i);
        assert_eq!(s.counters().steps, 2);
    }

    // verifies: REQ-SERVO-071, REQ-SERVO-072
    #[test]
    fn holdover_then_reacquire_keeping_frequency() {
        let mut s = Servo::new(cfg()).unwrap().with_integrator(40 << 32);
        assert_eq!(s.update(sample(0, 0)).verdict, Verdict::Accepted);
        for _ in 0..3 {
            let o = s.update(Input::Missing);
            assert_eq!((o.mode, o.verdict), (Mode::Holdover, Verdict::Missing));
            assert_eq!(o.command_q32, s.integrator_q32());
        }
        // The 4th missing sample exceeds holdover_max = 3: re-acquire, I kept.
        let i = s.integrator_q32();
        assert_eq!(s.update(Input::Missing).mode, Mode::Holdover);
        assert_eq!(s.counters().reacquired, 1);
        assert_eq!(s.integrator_q32(), i);
        // Next sample: a first step is allowed again, time anchor was dropped.
        let o = s.update(sample(999_999_999, 20_000));
        assert_eq!((o.verdict, o.mode), (Verdict::Stepped, Mode::Acquire));
    }

    // verifies: REQ-SERVO-085
    #[test]
    fn gear_shift_and_lock() {
        let mut s = Servo::new(cfg()).unwrap();
        assert!(!s.is_locked(), "a new servo is not locked");
        let mut t = 0;
        for _ in 0..4 {
            s.update(sample(t, 10));
            t += 1000;
        }
        assert_eq!(s.mode(), Mode::Tracking);
        assert!(s.is_locked());
        // Outlier rejected once the gate is armed (8 samples in the window).
        for _ in 0..8 {
            s.update(sample(t, 10));
            t += 1000;
        }
        assert_eq!(s.update(sample(t, 5_000)).verdict, Verdict::Rejected);
        assert!(s.is_locked());
        assert!(Servo::new(ServoConfig {
            interval_ns: 0,
            ..cfg()
        })
        .is_err());
    }

    /// REQ-SERVO-086: fault flag raised once per run of stuck saturation, cleared after it.
    // verifies: REQ-SERVO-086
    #[test]
    fn fault_when_saturated_and_not_shrinking() {
        let mut c = cfg();
        c.first_step_ns = 0;
        c.step_ns = 0;
        let mut s = Servo::new(c).unwrap();
        let mut t = 0;
        // The error shrinks while saturated (a working actuator slewing): no fault.
        for k in 0..10 {
            let o = s.update(sample(t, 9_000 - 100 * k));
            assert!(o.saturated && !o.fault);
            t += 1000;
        }
        // Back where the saturated run started (15 samples ago): no progress, fault.
        let o = s.update(sample(t, 9_000));
        assert!(o.fault);
        t += 1000;
        // A fresh servo pinned at the limit with a growing error: fault from the 5th sample,
        // counted once.
        let mut s = Servo::new(c).unwrap();
        let mut first = None;
        for k in 0..10 {
            let o = s.update(sample(t, 9_000 + 100 * k));
            if o.fault && first.is_none() {
                first = Some(k);
            }
            t += 1000;
        }
        assert_eq!(first, Some(4));
        assert_eq!(s.counters().faults, 1);
        // Leaving saturation clears it.
        assert!(!s.update(sample(t, 1)).fault);
    }
}
