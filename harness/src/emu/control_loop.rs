//! The ESC's hardware time-control loop (drift compensation), as a *rate* correction with
//! memory.
//!
//! What is documented (docs/background/esc-registers.md §4.1): every ECAT write covering 0x0910 on a slave gives a
//! sample Δt = (local copy at SOF − 0x0928) − received, on the lower 32 bits; 0x092C is the mean
//! of Δt over 0x0934 samples in sign-magnitude; 0x0932 is a filtered period-deviation estimate
//! (depth 0x0935) in ±(S − 0x7F); the clock runs `correction_rate(S, D)` faster or slower.
//!
//! What is *not* documented is the update law from Δt to D. The law here is this emulator's
//! choice (docs/emulator.md §Constants): a PI controller on the filtered Δt, with the integral
//! part as the rate memory, anti-windup at the ±(S − 0x7F) limit, and the applied D being the
//! mean of the last 0x0935 commands. REQ-ESC-050..REQ-ESC-056.

/// The counter tick the speed-counter formula is defined on (100 MHz).
pub const NOMINAL_TICK_NS: i64 = 10;
/// Reset value of 0x0930 (DS S2-76 Tab.104).
pub const SPEED_COUNTER_START_RESET: u16 = 0x1000;
/// Smallest valid 0x0930 value (DS S2-76).
pub const SPEED_COUNTER_START_MIN: u16 = 0x0080;
/// Largest valid 0x0930 value (DS S2-76).
pub const SPEED_COUNTER_START_MAX: u16 = 0x3FFF;
/// Reset value of 0x0934 (KickCAT, "from the datasheet"; unverified).
pub const DIFF_FILTER_DEPTH_RESET: u8 = 4;
/// Reset value of 0x0935 (KickCAT; unverified).
pub const SPEED_FILTER_DEPTH_RESET: u8 = 0x0C;
/// Fractional bits of the gains and the integrator.
const GAIN_FRAC: u32 = 16;

/// Gains of the (undocumented) update law. Model constants without a source.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LoopGains {
    /// Proportional gain: D LSB per ns of filtered Δt.
    pub kp: f64,
    /// Integral gain: D LSB per ns of filtered Δt, per sample.
    pub ki: f64,
    /// Power-on value of 0x0934 (system time difference filter depth). Default
    /// [`DIFF_FILTER_DEPTH_RESET`]; a model input because that reset value is unverified
    /// (`ecdc bench sensitivity` varies it).
    pub diff_filter_reset: u8,
    /// Power-on value of 0x0935 (speed counter filter depth). Default
    /// [`SPEED_FILTER_DEPTH_RESET`], unverified like 0x0934's.
    pub speed_filter_reset: u8,
}

impl Default for LoopGains {
    fn default() -> Self {
        // Chosen so that at S = 0x1000 and one sample per ms the phase settles in ≈ 100
        // samples with ≈ 0.7 damping, and 15 000 back-to-back samples still converge.
        LoopGains {
            kp: 1.5,
            ki: 0.008,
            diff_filter_reset: DIFF_FILTER_DEPTH_RESET,
            speed_filter_reset: SPEED_FILTER_DEPTH_RESET,
        }
    }
}

/// A fixed-capacity moving mean (depth 1..=255).
#[derive(Debug, Clone)]
struct MeanFilter {
    buf: Vec<i64>,
    len: usize,
    pos: usize,
    depth: usize,
    sum: i64,
}

impl MeanFilter {
    fn new(depth: u8) -> Self {
        MeanFilter {
            buf: vec![0; usize::from(depth.max(1))],
            len: 0,
            pos: 0,
            depth: usize::from(depth.max(1)),
            sum: 0,
        }
    }

    #[inline(always)]
    fn push(&mut self, v: i64) -> i64 {
        if self.len == self.depth {
            self.sum -= self.buf[self.pos];
        } else {
            self.len += 1;
        }
        self.buf[self.pos] = v;
        self.sum += v;
        self.pos += 1;
        if self.pos == self.depth {
            self.pos = 0;
        }
        // Round half away from zero so a symmetric input gives a symmetric mean.
        let n = self.len as i64;
        let x = if self.sum >= 0 {
            self.sum + n / 2
        } else {
            self.sum - n / 2
        };
        div_small(x, n)
    }
}

