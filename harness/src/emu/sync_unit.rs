//! The cyclic (SYNC) unit of one ESC: activation rules, start time, SYNC0/SYNC1 cycle and
//! single-shot, next-pulse registers. Pulses are generated lazily by the ESC, which asks for the
//! distance (in local-copy ns) to the next pulse and inverts its clock to get the true time.
//! REQ-ESC-070..REQ-ESC-079.
//!
//! Comparison rule (an inference, docs/background/esc-registers.md §3.5): a pulse fires when the local copy of system
//! time *reaches* the programmed value, i.e. after the modular distance (X − now) mod 2^width;
//! a step of the local copy that passes over X reaches it (the ESC fires every pulse a move of
//! its clock passes over, `Esc::run_until_pulses`).
//! A start time already in the past therefore fires only after the counter wraps round to it
//! (≈ 4.3 s on a 32-bit DC, never on a 64-bit DC) unless the plausibility check (0x0981 bit 5)
//! is enabled, which fires at once and sets 0x0984 bit 2.

use super::registers::{addr, RegisterFile};
use serde::{Deserialize, Serialize};

/// Which SYNC output fired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SyncSignal {
    Sync0,
    Sync1,
}

/// Near-future window with 0x0981 bit 6 set ("≈ 2.1 s"): 2^31 ns, this model's reading.
pub const NEAR_FUTURE_SHORT_NS: u64 = 1 << 31;

// The bits of Activation 0x0981, by the datasheet's bit numbers.
/// Bit 0: cyclic operation.
const ACT_ACTIVE: u8 = 1 << 0;
/// Bit 1: SYNC0 generation.
const ACT_SYNC0: u8 = 1 << 1;
/// Bit 2: SYNC1 generation.
const ACT_SYNC1: u8 = 1 << 2;
/// Bit 3: auto-activation by writing the start time.
const ACT_AUTO: u8 = 1 << 3;
/// Bit 4: extension of a 32-bit start time to 64 bits.
const ACT_EXTEND: u8 = 1 << 4;
/// Bit 5: start time plausibility check (near future).
const ACT_CHECK: u8 = 1 << 5;
/// Bit 6: the short near-future window.
const ACT_SHORT_WINDOW: u8 = 1 << 6;
/// Bit 7: one debug pulse (self-clearing).
const ACT_DEBUG_PULSE: u8 = 1 << 7;

/// Dynamic state of the cyclic unit (configuration lives in the register file).
#[derive(Debug, Clone, Default)]
pub struct SyncUnit {
    next0: Option<u64>,
    next1: Option<u64>,
}

impl SyncUnit {
    #[inline]
    fn mask(regs: &RegisterFile) -> u64 {
        if regs.kind().is_64bit() {
            u64::MAX
        } else {
            u32::MAX as u64
        }
    }

    /// The next pulse and its distance from `sys_now` in local-copy ns. SYNC1 wins ties so a
    /// SYNC1 cycle that is a multiple of the SYNC0 cycle re-arms on the coinciding SYNC0.
    /// The distance is modular (REQ-ESC-075): a past start time fires after the wrap.
    #[inline]
    pub fn next_due(&self, regs: &RegisterFile, sys_now: u64) -> Option<(SyncSignal, u64)> {
        let m = Self::mask(regs);
        let d0 = self
            .next0
            .map(|x| (SyncSignal::Sync0, x.wrapping_sub(sys_now) & m));
        let d1 = self
            .next1
            .map(|x| (SyncSignal::Sync1, x.wrapping_sub(sys_now) & m));
        match (d0, d1) {
            (Some(a), Some(b)) => Some(if b.1 <= a.1 { b } else { a }),
            (a, b) => a.or(b),
        }
    }

