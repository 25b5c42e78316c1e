//! One ESC's local clock, evaluated in closed form between events.
//!
//! Why closed form: the ESC counter ticks at 100 MHz; stepping it tick by tick would cost 10^8
//! steps per simulated second per slave. Instead the raw counter is a piecewise-linear function
//! of true time (constant rate between *anchors*), and the loop correction is linear in the raw
//! counter (constant between loop samples). Values are quantised only where they are observed
//! (a latch, a register read, a SYNC edge). REQ-ESC-040..REQ-ESC-044.
//!
//! Fixed point: raw counter, correction and rates carry [`FRAC`] fractional bits in `i128`, so
//! no error accumulates however long the run is.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Fractional bits of the fixed-point raw counter, correction and rates.
pub(crate) const FRAC: u32 = 40;
const ONE: i128 = 1 << FRAC;
/// Longest stretch of true time covered by one linear piece; keeps every product inside `i128`.
const MAX_PIECE_NS: u64 = 1 << 36;
/// Distances (ns) beyond this are reported as "not before the next piece" to keep the
/// inversion inside `i128`; the caller re-asks after the next anchor.
const MAX_SOLVE_NS: u128 = 1 << 50;

/// Slow random frequency wander (thermal drift of the crystal). Model constants without a
/// source: see docs/emulator.md §Constants.
#[derive(Debug, Clone)]
pub struct Wander {
    /// Length of one constant-frequency piece, true ns. 0 disables wander.
    pub interval_ns: u64,
    /// Standard deviation of the random step per piece, ppb.
    pub step_ppb: f64,
    /// Mean-reversion time constant in pieces (Ornstein-Uhlenbeck); keeps the wander bounded.
    pub revert_pieces: f64,
}

/// The oscillator and loop-correction state of one ESC.
#[derive(Debug, Clone)]
pub struct Oscillator {
    /// True time of the current anchor.
    anchor: u64,
    /// Raw counter (ns × 2^FRAC) at the anchor, since power-on.
    raw: i128,
    /// Accumulated loop correction (ns × 2^FRAC) at the anchor.
    corr: i128,
    /// Raw counter ns per true ns (× 2^FRAC), from the base ppm, steps and wander.
    rate: i128,
    /// Correction ns per raw ns (× 2^FRAC), set by the control loop.
    dev: i128,
    /// Observation quantum (10 ns on real ESCs).
    tick: u64,
    /// True time at which the current linear piece ends.
    piece_end: u64,
    /// `rate · dev`: steps `draw · dev` back by one true ns.
    rate_dev: i128,
    /// `rate` and `rate · (1 + dev)` as f64, for estimates only.
    rate_f: f64,
    speed_f: f64,
    base_ppb: f64,
    wander_ppb: f64,
    wander: Wander,
    rng: ChaCha8Rng,
}

/// Raw rate (× 2^FRAC) for a frequency error in ppb.
fn rate_from_ppb(ppb: f64) -> i128 {
    ONE + ((ppb * (ONE as f64)) / 1e9).round() as i128
}

impl Oscillator {
    /// A clock whose raw counter reads `initial_raw_ns` at true time `now`.
    pub fn new(
        now: u64,
        initial_raw_ns: u64,
        base_ppb: f64,
        tick: u64,
        wander: Wander,
        rng: ChaCha8Rng,
    ) -> Self {
        let mut o = Oscillator {
            anchor: now,
            raw: i128::from(initial_raw_ns) << FRAC,
            corr: 0,
            rate: rate_from_ppb(base_ppb),
            dev: 0,
            tick: tick.max(1),
            piece_end: now,
            rate_dev: 0,
            rate_f: 0.0,
            speed_f: 0.0,
            base_ppb,
            wander_ppb: 0.0,
            wander,
            rng,
        };
        o.piece_end = o.next_piece_end(now);
        o.refresh_f();
        o
    }

    fn refresh_f(&mut self) {
        self.rate_dev = self.rate * self.dev;
        let one = ONE as f64;
        // rate and dev are below 2^63 in fixed point: convert through i64 (cheap).
        self.rate_f = self.rate as i64 as f64 / one;
        self.speed_f = self.rate_f * (1.0 + self.dev as i64 as f64 / one);
    }

