//! The application layer state machine as a slave's firmware drives it through AL control
//! (0x0120), AL status (0x0130) and the AL status code (0x0134): Beckhoff ESC datasheet
//! Section II, "AL Control", "AL Status", "AL Status Code"; transitions and codes from
//! ETG.1000.6 (docs/background/sii-al.md §3).
//!
//! The firmware checks the mailbox SyncManagers at INIT→PREOP and the process-data
//! SyncManagers at PREOP→SAFEOP against the SII's SyncManager category, requires each
//! process-data SyncManager to be mapped by an FMMU of its direction, and keeps the
//! SyncManagers it does not use in the current state deactivated from the PDI side (0x0807
//! bit 0), so process data only flows in SAFEOP and OP. A slave whose SII lists no
//! SyncManagers (`bare`) has nothing to check.

use super::device::{sm_type, SmEntry};
use super::registers::{addr, RegisterFile};

/// AL states, as AL control and AL status bits 0..3 hold them.
pub const INIT: u16 = 0x1;
pub const PREOP: u16 = 0x2;
pub const BOOT: u16 = 0x3;
pub const SAFEOP: u16 = 0x4;
pub const OP: u16 = 0x8;

/// Registers of SyncManager `n` (datasheet 0x0800 + 8n: start, length, control, status,
/// activate, PDI control).
pub fn sm_base(n: usize) -> u16 {
    addr::SM0 + 8 * (n.min(15) as u16)
}

/// Why the SyncManager `n` the SII describes as `want` is not configured as the firmware
/// needs: not activated, another length, mode or direction, or a buffer neither where the
/// SII puts it nor inside process RAM (some devices place theirs in register space, e.g.
/// 0x0F00, and a master may move a buffer within process RAM). `None` = fine.
fn sm_mismatch(regs: &RegisterFile, n: usize, want: &SmEntry) -> Option<&'static str> {
    let b = sm_base(n);
    let start = regs.get_u16(b);
    let len = regs.get_u16(b + 2);
    let ctrl = regs.get_u8(b + 4);
    let act = regs.get_u8(b + 6);
    if act & 0x01 == 0 {
        return Some("not activated");
    }
    if len != want.len {
        return Some("length");
    }
    if ctrl & 0x0F != want.control & 0x0F {
        return Some("mode or direction");
    }
    let end = u32::from(start) + u32::from(len);
    let in_ram = start >= addr::PROCESS_RAM && end <= regs.len() as u32;
    if start != want.start && !in_ram {
        return Some("outside process RAM");
    }
    None
}

/// Registers of FMMU `n` (datasheet 0x0600 + 16n: logical start u32, length u16, logical
/// start and stop bit, physical start u16, physical start bit, type, activate).
pub fn fmmu_base(n: usize) -> u16 {
    addr::FMMU0 + 16 * (n.min(15) as u16)
}

/// Whether an activated FMMU whose type has `dir` (0x01 read = inputs, 0x02 write = outputs)
/// maps some byte of SyncManager `n`'s buffer as its registers place it now. Only the FMMUs
/// the ESC has (0x0004) count.
fn fmmu_maps(regs: &RegisterFile, n: usize, dir: u8) -> bool {
    let b = sm_base(n);
    let s0 = u32::from(regs.get_u16(b));
    let s1 = s0 + u32::from(regs.get_u16(b + 2));
    let nf = usize::from(regs.get_u8(addr::FMMUS_SUPPORTED).min(16));
    (0..nf).any(|f| {
        let fb = fmmu_base(f);
        let p0 = u32::from(regs.get_u16(fb + 8));
        let p1 = p0 + u32::from(regs.get_u16(fb + 4));
        regs.get_u8(fb + 12) & 0x01 != 0 && regs.get_u8(fb + 11) & dir != 0 && p0 < s1 && s0 < p1
    })
}

/// The code of the first SyncManager of a type in `types` that is not configured as the SII
/// says; then (when `fmmus`, and all of them are) of the first that no FMMU of its direction
/// maps.
fn check(
    regs: &RegisterFile,
    sms: &[SmEntry],
    types: &[(u8, StatusCode)],
    fmmus: bool,
) -> Option<StatusCode> {
    // SyncManagers the SII lists as disabled or empty are not used.
    let used = || {
        sms.iter().enumerate().filter_map(|(n, e)| {
            let &(t, c) = types.iter().find(|(t, _)| *t == e.typ)?;
            (e.len != 0 && e.enable & 0x01 != 0).then_some((n, e, t, c))
        })
    };
    if let Some((.., c)) = used().find(|&(n, e, ..)| sm_mismatch(regs, n, e).is_some()) {
        return Some(c);
    }
    if !fmmus {
        return None;
    }
    used()
        .find(|&(n, _, t, _)| {
            let dir = if t == sm_type::PD_OUT { 0x02 } else { 0x01 };
            !fmmu_maps(regs, n, dir)
        })
        .map(|(.., c)| c)
}

