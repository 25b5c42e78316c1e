//! Test-only oracle: the servo hot path (gate, engine, master adapter) exactly as it was at
//! 34e7a71, before the per-update instruction work. The differential tests drive it and the
//! current code with the same inputs and require equal outputs and equal `Debug` of the whole
//! state after every step (the structs keep their names, so the `Debug` text is comparable).
//! Helpers the work left unchanged (`sorted_insert`, `median_mad_sorted`, `fold_near`,
//! `fit_multiple`, `low32`) are not copied: the oracle calls the live ones.
#![allow(dead_code, missing_docs, clippy::all)]

pub mod gate {
    // Unchanged since 34e7a71: the live helpers (their own tests pin them).
    use crate::servo::gate::{median_mad_sorted, sorted_insert};
    use crate::servo::gate::{GateConfig, GateVerdict, GATE_WINDOW};

    /// Gate state: a ring of recent accepted errors plus the current rejection run.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct Gate {
        buf: [i64; GATE_WINDOW],
        /// The same `len` entries as `buf`, kept in ascending order by [`Gate::push`] (entries
        /// past `len` are unspecified), so the median and MAD need no sort per judgement.
        sorted: [i64; GATE_WINDOW],
        len: u8,
        head: u8,
        run: u8,
        run_positive: bool,
    }

    impl Default for Gate {
        fn default() -> Self {
            Self::new()
        }
    }

    /// Replace one entry equal to `old` in the ascending prefix `s[..n]` by `new` (if `old` is
    /// present), keeping it ascending: the entries between the two positions shift by one.
    fn sorted_replace(s: &mut [i64; GATE_WINDOW], n: usize, old: i64, new: i64) {
        let Some(v) = s.get_mut(..n) else {
            return;
        };
        let Ok(mut i) = v.binary_search(&old) else {
            return;
        };
        // Larger entries to the right move left while they are below `new` ...
        while let Some(&next) = v.get(i.wrapping_add(1)) {
            if next >= new {
                break;
            }
            if let Some(slot) = v.get_mut(i) {
                *slot = next;
            }
            i = i.wrapping_add(1);
        }
        // ... or smaller entries to the left move right while they are above it.
        while let Some(prev) = i.checked_sub(1).and_then(|k| v.get(k).copied()) {
            if prev <= new {
                break;
            }
            if let Some(slot) = v.get_mut(i) {
                *slot = prev;
            }
            i = i.wrapping_sub(1);
        }
        if let Some(slot) = v.get_mut(i) {
            *slot = new;
        }
    }

    impl Gate {
        /// An empty, unarmed gate.
        pub const fn new() -> Self {
            Gate {
                buf: [0; GATE_WINDOW],
                sorted: [0; GATE_WINDOW],
                len: 0,
                head: 0,
                run: 0,
                run_positive: false,
            }
        }

        /// Number of samples in the window.
        pub const fn len(&self) -> usize {
            self.len as usize
        }

        /// True when the window is empty.
        pub const fn is_empty(&self) -> bool {
            self.len == 0
        }

        /// (median, threshold) of the current window, or `None` while not armed.
        pub fn threshold(&self, cfg: &GateConfig) -> Option<(i64, i64)> {
            let n = self.len();
            if cfg.kappa_q8 == 0 || n < usize::from(cfg.min_samples.max(3)) {
                return None;
            }
            // Window entries are clamped to ±2^40 on entry: the deviations cannot overflow.
            let (med, mad) = median_mad_sorted(self.sorted.get(..n)?);
            // MAD ≤ 2^41, κ_q8 < 2^32: the product fits in i64 before the shift.
            let t = mad.saturating_mul(i64::from(cfg.kappa_q8)) >> 8;
            Some((med, t.max(i64::from(cfg.floor_ns))))
        }

        /// REQ-SERVO-050: judge `theta`. Does not record it; call [`Gate::push`] for accepted ones.
        pub fn judge(&mut self, cfg: &GateConfig, theta: i64) -> GateVerdict {
            let Some((med, thr)) = self.threshold(cfg) else {
                self.run = 0;
                return GateVerdict::Accept;
            };
            let e = theta.clamp(-WINDOW_CLAMP, WINDOW_CLAMP).wrapping_sub(med);
            if e.wrapping_abs() <= thr {
                self.run = 0;
                return GateVerdict::Accept;
            }
            let positive = e > 0;
            if self.run == 0 || positive != self.run_positive {
                self.run = 1;
                self.run_positive = positive;
            } else {
                self.run = self.run.saturating_add(1);
            }
            if self.run >= cfg.confirm.max(1) {
                self.run = 0;
                GateVerdict::Confirmed
            } else {
                GateVerdict::Reject
            }
        }

        /// Record an accepted error.
        pub fn push(&mut self, theta: i64) {
            let h = usize::from(self.head) % GATE_WINDOW;
            let x = theta.clamp(-WINDOW_CLAMP, WINDOW_CLAMP);
            let n = self.len().min(GATE_WINDOW);
            if let Some(slot) = self.buf.get_mut(h) {
                if n == GATE_WINDOW {
                    // Full: slot h holds the oldest entry, which leaves the window.
                    sorted_replace(&mut self.sorted, n, *slot, x);
                } else {
                    sorted_insert(&mut self.sorted, n, x);
                }
                *slot = x;
            }
            self.head = u8::try_from(h.wrapping_add(1) % GATE_WINDOW).unwrap_or(0);
            if self.len() < GATE_WINDOW {
                self.len = self.len.saturating_add(1);
            }
        }

        /// Forget the window (after a step or a confirmed change).
        pub fn clear(&mut self) {
            *self = Self::new();
        }
    }

    /// Window entries are clamped to ±2^40 ns so median/MAD arithmetic cannot overflow.
    const WINDOW_CLAMP: i64 = 1 << 40;
}