    /// Upper bound of local ns covered in `dt` true ns (for cheap "not yet" checks).
    #[inline]
    pub fn max_advance(&self, dt: u64) -> u64 {
        let local = (dt as f64 * self.speed_f.max(0.0) * (1.0 + 1e-9)) as u64;
        local.saturating_add(2 * self.tick + 2)
    }

    fn next_piece_end(&self, from: u64) -> u64 {
        let len = if self.wander.interval_ns == 0 {
            MAX_PIECE_NS
        } else {
            self.wander.interval_ns.min(MAX_PIECE_NS)
        };
        from.saturating_add(len)
    }

    /// True time of the anchor (the last instant the state was evaluated at).
    #[inline]
    pub fn anchor(&self) -> u64 {
        self.anchor
    }

    /// End of the current linear piece (a wander step happens there).
    #[inline]
    pub fn piece_end(&self) -> u64 {
        self.piece_end
    }

    /// Moves the anchor forward to `t`, crossing wander pieces. `t` before the anchor is a
    /// caller bug; it is ignored (the state stays at the anchor).
    #[inline]
    pub fn advance(&mut self, t: u64) {
        while self.piece_end <= t {
            let end = self.piece_end;
            self.move_anchor(end);
            self.step_wander();
            self.piece_end = self.next_piece_end(end);
        }
        self.move_anchor(t);
    }

    #[inline]
    fn move_anchor(&mut self, t: u64) {
        if t <= self.anchor {
            return;
        }
        let dt = i128::from(t - self.anchor);
        let draw = dt * self.rate;
        self.raw += draw;
        self.corr += (draw * self.dev) >> FRAC;
        self.anchor = t;
    }

    fn step_wander(&mut self) {
        if self.wander.interval_ns == 0 || self.wander.step_ppb == 0.0 {
            return;
        }
        // Box-Muller from two uniforms: deterministic for a given seed.
        let u1: f64 = self.rng.gen::<f64>().max(f64::MIN_POSITIVE);
        let u2: f64 = self.rng.gen::<f64>();
        let n = (-2.0 * u1.ln()).sqrt() * (core::f64::consts::TAU * u2).cos();
        let revert = if self.wander.revert_pieces > 0.0 {
            1.0 / self.wander.revert_pieces
        } else {
            0.0
        };
        self.wander_ppb = self.wander_ppb * (1.0 - revert) + n * self.wander.step_ppb;
        self.rate = rate_from_ppb(self.base_ppb + self.wander_ppb);
        self.refresh_f();
    }

    /// Sets the frequency error (ppb) from the anchor on; wander continues on top of it.
    pub fn set_base_ppb(&mut self, ppb: f64) {
        self.base_ppb = ppb;
        self.rate = rate_from_ppb(self.base_ppb + self.wander_ppb);
        self.refresh_f();
    }

    /// Current frequency error of the raw oscillator (base + wander), ppb.
    pub fn ppb(&self) -> f64 {
        self.base_ppb + self.wander_ppb
    }

    /// Sets the correction rate (× 2^FRAC, correction ns per raw ns) from the anchor on.
    pub fn set_dev(&mut self, dev: i128) {
        self.dev = dev;
        self.refresh_f();
    }

    /// Local time observed at the anchor: raw counter quantised to the tick, plus the integer
    /// part of the correction. Wraps modulo 2^64 like the 64-bit register.
    #[inline]
    pub fn local(&self) -> u64 {
        self.local_wide() as u64
    }

    /// Observed local time at the anchor without 64-bit wrap (raw counters start near 0 at
    /// power-up, so the raw part fits `i64` for 292 years).
    #[inline]
    pub(crate) fn local_wide(&self) -> i128 {
        self.quantise(self.raw, self.corr)
    }

    /// REQ-ESC-041: whole ticks of the raw counter (floor) plus the integer part of the loop
    /// correction.
    #[inline]
    fn quantise(&self, raw: i128, corr: i128) -> i128 {
        let raw_ns = (raw >> FRAC) as i64;
        // Constant divisors for the common ticks let the compiler avoid a division.
        let q = match self.tick {
            10 => raw_ns - raw_ns.rem_euclid(10),
            1 => raw_ns,
            t => raw_ns - raw_ns.rem_euclid(t as i64),
        };
        i128::from(q) + (corr >> FRAC)
    }