/// `x / n` (truncating, like `/`), with the usual filter depths as constant divisors so the
/// compiler replaces the slow hardware division by multiply-and-shift (same result).
fn div_small(x: i64, n: i64) -> i64 {
    match n {
        1 => x,
        2 => x / 2,
        3 => x / 3,
        4 => x / 4,
        5 => x / 5,
        6 => x / 6,
        7 => x / 7,
        8 => x / 8,
        9 => x / 9,
        10 => x / 10,
        11 => x / 11,
        12 => x / 12,
        13 => x / 13,
        14 => x / 14,
        15 => x / 15,
        16 => x / 16,
        _ => x / n,
    }
}

/// Loop state of one ESC.
#[derive(Debug, Clone)]
pub struct ControlLoop {
    s: u16,
    kp: i64,
    ki: i64,
    diff: MeanFilter,
    speed: MeanFilter,
    /// Rate memory: D × 2^GAIN_FRAC.
    integ: i64,
    d: i16,
    diff_mean: i64,
    samples: u64,
}

/// Effective speed counter start: bits 14:0 of the register, clamped to the valid range
/// (the datasheet gives no behaviour for invalid values; clamping is this model's choice).
pub fn effective_start(reg: u16) -> u16 {
    (reg & 0x7FFF).clamp(SPEED_COUNTER_START_MIN, SPEED_COUNTER_START_MAX)
}

/// Encodes a signed difference as register 0x092C: bits 30..0 = |Δt| (saturated), bit 31 set
/// when Δt < 0 (local copy behind). REQ-ESC-051, REQ-CONV-006.
pub fn encode_difference(dt: i64) -> u32 {
    let mag = dt.unsigned_abs().min(0x7FFF_FFFF) as u32;
    if dt < 0 {
        mag | 0x8000_0000
    } else {
        mag
    }
}

impl ControlLoop {
    /// A loop in its reset state.
    pub fn new(gains: LoopGains) -> Self {
        ControlLoop {
            s: SPEED_COUNTER_START_RESET,
            kp: (gains.kp * f64::from(1u32 << GAIN_FRAC)) as i64,
            ki: (gains.ki * f64::from(1u32 << GAIN_FRAC)) as i64,
            diff: MeanFilter::new(gains.diff_filter_reset),
            speed: MeanFilter::new(gains.speed_filter_reset),
            integ: 0,
            d: 0,
            diff_mean: 0,
            samples: 0,
        }
    }

    /// Write to 0x0930: clears 0x092C, 0x0932 and both filters, and latches the filter depths
    /// (a depth change takes effect here, as KickCAT reports for several ESCs). REQ-ESC-053.
    pub fn reset(&mut self, start_reg: u16, diff_depth: u8, speed_depth: u8) {
        self.s = effective_start(start_reg);
        self.diff = MeanFilter::new(diff_depth);
        self.speed = MeanFilter::new(speed_depth);
        self.integ = 0;
        self.d = 0;
        self.diff_mean = 0;
    }

    /// Largest |D| allowed: S − 0x7F (DS S2-76 Tab.105). REQ-ESC-054.
    pub fn d_limit(&self) -> i16 {
        (self.s - 0x7F) as i16
    }

    /// Effective speed counter start.
    pub fn start(&self) -> u16 {
        self.s
    }

    /// One sample Δt (ns, wrap-safe lower-32-bit difference). Returns the new D.
    pub fn sample(&mut self, dt: i32) -> i16 {
        self.samples += 1;
        let m = self.diff.push(i64::from(dt));
        self.diff_mean = m;
        let lim = i64::from(self.d_limit());
        let kp = self.kp;
        let ki = self.ki;
        // Clamp the error so products stay small; at this size the command saturates anyway.
        let e = m.clamp(-(1 << 30), 1 << 30);
        let p = e.saturating_mul(kp);
        let cmd_unclamped = self.integ.saturating_sub(p) >> GAIN_FRAC;
        let saturated_up = cmd_unclamped >= lim && e < 0;
        let saturated_down = cmd_unclamped <= -lim && e > 0;
        if !(saturated_up || saturated_down) {
            let lim_fp = lim << GAIN_FRAC;
            self.integ = self
                .integ
                .saturating_sub(e.saturating_mul(ki))
                .clamp(-lim_fp, lim_fp);
        }
        let cmd = (self.integ.saturating_sub(p) >> GAIN_FRAC).clamp(-lim, lim);
        // REQ-ESC-055: 0x0932 = mean of the last max(1, 0x0935) commands.
        let applied = self.speed.push(cmd).clamp(-lim, lim);
        self.d = applied as i16;
        self.d
    }

