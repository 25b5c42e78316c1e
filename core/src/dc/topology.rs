//! Topology reconstruction: which slave hangs off which port of which slave.
//!
//! Input, per slave in auto-increment order (the order a frame first reaches them): the open
//! ports from DL status (REQ-DC-011) and, for slaves with receive-time latches, the latched port
//! times. Output: a tree, each slave knowing its entry port, its parent and the parent's port.
//!
//! Why this works: the frame walks the tree depth first, visiting each ESC's ports in processing
//! order 0 → 3 → 1 → 2 starting after the entry port (REQ-DC-010), so the auto-increment order is
//! the preorder of that walk. Slave i+1 therefore hangs off the most recent slave that still has
//! an unvisited open port, at the first such port. A stack replays the walk (REQ-DC-012).
//!
//! ```text
//!  master ─ 0[S0]1 ─ 0[S1]3 ─ 0[S2]          S1 is a cross/fork: ports visited 0,3,1,2
//!                        1 ─ 0[S3]1 ─ 0[S4]   auto-increment order S0 S1 S2 S3 S4 S5
//!                        2 ─ 0[S5]
//! ```
//!
//! Entry port (REQ-DC-013): for a slave with latches, the open port with the earliest receive
//! time by wrapping difference ([`PortTime::earliest`]), so a 32-bit wrap during the latch
//! cannot pick the wrong port (SOEM #979, ethercrab #374). Slaves without latches are assumed to
//! be wired upstream on their first open port in processing order (port 0 when open), as IgH
//! does. The latched times must then increase along the processing order from the entry port;
//! otherwise the latches are stale or the DL status is wrong and the slave is rejected.

use super::port::{Port, PortSet};
use crate::time::PortTime;

/// Receive-time latches of one slave after the latching write to 0x0900.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{port::Port, topology::Latches};
/// use ecdc_core::time::PortTime;
///
/// // Port 0 latched the frame going out, port 1 when it came back 1 µs later.
/// let l = Latches::from_raw([1_000, 2_000, 0, 0], 0x7_0000_03E8);
/// assert_eq!(l.at(Port::P1).wrapping_since(l.at(Port::P0)), 1_000);
/// assert_eq!(l.ports[0], PortTime(1_000));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Latches {
    /// Receive Time Port 0..3 (0x0900..0x090F), indexed by port number, local time. Values of
    /// closed ports are stale and ignored.
    pub ports: [PortTime; 4],
    /// Receive Time ECAT Processing Unit (0x0918), local time (64-bit; on 32-bit ESCs only the
    /// low 32 bits are meaningful).
    pub epu: u64,
}

impl Latches {
    /// From raw register values (e.g. `wire::ReceiveTimes::port` and `::epu`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::topology::Latches;
    /// use ecdc_core::time::PortTime;
    /// use ecdc_core::wire::register::ReceiveTimes;
    ///
    /// // Straight from the 32-byte block read at 0x0900.
    /// let read = ReceiveTimes {
    ///     port: [1_000, 2_000, 0, 0],
    ///     system_time: 0,
    ///     epu: 1_000,
    /// };
    /// let l = Latches::from_raw(read.port, read.epu);
    /// assert_eq!(l.ports[1], PortTime(2_000));
    /// assert_eq!(l.epu, 1_000);
    /// ```
    pub const fn from_raw(ports: [u32; 4], epu: u64) -> Latches {
        Latches {
            ports: [
                PortTime(ports[0]),
                PortTime(ports[1]),
                PortTime(ports[2]),
                PortTime(ports[3]),
            ],
            epu,
        }
    }

    /// The latched time of `port`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{port::Port, topology::Latches};
    /// use ecdc_core::time::PortTime;
    ///
    /// let l = Latches::from_raw([10, 20, 30, 40], 10);
    /// assert_eq!(l.at(Port::P3), PortTime(40));
    /// ```
    #[inline]
    pub fn at(&self, port: Port) -> PortTime {
        self.ports.get(port.index()).copied().unwrap_or_default()
    }
}