    /// Observed local time at true time `t` (≥ anchor, inside the current piece), without
    /// moving the anchor.
    #[inline]
    fn observed_at(&self, t: u64) -> i128 {
        self.eval_at(t).2
    }

    /// Raw counter, `draw · dev` (the correction's advance before the shift) and observed
    /// local time at true time `t` (≥ anchor, inside the piece).
    #[inline]
    fn eval_at(&self, t: u64) -> (i128, i128, i128) {
        let dt = i128::from(t.saturating_sub(self.anchor));
        let draw = dt * self.rate;
        let raw = self.raw + draw;
        let p = draw * self.dev;
        (raw, p, self.quantise(raw, self.corr + (p >> FRAC)))
    }

    /// Observed local time one ns before an instant after the anchor that evaluated to
    /// `(raw, p, _)`: exactly `observed_at(t − 1)`, since `draw(t − 1) = draw(t) − rate`.
    #[inline]
    fn observed_before(&self, raw: i128, p: i128) -> i128 {
        self.quantise(raw - self.rate, self.corr + ((p - self.rate_dev) >> FRAC))
    }

    /// True ns from the instant the raw counter reads `raw` until it reaches its next tick
    /// boundary (≥ 1).
    #[inline]
    fn ns_to_next_tick(&self, raw: i128) -> u64 {
        let raw_ns = (raw >> FRAC) as i64;
        let tick = self.tick as i64;
        // Constant divisor for the common tick (no hardware division; same result).
        let below = if tick == 10 {
            raw_ns.rem_euclid(10)
        } else {
            raw_ns.rem_euclid(tick)
        };
        let boundary = i128::from(raw_ns - below + tick) << FRAC;
        let ns = ((boundary - raw) >> 20) as i64 as f64 / (self.rate_f * f64::from(1u32 << 20));
        (ns as u64 + 1).max(1)
    }

    /// The start of the inversion for an advance by `d` from `local_now`: `Ok((t, target))`,
    /// a first instant within the piece (the rounded-up f64 estimate of the continuous
    /// crossing, or the piece's last ns) and the observed local time to reach; `Err(answer)`
    /// when the answer needs no search (`d` too large or 0, or no crossing in the piece).
    fn crossing_estimate(&self, d: u64, local_now: i128) -> Result<(u64, i128), Option<u64>> {
        if u128::from(d) > MAX_SOLVE_NS {
            return Err(None);
        }
        if d == 0 {
            return Err(Some(self.anchor));
        }
        let target = local_now + i128::from(d);
        // Part of the continuous value not yet shown (< tick + 1 ns): small, exact in f64.
        let hidden = (self.raw + self.corr - (local_now << FRAC)) as i64 as f64 / ONE as f64;
        let x = ((d as f64 - hidden) / self.speed_f).max(0.0);
        let xi = x as u64;
        let est = if (xi as f64) < x { xi + 1 } else { xi };
        let mut t = self.anchor.checked_add(est).ok_or(None)?;
        if t >= self.piece_end {
            // The estimate may be a hair late: check the last ns of the piece exactly.
            let last = self.piece_end.checked_sub(1).ok_or(None)?;
            if last < self.anchor || self.observed_at(last) < target {
                return Err(None);
            }
            t = last;
        }
        Ok((t, target))
    }

    /// True time (≥ anchor) at which the observed local time has advanced by `d` ns from its
    /// value at the anchor, if that happens before the end of the current piece: the first
    /// integer ns at which the quantised counter plus correction reaches the target.
    ///
    /// A floating-point estimate of the continuous crossing is refined with exact integer
    /// evaluations (`observed_at`), so the answer is exact and needs no 128-bit division.
    pub fn time_to_advance(&self, d: u64) -> Option<u64> {
        self.time_to_advance_from(d, self.local_wide())
    }

