//! An IEEE 1588 slave-clock servo built from the seed 004 pieces and the generic engine
//! (REQ-SERVO-120..123): per exchange, offset and mean path delay (eq. 1–2), optionally the
//! two-pole offset filter (eq. 7–9), the engine (PI with the same clamps, steps, gate, lock,
//! holdover), and the command in the actuator's units: a frequency adjustment in ppb (PHC) and,
//! when configured, a per-interval counter correction with carried remainder (eq. 15–18).
//!
//! Signs: offset = slave − master (positive: slave ahead, REQ-CONV-007). `freq_ppb` is the
//! adjustment to apply to the slave's frequency (negative slows it), `step_ns` the amount to add
//! to the slave clock (−θ), as linuxptp applies `clockadj_set_freq(−adj)` and `step(−offset)`.

use super::counter::CounterCompensator;
use super::engine::{ConfigError, Input, Output, Servo, ServoConfig};
use super::filter::OffsetFilter;
use super::gains::FRAC_BITS;
use super::ieee1588::{offset_and_delay, Exchange};
use super::pi::{PiLimits, LIMIT_MAX_NS};

/// PTP servo configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PtpConfig {
    /// Engine configuration (interval = sync interval; its `limits` are replaced by `max_ppb`).
    pub servo: ServoConfig,
    /// Actuator limit, ppb (> 0); y_max = I_max = max_ppb · h₀ / 10^9 ns per interval.
    pub max_ppb: u32,
    /// Run the seed 004 two-pole filter on the offset before the servo. It adds two poles of lag
    /// inside the loop: [DERIVED] with fast PI poles (1/2 and 1/3, the filter's own pole values
    /// reused as loop poles — the seed gives no loop gains) the loop rings (error ÷10 per ~200
    /// samples); with slower PI poles (double pole 0.7 / 0.9) it stays well damped but the PI
    /// already averages, so `false` is the recommended setting.
    pub offset_filter: bool,
    /// Counter actuator (crystal Hz, PLL multiplier) for seed eq. 15–18 output, if any.
    pub counter: Option<(u64, u32)>,
}

/// Output per exchange.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PtpOutput {
    /// Frequency adjustment to apply, ppb, |·| ≤ max_ppb.
    pub freq_ppb: i64,
    /// Counter correction for this interval, fine counts (when a counter is configured).
    pub counter_counts: Option<i64>,
    /// Add this to the slave clock, ns (0 = no step).
    pub step_ns: i64,
    /// Offset from master used (after the optional filter), ns; 0 when the exchange was bad.
    pub offset_ns: i64,
    /// Mean path delay, ns (0 when the exchange was bad).
    pub delay_ns: i64,
    /// Engine decision.
    pub engine: Output,
}

/// IEEE 1588 slave-clock servo.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PtpServo {
    servo: Servo,
    interval_ns: u32,
    filter: Option<OffsetFilter>,
    counter: Option<CounterCompensator>,
}

impl PtpServo {
    /// Validate and build. Refuses max_ppb whose per-interval limit is below 1 ns or above
    /// 2^28 ns.
    pub fn new(mut cfg: PtpConfig) -> Result<Self, ConfigError> {
        let h0 = u128::from(cfg.servo.interval_ns);
        // max_ppb·h₀ < 2^64, ·2^32 < 2^96: no overflow in u128.
        let y_q = u128::from(cfg.max_ppb).wrapping_mul(h0) << FRAC_BITS;
        let y_q = y_q.wrapping_div(1_000_000_000);
        let y_lim = u128::from(LIMIT_MAX_NS.unsigned_abs()) << FRAC_BITS;
        if y_q < 1 << FRAC_BITS || y_q > y_lim {
            return Err(ConfigError::Parameter);
        }
        let y = i64::try_from(y_q).map_err(|_| ConfigError::Parameter)?;
        cfg.servo.limits = PiLimits::from_q32(y, y).map_err(ConfigError::Limits)?;
        let counter = match cfg.counter {
            None => None,
            Some((hz, npll)) => {
                Some(CounterCompensator::new(hz, npll).map_err(|_| ConfigError::Parameter)?)
            }
        };
        Ok(PtpServo {
            servo: Servo::new(cfg.servo)?,
            interval_ns: cfg.servo.interval_ns,
            filter: cfg.offset_filter.then(OffsetFilter::new),
            counter,
        })
    }

    /// The engine (mode, lock, counters).
    pub const fn engine(&self) -> &Servo {
        &self.servo
    }

    /// Start over (e.g. after a grandmaster change), keeping the learned frequency.
    pub fn reset(&mut self) {
        self.servo.reset();
        if let Some(f) = self.filter.as_mut() {
            f.reset();
        }
    }

    /// REQ-SERVO-120: one exchange (t1..t4) taken at local time `local_ns`; `None` = lost.
    /// A refused exchange (negative delay, overflow) is treated as lost: holdover.
    pub fn sample(&mut self, local_ns: u64, exchange: Option<&Exchange>) -> PtpOutput {
        let measured = exchange.and_then(|e| offset_and_delay(e).ok());
        let (input, offset, delay) = match measured {
            None => (Input::Missing, 0, 0),
            Some((o, d)) => {
                let o = match self.filter.as_mut() {
                    Some(f) => f.update(o),
                    None => o,
                };
                (
                    Input::Sample {
                        local_ns,
                        theta_ns: o,
                    },
                    o,
                    d,
                )
            }
        };
        let out = self.servo.update(input);
        if out.step_ns != 0 {
            if let Some(f) = self.filter.as_mut() {
                f.reset();
            }
        }
        let counter_counts = self
            .counter
            .as_mut()
            .map(|c| c.per_period_q32(out.command_q32));
        PtpOutput {
            freq_ppb: self.ppb_of(out.command_q32),
            counter_counts,
            step_ns: out.step_ns.saturating_neg(),
            offset_ns: offset,
            delay_ns: delay,
            engine: out,
        }
    }

