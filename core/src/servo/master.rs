//! Master-follows-reference: the loop that keeps the master's cycle on the DC reference clock
//! by correcting the master's next wake-up deadline (REQ-SERVO-100..104).
//!
//! Model. The master keeps a nominal "app time" that advances exactly one period P per cycle
//! (its idea of DC system time at the cycle's wake-up), and sends it with the cyclic frame whose
//! FRMW on the reference's 0x0910 returns the reference's time. Per cycle:
//!   raw = (app − ref) − target,   θ = fold(raw) ∈ (−P/2, P/2]  (REQ-TIME-008),
//! positive θ = the master is ahead (woke early in DC terms, REQ-CONV-007). Delaying the next
//! deadline by c ns lowers the next θ by c, and the master's timer drift adds δ per cycle, so
//! θₖ₊₁ = θₖ + δ − cₖ: exactly the loop [`super::gains`] places the poles of.
//!
//! Outputs per cycle:
//! - `deadline_correction_ns`: add to the next wake-up deadline (next = prev + P + this). It is
//!   the PI command quantised with a carried remainder (exact long-run rate), plus a one-off
//!   phase step when acquiring if enabled (off by default); |PI part| ≤ y_max_ns (REQ-SERVO-101).
//! - `app_time_step_ns`: a whole number of periods to add to the app-time base, so app time and
//!   DC time agree to within P/2 (REQ-SERVO-102). Whole periods never move the wake-up phase,
//!   so this is how a large offset is absorbed without disturbing the cycle (linuxcnc-ethercat
//!   PR #502: resync by whole periods only, the remainder is left to the controller).
//!
//! Per cycle (the runtime / simulator side):
//! ```
//! use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
//! let period = 1_000_000u32; // 1 ms
//! let mut servo = MasterServo::new(MasterConfig::for_period(period).unwrap()).unwrap();
//! let (mut app_base, mut deadline) = (5_000_000_000u64, 0u64);
//! for cycle in 0..3u64 {
//!     let app = app_base + cycle * u64::from(period); // nominal DC time of this cycle
//!     let reference = app - 250; // what the FRMW on 0x0910 returned (here: master 250 ns ahead)
//!     let out = servo.update(MasterInput::Sample { local_ns: deadline, app_ns: app, ref_ns: reference });
//!     // (on a lost frame: servo.update(MasterInput::Lost))
//!     app_base = app_base.wrapping_add_signed(out.app_time_step_ns); // whole periods only
//!     deadline = deadline
//!         .wrapping_add(u64::from(period))
//!         .wrapping_add_signed(out.deadline_correction_ns); // wake later when ahead
//!     assert!(out.deadline_correction_ns > 0);
//! }
//! assert!(!servo.is_locked()); // lock needs 32 cycles within P/50
//! ```

use super::carry::Carry;
use super::engine::{ConfigError, Counters, Input, Mode, Output, Servo, ServoConfig, Verdict};
use super::gains::{PiGains, Pole};
use super::gate::GateConfig;
use super::lock::LockConfig;
use super::pi::{PiLimits, THETA_MAX};
use crate::num::{fold, fold_near, low32, wrapping_diff};

/// Largest cycle period the loop accepts: 2·THETA_MAX (536 ms), so the folded error always fits
/// the PI kernel unclamped.
pub const PERIOD_MAX_NS: u32 = 1 << 29;

/// Master-loop configuration.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::{MasterConfig, MasterServo};
///
/// // A 1 ms cycle whose app-time stamp is taken 30 µs before the frame passes the reference.
/// let cfg = MasterConfig {
///     target_ns: -30_000,
///     ..MasterConfig::for_period(1_000_000)?
/// };
/// let servo = MasterServo::new(cfg)?;
/// assert!(!servo.is_locked());
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MasterConfig {
    /// Cycle period P, ns, in [1000, PERIOD_MAX_NS].
    pub period_ns: u32,
    /// Desired value of (app − ref), ns, |·| ≤ P (e.g. minus the latency from the app-time
    /// stamp to the frame passing the reference).
    pub target_ns: i64,
    /// The reference is a 32-bit DC: compare only the low 32 bits (wrap-safe for |Δ| < 2^31).
    pub ref_32bit: bool,
    /// Engine configuration; `interval_ns` must equal `period_ns`.
    pub servo: ServoConfig,
}

