//! Clocks for the P6 model checker's line (`crate::model`): what the slaves' DC registers
//! hold when each slave has its own free-running local clock, a 32- or 64-bit system time and
//! the offset the master wrote, so that the search runs the machine on real clock arithmetic
//! (32-bit wraps, mixed widths, a running domain ahead of the master's clock) and can check
//! what the offsets achieve, not only which frames carry them.
//!
//! The model (ideal crystals: no drift, so no time-control loop is needed):
//! - true time is the master's clock `now`; slave `p`'s local time is `now + base[p]`, reduced
//!   to 32 bits on a 32-bit slave; its system time adds the offset 0x0920 (same width);
//! - a latch (BWR 0x0900) at `now` reaches slave `p` at `now + 1000·p` (1 µs per hop, the
//!   [`crate::machine`] line) and returns through port 1 at `now + 1000·(2(k−1) − p)` (no
//!   turn-round time and t_Diff 0, so the delays of the machine's formula are exactly
//!   `1000·p` and the offsets it writes can be judged to the nanosecond); the port times are
//!   the local times then, 0x0918 the local time at port 0;
//! - FRMW 0x0910: the reference's system time; 0x092C: a slave's system time minus the
//!   reference's (sign bit 31, magnitude bits 30..0, on the narrower width); BRD 0x092C ORs
//!   the values of every slave; FPRD/FPWR 0x0920 read and write the offset;
//! - a power cycle restarts the local time at 0 with offset 0; a slave started by another
//!   master (AL race) joins that master's domain, the one the slaves found running are in
//!   (model choice: a master that starts a slave synchronises it first;
//!   two running domains that disagree could not be joined without writing 0x0920 under a
//!   running application, which REQ-DC-030 forbids, and a running slave whose 0x0920 was
//!   never set is in no domain at all: the bring-up then restarts with `NotConverged` until
//!   the slave leaves SAFE-OP/OP, which is not what this check is about);
//! - a port-time wrap places every local clock 1.5 µs below 2^32 at the next latch, and the
//!   offsets with them: the system times do not move, that latch's receive times straddle the
//!   wrap.

use ecdc_core::wire::Command;

use crate::machine::CAP;

/// Hop delay of the model line, ns (as `crate::machine::Model`).
const HOP_NS: u64 = 1_000;
/// How far the running domain of the slaves found in SAFE-OP/OP is ahead of the master's
/// clock, ns (model choice: a few ms, as REQ-DC-131's soak found after an hour at 1 ppm).
pub const DOMAIN_SHIFT_NS: u64 = 3_100_000;

/// The clocks of a line of at most [`CAP`] slaves.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Clocks {
    /// Per position: local time minus true time (wrapping).
    base: [u64; CAP],
    /// Per position: 0x0920, reduced to the slave's width.
    offset: [u64; CAP],
    /// Bit `p`: slave `p` has a 32-bit system time (0x0008 bit 3 clear).
    bits32: u8,
    /// True time of the last latch (BWR 0x0900); `None` before the first, when the port time
    /// registers hold their reset value 0.
    latch_at: Option<u64>,
    /// A port-time wrap is due at the next latch.
    wrap_pending: bool,
    /// Mutation knob for the checker's own test (0 in real runs): added to slave `p`'s latched
    /// receive times (0x0900..0x090F, 0x0918), as a latch unit that lies would.
    latch_error: [u64; CAP],
}

impl Clocks {
    /// Clocks powered on at different moments (slave `p` about `p + 1` s before `now`); the
    /// slaves whose AL state is SAFE-OP or OP form a running domain [`DOMAIN_SHIFT_NS`] ahead
    /// of the master's clock; the others have offset 0.
    pub fn new(now: u64, al: &[u16; CAP], bits32: u8) -> Clocks {
        let mut c = Clocks {
            base: [0; CAP],
            offset: [0; CAP],
            bits32,
            latch_at: None,
            wrap_pending: false,
            latch_error: [0; CAP],
        };
        for (p, a) in al.iter().enumerate() {
            let up = (p as u64 + 1) * 1_000_000_123 + (p as u64) * 7_777;
            c.base[p] = up.wrapping_sub(now);
            if matches!(a & 0x0F, 4 | 8) {
                c.join_running(p, now);
            }
        }
        c
    }

