//! Process data: how SyncManagers gate logical (FMMU) access to process RAM, and how the
//! slave's application exchanges its buffers.
//!
//! SyncManager registers (Beckhoff ESC datasheet Section II, "SyncManager"): 0x0800 + 8n
//! start, +2 length, +4 control (mode bits 1:0, direction bits 3:2), +5 status, +6 activate
//! (bit 0 enable), +7 PDI control (bit 0 deactivate). Model (docs/background/sii-al.md §4):
//! - a byte inside an activated SyncManager that the PDI has deactivated is not accessible
//!   from ECAT: the access neither reads nor writes it nor counts in the working counter;
//! - ECAT cannot write into a buffer whose direction is "ECAT reads" (inputs);
//! - a buffered SyncManager is modelled as one buffer: the slave sees the master's latest
//!   complete write and the master reads the slave's latest inputs (the three-buffer
//!   exchange of the ESC gives the same data when one master writes and reads once per
//!   cycle);
//! - bytes outside every activated SyncManager are plain memory, as before.

use super::al::sm_base;
use super::registers::RegisterFile;
use serde::{Deserialize, Serialize};

/// ECAT access rights of process RAM bytes, from the SyncManager registers (REQ-ESC-026).
#[derive(Debug, Clone, Default)]
pub struct SmGate {
    /// (first byte, end, ECAT may read, ECAT may write).
    areas: Vec<(u32, u32, bool, bool)>,
}

impl SmGate {
    /// Reads the table of `n` SyncManagers.
    pub fn from_regs(regs: &RegisterFile, n: usize) -> Self {
        let mut areas = Vec::new();
        for k in 0..n.min(16) {
            let b = sm_base(k);
            if regs.get_u8(b + 6) & 0x01 == 0 {
                continue;
            }
            let start = u32::from(regs.get_u16(b));
            let end = start + u32::from(regs.get_u16(b + 2));
            let pdi_off = regs.get_u8(b + 7) & 0x01 != 0;
            let ecat_writes = (regs.get_u8(b + 4) >> 2) & 0x03 == 0x01;
            areas.push((start, end, !pdi_off, !pdi_off && ecat_writes));
        }
        SmGate { areas }
    }

    /// Whether no SyncManager restricts anything (the common case of DC-only runs).
    pub fn is_open(&self) -> bool {
        self.areas.is_empty()
    }

    /// (may read, may write) byte `a`.
    pub fn access(&self, a: u16) -> (bool, bool) {
        let a = u32::from(a);
        for &(s, e, r, w) in &self.areas {
            if (s..e).contains(&a) {
                return (r, w);
            }
        }
        (true, true)
    }
}

/// What a slave's application sees and drives, for observers (`Network::process_image`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProcessImage {
    /// AL state (0x0130 bits 3:0).
    pub al_state: u8,
    /// Outputs the device drives (safe state, all zero, outside OP).
    pub outputs: Vec<u8>,
    /// Inputs the device presents to the master.
    pub inputs: Vec<u8>,
}