    /// −command·10^9/(h₀·2^32), rounded to nearest: |command| ≤ y_max = ⌊max_ppb·h₀·2^32/10^9⌋
    /// gives |ppb| ≤ max_ppb.
    fn ppb_of(&self, command_q32: i64) -> i64 {
        let num = i128::from(command_q32).wrapping_mul(1_000_000_000);
        let den = i128::from(self.interval_ns) << FRAC_BITS;
        let half = den >> 1;
        let q = if num >= 0 {
            num.wrapping_add(half).checked_div(den).unwrap_or(0)
        } else {
            num.wrapping_sub(half).checked_div(den).unwrap_or(0)
        };
        i64::try_from(q).unwrap_or(0).saturating_neg()
    }
}

#[cfg(test)]
mod tests {
    use super::super::gains::{PiGains, Pole};
    use super::super::gate::GateConfig;
    use super::super::lock::LockConfig;
    use super::*;

    fn cfg() -> PtpConfig {
        let g = PiGains::double_pole(Pole::from_micro(700_000).unwrap()).unwrap();
        PtpConfig {
            servo: ServoConfig {
                interval_ns: 125_000_000,
                acquire: g,
                track: PiGains::double_pole(Pole::from_micro(900_000).unwrap()).unwrap(),
                limits: PiLimits::from_ns(1, 1).unwrap(),
                first_step_ns: 20_000,
                step_ns: 0,
                step_confirm: 3,
                blank: 1,
                gear_ns: 100,
                gear_count: 8,
                acquire_max: 0,
                gate: GateConfig::with_floor(50),
                lock: LockConfig {
                    low_ns: 50,
                    high_ns: 200,
                    count: 8,
                },
                holdover_max: 16,
                fault_after: 0,
            },
            max_ppb: 500_000,
            offset_filter: false,
            counter: Some((25_000_000, 4)),
        }
    }

    /// Runs `n` exchanges against a slave `drift_ppb` fast starting `init` ns ahead; returns
    /// (final offset, final freq, last output).
    fn run(
        mut s: PtpServo,
        drift_ppb: i64,
        init: i64,
        n: usize,
    ) -> (i64, i64, PtpOutput, PtpServo) {
        let h = 125_000_000i64;
        let mut slave_offset = init;
        let mut frac = 0i64; // sub-ns remainder of the simulated clock, ns·10^9
        let mut freq = 0i64;
        let delay = 800i64;
        let mut t = 1u64 << 42;
        let mut last = None;
        for _ in 0..n {
            let e = Exchange {
                t1: t,
                t2: (t as i64 + delay + slave_offset) as u64,
                t3: (t as i64 + 10_000 + slave_offset) as u64,
                t4: t + 10_000 + delay as u64,
            };
            let o = s.sample(t, Some(&e));
            slave_offset += o.step_ns;
            freq = o.freq_ppb;
            last = Some(o);
            frac += (drift_ppb + freq) * h;
            slave_offset += frac.div_euclid(1_000_000_000);
            frac = frac.rem_euclid(1_000_000_000);
            t += h as u64;
        }
        (slave_offset, freq, last.unwrap(), s)
    }

    #[test]
    fn disciplines_a_drifting_slave() {
        let (off, freq, last, s) = run(PtpServo::new(cfg()).unwrap(), 37_000, 1_000_000, 400);
        assert!(s.engine().is_locked());
        assert!(off.abs() < 10, "{off}");
        assert!((freq + 37_000).abs() <= 1, "{freq}");
        assert_eq!(last.delay_ns, 800);
        assert!(last.counter_counts.is_some());
        assert!(PtpServo::new(PtpConfig {
            max_ppb: 1,
            ..cfg()
        })
        .is_err());
    }

    #[test]
    fn offset_filter_inside_the_loop() {
        // The seed's filter on the offset (eq. 7–9). The seed gives no loop gains; its filter
        // poles 1/2 and 1/3 reused as PI poles make a fast loop. [DERIVED] The filter's lag then
        // leaves a lightly damped pole pair (error ÷10 per ~200 samples), so this needs far more
        // exchanges than the unfiltered loop above.
        let fast =
            PiGains::from_poles(Pole::from_q32(1 << 31), Pole::from_q32(0x5555_5555)).unwrap();
        let mut c = cfg();
        c.servo.acquire = fast;
        c.servo.track = fast;
        c.offset_filter = true;
        // The lightly damped loop plus the filter's 1 ns output quantisation settles into a
        // small limit cycle (measured: about ±10 ns, ±60 ppb) instead of converging exactly.
        let (off, freq, _, s) = run(PtpServo::new(c).unwrap(), -80_000, -3_000, 3000);
        assert!(s.engine().is_locked());
        assert!(off.abs() <= 20, "{off}");
        assert!((freq - 80_000).abs() <= 100, "{freq}");
        // With the default-style slower gains the filtered loop is well damped.
        let mut c = cfg();
        c.offset_filter = true;
        let (off, _, _, s) = run(PtpServo::new(c).unwrap(), -80_000, -3_000, 400);
        assert!(s.engine().is_locked() && off.abs() < 10, "{off}");
    }
}