impl MasterConfig {
    /// Defaults for period P (ecdc choices, REQ-SERVO-104):
    /// - acquire: double pole 0.9 (Kp 0.19, Ki 0.01), track: double pole 0.99 (noise-rejecting);
    /// - |correction| ≤ P/1000 per cycle (IgH's ±0.1 %), I_max = y_max;
    /// - no phase steps of the wake-up at all: steps are by whole periods of app time only
    ///   (a sub-period offset is slewed away at ≤ P/1000 per cycle, i.e. ≤ P/2 in 500 cycles
    ///   plus the drift); set `servo.first_step_ns` to allow one first-sample wake-up shift;
    /// - gear to tracking after 32 cycles with |θ| < P/50, or after 2000 cycles regardless;
    /// - lock below P/50 for 32 cycles, unlock above P/20 (linuxcnc: P/10);
    /// - gate κ = 5 with floor P/100; holdover 100 cycles; fault after 1000 saturated cycles
    ///   without progress.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::gains::ONE;
    /// use ecdc_core::servo::master::MasterConfig;
    /// use ecdc_core::servo::ConfigError;
    ///
    /// let cfg = MasterConfig::for_period(1_000_000)?;
    /// assert_eq!(cfg.servo.interval_ns, 1_000_000);
    /// assert_eq!(cfg.servo.limits.y_max(), 1_000 * ONE); // P/1000 per cycle
    /// assert_eq!(MasterConfig::for_period(500), Err(ConfigError::Parameter));
    /// # Ok::<(), ConfigError>(())
    /// ```
    pub fn for_period(period_ns: u32) -> Result<Self, ConfigError> {
        if !(1000..=PERIOD_MAX_NS).contains(&period_ns) {
            return Err(ConfigError::Parameter);
        }
        let p = u64::from(period_ns);
        let y_max = i64::from(period_ns / 1000);
        let acquire = PiGains::double_pole(Pole::from_micro(900_000).map_err(ConfigError::Gains)?)
            .map_err(ConfigError::Gains)?;
        let track = PiGains::double_pole(Pole::from_micro(990_000).map_err(ConfigError::Gains)?)
            .map_err(ConfigError::Gains)?;
        let limits = PiLimits::from_ns(y_max, y_max).map_err(ConfigError::Limits)?;
        let floor = u32::try_from(p / 100).unwrap_or(u32::MAX);
        Ok(MasterConfig {
            period_ns,
            target_ns: 0,
            ref_32bit: false,
            servo: ServoConfig {
                interval_ns: period_ns,
                acquire,
                track,
                limits,
                first_step_ns: 0,
                step_ns: 0,
                step_confirm: 3,
                blank: 1,
                gear_ns: p / 50,
                gear_count: 32,
                acquire_max: 2000,
                gate: GateConfig::with_floor(floor),
                lock: LockConfig {
                    low_ns: p / 50,
                    high_ns: p / 20,
                    count: 32,
                },
                holdover_max: 100,
                fault_after: 1000,
            },
        })
    }
}

/// One cycle's input.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
/// use ecdc_core::servo::Verdict;
///
/// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
/// servo.update(MasterInput::Sample {
///     local_ns: 0,
///     app_ns: 5_000_000_000,
///     ref_ns: 4_999_999_900,
/// });
/// // The cyclic frame did not come back: hold the learned rate.
/// let out = servo.update(MasterInput::Lost);
/// assert_eq!(
///     (out.engine.verdict, out.phase_error_ns),
///     (Verdict::Missing, 0)
/// );
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MasterInput {
    /// The FRMW came back.
    Sample {
        /// Master's local monotonic time when the cycle ran (for interval sanity), ns.
        local_ns: u64,
        /// The app (nominal DC) time this cycle's frame carried, ns.
        app_ns: u64,
        /// The reference's system time returned by the FRMW (low 32 bits if 32-bit), ns.
        ref_ns: u64,
    },
    /// The FRMW was lost (frame lost, WKC 0): hold the learned rate.
    Lost,
}

