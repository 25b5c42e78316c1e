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
            base_ppb,
            wander_ppb: 0.0,
            wander,
            rng,
        };
        o.piece_end = o.next_piece_end(now);
        o
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
    pub fn anchor(&self) -> u64 {
        self.anchor
    }

    /// End of the current linear piece (a wander step happens there).
    pub fn piece_end(&self) -> u64 {
        self.piece_end
    }

    /// Moves the anchor forward to `t`, crossing wander pieces. `t` before the anchor is a
    /// caller bug; it is ignored (the state stays at the anchor).
    pub fn advance(&mut self, t: u64) {
        while self.piece_end <= t {
            let end = self.piece_end;
            self.move_anchor(end);
            self.step_wander();
            self.piece_end = self.next_piece_end(end);
        }
        self.move_anchor(t);
    }

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
    }

    /// Sets the frequency error (ppb) from the anchor on; wander continues on top of it.
    pub fn set_base_ppb(&mut self, ppb: f64) {
        self.base_ppb = ppb;
        self.rate = rate_from_ppb(self.base_ppb + self.wander_ppb);
    }

    /// Current frequency error of the raw oscillator (base + wander), ppb.
    pub fn ppb(&self) -> f64 {
        self.base_ppb + self.wander_ppb
    }

    /// Sets the correction rate (× 2^FRAC, correction ns per raw ns) from the anchor on.
    pub fn set_dev(&mut self, dev: i128) {
        self.dev = dev;
    }

    /// Local time observed at the anchor: raw counter quantised to the tick, plus the integer
    /// part of the correction. Wraps modulo 2^64 like the 64-bit register.
    pub fn local(&self) -> u64 {
        let raw_ns = self.raw >> FRAC;
        let t = i128::from(self.tick);
        let q = raw_ns - raw_ns.rem_euclid(t);
        (q + (self.corr >> FRAC)) as u64
    }

    /// True time (≥ anchor) at which the observed local time has advanced by `d` ns from its
    /// value at the anchor, if that happens before the end of the current piece. The result is
    /// the first tick boundary at which the counter has covered the distance (±1 ns from the
    /// integer rounding of the correction).
    pub fn time_to_advance(&self, d: u64) -> Option<u64> {
        if u128::from(d) > MAX_SOLVE_NS {
            return None;
        }
        let local_now = i128::from(self.local_wide());
        // Continuous value minus observed value: the part already "accrued" but not shown.
        let accrued = self.raw + self.corr - (local_now << FRAC);
        let need = (i128::from(d) << FRAC) - accrued;
        if need <= 0 {
            return Some(self.anchor);
        }
        // draw = need / (1 + dev), written as need - need*dev/(1+dev) to stay inside i128.
        let draw = need - need * self.dev / (ONE + self.dev);
        let tick_fp = i128::from(self.tick) << FRAC;
        let target = self.raw + draw;
        let boundary = (target + tick_fp - 1).div_euclid(tick_fp) * tick_fp;
        let draw = boundary - self.raw;
        let dt = (draw + self.rate - 1).div_euclid(self.rate).max(0);
        let t = i128::from(self.anchor) + dt;
        if t >= i128::from(self.piece_end) || t > i128::from(u64::MAX) {
            return None;
        }
        Some(t as u64)
    }

    /// Observed local time at the anchor without 64-bit wrap (raw counters start near 0, so
    /// this never exceeds `i128`).
    fn local_wide(&self) -> i128 {
        let raw_ns = self.raw >> FRAC;
        let t = i128::from(self.tick);
        raw_ns - raw_ns.rem_euclid(t) + (self.corr >> FRAC)
    }
}

/// Correction rate (× 2^FRAC, correction ns per raw ns) for speed counter start `s` and speed
/// counter diff `d`: one +1 ns step every (S − D + 2) ticks and one −1 ns step every
/// (S + D + 2) ticks of 10 ns (esc-dc.md §4.1, DS S2-76 Tab.105 deviation formula). REQ-ESC-052.
pub fn correction_rate(s: u16, d: i16) -> i128 {
    let s = i128::from(s);
    let d = i128::from(d);
    let up = s - d + 2;
    let down = s + d + 2;
    if up <= 0 || down <= 0 {
        return 0;
    }
    let tick = i128::from(super::control_loop::NOMINAL_TICK_NS);
    ONE / (tick * up) - ONE / (tick * down)
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
        // 50 ppm needs D ≈ 2560 at S = 0x1000 (esc-dc.md §4.2); max ≈ 763 ppm.
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
}
