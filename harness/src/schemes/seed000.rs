//! The seed 000 scheme (Chen et al. 2025, §2 and §3.2), reproduced as a small independent
//! master so ecdc can be compared with it on the same emulated network:
//!
//! 1. count, address, one receive-time latch (BWR 0x0900), read the port and EPU times;
//! 2. delays by **eq. 23 as printed** (including the `i·t_DIFF` of the last case, an erratum:
//!    the derivation gives `(n − 2)·t_DIFF`, so the last slave's delay comes out `t_DIFF` too
//!    large), with `t_DIFF` = the scenario's nominal `t_P − t_F`; written to 0x0928;
//! 3. offsets by **eq. 24 without the delay folded in**: `t_OFF = t_SYS,REF − t_LOCAL` from the
//!    EPU receive times of the latch frame (the printed sign `t_LOCAL − t_SYS,REF` contradicts
//!    eq. 25 and the datasheet; we use the sign eq. 25 needs, see spec/src/seed000.rs). Every
//!    slave therefore starts `t_REF,i` behind the reference and the ESC loops must pull that
//!    phase in during the burst; the reference keeps offset 0;
//! 4. a **fixed burst of 15 000 FRMW** frames back to back (§2.3), no convergence gate;
//! 5. SYNC0 start on the cycle grid, 100 ms ahead; then **one FRMW per cycle**.

use ecdc_spec::seed000 as spec;

use super::bringup::{self, Latched};
use super::link::Link;
use super::{Scheme, Written};
use crate::emu::{Network, TrueTime};

/// Burst length of §2.3 ("about 15 000 ARMW/FRMW commands").
pub const BURST_FRAMES: u64 = 15_000;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    BringUp,
    Burst,
    Sync,
    Cyclic,
}

/// The seed 000 master.
#[derive(Debug)]
pub struct Seed000 {
    link: Link,
    phase: Phase,
    n: usize,
    t_diff_ns: i64,
    cycle_ns: u32,
    burst_sent: u64,
    dist_frames: u64,
    next_cycle: TrueTime,
    written: Vec<Written>,
}

/// Eq. 23 exactly as printed, halved with the spec's rounding rule. `i` is 0-based here.
pub fn eq23_as_printed(l: &Latched, n: usize, i: usize, t_diff: i128) -> Option<i128> {
    let rtt: Vec<i128> = (0..n).map(|k| l.rtt(k)).collect();
    let x2 = if i + 1 == n && n > 1 {
        spec::eq23_printed_last_x2(*rtt.first()?, n, t_diff)
    } else {
        spec::eq23_t_ref_x2(&rtt, n, i + 1, t_diff)?
    };
    Some(spec::half(x2))
}

impl Seed000 {
    /// A master for `net`; `t_diff_ns` = nominal t_P − t_F, `cycle_ns` = SYNC0 and FRMW cycle.
    pub fn new(net: Network, t_diff_ns: i64, cycle_ns: u32) -> Self {
        Seed000 {
            link: Link::new(net),
            phase: Phase::BringUp,
            n: 0,
            t_diff_ns,
            cycle_ns,
            burst_sent: 0,
            dist_frames: 0,
            next_cycle: 0,
            written: Vec::new(),
        }
    }

    fn bring_up(&mut self) -> anyhow::Result<()> {
        let n = bringup::require_line_of_dc64(&self.link)?;
        self.n = n;
        let l = bringup::discover_and_latch(&mut self.link, n)?;
        let t_ref = *l.epu.first().unwrap_or(&0);
        self.written = vec![Written::default(); n];
        for i in 0..n {
            let delay = eq23_as_printed(&l, n, i, i128::from(self.t_diff_ns)).unwrap_or(0);
            let delay = u32::try_from(delay.max(0)).unwrap_or(u32::MAX);
            let local = i128::from(*l.epu.get(i).unwrap_or(&0));
            let off = if i == 0 {
                0
            } else {
                spec::offset_consistent_with_eq25(local, i128::from(t_ref), 0)
            };
            // Two's complement image of the 64-bit register.
            let off_reg = (off as i64) as u64;
            if i > 0 {
                bringup::write_offset(&mut self.link, i, off_reg)?;
                bringup::write_delay(&mut self.link, i, delay)?;
            }
            self.written[i] = Written {
                offset: (i > 0).then_some(off_reg as i64),
                delay: (i > 0).then_some(delay),
            };
        }
        Ok(())
    }
}

impl Scheme for Seed000 {
    fn name(&self) -> &'static str {
        "seed000"
    }

    fn advance(&mut self, until: TrueTime) -> anyhow::Result<()> {
        loop {
            match self.phase {
                Phase::BringUp => {
                    self.bring_up()?;
                    self.phase = Phase::Burst;
                }
                Phase::Burst => {
                    while self.burst_sent < BURST_FRAMES && self.link.now < until {
                        bringup::frmw(&mut self.link)?;
                        self.burst_sent += 1;
                        self.dist_frames += 1;
                    }
                    if self.burst_sent < BURST_FRAMES {
                        break;
                    }
                    self.phase = Phase::Sync;
                }
                Phase::Sync => {
                    bringup::program_sync0(&mut self.link, self.n, self.cycle_ns)?;
                    let c = u64::from(self.cycle_ns.max(1));
                    self.next_cycle = (self.link.now / c + 1) * c;
                    self.phase = Phase::Cyclic;
                }
                Phase::Cyclic => {
                    while self.next_cycle < until {
                        self.link.now = self.link.now.max(self.next_cycle);
                        bringup::frmw(&mut self.link)?;
                        self.dist_frames += 1;
                        self.next_cycle += u64::from(self.cycle_ns.max(1));
                    }
                    break;
                }
            }
        }
        self.link.advance_to(until)
    }

    fn net(&mut self) -> &mut Network {
        &mut self.link.net
    }

    fn reference(&self) -> usize {
        0
    }

    fn dist_frames(&self) -> u64 {
        self.dist_frames
    }

    fn static_drift_frames(&self) -> Option<u64> {
        (self.phase == Phase::Cyclic || self.phase == Phase::Sync).then_some(self.burst_sent)
    }

    fn written(&self) -> Vec<Written> {
        self.written.clone()
    }

    fn frames_lost(&self) -> u64 {
        self.link.lost
    }
}