/// One cycle's output.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
///
/// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
/// // App time is 3.25 cycles ahead of the reference: 3 whole cycles go into the app-time
/// // base, the remaining quarter cycle is the phase error the loop slews away.
/// let out = servo.update(MasterInput::Sample {
///     local_ns: 0,
///     app_ns: 5_003_250_000,
///     ref_ns: 5_000_000_000,
/// });
/// assert_eq!(out.phase_error_ns, 250_000);
/// assert_eq!(out.app_time_step_ns, -3_000_000);
/// assert_eq!(out.deadline_correction_ns, 1_000); // slewing at the P/1000 limit
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MasterOutput {
    /// Add to the next wake-up deadline, ns (positive = wake later).
    pub deadline_correction_ns: i64,
    /// Add to the app-time base, ns; always a multiple of P (0 = none).
    pub app_time_step_ns: i64,
    /// Folded phase error θ ∈ (−P/2, P/2], ns (0 when lost).
    pub phase_error_ns: i64,
    /// The engine's decision (mode, lock, verdict, saturation).
    pub engine: Output,
}

/// Master-follows-reference servo state.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
///
/// // The master's timer gains 50 ns per 1 ms cycle on the reference: each wake-up comes 50 ns
/// // earlier in DC terms than asked for. Simulate the loop: θ' = θ + 50 − correction.
/// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
/// let (app, mut ref_lag) = (5_000_000_000u64, 0i64); // ref = app − θ
/// for k in 0..4_000u64 {
///     let app_k = app + k * 1_000_000;
///     let ref_k = app_k.wrapping_add_signed(ref_lag);
///     let out = servo.update(MasterInput::Sample {
///         local_ns: k * 1_000_000,
///         app_ns: app_k,
///         ref_ns: ref_k,
///     });
///     ref_lag -= 50 - out.deadline_correction_ns;
/// }
/// assert!(servo.is_locked());
/// assert_eq!(servo.drift_ns_per_cycle(), 50);
/// # Ok::<(), ecdc_core::servo::ConfigError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MasterServo {
    period: u32,
    target: i64,
    ref_32bit: bool,
    servo: Servo,
    carry: Carry,
    started: bool,
    whole_run: u8,
    whole_last: i64,
}

impl MasterServo {
    /// Validate and build.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::{MasterConfig, MasterServo};
    /// use ecdc_core::servo::{ConfigError, Mode};
    ///
    /// let servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
    /// assert_eq!(servo.mode(), Mode::Init);
    /// // The engine's interval must be the cycle period.
    /// let mut cfg = MasterConfig::for_period(1_000_000)?;
    /// cfg.servo.interval_ns = 2_000_000;
    /// assert_eq!(
    ///     MasterServo::new(cfg).map(|s| s.mode()),
    ///     Err(ConfigError::Parameter)
    /// );
    /// # Ok::<(), ConfigError>(())
    /// ```
    pub fn new(cfg: MasterConfig) -> Result<Self, ConfigError> {
        if !(1000..=PERIOD_MAX_NS).contains(&cfg.period_ns)
            || cfg.servo.interval_ns != cfg.period_ns
            || cfg.target_ns.unsigned_abs() > u64::from(cfg.period_ns)
            // The folded phase error (at most P/2) must stay within the engine's θ range;
            // with P <= PERIOD_MAX_NS this always holds, and the check keeps it so if either
            // bound changes.
            || i64::from(cfg.period_ns / 2) > THETA_MAX
        {
            return Err(ConfigError::Parameter);
        }
        Ok(MasterServo {
            period: cfg.period_ns,
            target: cfg.target_ns,
            ref_32bit: cfg.ref_32bit,
            servo: Servo::new(cfg.servo)?,
            carry: Carry::new(),
            started: false,
            whole_run: 0,
            whole_last: 0,
        })
    }