/// What the DC maths needs to know about one slave (REQ-DC-001).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::port::{Port, PortSet};
/// use ecdc_core::dc::topology::{Latches, SlaveSample};
///
/// // A DC slave with ports 0 and 1 open and a t_Diff of 20 ns from its datasheet.
/// let s = SlaveSample {
///     ports: PortSet::EMPTY.with(Port::P0).with(Port::P1),
///     latches: Some(Latches::from_raw([1_000, 2_000, 0, 0], 1_000)),
///     t_diff: 20,
/// };
/// assert_eq!(
///     s,
///     SlaveSample::from_registers(0x5A00, 0x0004, [1_000, 2_000, 0, 0], 1_000, 20)
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SlaveSample {
    /// Open ports, from DL status 0x0110 ([`PortSet::from_dl_status`]).
    pub ports: PortSet,
    /// Receive-time latches; `None` for slaves without DC (ESC features 0x0008 bit 2 clear).
    pub latches: Option<Latches>,
    /// `t_Diff = t_P − t_F` of this ESC in ns (processing minus forwarding delay, from the ESI or
    /// the ESC datasheet); 0 when unknown (REQ-DC-015).
    pub t_diff: i32,
}

impl SlaveSample {
    /// From the raw registers read after a latch: DL Status 0x0110, ESC Features 0x0008,
    /// Receive Time Port 0..3 (0x0900..0x090F) and Receive Time EPU (0x0918). The latches are
    /// kept only when the ESC has DC (features bit 2); `t_diff` as in [`SlaveSample::t_diff`].
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    /// use ecdc_core::dc::topology::SlaveSample;
    ///
    /// // DL status 0x5A00: ports 0 and 1 open; features 0x000C: 64-bit DC.
    /// let dc = SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0);
    /// assert_eq!(dc.ports, PortSet::EMPTY.with(Port::P0).with(Port::P1));
    /// assert!(dc.latches.is_some());
    /// // Features without bit 2: a slave without DC, whose latch registers mean nothing.
    /// let plain = SlaveSample::from_registers(0x5A00, 0x0000, [1_000, 2_000, 0, 0], 1_000, 0);
    /// assert_eq!(plain.latches, None);
    /// ```
    pub fn from_registers(
        dl_status: u16,
        features: u16,
        port_times: [u32; 4],
        epu: u64,
        t_diff: i32,
    ) -> SlaveSample {
        SlaveSample {
            ports: PortSet::from_dl_status(dl_status),
            latches: (features & 0x0004 != 0).then_some(Latches::from_raw(port_times, epu)),
            t_diff,
        }
    }
}

/// Where a slave is attached upstream.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::port::Port;
/// use ecdc_core::dc::topology::{Link, SlaveSample, Topology};
///
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples)?;
/// // Slave 1 hangs off port 1 of slave 0.
/// assert_eq!(
///     topo.node(1).and_then(|n| n.parent),
///     Some(Link {
///         slave: 0,
///         port: Port::P1
///     })
/// );
/// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Link {
    /// Index (auto-increment position) of the upstream slave.
    pub slave: u16,
    /// The upstream slave's port this slave is wired to.
    pub port: Port,
}

/// One slave in the reconstructed tree.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::port::Port;
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples)?;
/// let first = topo
///     .node(0)
///     .ok_or(ecdc_core::dc::topology::TopologyError::Capacity)?;
/// assert_eq!(first.entry, Port::P0);
/// assert_eq!(first.parent, None); // wired to the master
/// assert_eq!(first.children, [None, Some(1), None, None]);
/// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Node {
    /// Port wired upstream (towards the master).
    pub entry: Port,
    /// Open ports (from DL status).
    pub ports: PortSet,
    /// Upstream slave; `None` for the slave wired to the master.
    pub parent: Option<Link>,
    /// Downstream slave per port number (`None` for the entry port and closed ports).
    pub children: [Option<u16>; 4],
}