pub mod engine {
    use super::gate::Gate;
    use crate::num::wrapping_diff;
    use crate::servo::engine::{ConfigError, Counters, Input, Mode, Output, ServoConfig, Verdict};
    use crate::servo::gate::GateVerdict;
    use crate::servo::lock::LockDetector;
    use crate::servo::pi::{hold, pi_step};

    /// The servo engine state.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
        step_run: u8,
        step_positive: bool,
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
                step_run: 0,
                step_positive: false,
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
        pub fn with_integrator(mut self, i_q32: i64) -> Self {
            self.integrator = hold(self.cfg.limits, i_q32);
            self
        }

        /// Configuration in use.
        pub const fn config(&self) -> &ServoConfig {
            &self.cfg
        }

        /// Current mode.
        pub const fn mode(&self) -> Mode {
            self.mode
        }

        /// Current lock flag.
        pub const fn is_locked(&self) -> bool {
            self.lock.is_locked()
        }

        /// Integrator (learned frequency), Q32 ns per interval, |·| ≤ I_max.
        pub const fn integrator_q32(&self) -> i64 {
            self.integrator
        }

        /// Event counters.
        pub const fn counters(&self) -> &Counters {
            &self.counters
        }

        /// Back to `Init`, keeping the learned frequency (a restart does not change the crystal's rate).
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
            self.step_run = 0;
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
        pub fn update(&mut self, input: Input) -> Output {
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
                let positive = theta > 0;
                if self.step_run == 0 || positive != self.step_positive {
                    self.step_run = 1;
                    self.step_positive = positive;
                } else {
                    self.step_run = self.step_run.saturating_add(1);
                }
                if self.step_run >= self.cfg.step_confirm {
                    return self.step(theta);
                }
                return self.held(Verdict::StepPending, theta);
            } else {
                self.step_run = 0;
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
}

pub mod master {
    use super::engine::Servo;
    use crate::num::{fold, wrapping_diff};
    use crate::servo::carry::Carry;
    use crate::servo::engine::{ConfigError, Counters, Input, Mode, Output, Verdict};
    use crate::servo::master::{MasterConfig, MasterInput, MasterOutput, PERIOD_MAX_NS};
    use crate::servo::pi::THETA_MAX;
    // Unchanged since 34e7a71: the live helpers (their own tests pin them).
    use crate::servo::master::{fit_multiple, fold_near, low32};

