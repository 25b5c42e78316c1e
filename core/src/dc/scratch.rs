//! The machine's working tables: every per-slave array a computation needs while it runs (the
//! latch round's samples, topology and delays, the t_Diff plan's subtree sizes and resolved
//! values). They live inside the machine, not on the thread's stack, so that a step of a
//! `Machine<N>` needs a stack independent of `N` (issue #15: a bring-up of 1024 slaves within
//! 64 KiB of stack). Nothing here carries state from one computation to the next, except the
//! last latch round's topology and delays, which the step that follows reads, and the round
//! robin's list, a cache checked against the slave table before each use.
//! Only those two belong to the machine's control state (`dc/control.rs`).

use crate::dc::delay::{DelayScratch, Delays};
use crate::dc::monitor::MonitorList;
use crate::dc::port::{Port, PortSet};
use crate::dc::tdiff::TdiffSource;
use crate::dc::topology::{SlaveSample, Topology};

#[derive(Clone)]
pub(crate) struct Scratch<const N: usize> {
    /// The latch round's inputs to the pure DC maths, per position.
    pub(crate) samples: [SlaveSample; N],
    /// The tree of the latest latch round (the offsets use its entry ports).
    pub(crate) topo: Topology<N>,
    /// The topology reconstruction's depth-first stack.
    pub(crate) stack: [(u16, Port); N],
    /// The delay walk's input and output.
    pub(crate) delay: DelayScratch<N>,
    /// The delays of the latest latch round.
    pub(crate) round: Delays<N>,
    /// t_Diff plan: subtree size per position.
    pub(crate) subtree: [u16; N],
    /// t_Diff resolution: (value, source) per position.
    pub(crate) resolved: [(i32, TdiffSource); N],
    /// The cyclic round robin's slave list: a cache of the slave table, rebuilt whenever it
    /// might not match it (`dc/monitor.rs`).
    pub(crate) monitor: MonitorList<N>,
}

impl<const N: usize> Scratch<N> {
    pub(crate) const fn new() -> Self {
        Scratch {
            samples: [SlaveSample {
                ports: PortSet::EMPTY,
                latches: None,
                t_diff: 0,
            }; N],
            topo: Topology::new(),
            stack: [(0, Port::P0); N],
            delay: DelayScratch::new(),
            round: Delays::new(),
            subtree: [0; N],
            resolved: [(0, TdiffSource::Default); N],
            monitor: MonitorList::new(),
        }
    }
}

impl<const N: usize> core::fmt::Debug for Scratch<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // Per-slave tables of N entries, mostly leftovers of the last computation.
        f.debug_struct("Scratch")
            .field("topo", &self.topo)
            .field("round", &self.round)
            .finish_non_exhaustive()
    }
}