/// Keeps the SyncManagers the SII lists deactivated from the PDI side unless the state
/// uses them: mailboxes from PREOP on, process data from SAFEOP on. REQ-ESC-026.
pub fn apply_pdi_control(regs: &mut RegisterFile, sms: &[SmEntry], state: u16) {
    for (n, e) in sms.iter().enumerate() {
        let on = match e.typ {
            sm_type::MBX_OUT | sm_type::MBX_IN => matches!(state, PREOP | SAFEOP | OP | BOOT),
            sm_type::PD_OUT | sm_type::PD_IN => matches!(state, SAFEOP | OP),
            _ => true,
        };
        let a = sm_base(n) + 7;
        let v = regs.get_u8(a);
        regs.set_u8(a, if on { v & !0x01 } else { v | 0x01 });
    }
}

/// AL status bit 4: error indication, with the reason in the AL status code 0x0134; AL
/// control bit 4: error acknowledge.
pub const ERROR: u16 = 0x10;

/// The AL status codes this firmware reports (ETG.1000.6, "AL Status Codes").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StatusCode {
    /// The requested transition is not allowed from the current state.
    InvalidTransition,
    /// The requested state is not a state.
    UnknownState,
    /// A mailbox SyncManager is not configured as the SII says.
    InvalidMailboxConfig,
    /// The output SyncManager or its FMMU is not configured as needed.
    InvalidOutputConfig,
    /// The input SyncManager or its FMMU is not configured as needed.
    InvalidInputConfig,
}

impl StatusCode {
    /// The value of 0x0134.
    pub fn value(self) -> u16 {
        match self {
            StatusCode::InvalidTransition => 0x0011,
            StatusCode::UnknownState => 0x0012,
            StatusCode::InvalidMailboxConfig => 0x0016,
            StatusCode::InvalidOutputConfig => 0x001D,
            StatusCode::InvalidInputConfig => 0x001E,
        }
    }
}

/// Handles a write to AL control (REQ-ESC-020, SyncManager checks REQ-ESC-025, FMMU checks
/// REQ-ESC-028). `sms` is the
/// SII's SyncManager category. Returns the new state. Rules (ETG.1000.6): any state → INIT; INIT → PREOP/BOOT; PREOP → SAFEOP; SAFEOP →
/// OP; back from OP/SAFEOP to lower states; BOOT → INIT; requesting the current state is
/// fine. While the error flag is set, only an acknowledge or a request for a lower state is
/// acted on: a higher state needs the acknowledge first.
pub fn control(regs: &mut RegisterFile, sms: &[SmEntry]) -> u16 {
    let ctrl = regs.get_u16(addr::AL_CONTROL);
    let status = regs.get_u16(addr::AL_STATUS);
    let cur = status & 0x0F;
    let ack = ctrl & ERROR != 0;
    let mut err = status & ERROR != 0 && !ack;
    let req = ctrl & 0x0F;
    let rank = |s: u16| match s {
        INIT => 0,
        PREOP | BOOT => 1,
        SAFEOP => 2,
        OP => 3,
        _ => 0,
    };
    let known = matches!(req, INIT | PREOP | BOOT | SAFEOP | OP);
    let allowed = match (cur, req) {
        (_, INIT) => true,
        (a, b) if a == b => true,
        (INIT, PREOP) | (INIT, BOOT) | (PREOP, SAFEOP) | (SAFEOP, OP) => true,
        (SAFEOP, PREOP) | (OP, SAFEOP) | (OP, PREOP) => true,
        _ => false,
    };
    let (new, code) = if err && known && rank(req) > rank(cur) {
        // Waits for the acknowledge; status and code stay as they are.
        (cur, None)
    } else if !known {
        (cur, Some(StatusCode::UnknownState))
    } else if !allowed {
        (cur, Some(StatusCode::InvalidTransition))
    } else {
        // The SyncManager types the firmware checks on this transition, each with the code
        // of its failure, and whether their FMMUs are checked too (process data only).
        let (checked, fmmus): (&[(u8, StatusCode)], bool) = match (cur, req) {
            (INIT, PREOP) => (
                &[
                    (sm_type::MBX_OUT, StatusCode::InvalidMailboxConfig),
                    (sm_type::MBX_IN, StatusCode::InvalidMailboxConfig),
                ],
                false,
            ),
            (PREOP, SAFEOP) => (
                &[
                    (sm_type::PD_OUT, StatusCode::InvalidOutputConfig),
                    (sm_type::PD_IN, StatusCode::InvalidInputConfig),
                ],
                true,
            ),
            _ => (&[], false),
        };
        match check(regs, sms, checked, fmmus) {
            Some(c) => (cur, Some(c)),
            None => (req, None),
        }
    };
    if let Some(c) = code {
        err = true;
        regs.set_u16(addr::AL_STATUS_CODE, c.value());
    } else if !err {
        regs.set_u16(addr::AL_STATUS_CODE, 0);
    }
    regs.set_u16(addr::AL_STATUS, new | if err { ERROR } else { 0 });
    apply_pdi_control(regs, sms, new);
    new
}