    /// Master-follows-reference servo state.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
        pub fn new(cfg: MasterConfig) -> Result<Self, ConfigError> {
            if !(1000..=PERIOD_MAX_NS).contains(&cfg.period_ns)
                || cfg.servo.interval_ns != cfg.period_ns
                || cfg.target_ns.unsigned_abs() > u64::from(cfg.period_ns)
            {
                return Err(ConfigError::Parameter);
            }
            debug_assert!(i64::from(cfg.period_ns / 2) <= THETA_MAX);
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
        pub const fn engine(&self) -> &Servo {
            &self.servo
        }

        /// Current mode.
        pub const fn mode(&self) -> Mode {
            self.servo.mode()
        }

        /// Lock flag (hysteresis, REQ-SERVO-060).
        pub const fn is_locked(&self) -> bool {
            self.servo.is_locked()
        }

        /// Event counters.
        pub const fn counters(&self) -> &Counters {
            self.servo.counters()
        }

        /// Start over (e.g. after the DC network was re-initialised): back to `Init`, app time is
        /// re-aligned by whole periods on the next sample, the learned drift is kept.
        pub fn reset(&mut self) {
            self.servo.reset();
            self.carry.reset();
            self.started = false;
            self.whole_run = 0;
            self.whole_last = 0;
        }

        /// Learned drift of the master's timer, ns per cycle (Q32 integrator rounded toward −∞).
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
        /// [`MasterServo::measure_wide`] for every input, cheaper on the common path: when
        /// (app − ref) lies within two periods of the fold window no division is needed, and when
        /// raw and θ − raw fit in i64 (always, unless |app − ref| is within 2^29 of 2^63) the
        /// correction is θ − raw itself (that is what `fit_multiple` returns for a value that fits).
        #[inline]
        fn measure(&self, app: u64, reference: u64) -> (i64, i64, bool) {
            let d = self.difference(app, reference);
            let p = i64::from(self.period);
            // |fold(d)| ≤ P/2, |target| ≤ P ≤ 2^29: no overflow; ≡ raw (mod P).
            let theta = fold_near(fold_near(d, p).wrapping_sub(self.target), p);
            match d.checked_sub(self.target) {
                Some(raw) => match theta.checked_sub(raw) {
                    Some(correction) => (theta, correction, raw.unsigned_abs() >= p.unsigned_abs()),
                    None => self.measure_wide(app, reference),
                },
                None => self.measure_wide(app, reference),
            }
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
        pub fn update(&mut self, input: MasterInput) -> MasterOutput {
            let (local_ns, (theta, correction, beyond)) = match input {
                MasterInput::Lost => {
                    let out = self.servo.update(Input::Missing);
                    return self.finish(out, 0, 0);
                }
                MasterInput::Sample {
                    local_ns,
                    app_ns,
                    ref_ns,
                } => (local_ns, self.measure(app_ns, ref_ns)),
            };
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
            let out = self.servo.update(Input::Sample {
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
}

#[cfg(test)]
mod tests {
    use crate::servo::engine::{Input, Mode, Servo, ServoConfig, Verdict};
    use crate::servo::gains::{PiGains, Pole};
    use crate::servo::gate::{Gate, GateConfig, GATE_WINDOW};
    use crate::servo::lock::LockConfig;
    use crate::servo::master::{MasterConfig, MasterInput, MasterServo};
    use crate::servo::pi::PiLimits;
    use std::format;

    use crate::servo::test_rng::Rng;
    impl Rng {
        fn below(&mut self, n: u64) -> u64 {
            self.next() % n
        }
        fn chance(&mut self, one_in: u64) -> bool {
            self.below(one_in) == 0
        }
        fn pick<T: Copy>(&mut self, v: &[T]) -> T {
            v[self.below(v.len() as u64) as usize]
        }
        /// A signed error around `center` with noise `noise`, sometimes an outlier or an
        /// extreme value.
        fn theta(&mut self, center: i64, noise: i64) -> i64 {
            match self.below(40) {
                0 => self.pick(&[
                    i64::MIN,
                    i64::MAX,
                    0,
                    1 << 40,
                    (1 << 40) + 1,
                    -(1 << 40),
                    -(1 << 40) - 1,
                    1 << 62,
                    (1 << 62) + 1,
                    -(1 << 62) - 1,
                    1 << 28,
                    -(1 << 28) - 1,
                ]),
                1 | 2 => center.wrapping_add((self.next() >> 40) as i64 - (1 << 23)),
                3 => self.next() as i64,
                _ => center.wrapping_add(self.below(2 * noise as u64 + 1) as i64 - noise),
            }
        }
    }

    fn gate_cfg(r: &mut Rng) -> GateConfig {
        GateConfig {
            kappa_q8: r.pick(&[1898, 1898, 1898, 0, 1, 256, u32::MAX]),
            floor_ns: r.pick(&[0, 1, 5, 50, 100, 10_000, u32::MAX]),
            min_samples: r.pick(&[8, 8, 0, 1, 3, 4, 15, 16, 17, 255]),
            confirm: r.pick(&[3, 3, 0, 1, 2, 5, 255]),
        }
    }

    fn servo_cfg(r: &mut Rng) -> ServoConfig {
        let pole = |m: u32| PiGains::double_pole(Pole::from_micro(m).unwrap()).unwrap();
        let y = r.pick(&[1i64, 10, 100, 1000, 1 << 28]);
        let i = r.pick(&[1i64, y / 2 + 1, y]).min(y);
        let lock_low = r.pick(&[0u64, 10, 50, 200, 1000]);
        ServoConfig {
            interval_ns: r.pick(&[1u32, 2, 1000, 1_000_000, 4_000_000, u32::MAX]),
            acquire: pole(r.pick(&[500_000, 900_000, 990_000])),
            track: pole(r.pick(&[500_000, 900_000, 990_000, 999_000])),
            limits: PiLimits::from_ns(y, i).unwrap(),
            first_step_ns: r.pick(&[0, 0, 1, 1000, 10_000, u64::MAX]),
            step_ns: r.pick(&[0, 0, 1, 5000, 50_000, 1 << 40, u64::MAX]),
            step_confirm: r.pick(&[1, 2, 3, 255]),
            blank: r.pick(&[0, 1, 2, 255]),
            gear_ns: r.pick(&[0, 20, 50, 1000, u64::MAX]),
            gear_count: r.pick(&[1, 2, 4, 32, u16::MAX]),
            acquire_max: r.pick(&[0, 1, 10, 50]),
            gate: gate_cfg(r),
            lock: LockConfig {
                low_ns: lock_low,
                high_ns: lock_low.saturating_mul(r.pick(&[1, 2, 4])),
                count: r.pick(&[1, 4, 32, u16::MAX]),
            },
            holdover_max: r.pick(&[0, 1, 3, 100, u32::MAX]),
            fault_after: r.pick(&[0, 1, 5, 1000]),
        }
    }

    /// One servo input for interval `h0`: usually a sample one interval on, sometimes a missing
    /// one, a bad interval, a time jump or a wrap.
    fn servo_input(r: &mut Rng, t: &mut u64, h0: u64, center: i64, noise: i64) -> Input {
        let dt = match r.below(50) {
            0 => return Input::Missing,
            1 => 0,
            2 => h0 / 2,
            3 => (h0 / 2).wrapping_sub(1),
            4 => h0.wrapping_mul(4),
            5 => h0.wrapping_mul(4).wrapping_add(1),
            6 => r.next(),
            7 => u64::MAX - r.below(3),
            8 => h0.wrapping_add(r.below(h0.max(1))) / 2,
            _ => h0.wrapping_add(r.below(h0 / 8 + 1)).wrapping_sub(h0 / 16),
        };
        *t = t.wrapping_add(dt);
        Input::Sample {
            local_ns: *t,
            theta_ns: r.theta(center, noise),
        }
    }

    #[test]
    fn gate_equals_oracle() {
        let mut r = Rng(0x0123_4567_89AB_CDEF);
        let mut full_judged = 0u64;
        let mut by_mad = 0u64;
        for seq in 0..3000u64 {
            let mut new = Gate::new();
            let mut old = super::gate::Gate::new();
            let cfgs = [
                gate_cfg(&mut r),
                gate_cfg(&mut r),
                GateConfig::with_floor(100),
            ];
            let noise = r.pick(&[0i64, 1, 3, 100, 10_000, 1 << 45]);
            let mut center = r.theta(0, 1000);
            let drift = r.pick(&[0i64, 0, 1, -1, 37, -1000]);
            for _ in 0..200 {
                center = center.wrapping_add(drift);
                let theta = r.theta(center, noise);
                let cfg = &cfgs[(seq as usize + r.below(8) as usize / 7) % 3];
                assert_eq!(new.threshold(cfg), old.threshold(cfg));
                if new.len() == GATE_WINDOW {
                    full_judged += 1;
                }
                let verdict = new.judge(cfg, theta);
                assert_eq!(verdict, old.judge(cfg, theta));
                // Accepted by the MAD term although outside the floor (judge's slow path).
                if let Some((med, thr)) = old.threshold(cfg) {
                    let dist = theta.clamp(-(1 << 40), 1 << 40).wrapping_sub(med).abs();
                    if dist > i64::from(cfg.floor_ns) && dist <= thr {
                        by_mad += 1;
                    }
                }
                match r.below(100) {
                    0 => {
                        new.clear();
                        old.clear();
                    }
                    1..=9 => {}
                    _ => {
                        new.push(theta);
                        old.push(theta);
                    }
                }
                assert_eq!(format!("{new:?}"), format!("{old:?}"));
                assert_eq!(new.len(), old.len());
            }
        }
        assert!(full_judged > 300_000, "{full_judged}");
        assert!(by_mad > 10_000, "{by_mad}");
    }

    #[test]
    fn servo_equals_oracle() {
        let mut r = Rng(0xDEAD_BEEF_CAFE_F00D);
        let mut steps = 0u64;
        let mut seen = [[0u64; 7]; 4];
        for _ in 0..600 {
            let cfg = servo_cfg(&mut r);
            let (Ok(mut new), Ok(mut old)) = (Servo::new(cfg), super::engine::Servo::new(cfg))
            else {
                panic!("config refused");
            };
            if r.chance(3) {
                let i = r.next() as i64 >> r.below(64);
                new = new.with_integrator(i);
                old = old.with_integrator(i);
            }
            let h0 = u64::from(cfg.interval_ns);
            let mut t = r.next();
            let noise = r.pick(&[0i64, 2, 20, 200, 5000]);
            let mut center = r.pick(&[0i64, 0, 30, -3000, 20_000, 1 << 30]);
            let drift = r.pick(&[0i64, 0, 1, -2, 100]);
            for _ in 0..400 {
                center = center.wrapping_add(drift);
                if r.chance(150) {
                    center = r.theta(0, 100_000);
                }
                if r.chance(500) {
                    new.reset();
                    old.reset();
                }
                let input = servo_input(&mut r, &mut t, h0, center, noise);
                let mode = new.mode();
                let (a, b) = (new.update(input), old.update(input));
                assert_eq!(a, b, "{input:?}");
                assert_eq!(format!("{new:?}"), format!("{old:?}"));
                seen[mode as usize][a.verdict as usize] += 1;
                steps += 1;
            }
        }
        assert!(steps >= 200_000);
        // Every verdict occurred in Tracking (where the gate is armed) at least a few times.
        let tracking = seen[Mode::Tracking as usize];
        for v in [
            Verdict::Accepted,
            Verdict::Rejected,
            Verdict::Missing,
            Verdict::BadInterval,
            Verdict::StepPending,
            Verdict::Stepped,
        ] {
            assert!(tracking[v as usize] > 10, "{v:?}: {seen:?}");
        }
    }

    #[test]
    fn master_equals_oracle() {
        let mut r = Rng(0x5151_7777_0000_1234);
        let mut steps = 0u64;
        let mut locked_tracking = 0u64;
        let mut wide = 0u64;
        for _ in 0..400 {
            let period = r.pick(&[1000u32, 1_000_000, 250_000, 1 << 29, 1_000_001]);
            let mut cfg = MasterConfig::for_period(period).unwrap();
            cfg.ref_32bit = r.chance(3);
            let p = i64::from(period);
            cfg.target_ns = r.pick(&[0, 0, -250, p, -p, p / 3]);
            if r.chance(3) {
                cfg.servo.gate = gate_cfg(&mut r);
            }
            if r.chance(4) {
                cfg.servo.gear_count = r.pick(&[1, 4]);
                cfg.servo.lock.count = r.pick(&[1, 4]);
            }
            if r.chance(4) {
                cfg.servo.step_ns = r.pick(&[1, 1000, p as u64 / 4]);
                cfg.servo.first_step_ns = r.pick(&[0, 1, 1000]);
            }
            let (Ok(mut new), Ok(mut old)) =
                (MasterServo::new(cfg), super::master::MasterServo::new(cfg))
            else {
                panic!("config refused");
            };
            let noise = r.pick(&[0i64, 3, p / 1000, p / 20, p]);
            let drift = r.pick(&[0i64, 0, 1, -7, p / 2000]);
            // (app − ref) actual, closed loop through the deadline correction.
            let mut offset = r.pick(&[0i64, 100, -p / 3, 5 * p, -7 * p + 13, i64::MAX - 3]);
            let mut app = r.next() >> r.below(2);
            let mut local = r.next();
            for _ in 0..500 {
                let input = if r.chance(40) {
                    MasterInput::Lost
                } else {
                    let jitter = r.below(2 * noise as u64 + 1) as i64 - noise;
                    let reference = app.wrapping_sub(offset.wrapping_add(jitter) as u64);
                    let reference = match r.below(100) {
                        0 => r.next(),
                        // (app − ref) within a few periods of ±2^63: the wide path.
                        1 | 2 => app.wrapping_sub(
                            (1u64 << 63)
                                .wrapping_add(r.below(8 * period as u64))
                                .wrapping_sub(4 * period as u64),
                        ),
                        _ => reference,
                    };
                    MasterInput::Sample {
                        local_ns: if r.chance(100) { r.next() } else { local },
                        app_ns: app,
                        ref_ns: if cfg.ref_32bit {
                            reference & 0xFFFF_FFFF
                        } else {
                            reference
                        },
                    }
                };
                if r.chance(700) {
                    new.reset();
                    old.reset();
                }
                if let MasterInput::Sample { app_ns, ref_ns, .. } = input {
                    // (app − ref) near ±2^63: the measurement takes the wide (i128) path.
                    let d = app_ns.wrapping_sub(ref_ns) as i64;
                    if !cfg.ref_32bit && d.unsigned_abs() > (1u64 << 63) - (1 << 30) {
                        wide += 1;
                    }
                }
                let (a, b) = (new.update(input), old.update(input));
                assert_eq!(a, b, "{input:?}");
                assert_eq!(format!("{new:?}"), format!("{old:?}"));
                if a.engine.locked && a.engine.mode == Mode::Tracking {
                    locked_tracking += 1;
                }
                steps += 1;
                app = app
                    .wrapping_add(u64::from(period))
                    .wrapping_add(a.app_time_step_ns as u64);
                offset = offset
                    .wrapping_add(drift)
                    .wrapping_add(a.app_time_step_ns)
                    .wrapping_sub(a.deadline_correction_ns);
                local = local
                    .wrapping_add(u64::from(period))
                    .wrapping_add(a.deadline_correction_ns as u64);
            }
        }
        assert!(steps >= 200_000);
        assert!(locked_tracking > 20_000, "{locked_tracking}");
        assert!(wide > 1000, "{wide}");
    }
}
