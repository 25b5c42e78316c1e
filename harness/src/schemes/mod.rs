//! DC compensation schemes compared by `ecdc simulate`, each a master driving its own copy of
//! the same emulated network (same [`crate::emu::Scenario`], same seed):
//!
//! - [`ecdc::Ecdc`]: ecdc's state machine through the simulation driver;
//! - [`seed000::Seed000`]: an independent reproduction of the seed 000 scheme (eq. 23 as
//!   printed, eq. 24 without delay folding, fixed 15 000-frame burst, one FRMW per cycle);
//! - [`uncompensated::Uncompensated`]: offsets only, no delay and no drift compensation;
//! - [`igh::Igh`] and [`ethercrab::Ethercrab`] (used by `ecdc bench dc`): reproductions of the
//!   IgH and ethercrab DC bring-ups as documented in `../shared/reference/masters.md`.
//!
//! [`run::run_scheme`] drives any of them under one recorder (true clock errors, 0x092C,
//! SYNC0 edges, lock), and [`measure`] turns the record into the reported numbers.

pub mod bringup;
pub mod ecdc;
pub mod ethercrab;
pub mod igh;
pub mod link;
pub mod measure;
pub mod run;
pub mod seed000;
pub mod uncompensated;

use crate::emu::{Network, TrueTime};

/// What a scheme wrote to one slave during bring-up (`None` = not written).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Written {
    /// 0x0920 as a signed 64-bit value (the register's two's complement image).
    pub offset: Option<i64>,
    /// 0x0928, ns.
    pub delay: Option<u32>,
}

/// A master under test. The recorder calls [`Scheme::advance`] with increasing true times and
/// observes the network in between.
pub trait Scheme {
    /// Short name used in reports (`ecdc`, `seed000`, `uncompensated`).
    fn name(&self) -> &'static str;
    /// Does everything the master does up to true time `until` (a blocking step, such as a
    /// bring-up, may end later), then lets the network run to at least `until`.
    fn advance(&mut self, until: TrueTime) -> anyhow::Result<()>;
    /// The emulated network this master drives.
    fn net(&mut self) -> &mut Network;
    /// Emulator index of the reference clock.
    fn reference(&self) -> usize;
    /// Frames sent so far that distribute the reference time (static drift compensation and
    /// cyclic FRMW frames).
    fn dist_frames(&self) -> u64;
    /// Frames of the static drift compensation, once it is over.
    fn static_drift_frames(&self) -> Option<u64>;
    /// Per slave (emulator index), what was written to 0x0920 and 0x0928.
    fn written(&self) -> Vec<Written>;
    /// Frames this master sent that the network lost (every kind of frame).
    fn frames_lost(&self) -> u64;
}
