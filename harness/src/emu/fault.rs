//! Faults that a scenario (or a running test) can inject at given true times. REQ-ESC-090..096.

use serde::{Deserialize, Serialize};

/// A fault and when it happens (true time, ns since the start of the run).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FaultSpec {
    pub at_ns: u64,
    #[serde(flatten)]
    pub fault: Fault,
}

/// What goes wrong.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Fault {
    /// The cable at `port` of `slave` goes down (port 0 = the cable towards the master). Both
    /// neighbours close that port; frames already beyond the break circulate and are destroyed.
    LinkBreak { slave: usize, port: u8 },
    /// The cable comes back.
    LinkRestore { slave: usize, port: u8 },
    /// The slave loses power: it disappears from the chain (its neighbours' ports close).
    /// Loss of the reference slave is this fault applied to the reference.
    PowerOff { slave: usize },
    /// Power returns: local time restarts at 0 and every register takes its reset value.
    PowerOn { slave: usize },
    /// Off now, on again `off_ns` later.
    PowerCycle { slave: usize, off_ns: u64 },
    /// From now on, each frame is lost with this probability.
    FrameLossRate { rate: f64 },
    /// The slave's crystal error changes to `ppm` (a temperature step).
    FrequencyStep { slave: usize, ppm: f64 },
    /// The cable into the slave's port 0 changes length (applied at frame boundaries).
    CableLength { slave: usize, meters: f64 },
    /// Chooses the slave's power-on phase so that its 32-bit local time (the port receive
    /// times) wraps exactly at this fault's time — e.g. in the middle of a delay measurement.
    /// Scenario-only (it sets the initial state); `None` = every slave.
    PortTimeWrap { slave: Option<usize> },
    /// The wire goes silent for `duration_ns`: every frame the master sends in that window is
    /// lost before the first slave, and every reply that would reach the master in it is lost
    /// on the way back (the slaves did process that frame). A stopped peer process on a veth
    /// pair, or a switch rebooting, looks like this. The slaves' clocks run on (REQ-ESC-095).
    WireSilence { duration_ns: u64 },
    /// The master stops for `duration_ns` (a stalled host or process): it neither sends nor
    /// reads. Frames already sent still travel and wait for it; it resumes at the end with its
    /// own clock advanced by the stall. Acted on by the driver that plays the master
    /// ([`crate::sim::Sim`]), which asks [`crate::emu::Network::master_stalled`] (REQ-ESC-096).
    MasterStall { duration_ns: u64 },
}