impl Node {
    const EMPTY: Node = Node {
        entry: Port::P0,
        ports: PortSet::EMPTY,
        parent: None,
        children: [None; 4],
    };

    /// Number of downstream (non-entry) open ports.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples)?;
    /// let counts = topo.nodes().iter().map(|n| n.downstream_ports());
    /// assert!(counts.eq([1, 0])); // slave 1 ends the line
    /// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
    /// ```
    pub fn downstream_ports(&self) -> u32 {
        self.ports.len().saturating_sub(1)
    }

    /// The last open port the frame visits before leaving through the entry port (the entry
    /// port itself for a line end).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples)?;
    /// let last = topo.nodes().iter().map(|n| n.last_port());
    /// // Slave 0 last sees the frame at port 1 (coming back); the line end only at its entry.
    /// assert!(last.eq([Port::P1, Port::P0]));
    /// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
    /// ```
    pub fn last_port(&self) -> Port {
        self.ports.prev_before(self.entry).unwrap_or(self.entry)
    }
}

/// Why the topology could not be reconstructed.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::port::Port;
/// use ecdc_core::dc::topology::{SlaveSample, Topology, TopologyError};
///
/// // One slave reports port 1 open, but no second slave answered behind it.
/// let samples = [SlaveSample::from_registers(
///     0x5A00,
///     0x000C,
///     [1_000, 2_000, 0, 0],
///     1_000,
///     0,
/// )];
/// assert_eq!(
///     Topology::<8>::build(&samples),
///     Err(TopologyError::DanglingPort {
///         slave: 0,
///         port: Port::P1
///     })
/// );
/// // A slave without any open port cannot have been reached.
/// let dead = [SlaveSample::from_registers(0x0000, 0x0000, [0; 4], 0, 0)];
/// assert_eq!(
///     Topology::<8>::build(&dead),
///     Err(TopologyError::NoOpenPort { slave: 0 })
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum TopologyError {
    /// More slaves than the capacity `N` (or than `u16` positions).
    Capacity,
    /// The slave has no open port, so no frame could have reached it.
    NoOpenPort {
        /// Auto-increment position.
        slave: u16,
    },
    /// No earlier slave has an unvisited open port for this slave to hang off.
    NoFreePort {
        /// Auto-increment position.
        slave: u16,
    },
    /// An open port with no slave behind it after the last slave (a redundancy ring, a
    /// non-EtherCAT device, or a wrong DL status).
    DanglingPort {
        /// Auto-increment position.
        slave: u16,
        /// The unused open port.
        port: Port,
    },
    /// The latched receive times do not increase along the processing order from the entry port.
    LatchOrder {
        /// Auto-increment position.
        slave: u16,
    },
}

impl core::fmt::Display for TopologyError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TopologyError::Capacity => write!(f, "more slaves than the configured capacity"),
            TopologyError::NoOpenPort { slave } => write!(f, "slave {slave} has no open port"),
            TopologyError::NoFreePort { slave } => {
                write!(f, "slave {slave}: no earlier slave has a free open port")
            }
            TopologyError::DanglingPort { slave, port } => {
                write!(
                    f,
                    "slave {slave}: open port {} leads to no slave",
                    port.number()
                )
            }
            TopologyError::LatchOrder { slave } => {
                write!(f, "slave {slave}: receive times not in processing order")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for TopologyError {}

/// The reconstructed tree for up to `N` slaves (REQ-DC-012).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::port::Port;
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// // Two DC slaves in a line, in auto-increment order.
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples)?;
/// assert_eq!(topo.len(), 2);
/// assert_eq!(
///     topo.node(0).map(|n| n.children[Port::P1.index()]),
///     Some(Some(1))
/// );
/// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Topology<const N: usize> {
    nodes: [Node; N],
    len: u16,
}