    /// Register 0x092C.
    pub fn difference_register(&self) -> u32 {
        encode_difference(self.diff_mean)
    }

    /// Register 0x0932 (two's complement).
    pub fn speed_diff(&self) -> i16 {
        self.d
    }

    /// Number of samples since power-on (diagnostics).
    pub fn samples(&self) -> u64 {
        self.samples
    }
}

#[cfg(test)]
mod test {
    use super::*;

    /// The constant-divisor fast path divides exactly like `/` (truncation toward zero).
    #[test]
    fn div_small_is_division() {
        let xs = [
            0i64,
            1,
            -1,
            5,
            -5,
            6,
            -6,
            7,
            -7,
            1 << 40,
            -(1 << 40),
            i64::MAX,
            i64::MIN + 8,
        ];
        for n in 1..=40i64 {
            for &x in &xs {
                for dx in -20..=20 {
                    let v = x.saturating_add(dx);
                    assert_eq!(div_small(v, n), v / n, "{v} / {n}");
                }
            }
        }
    }

    /// REQ-ESC-051: bit 31 set means the local copy is behind (Δt < 0).
    // verifies: REQ-ESC-051
    #[test]
    fn sign_magnitude() {
        assert_eq!(encode_difference(-5), 0x8000_0005);
        assert_eq!(encode_difference(5), 5);
        assert_eq!(encode_difference(0), 0);
        assert_eq!(encode_difference(-(1i64 << 40)), 0xFFFF_FFFF);
        assert_eq!(encode_difference(1i64 << 40), 0x7FFF_FFFF);
    }

    /// REQ-ESC-054: D stays within ±(S − 0x7F) however large the error.
    // verifies: REQ-ESC-054
    #[test]
    fn d_bounded() {
        let mut l = ControlLoop::new(LoopGains::default());
        l.reset(0x1000, 4, 12);
        for _ in 0..1000 {
            l.sample(i32::MIN);
        }
        assert_eq!(l.speed_diff(), 0x1000 - 0x7F);
        l.reset(0x0080, 4, 12);
        for _ in 0..1000 {
            l.sample(i32::MAX);
        }
        assert_eq!(l.speed_diff(), -1);
    }

    #[test]
    fn mean_filter_depth() {
        let mut f = MeanFilter::new(4);
        for v in [4, 8, 12, 16, 20] {
            f.push(v);
        }
        assert_eq!(f.sum, 8 + 12 + 16 + 20);
        let mut g = MeanFilter::new(0);
        assert_eq!(g.push(-7), -7);
        assert_eq!(g.push(3), 3);
    }

    /// REQ-ESC-055: 0x0932 is the mean (rounded half away from zero) of the last
    /// max(1, 0x0935) D commands. The commands do not depend on the speed filter, so a depth-1
    /// loop fed the same samples shows them one by one.
    // verifies: REQ-ESC-055
    #[test]
    fn speed_diff_is_mean_of_last_commands() {
        let samples: Vec<i32> = (0..60).map(|k| ((k * 7919) % 4001) - 1500).collect();
        let mut raw = ControlLoop::new(LoopGains::default());
        raw.reset(0x1000, 1, 1);
        let cmds: Vec<i64> = samples
            .iter()
            .map(|&dt| i64::from(raw.sample(dt)))
            .collect();
        assert!(cmds.windows(2).any(|w| w[0] != w[1]), "commands vary");
        for depth in [0u8, 1, 3, 12] {
            let mut l = ControlLoop::new(LoopGains::default());
            l.reset(0x1000, 1, depth);
            let n = usize::from(depth.max(1));
            for (k, &dt) in samples.iter().enumerate() {
                let d = l.sample(dt);
                let last = &cmds[(k + 1).saturating_sub(n)..=k];
                let sum: i64 = last.iter().sum();
                let m = last.len() as i64;
                let want = if sum >= 0 {
                    (sum + m / 2) / m
                } else {
                    (sum - m / 2) / m
                };
                assert_eq!(i64::from(d), want, "depth {depth}, sample {k}");
                assert_eq!(l.speed_diff(), d);
            }
        }
    }
}