    /// [`Oscillator::time_to_advance`] given `local_now = self.local_wide()` (callers that
    /// have it already save a quantisation).
    pub(crate) fn time_to_advance_from(&self, d: u64, local_now: i128) -> Option<u64> {
        let (mut t, target) = match self.crossing_estimate(d, local_now) {
            Ok(x) => x,
            Err(answer) => return answer,
        };
        let (mut raw, mut p, obs) = self.eval_at(t);
        if obs >= target {
            // Normally `t − 1` lies before the continuous crossing; guard the f64 rounding.
            if t > self.anchor && self.observed_before(raw, p) >= target {
                t -= 1;
            }
            return Some(t);
        }
        // Last instant evaluated below the target.
        let mut below = t;
        let mut guard = 0u32;
        loop {
            t = t.checked_add(self.ns_to_next_tick(raw))?;
            if t >= self.piece_end {
                return None;
            }
            let obs;
            (raw, p, obs) = self.eval_at(t);
            if obs >= target {
                break;
            }
            below = t;
            guard += 1;
            if guard > 64 {
                return None;
            }
        }
        // The jump may land 1 ns after the boundary (rounding up); `t − 1 = below` is known
        // to be below the target.
        if t > self.anchor && t - 1 != below && self.observed_before(raw, p) >= target {
            t -= 1;
        }
        Some(t)
    }
}

/// Correction rate (× 2^FRAC, correction ns per raw ns) for speed counter start `s` and speed
/// counter diff `d`: one +1 ns step every (S − D + 2) ticks and one −1 ns step every
/// (S + D + 2) ticks of 10 ns (docs/background/esc-registers.md §4.1; ESC datasheet Section II Table 105 deviation formula). REQ-ESC-052.
pub fn correction_rate(s: u16, d: i16) -> i128 {
    let s = i128::from(s);
    let d = i128::from(d);
    let up = s - d + 2;
    let down = s + d + 2;
    if up <= 0 || down <= 0 {
        return 0;
    }
    // 64-bit division is plenty: 2^40 / (10 · up) with up ≥ 1.
    let tick = super::control_loop::NOMINAL_TICK_NS;
    let one = 1i64 << FRAC;
    i128::from(one / (tick * up as i64) - one / (tick * down as i64))
}

/// The same deviation as a plain fraction (for tests and docs).
pub fn correction_ppm(s: u16, d: i16) -> f64 {
    correction_rate(s, d) as f64 / ONE as f64 * 1e6
}

#[cfg(test)]
mod test {
    use super::*;
    use rand::SeedableRng;

    fn osc(ppb: f64, tick: u64) -> Oscillator {
        let w = Wander {
            interval_ns: 0,
            step_ppb: 0.0,
            revert_pieces: 0.0,
        };
        Oscillator::new(0, 0, ppb, tick, w, ChaCha8Rng::seed_from_u64(1))
    }

    #[test]
    fn drifts_at_configured_rate() {
        let mut o = osc(50_000.0, 10);
        o.advance(1_000_000_000);
        // 50 ppm fast: 1 s of true time reads 1.00005 s, quantised down to the 10 ns tick.
        let v = o.local();
        assert!((1_000_049_990..=1_000_050_000).contains(&v), "{v}");
        assert_eq!(v % 10, 0);
    }

    #[test]
    fn correction_formula_limits() {
        // 50 ppm needs D ≈ 2560 at S = 0x1000 (docs/background/esc-registers.md §4.2); max ≈ 763 ppm.
        assert!((correction_ppm(0x1000, 2560) - 50.0).abs() < 0.1);
        assert!((correction_ppm(0x1000, 3969) - 763.0).abs() < 1.0);
        assert_eq!(correction_rate(0x1000, 0), 0);
    }

    #[test]
    fn time_to_advance_hits_tick() {
        let mut o = osc(0.0, 10);
        o.advance(3);
        let t = o.time_to_advance(1000).unwrap();
        assert_eq!(t, 1000);
        let mut o2 = o.clone();
        o2.advance(t);
        assert_eq!(o2.local(), 1000);
        let mut o3 = o.clone();
        o3.advance(t - 1);
        assert!(o3.local() < 1000);
    }

    #[test]
    fn time_to_advance_with_drift_and_correction() {
        let mut o = osc(-30_000.0, 10);
        o.set_dev(correction_rate(0x1000, 1500));
        o.advance(123_457);
        let start = o.local();
        let t = o.time_to_advance(500_000).unwrap();
        let mut a = o.clone();
        a.advance(t);
        let mut b = o.clone();
        b.advance(t - 2);
        assert!(a.local() >= start + 500_000 - 1, "{} {}", a.local(), start);
        assert!(b.local() < start + 500_000, "{} {}", b.local(), start);
    }