    fn mask(&self, p: usize) -> u64 {
        if p < 8 && self.bits32 & (1u8 << p) != 0 {
            u64::from(u32::MAX)
        } else {
            u64::MAX
        }
    }

    fn local(&self, p: usize, t: u64) -> u64 {
        t.wrapping_add(self.base[p]) & self.mask(p)
    }

    /// A local time as slave `p`'s latch unit reports it.
    fn latched(&self, p: usize, t: u64) -> u64 {
        self.local(p, t).wrapping_add(self.latch_error[p]) & self.mask(p)
    }

    /// Mutation knob: slave `p`'s latches report `ns` late (a test of the checker).
    pub fn with_latch_error(mut self, p: usize, ns: u64) -> Clocks {
        if let Some(e) = self.latch_error.get_mut(p) {
            *e = ns;
        }
        self
    }

    /// System time of slave `p` at true time `t`.
    pub fn system(&self, p: usize, t: u64) -> u64 {
        self.local(p, t).wrapping_add(self.offset[p]) & self.mask(p)
    }

    /// System time of `p` minus system time of `q` at `t`, on the narrower width.
    fn between(&self, p: usize, q: usize, t: u64) -> i64 {
        let d = self.system(p, t).wrapping_sub(self.system(q, t));
        if self.mask(p) != u64::MAX || self.mask(q) != u64::MAX {
            i64::from(d as u32 as i32)
        } else {
            d as i64
        }
    }

    /// System time of `p` minus the reference's (position 0) at `t`, on the narrower width.
    pub fn difference(&self, p: usize, t: u64) -> i64 {
        self.between(p, 0, t)
    }

    /// |system time of `p` − system time of `q`| at `t`, on the narrower width.
    pub fn apart(&self, p: usize, q: usize, t: u64) -> u64 {
        self.between(p, q, t).unsigned_abs()
    }

    /// Whether every slave of a line of `k` agrees with the reference within `tol_ns` at `t`.
    pub fn agree(&self, k: u16, t: u64, tol_ns: u64) -> bool {
        (1..usize::from(k).min(CAP)).all(|p| self.apart(p, 0, t) <= tol_ns)
    }

    /// Slave `j`, started by another master at `now`, joins that master's domain,
    /// [`DOMAIN_SHIFT_NS`] ahead of the master's clock: the domain of every slave that runs
    /// (the ones found running and the ones started since), so a 64-bit slave gets the whole
    /// time of which a 32-bit one holds the low half (see the module doc).
    pub fn join_running(&mut self, j: usize, now: u64) {
        let want = now.wrapping_add(DOMAIN_SHIFT_NS);
        self.offset[j] = want.wrapping_sub(self.local(j, now)) & self.mask(j);
    }

    /// Power cycle of slave `p` at `now`.
    pub fn reset(&mut self, p: usize, now: u64) {
        self.base[p] = 0u64.wrapping_sub(now);
        self.offset[p] = 0;
    }

    /// The next latch's port times straddle 2^32 (see [`Clocks::wrap_at`]).
    pub fn wrap(&mut self) {
        self.wrap_pending = true;
    }

    /// At the latch at `t`: every local clock is placed 1.5 µs below 2^32, so that the frame
    /// reaches slaves 0 and 1 before the wrap and the others after it. The offsets follow, so
    /// no system time moves. Placing the clocks at the latch itself keeps the model physical
    /// for the machine: every local time it has read since is read after the move.
    fn wrap_at(&mut self, t: u64) {
        for p in 0..CAP {
            let before = self.system(p, t);
            let low = self.local(p, t) as u32;
            let target = u32::MAX - 1_499;
            self.base[p] = self.base[p].wrapping_add(u64::from(target.wrapping_sub(low)));
            self.offset[p] = before.wrapping_sub(self.local(p, t)) & self.mask(p);
        }
    }