    /// The engine (mode, lock, counters, integrator).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::{MasterConfig, MasterServo};
    ///
    /// let servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
    /// assert_eq!(servo.engine().config().interval_ns, 1_000_000);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn engine(&self) -> &Servo {
        &self.servo
    }

    /// Current mode.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
    /// use ecdc_core::servo::Mode;
    ///
    /// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
    /// servo.update(MasterInput::Sample {
    ///     local_ns: 0,
    ///     app_ns: 1_000_000,
    ///     ref_ns: 1_000_000,
    /// });
    /// assert_eq!(servo.mode(), Mode::Acquire);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn mode(&self) -> Mode {
        self.servo.mode()
    }

    /// Lock flag (hysteresis, REQ-SERVO-060).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
    ///
    /// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
    /// // 32 cycles on the reference's grid: locked.
    /// for k in 0..32u64 {
    ///     let t = 1_000_000_000 + k * 1_000_000;
    ///     servo.update(MasterInput::Sample {
    ///         local_ns: t,
    ///         app_ns: t,
    ///         ref_ns: t,
    ///     });
    /// }
    /// assert!(servo.is_locked());
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn is_locked(&self) -> bool {
        self.servo.is_locked()
    }

    /// Event counters.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
    ///
    /// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
    /// servo.update(MasterInput::Lost);
    /// servo.update(MasterInput::Lost);
    /// assert_eq!(servo.counters().held, 2);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn counters(&self) -> &Counters {
        self.servo.counters()
    }

    /// Start over (e.g. after the DC network was re-initialised): back to `Init`, app time is
    /// re-aligned by whole periods on the next sample, the learned drift is kept.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
    /// use ecdc_core::servo::Mode;
    ///
    /// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
    /// servo.update(MasterInput::Sample {
    ///     local_ns: 0,
    ///     app_ns: 1_000_000,
    ///     ref_ns: 1_000_000,
    /// });
    /// servo.reset(); // the DC network was re-initialised
    /// assert_eq!(servo.mode(), Mode::Init);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub fn reset(&mut self) {
        self.servo.reset();
        self.carry.reset();
        self.started = false;
        self.whole_run = 0;
        self.whole_last = 0;
    }

    /// Learned drift of the master's timer, ns per cycle (Q32 integrator rounded toward −∞).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
    ///
    /// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
    /// assert_eq!(servo.drift_ns_per_cycle(), 0);
    /// // Persistently 200 ns ahead: the integrator starts learning a retard.
    /// for k in 0..10u64 {
    ///     let t = 1_000_000_000 + k * 1_000_000;
    ///     servo.update(MasterInput::Sample {
    ///         local_ns: t,
    ///         app_ns: t,
    ///         ref_ns: t - 200,
    ///     });
    /// }
    /// assert!(servo.drift_ns_per_cycle() > 0);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub const fn drift_ns_per_cycle(&self) -> i64 {
        self.servo.integrator_q32() >> 32
    }

    /// The wrap-safe difference app − ref in the configured width.
    #[inline]
    fn difference(&self, app: u64, reference: u64) -> i64 {
        if self.ref_32bit {
            i64::from(wrapping_diff::<u32>(low32(app), low32(reference)))
        } else {
            wrapping_diff::<u64>(app, reference)
        }
    }

    /// REQ-SERVO-100: θ = fold((app − ref) − target), the app-time correction that removes the
    /// whole periods of raw − θ, and whether |raw| ≥ P — the same values as
    /// [`MasterServo::measure_wide`] for every input (see [`MasterServo::measure_fast`]).
    #[cfg(test)]
    fn measure(&self, app: u64, reference: u64) -> (i64, i64, bool) {
        self.measure_fast(app, reference)
            .unwrap_or_else(|| self.measure_wide(app, reference))
    }

    /// [`MasterServo::measure`] on the common path, `None` where it needs the wide path: when
    /// raw and θ − raw fit in i64 (always, unless |app − ref| is within 2^29 of 2^63) θ is raw
    /// folded once (raw is exact, so this is the representative of raw mod P that the wide path
    /// reaches by folding d, subtracting the target and folding again; no division when raw
    /// lies within two periods of the fold window) and the correction is θ − raw itself (that is
    /// what `fit_multiple` returns for a value that fits).
    #[inline]
    fn measure_fast(&self, app: u64, reference: u64) -> Option<(i64, i64, bool)> {
        let d = self.difference(app, reference);
        let p = i64::from(self.period);
        let raw = d.checked_sub(self.target)?;
        // raw: any i64 (that is all the precondition of fold_near's proof asks of x).
        let theta = fold_near::<u64>(raw, u64::from(self.period));
        let correction = theta.checked_sub(raw)?;
        Some((theta, correction, raw.unsigned_abs() >= p.unsigned_abs()))
    }

    /// [`MasterServo::measure`] computed in i128 throughout (the fallback when
    /// an i64 intermediate could overflow, and the oracle of the equality test).
    fn measure_wide(&self, app: u64, reference: u64) -> (i64, i64, bool) {
        let d = self.difference(app, reference);
        let p = u64::from(self.period);
        // |fold(d)| ≤ P/2 and |target| ≤ P ≤ 2^29: the inner difference cannot overflow, and
        // it is ≡ raw (mod P), so folding it again gives fold(raw).
        let theta = fold::<u64>(fold::<u64>(d, p).wrapping_sub(self.target), p);
        let raw = i128::from(d).wrapping_sub(i128::from(self.target));
        let correction = fit_multiple(i128::from(theta).wrapping_sub(raw), i128::from(p));
        (theta, correction, raw.unsigned_abs() >= u128::from(p))
    }

    /// REQ-SERVO-100..104: process one cycle.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::master::{MasterConfig, MasterInput, MasterServo};
    ///
    /// let mut servo = MasterServo::new(MasterConfig::for_period(1_000_000)?)?;
    /// // The master is 250 ns ahead of the reference: wake later.
    /// let out = servo.update(MasterInput::Sample {
    ///     local_ns: 0,
    ///     app_ns: 7_000_000,
    ///     ref_ns: 6_999_750,
    /// });
    /// assert_eq!(out.phase_error_ns, 250);
    /// assert!(out.deadline_correction_ns > 0);
    /// assert_eq!(out.app_time_step_ns, 0);
    /// # Ok::<(), ecdc_core::servo::ConfigError>(())
    /// ```
    pub fn update(&mut self, input: MasterInput) -> MasterOutput {
        match input {
            MasterInput::Lost => {
                let out = self.servo.update(Input::Missing);
                self.finish(out, 0, 0)
            }
            MasterInput::Sample {
                local_ns,
                app_ns,
                ref_ns,
            } => match self.measure_fast(app_ns, ref_ns) {
                Some(m) => self.sample(local_ns, m),
                None => self.sample_wide(local_ns, app_ns, ref_ns),
            },
        }
    }

    /// A sample whose measurement needs [`MasterServo::measure_wide`] (|app − ref| within 2^29
    /// of 2^63): out of line, so the common path keeps its values in registers.
    #[cold]
    #[inline(never)]
    fn sample_wide(&mut self, local_ns: u64, app_ns: u64, ref_ns: u64) -> MasterOutput {
        let m = self.measure_wide(app_ns, ref_ns);
        self.sample(local_ns, m)
    }

    /// One sample with its measurement (θ, whole-period correction, |raw| ≥ P).
    #[inline(always)]
    fn sample(
        &mut self,
        local_ns: u64,
        (theta, correction, beyond): (i64, i64, bool),
    ) -> MasterOutput {
        // θ is folded into (−P/2, P/2] with P ≤ 2^29, so this clamp never changes it; it tells
        // the optimiser the bound, which removes the engine's, the gate's and the PI kernel's
        // own (wider or equal) clamps from this path.
        let theta = theta.clamp(-THETA_MAX, THETA_MAX);
        let mut app_step = 0i64;
        if correction == 0 {
            self.whole_run = 0;
        } else if !self.started {
            // First sample: align app time to DC at once (nothing is running on it yet).
            app_step = correction;
        } else if beyond {
            // Later: only a confirmed offset of a period or more (jitter near ±P/2 must not
            // make the app time flip between neighbouring periods).
            if self.whole_run > 0 && correction == self.whole_last {
                self.whole_run = self.whole_run.saturating_add(1);
            } else {
                self.whole_run = 1;
                self.whole_last = correction;
            }
            if self.whole_run >= self.servo.config().step_confirm {
                app_step = correction;
                self.whole_run = 0;
            }
        }
        self.started = true;
        let out = self.servo.update_inline(Input::Sample {
            local_ns,
            theta_ns: theta,
        });
        if out.verdict == Verdict::Stepped {
            self.carry.reset();
        }
        self.finish(out, app_step, theta)
    }

    fn finish(&mut self, out: Output, app_step: i64, theta: i64) -> MasterOutput {
        let pi = self.carry.quantize(out.command_q32);
        MasterOutput {
            // |pi| ≤ y_max_ns ≤ 2^28 and |step| ≤ P/2 < 2^28: no overflow.
            deadline_correction_ns: pi.saturating_add(out.step_ns),
            app_time_step_ns: app_step,
            phase_error_ns: theta,
            engine: out,
        }
    }
}