    /// The inversion is exact: at the returned time the counter shows the target, one ns
    /// earlier it does not (random states, ticks 1 and 10, corrections of both signs).
    #[test]
    fn time_to_advance_exact_random() {
        let mut r = ChaCha8Rng::seed_from_u64(99);
        for i in 0..2000 {
            let tick = if i % 2 == 0 { 10 } else { 1 };
            let mut o = osc(r.gen_range(-200_000.0..200_000.0), tick);
            o.set_dev(correction_rate(0x1000, r.gen_range(-3969..=3969)));
            o.advance(r.gen_range(0..5_000_000_000));
            let d = r.gen_range(0..3_000_000);
            let start = o.local_wide();
            let Some(t) = o.time_to_advance(d) else {
                continue;
            };
            assert!(o.observed_at(t) >= start + i128::from(d), "case {i}");
            if t > o.anchor() {
                assert!(o.observed_at(t - 1) < start + i128::from(d), "case {i}");
            }
        }
    }

    /// The inversion's search as first written (three separate exact evaluations per step,
    /// from the same first estimate): the reference `time_to_advance` must match bit for bit.
    fn reference_time_to_advance(o: &Oscillator, d: u64) -> Option<u64> {
        let (mut t, target) = match o.crossing_estimate(d, o.local_wide()) {
            Ok(x) => x,
            Err(answer) => return answer,
        };
        if o.observed_at(t) >= target {
            if t > o.anchor && o.observed_at(t - 1) >= target {
                t -= 1;
            }
            return Some(t);
        }
        let next_tick = |t: u64| {
            let dt = i128::from(t.saturating_sub(o.anchor));
            let raw = o.raw + dt * o.rate;
            let raw_ns = (raw >> FRAC) as i64;
            let tick = o.tick as i64;
            let boundary = i128::from(raw_ns - raw_ns.rem_euclid(tick) + tick) << FRAC;
            let ns = ((boundary - raw) >> 20) as i64 as f64 / (o.rate_f * f64::from(1u32 << 20));
            (ns as u64 + 1).max(1)
        };
        let mut guard = 0u32;
        loop {
            t = t.checked_add(next_tick(t))?;
            if t >= o.piece_end {
                return None;
            }
            if o.observed_at(t) >= target {
                break;
            }
            guard += 1;
            if guard > 64 {
                return None;
            }
        }
        if t > o.anchor && o.observed_at(t - 1) >= target {
            t -= 1;
        }
        Some(t)
    }

    /// `time_to_advance` equals the reference on random states: ticks 1, 7 and 10, exact
    /// nominal rate (integer raw steps), wander pieces, corrections of both signs.
    #[test]
    fn time_to_advance_matches_reference() {
        let mut r = ChaCha8Rng::seed_from_u64(7);
        for i in 0..20_000 {
            let tick = [10, 1, 7, 10][i % 4];
            let ppb = if i % 5 == 0 {
                0.0
            } else {
                r.gen_range(-300_000.0..300_000.0)
            };
            let w = Wander {
                interval_ns: if i % 3 == 0 {
                    0
                } else {
                    r.gen_range(1..3_000_000)
                },
                step_ppb: 50.0,
                revert_pieces: 10.0,
            };
            let start = r.gen_range(0..1u64 << 40);
            let mut o =
                Oscillator::new(0, start, ppb, tick, w, ChaCha8Rng::seed_from_u64(i as u64));
            if i % 7 != 0 {
                o.set_dev(correction_rate(0x1000, r.gen_range(-3969..=3969)));
            }
            o.advance(r.gen_range(0..50_000_000));
            for _ in 0..4 {
                let d = match r.gen_range(0..4) {
                    0 => r.gen_range(0..40),
                    1 => r.gen_range(0..2_000_000),
                    2 => r.gen_range(0..1u64 << 36),
                    _ => r.gen_range(0..1u64 << 52),
                };
                assert_eq!(
                    o.time_to_advance(d),
                    reference_time_to_advance(&o, d),
                    "case {i}, d {d}"
                );
            }
        }
    }
}