    /// The DC registers of one datagram that reached slave `pos` (`None`: a broadcast) with
    /// working counter `wkc` from the line model: overwrites `data` with what the clocks say,
    /// and takes the offset of an FPWR 0x0920. `now`: true time the frame passes.
    pub fn answer(
        &mut self,
        cmd: u8,
        pos: Option<u16>,
        ado: u16,
        k: u16,
        now: u64,
        data: &mut [u8],
    ) {
        let put = |data: &mut [u8], v: u64| {
            for (b, v) in data.iter_mut().zip(v.to_le_bytes()) {
                *b = v;
            }
        };
        let cmd = Command::from_u8(cmd).ok();
        let k = usize::from(k).min(CAP);
        match (cmd, pos.map(usize::from)) {
            (Some(Command::Bwr), None) if ado == 0x0900 => {
                if self.wrap_pending {
                    self.wrap_at(now);
                    self.wrap_pending = false;
                }
                self.latch_at = Some(now);
            }
            (Some(Command::Frmw), _) if ado == 0x0910 => put(data, self.system(0, now)),
            (Some(Command::Brd), None) if ado == 0x092C => {
                let or = (0..k).fold(0u32, |a, p| a | self.diff_register(p, now));
                put(data, u64::from(or));
            }
            (Some(Command::Fprd), Some(p)) if p < k => match ado {
                0x0008 => put(
                    data,
                    if self.mask(p) == u64::MAX {
                        0x000C
                    } else {
                        0x0004
                    },
                ),
                0x0900 => {
                    let Some(t) = self.latch_at else {
                        data.iter_mut().for_each(|b| *b = 0);
                        return;
                    };
                    let there = t.wrapping_add(HOP_NS * p as u64);
                    let back = (2 * (k as u64 - 1)).saturating_sub(p as u64);
                    let back = t.wrapping_add(HOP_NS * back);
                    let mut v = [0u8; 32];
                    v[0..4].copy_from_slice(&(self.latched(p, there) as u32).to_le_bytes());
                    v[4..8].copy_from_slice(&(self.latched(p, back) as u32).to_le_bytes());
                    v[16..24].copy_from_slice(&self.system(p, now).to_le_bytes());
                    v[24..32].copy_from_slice(&self.latched(p, there).to_le_bytes());
                    for (b, v) in data.iter_mut().zip(v) {
                        *b = v;
                    }
                }
                0x0910 => put(data, self.system(p, now)),
                0x0918 => match self.latch_at {
                    Some(t) => put(data, self.latched(p, t.wrapping_add(HOP_NS * p as u64))),
                    None => data.iter_mut().for_each(|b| *b = 0),
                },
                0x0920 => put(data, self.offset[p]),
                0x092C => put(data, u64::from(self.diff_register(p, now))),
                _ => {}
            },
            (Some(Command::Fpwr), Some(p)) if p < k && ado == 0x0920 => {
                let mut v = [0u8; 8];
                for (d, s) in v.iter_mut().zip(data.iter()) {
                    *d = *s;
                }
                self.offset[p] = u64::from_le_bytes(v) & self.mask(p);
            }
            _ => {}
        }
    }

    /// 0x092C of slave `p`: sign bit 31 (set when the slave is behind), magnitude 30..0.
    fn diff_register(&self, p: usize, now: u64) -> u32 {
        let d = self.difference(p, now);
        let mag = u32::try_from(d.unsigned_abs().min(0x7FFF_FFFF)).unwrap_or(0x7FFF_FFFF);
        if d < 0 {
            mag | 0x8000_0000
        } else {
            mag
        }
    }
}