/// The multiple of `p` nearest to `v` toward zero that fits in i64 (`v` itself when it fits).
/// `v` is a multiple of `p` with |v| < 2^64; `p` in [1000, 2^29].
pub(super) fn fit_multiple(v: i128, p: i128) -> i64 {
    let max = i128::from(i64::MAX);
    let min = i128::from(i64::MIN);
    let excess = if v > max {
        v.wrapping_sub(max)
    } else if v < min {
        v.wrapping_sub(min)
    } else {
        0
    };
    // Round the excess away from zero to whole periods and remove it.
    let k = excess
        .unsigned_abs()
        .checked_add(p.unsigned_abs().saturating_sub(1))
        .and_then(|e| e.checked_div(p.unsigned_abs()))
        .unwrap_or(0);
    let k = i128::try_from(k).unwrap_or(0);
    let adj = k.wrapping_mul(p);
    let v = if excess > 0 {
        v.wrapping_sub(adj)
    } else {
        v.wrapping_add(adj)
    };
    i64::try_from(v).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::{vec, vec::Vec};

    /// A new servo is not locked.
    #[test]
    fn new_servo_is_unlocked() {
        let servo = MasterServo::new(MasterConfig::for_period(1_000_000).unwrap()).unwrap();
        assert!(!servo.is_locked());
    }

    /// Closed loop against a timer drifting `ppm`, no noise: locks and stays inside ±2 ns.
    fn run(ppm: i64, initial: i64) -> (MasterServo, i64) {
        let p = 1_000_000i64;
        let mut m = MasterServo::new(MasterConfig::for_period(1_000_000).unwrap()).unwrap();
        let delta = ppm; // ns per 1 ms cycle per ppm
        let mut theta_true = initial; // (app − ref) actual
        let mut app: u64 = 1 << 40;
        let mut local: u64 = 0;
        let mut worst_late = 0i64;
        for k in 0..20_000 {
            let reference = (app as i64 - theta_true) as u64;
            let out = m.update(MasterInput::Sample {
                local_ns: local,
                app_ns: app,
                ref_ns: reference,
            });
            // Whole-period app-time steps shift app and the measured error together.
            app = (app as i64 + out.app_time_step_ns) as u64;
            theta_true += out.app_time_step_ns;
            theta_true += delta - out.deadline_correction_ns;
            app += p as u64;
            local += p as u64;
            if k > 15_000 {
                worst_late = worst_late.max(theta_true.abs());
            }
        }
        (m, worst_late)
    }

    #[test]
    fn locks_on_drifting_master() {
        for &(ppm, init) in &[(100, 0), (-100, 12_345), (50, 3_400_000), (-80, -499_999)] {
            let (m, worst) = run(ppm, init);
            assert!(m.is_locked(), "ppm {ppm}");
            assert_eq!(m.mode(), Mode::Tracking);
            assert!(worst <= 2, "ppm {ppm} worst {worst}");
            assert!(
                (m.drift_ns_per_cycle() - ppm).abs() <= 1,
                "{}",
                m.drift_ns_per_cycle()
            );
        }
    }

    #[test]
    fn whole_periods_only_and_lost_frames_hold() {
        let mut m = MasterServo::new(MasterConfig::for_period(1_000_000).unwrap()).unwrap();
        let out = m.update(MasterInput::Sample {
            local_ns: 0,
            app_ns: 5_000_000_300,
            ref_ns: 3_000_000_000,
        });
        assert_eq!(out.app_time_step_ns, -2_000_000_000);
        assert_eq!(out.phase_error_ns, 300);
        let out = m.update(MasterInput::Lost);
        assert_eq!(out.engine.verdict, Verdict::Missing);
        assert_eq!(out.engine.mode, Mode::Holdover);
        assert_eq!(out.app_time_step_ns, 0);
        // After a reset the next sample realigns app time at once again, drift kept.
        m.reset();
        assert_eq!(m.mode(), Mode::Init);
        let out = m.update(MasterInput::Sample {
            local_ns: 0,
            app_ns: 7_000_000_000,
            ref_ns: 3_000_000_100,
        });
        assert_eq!(out.app_time_step_ns, -4_000_000_000);
        assert_eq!(out.phase_error_ns, -100);
    }

    #[test]
    fn extreme_differences_still_step_whole_periods() {
        for &(app, reference, target) in &[
            (0u64, 1u64 << 63, 999_999i64),
            (1u64 << 63, 0, -1_000_000),
            (u64::MAX, (1 << 63) - 1, 1),
        ] {
            let mut cfg = MasterConfig::for_period(1_000_000).unwrap();
            cfg.target_ns = target;
            let mut m = MasterServo::new(cfg).unwrap();
            let out = m.update(MasterInput::Sample {
                local_ns: 0,
                app_ns: app,
                ref_ns: reference,
            });
            assert_eq!(out.app_time_step_ns % 1_000_000, 0);
            assert!(out.app_time_step_ns != 0);
            let raw = i128::from(app.wrapping_sub(reference) as i64) - i128::from(target);
            let theta = i128::from(out.phase_error_ns);
            assert_eq!((raw - theta).rem_euclid(1_000_000), 0);
            assert!(2 * theta <= 1_000_000 && 2 * theta > -1_000_000);
        }
        assert_eq!(fit_multiple((1i128 << 63) + 192, 1000), i64::MAX - 807);
        assert_eq!(fit_multiple(-(1i128 << 63) - 192, 1000), i64::MIN + 808);
    }

    use crate::servo::test_rng::Rng;

    /// The branchy `i64` body `fold_near` had before it became the Word-generic
    /// `num::fold_near`, kept as the differential oracle: for `p` in [1000, 2^29], x, x ∓ p or
    /// x ∓ 2p when one lies in (⌊p/2⌋ − p, ⌊p/2⌋], else the division in [`fold`].
    fn fold_near_i64(x: i64, p: i64) -> i64 {
        let hi = p >> 1;
        let lo = hi.wrapping_sub(p); // exclusive
        if x > lo {
            if x <= hi {
                return x;
            }
            let y = x.wrapping_sub(p);
            if y <= hi {
                return y;
            }
            // y > hi ≥ 0 here: y − p cannot overflow.
            let y = y.wrapping_sub(p);
            if y <= hi {
                return y;
            }
        } else {
            // x ≤ lo < 0: x + p cannot overflow.
            let y = x.wrapping_add(p);
            if y > lo {
                return y;
            }
            let y = y.wrapping_add(p);
            if y > lo {
                return y;
            }
        }
        fold::<u64>(x, p.unsigned_abs())
    }

    #[test]
    fn fold_near_equals_fold() {
        let mut rng = Rng(0xD1B5_4A32_D192_ED03);
        for p in [
            1000i64,
            1001,
            999_999,
            1_000_000,
            1_000_001,
            PERIOD_MAX_NS as i64,
        ] {
            let mut xs = vec![0, 1, -1, i64::MIN, i64::MAX, i64::MIN + 1, i64::MAX - 1];
            for k in -4..=4i64 {
                for off in -2..=2i64 {
                    xs.push(k * p + off);
                    xs.push(k * p + p / 2 + off);
                    xs.push(k * p - p / 2 + off);
                }
            }
            for _ in 0..20_000 {
                let r = rng.next();
                xs.push(r as i64);
                xs.push((r % (10 * p as u64)) as i64 - 5 * p);
            }
            for &x in &xs {
                let f = fold::<u64>(x, p as u64);
                assert_eq!(fold_near::<u64>(x, p as u64), f, "x {x} p {p}");
                assert_eq!(fold_near_i64(x, p), f, "x {x} p {p}");
            }
        }
    }

    #[test]
    fn measure_equals_wide_measure() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for p in [1000u32, 1001, 333_333, 1_000_000, 1_000_001, PERIOD_MAX_NS] {
            let pi = i64::from(p);
            let mut targets = vec![0, 1, -1, pi, -pi, pi - 1, -pi + 1, pi / 2, -pi / 2];
            for _ in 0..4 {
                targets.push((rng.next() % (2 * p as u64 + 1)) as i64 - pi);
            }
            let mut ds: Vec<i64> = vec![i64::MIN, i64::MAX, 0, 1 << 31, -(1 << 31), 1 << 32];
            for base in [0, i64::MIN, i64::MAX, 1 << 31, -(1 << 31), 1 << 32] {
                for k in -3..=3i64 {
                    for off in [-pi / 2 - 1, -pi / 2, -1, 0, 1, pi / 2, pi / 2 + 1] {
                        ds.push(base.wrapping_add(k * pi).wrapping_add(off));
                    }
                }
            }
            for &target in &targets {
                for ref_32bit in [false, true] {
                    let mut cfg = MasterConfig::for_period(p).unwrap();
                    cfg.target_ns = target;
                    cfg.ref_32bit = ref_32bit;
                    let m = MasterServo::new(cfg).unwrap();
                    let check = |app: u64, reference: u64| {
                        assert_eq!(
                            m.measure(app, reference),
                            m.measure_wide(app, reference),
                            "p {p} target {target} 32-bit {ref_32bit} app {app} ref {reference}"
                        );
                    };
                    for &d in &ds {
                        let app = rng.next();
                        check(app, app.wrapping_sub(d as u64));
                    }
                    for _ in 0..2000 {
                        let app = rng.next();
                        check(app, rng.next());
                        let near = (rng.next() % (8 * u64::from(p))) as i64 - 4 * pi;
                        check(app, app.wrapping_sub(near as u64));
                    }
                }
            }
        }
    }

    #[test]
    fn fold_below_minus_half_period() {
        // The IgH `%` pitfall: −700 µs at P = 1 ms must fold to +300 µs.
        let mut cfg = MasterConfig::for_period(1_000_000).unwrap();
        cfg.servo.first_step_ns = 0;
        let mut m = MasterServo::new(cfg).unwrap();
        let out = m.update(MasterInput::Sample {
            local_ns: 0,
            app_ns: 10_000_000,
            ref_ns: 10_700_000,
        });
        assert_eq!(out.phase_error_ns, 300_000);
        assert_eq!(out.app_time_step_ns, 1_000_000);
        assert!(out.deadline_correction_ns > 0 && out.deadline_correction_ns <= 1000);
    }
}