impl<const N: usize> Topology<N> {
    /// Reconstructs the tree from per-slave samples in auto-increment order.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::topology::{SlaveSample, Topology, TopologyError};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// assert_eq!(Topology::<8>::build(&samples)?.len(), 2);
    /// // Capacity is fixed at compile time.
    /// assert_eq!(Topology::<1>::build(&samples), Err(TopologyError::Capacity));
    /// # Ok::<(), TopologyError>(())
    /// ```
    pub fn build(samples: &[SlaveSample]) -> Result<Self, TopologyError> {
        let mut topo = Topology::new();
        let mut stack = [(0, Port::P0); N];
        topo.build_in_place(samples, &mut stack)?;
        Ok(topo)
    }

    /// An empty tree (no slaves), e.g. the initial value of a buffer for
    /// [`build_in_place`](Self::build_in_place).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::topology::Topology;
    ///
    /// let topo = Topology::<64>::new();
    /// assert!(topo.is_empty());
    /// assert_eq!(topo.node(0), None);
    /// ```
    pub const fn new() -> Self {
        Topology {
            nodes: [Node::EMPTY; N],
            len: 0,
        }
    }

    /// Makes `self` equal to [`Topology::new`] in place (no temporary of size `N`).
    pub(crate) fn clear(&mut self) {
        self.nodes.fill(Node::EMPTY);
        self.len = 0;
    }

    /// [`build`](Self::build) into `self`, with `stack` as the depth-first walk's working
    /// space: nothing of size `N` goes on the thread's stack. On `Err` the contents of `self`
    /// are unspecified (but valid); on `Ok` it equals what `build` returns.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// // Buffers that live as long as the master (e.g. in a static or a struct), so a large `N`
    /// // never lands on a small embedded stack.
    /// let mut topo = Topology::<64>::new();
    /// let mut stack = [(0u16, Port::P0); 64];
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// topo.build_in_place(&samples, &mut stack)?;
    /// assert_eq!(topo, Topology::<64>::build(&samples)?);
    /// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
    /// ```
    pub fn build_in_place(
        &mut self,
        samples: &[SlaveSample],
        stack: &mut [(u16, Port); N],
    ) -> Result<(), TopologyError> {
        self.nodes.fill(Node::EMPTY);
        self.len = 0;
        if samples.len() > N {
            return Err(TopologyError::Capacity);
        }
        let len = u16::try_from(samples.len()).map_err(|_| TopologyError::Capacity)?;
        // Replay of the depth-first walk: (slave, last port handed out). Only entries below
        // `depth` are read, and each is written before.
        let mut depth = 0usize;
        for (i, sample) in (0u16..).zip(samples) {
            let entry = entry_port(sample).ok_or(TopologyError::NoOpenPort { slave: i })?;
            if let Some(latches) = &sample.latches {
                check_latch_order(sample.ports, entry, latches)
                    .ok_or(TopologyError::LatchOrder { slave: i })?;
            }
            let parent = if i == 0 {
                None
            } else {
                Some(attach(&mut self.nodes, stack, &mut depth, i)?)
            };
            let node = self
                .nodes
                .get_mut(usize::from(i))
                .ok_or(TopologyError::Capacity)?;
            *node = Node {
                entry,
                ports: sample.ports,
                parent,
                children: [None; 4],
            };
            let top = stack.get_mut(depth).ok_or(TopologyError::Capacity)?;
            *top = (i, entry);
            depth = depth.saturating_add(1);
        }
        self.len = len;
        // Every open port must have been handed out.
        while let Some(d) = depth.checked_sub(1) {
            let (slave, cursor) = stack.get(d).copied().ok_or(TopologyError::Capacity)?;
            let node = self
                .node(usize::from(slave))
                .ok_or(TopologyError::Capacity)?;
            if let Some(port) = next_downstream(node, cursor) {
                return Err(TopologyError::DanglingPort { slave, port });
            }
            depth = d;
        }
        Ok(())
    }