    /// Fires `sig`; returns the programmed system time and which signals produce an output
    /// edge (SYNC0, and SYNC1 when it mirrors SYNC0). Enable bits gate the outputs only.
    pub fn fire(&mut self, sig: SyncSignal, regs: &mut RegisterFile) -> (u64, [bool; 2]) {
        let m = Self::mask(regs);
        let act = regs.get_u8(addr::SYNC_ACTIVATION);
        let ack_mode = regs.get_u16(addr::SYNC_PULSE_LENGTH) == 0;
        let mut out = [false, false];
        match sig {
            SyncSignal::Sync0 => {
                let x = self.next0.unwrap_or(0);
                // REQ-ESC-076: repeat every 0x09A0 ns; 0 = single shot.
                let c0 = u64::from(regs.get_u32(addr::SYNC0_CYCLE));
                self.next0 = if c0 == 0 {
                    None
                } else {
                    Some(x.wrapping_add(c0) & m)
                };
                // REQ-ESC-073: 0x0990 reads the next SYNC0 time (0x0998 the next SYNC1).
                if let Some(n) = self.next0 {
                    regs.set_dc64(addr::START_TIME, n);
                }
                let st = regs.get_u8(addr::SYNC_ACTIVATION_STATUS) & !0x01;
                regs.set_u8(addr::SYNC_ACTIVATION_STATUS, st);
                out[0] = act & ACT_SYNC0 != 0;
                if out[0] && ack_mode {
                    regs.set_u8(addr::SYNC0_STATUS, 1);
                }
                // REQ-ESC-077: cycle 0 mirrors SYNC0; otherwise arm SYNC1 0x09A4 after this
                // SYNC0 unless one is already pending (re-armed by the first SYNC0 after it).
                let c1 = u64::from(regs.get_u32(addr::SYNC1_CYCLE));
                if act & ACT_SYNC1 != 0 {
                    if c1 == 0 {
                        out[1] = true;
                        regs.set_dc64(addr::NEXT_SYNC1, self.next0.unwrap_or(x));
                        let st = regs.get_u8(addr::SYNC_ACTIVATION_STATUS) & !0x02;
                        regs.set_u8(addr::SYNC_ACTIVATION_STATUS, st);
                        if ack_mode {
                            regs.set_u8(addr::SYNC1_STATUS, 1);
                        }
                    } else if self.next1.is_none() {
                        let n1 = x.wrapping_add(c1) & m;
                        self.next1 = Some(n1);
                        regs.set_dc64(addr::NEXT_SYNC1, n1);
                    }
                }
                (x, out)
            }
            SyncSignal::Sync1 => {
                let x = self.next1.take().unwrap_or(0);
                let st = regs.get_u8(addr::SYNC_ACTIVATION_STATUS) & !0x02;
                regs.set_u8(addr::SYNC_ACTIVATION_STATUS, st);
                out[1] = act & ACT_SYNC1 != 0;
                if out[1] && ack_mode {
                    regs.set_u8(addr::SYNC1_STATUS, 1);
                }
                (x, out)
            }
        }
    }

    fn activate(&mut self, regs: &mut RegisterFile, sys_now: u64) {
        let m = Self::mask(regs);
        let act = regs.get_u8(addr::SYNC_ACTIVATION);
        let mut start = regs.get_u64(addr::START_TIME) & m;
        let mut status = 0u8;
        if regs.kind().enhanced_sync() && act & ACT_CHECK != 0 {
            let window = if act & ACT_SHORT_WINDOW != 0 {
                NEAR_FUTURE_SHORT_NS
            } else {
                m / 2 + 1
            };
            let d = start.wrapping_sub(sys_now) & m;
            if d > window {
                // REQ-ESC-074: implausible start time, fire at once.
                start = sys_now;
                status |= 0x04;
            }
        }
        self.next0 = Some(start);
        self.next1 = None;
        if act & ACT_SYNC0 != 0 {
            status |= 0x01;
        }
        if act & ACT_SYNC1 != 0 {
            status |= 0x02;
        }
        regs.set_u8(addr::SYNC_ACTIVATION_STATUS, status);
    }

    /// After a write to 0x0981 (`old` = value before the write). Returns true when a one-shot
    /// debug pulse (bit 7) was requested.
    pub fn on_activation_write(&mut self, old: u8, regs: &mut RegisterFile, sys_now: u64) -> bool {
        let mut v = regs.get_u8(addr::SYNC_ACTIVATION);
        if !regs.kind().enhanced_sync() {
            v &= 0x07;
        }
        let debug = v & ACT_DEBUG_PULSE != 0;
        v &= !ACT_DEBUG_PULSE; // self-clearing
        regs.set_u8(addr::SYNC_ACTIVATION, v);
        if v & ACT_ACTIVE == 0 {
            self.next0 = None;
            self.next1 = None;
            regs.set_u8(addr::SYNC_ACTIVATION_STATUS, 0);
        } else if old & ACT_ACTIVE == 0 {
            self.activate(regs, sys_now);
        }
        debug
    }

    /// After an accepted write to 0x0990 (`upper_written`: any of bytes 4..7 written).
    /// Handles auto-activation and the 32→64-bit extension (0x0981 bits 3/4).
    pub fn on_start_time_write(
        &mut self,
        regs: &mut RegisterFile,
        sys_now: u64,
        upper_written: bool,
    ) {
        let act = regs.get_u8(addr::SYNC_ACTIVATION);
        if !regs.kind().enhanced_sync() || act & ACT_AUTO == 0 {
            return;
        }
        if act & ACT_EXTEND != 0 && !upper_written && regs.kind().is_64bit() {
            let low = regs.get_u64(addr::START_TIME) & 0xFFFF_FFFF;
            let mut v = (sys_now & !0xFFFF_FFFF) | low;
            if low < (sys_now & 0xFFFF_FFFF) {
                v = v.wrapping_add(1 << 32);
            }
            regs.set_dc64(addr::START_TIME, v);
        }
        regs.set_u8(addr::SYNC_ACTIVATION, act | ACT_ACTIVE);
        self.activate(regs, sys_now);
    }

    /// Whether the unit is active (0x0981 bit 0).
    pub fn active(regs: &RegisterFile) -> bool {
        regs.get_u8(addr::SYNC_ACTIVATION) & ACT_ACTIVE != 0
    }
}
