//! DC compensation schemes compared by `ecdc simulate`, each a master driving its own copy of
//! the same emulated network (same [`crate::emu::Scenario`], same seed):
//!
//! - [`ecdc::Ecdc`]: ecdc's state machine through the simulation driver;
//! - [`seed000::Seed000`]: independent reproductions of the seed 000 scheme: `seed000`, the
//!   flow the paper describes with eq. 23 as its own eq. 22 implies it, and `seed000-printed`,
//!   eq. 23 exactly as printed in the old minimal flow (see the module for both);
//! - [`uncompensated::Uncompensated`]: offsets only, no delay and no drift compensation;
//! - [`igh::Igh`] and [`ethercrab::Ethercrab`] (used by `ecdc bench dc`): reproductions of the
//!   IgH and ethercrab DC bring-ups (sources in docs/bench.md).
//!
//! [`run::run_scheme`] drives any of them under one recorder (true clock errors, 0x092C,
//! SYNC0 edges, lock), and [`measure`] turns the record into the reported numbers.

/// The [`Scheme`] methods of a scheme that drives its network through `self.link` (a
/// [`link::SimLink`]) and keeps what it wrote to 0x0920 / 0x0928 in `self.written`: `net`,
/// `written`, `frames_lost`. With `fields`, also `reference` and `dist_frames` from the fields
/// of those names.
macro_rules! sim_link_scheme {
    () => {
        fn net(&mut self) -> &mut crate::emu::Network {
            &mut self.link.net
        }

        fn written(&self) -> Vec<crate::schemes::Written> {
            self.written.clone()
        }

        fn frames_lost(&self) -> u64 {
            self.link.lost
        }
    };
    (fields) => {
        sim_link_scheme!();

        fn reference(&self) -> usize {
            self.reference
        }

        fn dist_frames(&self) -> u64 {
            self.dist_frames
        }
    };
}

pub mod cycle_grid;
pub mod ecdc;
pub mod ethercrab;
pub mod igh;
pub mod igh_steps;
pub mod link;
pub mod measure;
pub mod run;
pub mod seed000;
pub mod uncompensated;

use std::collections::BTreeMap;

use crate::emu::{Network, TrueTime};

/// What a scheme was told about the network beyond what it measures on the wire, by name
/// (e.g. `t_diff_ns` → 80). Empty when the scheme knows only what it measures. Reported next
/// to every scheme's numbers so that a comparison shows who knew what.
pub type Given = BTreeMap<&'static str, i64>;

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
    /// Short name used in reports (`ecdc`, `seed000`, `seed000-printed`, `igh`, `ethercrab`,
    /// `uncompensated`).
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
    /// What this master was told beyond what it measures on the wire (see [`Given`]).
    fn given(&self) -> Given;
    /// Per slave (position order) the t_DIFF the scheme determined itself, ns, and where the
    /// value came from; `None` for schemes that only use what they were given.
    fn t_diff_used(&self) -> Option<Vec<(i64, String)>> {
        None
    }
}
