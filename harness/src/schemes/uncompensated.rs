//! The "no compensation" baseline (seed 000 Fig. 9), defined precisely:
//!
//! - the same discovery and receive-time latch as the seed 000 scheme;
//! - **offset only**: 0x0920 = `t_SYS,REF − t_LOCAL` from the EPU receive times of the latch
//!   frame (eq. 24 with the sign eq. 25 needs, no delay folded in), so every slave's system
//!   time starts within its propagation delay from the reference's and SYNC0 starts on the same
//!   cycle everywhere;
//! - **no delay compensation**: 0x0928 is not written (stays 0);
//! - **no drift compensation**: no FRMW/ARMW of the reference time is ever sent, so the ESC
//!   loops never run and each system time advances at its own crystal rate;
//! - SYNC0 programmed exactly as in the seed 000 scheme (common start 100 ms ahead).
//!
//! The clock error therefore starts at about −t_REF,i and grows linearly with the crystal
//! difference (±50 ppm crystals: up to 100 ns per ms), as in Fig. 9.

use ecdc_spec::seed000 as spec;

use super::igh_steps;
use super::link::SimLink;
use super::{Given, Scheme, Written};
use crate::emu::{Network, TrueTime};

/// The uncompensated master.
#[derive(Debug)]
pub struct Uncompensated {
    link: SimLink,
    done: bool,
    cycle_ns: u32,
    written: Vec<Written>,
}

impl Uncompensated {
    /// A master for `net` programming SYNC0 with `cycle_ns`.
    pub fn new(net: Network, cycle_ns: u32) -> Self {
        Uncompensated {
            link: SimLink::new(net),
            done: false,
            cycle_ns,
            written: Vec::new(),
        }
    }

    fn bring_up(&mut self) -> anyhow::Result<()> {
        let n = igh_steps::require_line_of_dc64(&self.link)?;
        let l = igh_steps::discover_and_latch(&mut self.link, n)?;
        let t_ref = *l.epu.first().unwrap_or(&0);
        self.written = vec![Written::default(); n];
        for i in 1..n {
            let local = i128::from(*l.epu.get(i).unwrap_or(&0));
            let off = spec::offset_consistent_with_eq25(local, i128::from(t_ref), 0);
            let off_reg = (off as i64) as u64;
            igh_steps::write_offset(&mut self.link, i, off_reg)?;
            self.written[i].offset = Some(off_reg as i64);
        }
        igh_steps::program_sync0(&mut self.link, n, self.cycle_ns)?;
        Ok(())
    }
}

impl Scheme for Uncompensated {
    fn name(&self) -> &'static str {
        "uncompensated"
    }

    fn advance(&mut self, until: TrueTime) -> anyhow::Result<()> {
        if !self.done {
            self.bring_up()?;
            self.done = true;
        }
        self.link.advance_to(until)
    }

    sim_link_scheme!();

    fn reference(&self) -> usize {
        0
    }

    fn dist_frames(&self) -> u64 {
        0
    }

    fn static_drift_frames(&self) -> Option<u64> {
        self.done.then_some(0)
    }

    fn given(&self) -> Given {
        // Offsets only: nothing about the network is needed.
        Given::new()
    }
}
