//! Golden digests of the servo hot path (gate, engine, master adapter): seeded random input
//! sequences (outliers, extreme values, missing samples, bad intervals, wraps, resets) drive
//! the live code, and every output is folded into a 64-bit FNV-1a digest that must equal the
//! committed one. The digests were recorded from this code while a frozen copy of the
//! pre-optimisation servo was still run beside it on the same inputs with equal outputs, so they
//! pin that behaviour without keeping a second copy of the code. A change that alters any
//! output on these sequences fails here; if the change is intended, say why in the commit and
//! record the new digest (the assertion message prints it).
#![allow(clippy::all, clippy::pedantic, clippy::restriction)]

use crate::digest::Digest;
use crate::servo::engine::Output;
use crate::servo::master::MasterOutput;

/// Gate: verdicts, thresholds and window length, 600 000 judgements.
const GATE_DIGEST: u64 = 0x7d30_dd4e_f9be_bac5;
/// Engine: every `Output`, 240 000 updates.
const SERVO_DIGEST: u64 = 0x8e1f_fff2_ad6c_dc65;
/// Master adapter: every `MasterOutput`, 200 000 updates.
const MASTER_DIGEST: u64 = 0x40e9_3a8e_ca9a_02e7;

/// The servo's outputs folded into a digest.
impl Digest {
    fn threshold(&mut self, t: Option<(i64, i64)>) {
        match t {
            None => self.word(0),
            Some((m, thr)) => {
                self.word(1);
                self.int(m);
                self.int(thr);
            }
        }
    }

    fn output(&mut self, o: &Output) {
        self.int(o.command_q32);
        self.int(o.step_ns);
        self.word(o.mode as u64);
        self.word(u64::from(o.locked));
        self.word(o.verdict as u64);
        self.word(u64::from(o.saturated));
        self.word(u64::from(o.fault));
        self.int(o.theta_ns);
        self.int(o.integrator_q32);
    }

    fn master(&mut self, o: &MasterOutput) {
        self.int(o.deadline_correction_ns);
        self.int(o.app_time_step_ns);
        self.int(o.phase_error_ns);
        self.output(&o.engine);
    }
}

#[cfg(test)]
mod tests {
    use super::Digest;
    use crate::servo::engine::{Input, Mode, Servo, ServoConfig, Verdict};
    use crate::servo::gains::{PiGains, Pole};
    use crate::servo::gate::{Gate, GateConfig, GATE_WINDOW};
    use crate::servo::lock::LockConfig;
    use crate::servo::master::{MasterConfig, MasterInput, MasterServo};
    use crate::servo::pi::PiLimits;

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
    fn gate_matches_its_golden_digest() {
        let mut r = Rng(0x0123_4567_89AB_CDEF);
        let mut d = Digest::new();
        let mut full_judged = 0u64;
        let mut by_mad = 0u64;
        for seq in 0..3000u64 {
            let mut new = Gate::new();
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
                d.threshold(new.threshold(cfg));
                if new.len() == GATE_WINDOW {
                    full_judged += 1;
                }
                let verdict = new.judge(cfg, theta);
                d.word(verdict as u64);
                // Accepted by the MAD term although outside the floor (judge's slow path).
                if let Some((med, thr)) = new.threshold(cfg) {
                    let dist = theta.clamp(-(1 << 40), 1 << 40).wrapping_sub(med).abs();
                    if dist > i64::from(cfg.floor_ns) && dist <= thr {
                        by_mad += 1;
                    }
                }
                match r.below(100) {
                    0 => {
                        new.clear();
                    }
                    1..=9 => {}
                    _ => {
                        new.push(theta);
                    }
                }
                d.word(new.len() as u64);
            }
        }
        assert!(full_judged > 300_000, "{full_judged}");
        d.assert_golden("gate outputs", super::GATE_DIGEST);
        assert!(by_mad > 10_000, "{by_mad}");
    }

    #[test]
    fn servo_matches_its_golden_digest() {
        let mut r = Rng(0xDEAD_BEEF_CAFE_F00D);
        let mut d = Digest::new();
        let mut steps = 0u64;
        let mut seen = [[0u64; 7]; 4];
        for _ in 0..600 {
            let cfg = servo_cfg(&mut r);
            let Ok(mut new) = Servo::new(cfg) else {
                panic!("config refused");
            };
            if r.chance(3) {
                let i = r.next() as i64 >> r.below(64);
                new = new.with_integrator(i);
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
                }
                let input = servo_input(&mut r, &mut t, h0, center, noise);
                let mode = new.mode();
                let a = new.update(input);
                d.output(&a);
                seen[mode as usize][a.verdict as usize] += 1;
                steps += 1;
            }
        }
        assert!(steps >= 200_000);
        d.assert_golden("servo outputs", super::SERVO_DIGEST);
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
    fn master_matches_its_golden_digest() {
        let mut r = Rng(0x5151_7777_0000_1234);
        let mut d = Digest::new();
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
            let Ok(mut new) = MasterServo::new(cfg) else {
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
                }
                if let MasterInput::Sample { app_ns, ref_ns, .. } = input {
                    // (app − ref) near ±2^63: the measurement takes the wide (i128) path.
                    let d = app_ns.wrapping_sub(ref_ns) as i64;
                    if !cfg.ref_32bit && d.unsigned_abs() > (1u64 << 63) - (1 << 30) {
                        wide += 1;
                    }
                }
                let a = new.update(input);
                d.master(&a);
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
        d.assert_golden("master servo outputs", super::MASTER_DIGEST);
        assert!(locked_tracking > 20_000, "{locked_tracking}");
        assert!(wide > 1000, "{wide}");
    }
}