    /// Number of slaves.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [SlaveSample::from_registers(
    ///     0x5600,
    ///     0x000C,
    ///     [90, 0, 0, 0],
    ///     90,
    ///     0,
    /// )];
    /// assert_eq!(Topology::<8>::build(&samples)?.len(), 1);
    /// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
    /// ```
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// Whether there are no slaves.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::topology::Topology;
    ///
    /// assert!(Topology::<8>::build(&[])?.is_empty());
    /// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
    /// ```
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The node of slave `i` (auto-increment position).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [SlaveSample::from_registers(
    ///     0x5600,
    ///     0x000C,
    ///     [90, 0, 0, 0],
    ///     90,
    ///     0,
    /// )];
    /// let topo = Topology::<8>::build(&samples)?;
    /// assert_eq!(topo.node(0).map(|n| n.entry), Some(Port::P0));
    /// assert_eq!(topo.node(1), None); // beyond the slaves found, not beyond N
    /// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
    /// ```
    pub fn node(&self, i: usize) -> Option<&Node> {
        self.nodes.get(..self.len())?.get(i)
    }

    /// All nodes in auto-increment order.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples)?;
    /// let parents = topo.nodes().iter().map(|n| n.parent.map(|link| link.slave));
    /// assert!(parents.eq([None, Some(0)]));
    /// # Ok::<(), ecdc_core::dc::topology::TopologyError>(())
    /// ```
    pub fn nodes(&self) -> &[Node] {
        self.nodes.get(..self.len()).unwrap_or(&[])
    }
}

impl<const N: usize> Default for Topology<N> {
    fn default() -> Self {
        Topology::new()
    }
}

/// REQ-DC-013: the entry port of a slave.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::port::Port;
/// use ecdc_core::dc::topology::{entry_port, SlaveSample};
///
/// // Wired upstream on port 1: port 1 latched first, port 0 after the excursion behind it.
/// let s = SlaveSample::from_registers(0x5A00, 0x000C, [2_000, 1_000, 0, 0], 1_000, 0);
/// assert_eq!(entry_port(&s), Some(Port::P1));
/// // Port 0 latched just before the 32-bit counter wrapped: still the earliest.
/// let s = SlaveSample::from_registers(0x5A00, 0x000C, [u32::MAX - 10, 500, 0, 0], 0, 0);
/// assert_eq!(entry_port(&s), Some(Port::P0));
/// ```
pub fn entry_port(sample: &SlaveSample) -> Option<Port> {
    match &sample.latches {
        Some(latches) => {
            let mut times = [None; 4];
            for (t, port) in times.iter_mut().zip(Port::PROCESSING_ORDER) {
                if sample.ports.contains(port) {
                    *t = Some(latches.at(port));
                }
            }
            let idx = PortTime::earliest(&times)?;
            Port::PROCESSING_ORDER.get(idx).copied()
        }
        None => sample.ports.first_in_processing_order(),
    }
}

/// Latched times must be non-decreasing along the processing order from the entry port (each
/// later port sees the frame come back later); all differences are taken by wrapping. The walk
/// round the ports is bounded by their number: an entry port that is not among `ports` never
/// comes round again and fails the check instead of looping.
fn check_latch_order(ports: PortSet, entry: Port, latches: &Latches) -> Option<()> {
    let mut prev = entry;
    for _ in 0..Port::PROCESSING_ORDER.len() {
        let next = ports.next_after(prev)?;
        if next == entry {
            return Some(());
        }
        if latches.at(next).wrapping_since(latches.at(prev)) < 0
            || latches.at(next).wrapping_since(latches.at(entry)) < 0
        {
            return None;
        }
        prev = next;
    }
    None
}

/// The open port after `cursor` (exclusive) and before the entry port, in processing order.
fn next_downstream(node: &Node, cursor: Port) -> Option<Port> {
    let next = node.ports.next_after(cursor)?;
    (next != node.entry).then_some(next)
}

/// Hangs slave `i` off the deepest slave on the stack that still has an unvisited open port.
fn attach<const N: usize>(
    nodes: &mut [Node; N],
    stack: &mut [(u16, Port); N],
    depth: &mut usize,
    i: u16,
) -> Result<Link, TopologyError> {
    loop {
        let d = depth
            .checked_sub(1)
            .ok_or(TopologyError::NoFreePort { slave: i })?;
        let (slave, cursor) = stack.get(d).copied().ok_or(TopologyError::Capacity)?;
        let node = nodes
            .get_mut(usize::from(slave))
            .ok_or(TopologyError::Capacity)?;
        if let Some(port) = next_downstream(node, cursor) {
            if let Some(child) = node.children.get_mut(port.index()) {
                *child = Some(i);
            }
            if let Some(top) = stack.get_mut(d) {
                *top = (slave, port);
            }
            return Ok(Link { slave, port });
        }
        *depth = d;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Latches are kept exactly when features bit 2 (DC) is set, whatever the other bits.
    #[test]
    fn from_registers_keeps_latches_of_dc_slaves() {
        let times = [1_000, 2_000, 0, 0];
        for (features, dc) in [
            (0x0004u16, true),
            (0xFFFF, true),
            (0x0008, false),
            (0xFFFB, false),
            (0, false),
        ] {
            let s = SlaveSample::from_registers(0x0200, features, times, 1_000, 7);
            assert_eq!(s.latches.is_some(), dc, "{features:#06x}");
            assert_eq!((s.ports, s.t_diff), (PortSet::from_dl_status(0x0200), 7));
        }
    }

    /// Errors name the slave and what is wrong with it.
    #[test]
    fn error_messages_name_the_slave() {
        let e = TopologyError::DanglingPort {
            slave: 7,
            port: Port::P3,
        };
        assert_eq!(
            std::format!("{e}"),
            "slave 7: open port 3 leads to no slave"
        );
        assert_eq!(
            std::format!("{}", TopologyError::Capacity),
            "more slaves than the configured capacity"
        );
    }

    fn sample(ports: &[Port], times: Option<[u32; 4]>) -> SlaveSample {
        let mut set = PortSet::EMPTY;
        for p in ports {
            set = set.with(*p);
        }
        SlaveSample {
            ports: set,
            latches: times.map(|t| Latches::from_raw(t, u64::from(t[0]))),
            t_diff: 0,
        }
    }

    #[test]
    fn latch_order_walk_is_bounded() {
        use Port::*;
        let l = Latches::from_raw([0, 100, 200, 50], 0);
        let open = PortSet::EMPTY.with(P0).with(P3).with(P1).with(P2);
        assert_eq!(check_latch_order(open, P0, &l), Some(()));
        assert_eq!(check_latch_order(open, P1, &l), None);
        // An entry port that is not open never comes round again: the check fails, it does
        // not loop.
        // (Equal times never fail the order test, so only the bound ends the walk.)
        let same = Latches::from_raw([7; 4], 7);
        let without_entry = PortSet::EMPTY.with(P1).with(P2);
        assert_eq!(check_latch_order(without_entry, P0, &same), None);
        assert_eq!(
            check_latch_order(without_entry.with(P0), P0, &same),
            Some(())
        );
    }

    /// `downstream_ports` counts a node's open ports but its entry; `is_empty` and `clear`
    /// agree with `new`.
    #[test]
    fn counts_and_clear() {
        use Port::*;
        let s = [
            sample(&[P0, P1, P3], Some([0, 5000, 0, 900])),
            sample(&[P0], Some([100, 0, 0, 0])),
            sample(&[P0], Some([1000, 0, 0, 0])),
        ];
        let mut t = Topology::<4>::build(&s).unwrap();
        let down: std::vec::Vec<u32> = (0..3)
            .map(|i| t.node(i).unwrap().downstream_ports())
            .collect();
        assert_eq!(down, [2, 0, 0]);
        assert_eq!(Node::EMPTY.downstream_ports(), 0);
        assert!(!t.is_empty() && Topology::<4>::new().is_empty());
        t.clear();
        assert_eq!(t, Topology::<4>::new());
        assert!(t.is_empty());
    }

    #[test]
    fn line_and_cross() {
        use Port::*;
        // S0 line, S1 cross (0,3,1,2), S2 on port 3, S3 on port 1 with S4 below, S5 on port 2.
        let s = [
            sample(&[P0, P1], Some([0, 5000, 0, 0])),
            sample(&[P0, P1, P2, P3], Some([100, 2000, 4000, 600])),
            sample(&[P0], Some([7, 0, 0, 0])),
            sample(&[P0, P1], Some([10, 900, 0, 0])),
            sample(&[P0], None),
            sample(&[P0], Some([3, 0, 0, 0])),
        ];
        let t = Topology::<8>::build(&s).unwrap();
        assert_eq!(t.len(), 6);
        assert_eq!(t.node(1).unwrap().parent, Some(Link { slave: 0, port: P1 }));
        assert_eq!(t.node(2).unwrap().parent, Some(Link { slave: 1, port: P3 }));
        assert_eq!(t.node(3).unwrap().parent, Some(Link { slave: 1, port: P1 }));
        assert_eq!(t.node(4).unwrap().parent, Some(Link { slave: 3, port: P1 }));
        assert_eq!(t.node(5).unwrap().parent, Some(Link { slave: 1, port: P2 }));
        assert_eq!(
            t.node(1).unwrap().children,
            [None, Some(3), Some(5), Some(2)]
        );
    }

    #[test]
    fn wrap_safe_entry_port() {
        use Port::*;
        // Port 0 latched just before the 32-bit wrap, port 1 after it.
        let s = [
            sample(&[P0, P1], Some([0xFFFF_FF00, 0x0000_0400, 0, 0])),
            sample(&[P0], None),
        ];
        let t = Topology::<2>::build(&s).unwrap();
        assert_eq!(t.node(0).unwrap().entry, P0);
        // Entry on port 1 (wired "backwards"): its latch is the earliest.
        let s = [
            sample(&[P0, P1], Some([900, 100, 0, 0])),
            sample(&[P2], None),
        ];
        let t = Topology::<2>::build(&s).unwrap();
        assert_eq!(t.node(0).unwrap().entry, P1);
        assert_eq!(t.node(1).unwrap().parent, Some(Link { slave: 0, port: P0 }));
    }

    #[test]
    fn typed_errors() {
        use Port::*;
        let end = sample(&[P0], None);
        assert_eq!(
            Topology::<4>::build(&[end, end]),
            Err(TopologyError::NoFreePort { slave: 1 })
        );
        assert_eq!(
            Topology::<4>::build(&[sample(&[P0, P1], None)]),
            Err(TopologyError::DanglingPort { slave: 0, port: P1 })
        );
        assert_eq!(
            Topology::<1>::build(&[end, end]),
            Err(TopologyError::Capacity)
        );
        assert_eq!(
            Topology::<4>::build(&[sample(&[], None)]),
            Err(TopologyError::NoOpenPort { slave: 0 })
        );
        // Port 3 returns after port 1 although it is visited first: stale latch.
        let bad = sample(&[P0, P1, P3], Some([0, 500, 0, 900]));
        assert_eq!(
            Topology::<4>::build(&[bad, end, end]),
            Err(TopologyError::LatchOrder { slave: 0 })
        );
        assert!(Topology::<4>::build(&[]).unwrap().is_empty());
    }
}
