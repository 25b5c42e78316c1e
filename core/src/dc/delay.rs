//! Propagation delays from latched receive times (REQ-DC-014..019).
//!
//! The delay of slave `c` is the time the latch frame needs from the reference clock to `c`:
//! the value for System Time Delay 0x0928 (REQ-CONV-005). It is built hop by hop along the tree
//! from the nearest upstream slave `a` that has latches:
//!
//! ```text
//!   a: entry e ... q ──(port p)── [non-DC n₁ … nₖ] ── c: entry e_c … last
//!      t_a(q) − t_a(e): time already spent inside a before it sends towards c
//!      X = t_a(p) − t_a(q): excursion through everything behind p (out and back)
//!      rtt_c = t_c(last) − t_c(e_c): c's own subtree, seen from c
//!   2·(arrival at c − stamp at q) = X − rtt_c + t_Diff(a)·[q→p is a processing hop]
//!                                   − t_Diff(c)·[last→e_c is a processing hop]
//!                                   ± t_Diff(nᵢ) (+ if nᵢ's downstream hop is processing)
//! ```
//!
//! Why it is exact: the excursion is `hop_a(q→p) + 2·Σcables + Σ(hops through nᵢ) +
//! rtt_c + hop_c(last→e_c)`, while the arrival at `c` is `hop_a(q→p) + Σcables + Σ(downstream
//! hops through nᵢ)` after the stamp at `q`; with one common `t_F` and per-ESC `t_P = t_F +
//! t_Diff` everything except the listed `t_Diff` terms cancels. Seed 000 eq. 5/13/23 and the
//! datasheet's `t_AB`, `t_BC`, `t_CD` are special cases (a line: `q = e`, every hop from port 0
//! is processing, the line end's `last→e` hop too, so each hop gets `+t_Diff` except the last).
//!
//! All port-time differences are wrapping 32-bit differences taken relative to one slave's own
//! stamps (REQ-DC-016), so a wrap of any slave's clock during the latch is harmless. Twice the
//! delay is accumulated exactly in `i64` and halved once at the end (round half up), so rounding
//! never accumulates along a path (REQ-DC-014). Several latch rounds can be averaged by adding
//! their sums ([`Delays::accumulate`]) before the single division, which reduces the 10 ns
//! stamp quantisation of real ESCs. The arithmetic of one hop is [`twice_delay_step`], written
//! once against [`crate::num::Word`] so the P3 SMT proof in `ecdc-proofs` checks this code.
//!
//! Non-DC slaves (no latches) between DC slaves act as wire (REQ-DC-017): they must have exactly
//! two open ports, because the excursion seen by `a` would otherwise include branches no DC
//! slave timed. The datasheet requires receive times on every ESC with more than two ports.
//!
//! The whole pipeline for two 64-bit slaves in a line, from the registers read after the latch
//! to the values written back:
//!
//! ```
//! use ecdc_core::dc::{delay, offset, topology::{SlaveSample, Topology}};
//! use ecdc_core::time::SystemTime;
//! // DL status: ports 0+1 open (0x5A00) / only port 0 open (0x5600); features: 64-bit DC.
//! let samples = [
//!     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 0x7_0000_03E8, 0),
//!     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 0x2_0000_005A, 0),
//! ];
//! let topo = Topology::<8>::build(&samples).unwrap();
//! let delays = delay::compute(&samples, &topo, 0).unwrap(); // slave 0 is the reference
//! assert_eq!(delays.register_value(1), Ok(500)); // 0x0928 of slave 1: (2000 − 1000) / 2
//! let master = SystemTime(1_000_000_000); // sampled just before the latch (REQ-DC-002)
//! let entry = topo.node(1).unwrap().entry;
//! let latches = samples[1].latches.as_ref().unwrap();
//! let off = offset::initial_offset(
//!     master,
//!     delays.ns(1).unwrap(),
//!     offset::entry_local_time(latches, entry),
//!     offset::ClockWidth::Bits64,
//! );
//! // slave 1's system time when the frame reached it = reference's time then
//! assert_eq!(0x2_0000_005A_u64.wrapping_add(off.as_u64()), 1_000_000_500);
//! assert_eq!(off.to_register().as_slice().len(), 8); // exactly 8 bytes to 0x0920
//! ```

use super::port::Port;
use super::topology::{SlaveSample, Topology};
use crate::num::{overflowing_add, overflowing_sub, Logic, Word};

/// Why delays could not be computed. Every variant names the offending slave (auto-increment
/// position) so the caller can report it; no delay is produced from such input.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::{self, DelayError};
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
/// // There is no slave 5 to be the reference clock.
/// assert_eq!(
///     delay::compute(&samples, &topo, 5).map(|d| d.len()),
///     Err(DelayError::BadReference { slave: 5 })
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum DelayError {
    /// `samples` and the topology disagree in length, or an index is out of range.
    Mismatch,
    /// The chosen reference clock has no latches (or is out of range).
    BadReference {
        /// The requested reference.
        slave: u16,
    },
    /// A slave with latches has no upstream slave with latches, so nothing times its path
    /// (e.g. it sits in a second branch of a non-DC junction above the first DC slave).
    NoUpstreamDc {
        /// The slave without a timed path.
        slave: u16,
    },
    /// A non-DC slave with more than two open ports lies between two DC slaves (REQ-DC-017).
    NonDcJunction {
        /// The non-DC junction.
        slave: u16,
    },
    /// The excursion measured upstream is shorter than the slave's own round trip: latches are
    /// stale or do not belong to one frame.
    Inconsistent {
        /// The slave whose hop was negative.
        slave: u16,
    },
    /// The hop became negative only through the `t_Diff` corrections: the configured `t_Diff`
    /// values cannot be right.
    NegativeHop {
        /// The slave whose hop was negative.
        slave: u16,
    },
    /// A delay does not fit the target (i64 accumulation, or the u32 register).
    Overflow {
        /// The slave concerned.
        slave: u16,
    },
    /// The slave comes before the reference clock in processing order: its delay is negative
    /// and 0x0928 cannot hold it (REQ-DC-018).
    BeforeReference {
        /// The slave concerned.
        slave: u16,
    },
    /// [`Delays::accumulate`] got rounds with different slaves, reference or DC sets.
    RoundMismatch,
}

impl core::fmt::Display for DelayError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DelayError::Mismatch => write!(f, "samples and topology do not match"),
            DelayError::BadReference { slave } => {
                write!(f, "reference clock {slave} has no receive-time latches")
            }
            DelayError::NoUpstreamDc { slave } => {
                write!(f, "slave {slave}: no upstream DC slave times its path")
            }
            DelayError::NonDcJunction { slave } => {
                write!(f, "slave {slave}: non-DC junction between DC slaves")
            }
            DelayError::Inconsistent { slave } => {
                write!(
                    f,
                    "slave {slave}: receive times inconsistent (stale latch?)"
                )
            }
            DelayError::NegativeHop { slave } => {
                write!(f, "slave {slave}: configured t_Diff makes a hop negative")
            }
            DelayError::Overflow { slave } => write!(f, "slave {slave}: delay out of range"),
            DelayError::BeforeReference { slave } => {
                write!(
                    f,
                    "slave {slave} precedes the reference clock (negative delay)"
                )
            }
            DelayError::RoundMismatch => write!(f, "latch rounds differ in slaves or reference"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for DelayError {}

/// Propagation delays relative to a reference clock, for up to `N` slaves (REQ-DC-018).
///
/// Internally an exact fraction per slave (`sum / weight`, weight = 2 × rounds) so averaging
/// several latch rounds rounds only once.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::{self, DelayError};
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// // Slave 0 latched the frame at port 0 and again at port 1 1 µs later: the cable and
/// // slave 1 behind port 1 take 500 ns each way.
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
/// let delays = delay::compute(&samples, &topo, 0)?;
/// assert_eq!(delays.ns(0), Some(0)); // the reference clock itself
/// assert_eq!(delays.register_value(1)?, 500); // written to slave 1's 0x0928
/// # Ok::<(), DelayError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Delays<const N: usize> {
    sum: [Option<i64>; N],
    weight: i64,
    len: u16,
    reference: u16,
}

impl<const N: usize> Delays<N> {
    /// No delays: no slave, no round (every [`ns`](Self::ns) is `None`). The initial value of
    /// an output buffer for [`compute_in_place`].
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::Delays;
    ///
    /// let d = Delays::<8>::new();
    /// assert!(d.is_empty());
    /// assert_eq!((d.rounds(), d.ns(0)), (0, None));
    /// ```
    pub const fn new() -> Self {
        Delays {
            sum: [None; N],
            weight: 0,
            len: 0,
            reference: 0,
        }
    }

    /// Makes `self` equal to `other` without a temporary of size `N` on the stack.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError, Delays};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
    /// // Keep the last good result in a long-lived buffer.
    /// let mut last_good = Delays::<8>::new();
    /// last_good.copy_from(&delay::compute(&samples, &topo, 0)?);
    /// assert_eq!(last_good.ns(1), Some(500));
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn copy_from(&mut self, other: &Delays<N>) {
        self.sum.copy_from_slice(&other.sum);
        self.weight = other.weight;
        self.len = other.len;
        self.reference = other.reference;
    }

    /// Whether this holds at least one round (not [`Delays::new`] or cleared).
    pub(crate) fn has_rounds(&self) -> bool {
        self.weight != 0
    }

    /// Back to [`Delays::new`], in place.
    pub(crate) fn clear(&mut self) {
        self.sum.fill(None);
        self.weight = 0;
        self.len = 0;
        self.reference = 0;
    }

    /// Number of slaves covered (latched or not).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// // A DC slave followed by a slave without DC: both are covered, only one has a delay.
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x0000, [0; 4], 0, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
    /// let delays = delay::compute(&samples, &topo, 0)?;
    /// assert_eq!(delays.len(), 2);
    /// assert_eq!(delays.ns(1), None);
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// Whether no slave is covered.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [SlaveSample::from_registers(
    ///     0x5600,
    ///     0x000C,
    ///     [90, 0, 0, 0],
    ///     90,
    ///     0,
    /// )];
    /// let topo = Topology::<8>::build(&samples).expect("a single slave");
    /// assert!(!delay::compute(&samples, &topo, 0)?.is_empty());
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The reference clock's position.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
    /// assert_eq!(delay::compute(&samples, &topo, 1)?.reference(), 1);
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn reference(&self) -> u16 {
        self.reference
    }

    /// Number of latch rounds averaged.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
    /// let mut delays = delay::compute(&samples, &topo, 0)?;
    /// assert_eq!(delays.rounds(), 1);
    /// delays.accumulate(&delay::compute(&samples, &topo, 0)?)?;
    /// assert_eq!(delays.rounds(), 2);
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn rounds(&self) -> i64 {
        self.weight.checked_div(2).unwrap_or(0)
    }

    /// Delay of slave `i` relative to the reference in ns, rounded to nearest (ties up);
    /// negative for slaves before the reference; `None` for slaves without latches.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
    /// // With slave 1 as the reference, slave 0 sees the frame 500 ns before it.
    /// let delays = delay::compute(&samples, &topo, 1)?;
    /// assert_eq!(delays.ns(0), Some(-500));
    /// assert_eq!(delays.ns(1), Some(0));
    /// assert_eq!(delays.ns(2), None);
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn ns(&self, i: usize) -> Option<i64> {
        let sum = (*self.sum.get(..self.len())?.get(i)?)?;
        // round(sum / weight), ties towards +∞: ⌊(sum + ⌊weight/2⌋) / weight⌋ (weight even).
        sum.checked_add(self.weight.checked_div(2)?)?
            .checked_div_euclid(self.weight)
    }

    /// The exact value as `(numerator, denominator)` ns: twice the delay summed over rounds, and
    /// twice the number of rounds. For tests and diagnostics.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// // A 1 001 ns round trip: the delay is 500.5 ns, kept exactly as 1001 / 2.
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_001, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
    /// let delays = delay::compute(&samples, &topo, 0)?;
    /// assert_eq!(delays.exact(1), Some((1_001, 2)));
    /// assert_eq!(delays.ns(1), Some(501)); // ties round up
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn exact(&self, i: usize) -> Option<(i64, i64)> {
        let sum = (*self.sum.get(..self.len())?.get(i)?)?;
        Some((sum, self.weight))
    }

    /// REQ-DC-018: the value to write to System Time Delay 0x0928 (4 bytes) for slave `i`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let samples = [
    ///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
    ///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    /// ];
    /// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
    /// let delays = delay::compute(&samples, &topo, 0)?;
    /// assert_eq!(delays.register_value(1)?.to_le_bytes(), [0xF4, 0x01, 0, 0]); // 500
    /// // 0x0928 cannot hold a slave before the reference.
    /// let delays = delay::compute(&samples, &topo, 1)?;
    /// assert_eq!(delays.register_value(0), Err(DelayError::BeforeReference { slave: 0 }));
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn register_value(&self, i: usize) -> Result<u32, DelayError> {
        let slave = u16::try_from(i).map_err(|_| DelayError::Mismatch)?;
        let ns = self.ns(i).ok_or(DelayError::Mismatch)?;
        if ns < 0 {
            return Err(DelayError::BeforeReference { slave });
        }
        u32::try_from(ns).map_err(|_| DelayError::Overflow { slave })
    }

    /// Adds another latch round (same slaves, reference and DC set) for averaging.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::{self, DelayError};
    /// use ecdc_core::dc::topology::{SlaveSample, Topology};
    ///
    /// let round = |port1: u32| {
    ///     [
    ///         SlaveSample::from_registers(0x5A00, 0x000C, [1_000, port1, 0, 0], 1_000, 0),
    ///         SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
    ///     ]
    /// };
    /// let topo = Topology::<8>::build(&round(2_000)).expect("a line of two slaves");
    /// // Two latch rounds, 10 ns apart (the stamp resolution): 500 and 505 average to 502.5.
    /// let mut delays = delay::compute(&round(2_000), &topo, 0)?;
    /// delays.accumulate(&delay::compute(&round(2_010), &topo, 0)?)?;
    /// assert_eq!(delays.exact(1), Some((2_010, 4)));
    /// assert_eq!(delays.ns(1), Some(503));
    /// # Ok::<(), DelayError>(())
    /// ```
    pub fn accumulate(&mut self, other: &Delays<N>) -> Result<(), DelayError> {
        if other.len != self.len || other.reference != self.reference {
            return Err(DelayError::RoundMismatch);
        }
        for (i, (a, b)) in (0u16..).zip(self.sum.iter_mut().zip(other.sum.iter())) {
            match (a.as_mut(), b) {
                (Some(a), Some(b)) => {
                    *a = a.checked_add(*b).ok_or(DelayError::Overflow { slave: i })?;
                }
                (None, None) => {}
                _ => return Err(DelayError::RoundMismatch),
            }
        }
        self.weight = self
            .weight
            .checked_add(other.weight)
            .ok_or(DelayError::Overflow {
                slave: self.reference,
            })?;
        Ok(())
    }
}

impl<const N: usize> Default for Delays<N> {
    fn default() -> Self {
        Delays::new()
    }
}

// implements: REQ-DC-061
/// REQ-DC-014..018: computes every latched slave's propagation delay relative to `reference`
/// (usually the first slave with a system time) from one latch round.
///
/// The walk itself is [`walk`], written once against [`Word`] so the P3 SMT proof runs it on
/// symbolic stamps; this runs it on `u64` and turns its flags into the first error in
/// processing order (an arithmetic failure of an earlier slave before a structural one of a
/// later slave, as a hop-by-hop walk with early returns reports them).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::{self, DelayError};
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// // Slave 0 has t_Diff = 20 ns (its processing hop is 20 ns slower than forwarding).
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 20),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
/// let delays = delay::compute(&samples, &topo, 0)?;
/// // The outbound hop through slave 0's EPU is the slower one: (1000 + 20) / 2.
/// assert_eq!(delays.ns(1), Some(510));
/// # Ok::<(), DelayError>(())
/// ```
pub fn compute<const N: usize>(
    samples: &[SlaveSample],
    topology: &Topology<N>,
    reference: usize,
) -> Result<Delays<N>, DelayError> {
    let mut scratch = DelayScratch::new();
    let mut out = Delays::new();
    compute_in_place(samples, topology, reference, &mut scratch, &mut out)?;
    Ok(out)
}

/// The working space of [`compute_in_place`]: the walk's input and output for up to `N`
/// slaves. Kept by the caller (e.g. inside a long-lived state machine) so that a delay
/// computation puts nothing of size `N` on the thread's stack.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::{self, DelayError, DelayScratch, Delays};
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// // Long-lived buffers (a static, or a field of the master's state) for 256 slaves.
/// let mut scratch = DelayScratch::<256>::new();
/// let mut delays = Delays::<256>::new();
/// let samples = [SlaveSample::from_registers(
///     0x5600,
///     0x000C,
///     [90, 0, 0, 0],
///     90,
///     0,
/// )];
/// let topo = Topology::<256>::build(&samples).expect("a single slave");
/// delay::compute_in_place(&samples, &topo, 0, &mut scratch, &mut delays)?;
/// assert_eq!(delays.ns(0), Some(0));
/// # Ok::<(), DelayError>(())
/// ```
#[derive(Clone)]
pub struct DelayScratch<const N: usize> {
    slaves: [WalkSlave<u64>; N],
    walk: Walk<u64, N>,
}

impl<const N: usize> DelayScratch<N> {
    /// Fresh working space (its contents never carry over between computations).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::DelayScratch;
    ///
    /// let scratch = DelayScratch::<64>::new();
    /// assert_eq!(format!("{scratch:?}"), "DelayScratch");
    /// ```
    pub const fn new() -> Self {
        DelayScratch {
            slaves: [WalkSlave::non_dc(); N],
            walk: Walk::new(),
        }
    }
}

impl<const N: usize> Default for DelayScratch<N> {
    fn default() -> Self {
        DelayScratch::new()
    }
}

impl<const N: usize> core::fmt::Debug for DelayScratch<N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("DelayScratch")
    }
}

/// [`compute`] into `out`, with `scratch` as working space: nothing of size `N` goes on the
/// thread's stack. On `Ok`, `out` equals what `compute` returns; on `Err` its contents are
/// unspecified (but valid).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::{self, DelayError, DelayScratch, Delays};
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
/// let (mut scratch, mut out) = (DelayScratch::new(), Delays::new());
/// delay::compute_in_place(&samples, &topo, 0, &mut scratch, &mut out)?;
/// assert_eq!(out, delay::compute(&samples, &topo, 0)?);
/// # Ok::<(), DelayError>(())
/// ```
pub fn compute_in_place<const N: usize>(
    samples: &[SlaveSample],
    topology: &Topology<N>,
    reference: usize,
    scratch: &mut DelayScratch<N>,
    out: &mut Delays<N>,
) -> Result<(), DelayError> {
    if samples.len() != topology.len() {
        return Err(DelayError::Mismatch);
    }
    let len = u16::try_from(samples.len()).map_err(|_| DelayError::Mismatch)?;
    let ref16 = u16::try_from(reference).unwrap_or(u16::MAX);
    let DelayScratch {
        slaves,
        walk: walked,
    } = scratch;
    for (slot, sample) in slaves.iter_mut().zip(samples) {
        *slot = WalkSlave::from_sample(sample);
    }
    walk_in_place(
        slaves.get(..samples.len()).ok_or(DelayError::Mismatch)?,
        topology,
        reference,
        walked,
    )?;
    for (c, hop) in (0u16..).zip(walked.hops.iter()) {
        if let Some(hop) = hop {
            hop_result(hop, c)?;
        }
    }
    if let Some(e) = walked.stopped {
        return Err(e);
    }
    out.sum.fill(None);
    out.weight = 2;
    out.len = len;
    out.reference = ref16;
    for (i, (out, rel)) in (0u16..).zip(out.sum.iter_mut().zip(walked.twice.iter())) {
        if let Some((twice, overflow)) = rel {
            if *overflow {
                return Err(DelayError::Overflow { slave: i });
            }
            *out = Some(twice.to_signed());
        }
    }
    Ok(())
}

/// One slave's input to [`walk`] over a word type `W` (at least 64 bits wide): the four 32-bit
/// receive-time latches zero-extended into `W` (`None` for a slave without DC), and `t_Diff`
/// sign-extended.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::WalkSlave;
///
/// // The walk's input, built by hand: 32-bit stamps widened to the word, t_Diff = −20 ns.
/// let s = WalkSlave::<u64> {
///     stamps: Some([1_000, 2_000, 0, 0]),
///     t_diff: (-20i64) as u64,
/// };
/// assert_eq!(s.stamps.map(|t| t[1] - t[0]), Some(1_000));
/// ```
#[derive(Debug, Clone, Copy)]
pub struct WalkSlave<W: Word> {
    /// Receive Time Port 0..3, indexed by port number, as 32-bit values in the word.
    pub stamps: Option<[W; 4]>,
    /// `t_Diff` of the ESC, two's complement.
    pub t_diff: W,
}

impl WalkSlave<u64> {
    /// The walk input of a sample.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::WalkSlave;
    /// use ecdc_core::dc::topology::SlaveSample;
    ///
    /// let sample = SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, -20);
    /// let s = WalkSlave::from_sample(&sample);
    /// assert_eq!(s.stamps, Some([1_000, 2_000, 0, 0]));
    /// assert_eq!(s.t_diff as i64, -20);
    /// ```
    pub fn from_sample(sample: &SlaveSample) -> WalkSlave<u64> {
        WalkSlave {
            stamps: sample
                .latches
                .as_ref()
                .map(|l| l.ports.map(|t| u64::from(t.raw()))),
            t_diff: u64::from_signed(i64::from(sample.t_diff)),
        }
    }

    const fn non_dc() -> WalkSlave<u64> {
        WalkSlave {
            stamps: None,
            t_diff: 0,
        }
    }
}

/// The checks of one hop of the walk (slave `c` from its nearest latched ancestor), in the order
/// [`compute`] reports them.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::{self, DelayError, WalkSlave};
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
/// let walk = delay::walk(&samples.map(|s| WalkSlave::from_sample(&s)), &topo, 0)?;
/// let hop = walk.hops[1].ok_or(DelayError::Mismatch)?;
/// assert!(!hop.stale && !hop.non_dc_overflow);
/// assert_eq!(hop.step.hop2, 1_000);
/// # Ok::<(), DelayError>(())
/// ```
#[derive(Clone, Copy)]
pub struct HopChecks<W: Word> {
    /// The signed sum of the non-DC slaves' `t_Diff` left the signed range.
    pub non_dc_overflow: W::Bool,
    /// A wrapping 32-bit stamp difference (t(q) − t(e), t(p) − t(q) at the ancestor, or c's own
    /// round trip) is negative: the latches are stale.
    pub stale: W::Bool,
    /// The hop arithmetic and its flags.
    pub step: HopStep<W>,
}

/// What [`walk`] computed for one latch round.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::{self, DelayError, WalkSlave};
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
/// let walk = delay::walk(&samples.map(|s| WalkSlave::from_sample(&s)), &topo, 0)?;
/// // Twice the delay, with "left the signed range" = false.
/// assert_eq!(walk.twice[..2], [Some((0, false)), Some((1_000, false))]);
/// assert_eq!(walk.stopped, None);
/// # Ok::<(), DelayError>(())
/// ```
pub struct Walk<W: Word, const N: usize> {
    /// Per latched slave: twice its delay from the reference (`abs2 − abs2(reference)`, modulo
    /// 2^N) and whether that subtraction left the signed range. `None` for slaves without
    /// latches, and for every slave when the walk stopped.
    pub twice: [Option<(W, W::Bool)>; N],
    /// Per latched slave after the first: the checks of its hop (`None` for the root, slaves
    /// without latches, and slaves after a structural error).
    pub hops: [Option<HopChecks<W>>; N],
    /// The structural error (from the topology alone, never from a stamp value) at which the
    /// walk stopped; hops before it are in `hops`.
    pub stopped: Option<DelayError>,
}

impl<W: Word, const N: usize> Walk<W, N> {
    /// An empty result (no slave, not stopped): the initial value of the output buffer that
    /// [`compute_in_place`] fills through a [`DelayScratch`].
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::delay::Walk;
    ///
    /// let w = Walk::<u64, 8>::new();
    /// assert!(w.twice.iter().all(Option::is_none));
    /// assert_eq!(w.stopped, None);
    /// ```
    pub const fn new() -> Self {
        Walk {
            twice: [None; N],
            hops: [None; N],
            stopped: None,
        }
    }
}

impl<W: Word, const N: usize> Default for Walk<W, N> {
    fn default() -> Self {
        Walk::new()
    }
}

impl<W: Word, const N: usize> Clone for Walk<W, N> {
    fn clone(&self) -> Self {
        Walk {
            twice: self.twice,
            hops: self.hops,
            stopped: self.stopped,
        }
    }
}

/// REQ-DC-014..018: the delay walk over any [`Word`] of at least 64 bits: twice each latched
/// slave's delay from the first latched slave (the root of the timed tree, delay 0), hop by hop
/// through [`twice_delay_step`], then relative to `reference`. Which slaves, ports and `t_Diff`
/// terms each hop uses depends only on the topology and on which slaves have latches, never on
/// stamp values, so on symbolic stamps the walk is one straight-line formula per topology.
/// `Err` only for a reference without latches or mismatched lengths (checked before any hop).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::{self, DelayError, WalkSlave};
/// use ecdc_core::dc::topology::{SlaveSample, Topology};
///
/// let samples = [
///     SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 1_000, 0),
///     SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 90, 0),
/// ];
/// let topo = Topology::<8>::build(&samples).expect("a line of two slaves");
/// let slaves = samples.map(|s| WalkSlave::from_sample(&s));
/// let walk = delay::walk(&slaves, &topo, 0)?;
/// // `compute` is this walk on u64, halved once.
/// assert_eq!(walk.twice[1].map(|(twice, _)| twice / 2), Some(500));
/// # Ok::<(), DelayError>(())
/// ```
pub fn walk<W: Word, const N: usize>(
    slaves: &[WalkSlave<W>],
    topology: &Topology<N>,
    reference: usize,
) -> Result<Walk<W, N>, DelayError> {
    let mut out = Walk::new();
    walk_in_place(slaves, topology, reference, &mut out)?;
    Ok(out)
}

/// [`walk`] into `out` (whatever it held before): nothing of size `N` goes on the thread's
/// stack. On `Ok`, `out` equals what `walk` returns; on `Err` its contents are unspecified.
/// While the walk runs, `out.twice` holds each latched slave's doubled delay from the root
/// (the hops read their ancestors' there); it becomes relative to `reference` at the end.
pub(crate) fn walk_in_place<W: Word, const N: usize>(
    slaves: &[WalkSlave<W>],
    topology: &Topology<N>,
    reference: usize,
    out: &mut Walk<W, N>,
) -> Result<(), DelayError> {
    if slaves.len() != topology.len() {
        return Err(DelayError::Mismatch);
    }
    let bad_ref = DelayError::BadReference {
        slave: u16::try_from(reference).unwrap_or(u16::MAX),
    };
    if slaves.get(reference).ok_or(bad_ref)?.stamps.is_none() {
        return Err(bad_ref);
    }
    out.twice.fill(None);
    out.hops.fill(None);
    out.stopped = None;
    let zero = W::lit(0);
    let no = zero.ult(zero);
    let mut root_seen = false;
    for (i, slave) in (0u16..).zip(slaves) {
        if slave.stamps.is_none() {
            continue;
        }
        let value = if root_seen {
            match hop(slaves, topology, &out.twice, i) {
                Ok(checks) => {
                    let hop_slot = out.hops.get_mut(usize::from(i));
                    let hop_slot = hop_slot.ok_or(DelayError::Mismatch)?;
                    *hop_slot = Some(checks);
                    checks.step.abs2
                }
                Err(e) => {
                    out.twice.fill(None);
                    out.stopped = Some(e);
                    return Ok(());
                }
            }
        } else {
            root_seen = true;
            W::lit(0)
        };
        let slot = out
            .twice
            .get_mut(usize::from(i))
            .ok_or(DelayError::Mismatch)?;
        *slot = Some((value, no));
    }
    let Some((base, _)) = out.twice.get(reference).copied().flatten() else {
        out.twice.fill(None);
        out.stopped = Some(bad_ref);
        return Ok(());
    };
    for rel in out.twice.iter_mut() {
        *rel = rel.map(|(a, _)| overflowing_sub(a, base));
    }
    Ok(())
}

/// The hop of latched slave `c` from its nearest latched ancestor, given the doubled delays of
/// all earlier latched slaves; `Err` for a structural error.
fn hop<W: Word, const N: usize>(
    slaves: &[WalkSlave<W>],
    topology: &Topology<N>,
    abs2: &[Option<(W, W::Bool)>; N],
    c: u16,
) -> Result<HopChecks<W>, DelayError> {
    let zero = W::lit(0);
    let node_c = topology.node(usize::from(c)).ok_or(DelayError::Mismatch)?;
    let lat_c = stamps_of(slaves, c)?;
    let diff_c = t_diff_of(slaves, c)?;

    // Walk up through non-DC slaves to the nearest latched ancestor `a`, summing the non-DC
    // t_Diff terms (REQ-DC-017).
    let mut non_dc = zero;
    let mut non_dc_overflow = zero.ult(zero);
    let mut link = node_c.parent.ok_or(DelayError::NoUpstreamDc { slave: c })?;
    let mut below = c;
    let mut steps = 0usize;
    loop {
        let up = link.slave;
        let slave_up = slaves.get(usize::from(up)).ok_or(DelayError::Mismatch)?;
        if slave_up.stamps.is_some() {
            break;
        }
        let node_up = topology.node(usize::from(up)).ok_or(DelayError::Mismatch)?;
        if node_up.ports.len() != 2 {
            return Err(DelayError::NonDcJunction { slave: up });
        }
        // Down: entry → link port towards `below`; up: the reverse. Exactly one passes the EPU.
        let down = topology
            .node(usize::from(below))
            .and_then(|n| n.parent)
            .ok_or(DelayError::Mismatch)?
            .port;
        let (sum, o) = if node_up.entry.hop_is_processing(down) {
            overflowing_add(non_dc, slave_up.t_diff)
        } else {
            overflowing_sub(non_dc, slave_up.t_diff)
        };
        non_dc = sum;
        non_dc_overflow = non_dc_overflow.or(o);
        below = up;
        link = node_up
            .parent
            .ok_or(DelayError::NoUpstreamDc { slave: c })?;
        steps = steps.saturating_add(1);
        if steps > N {
            return Err(DelayError::Mismatch);
        }
    }
    let a = link.slave;
    let node_a = topology.node(usize::from(a)).ok_or(DelayError::Mismatch)?;
    let lat_a = stamps_of(slaves, a)?;
    let diff_a = t_diff_of(slaves, a)?;
    let (abs_a, _) = abs2
        .get(usize::from(a))
        .copied()
        .flatten()
        .ok_or(DelayError::NoUpstreamDc { slave: c })?;

    // At a: port p leads towards c; q is the open port visited just before p.
    let p = link.port;
    let q = node_a.ports.prev_before(p).unwrap_or(node_a.entry);
    let (before, s1) = since(lat_a, q, node_a.entry);
    let (excursion, s2) = since(lat_a, p, q);
    // At c: its own round trip from entry to the last open port.
    let last = node_c.last_port();
    let (rtt_c, s3) = since(lat_c, last, node_c.entry);

    let corr_a = if q.hop_is_processing(p) { diff_a } else { zero };
    let corr_c = if last.hop_is_processing(node_c.entry) {
        diff_c
    } else {
        zero
    };
    Ok(HopChecks {
        non_dc_overflow,
        stale: s1.or(s2).or(s3),
        step: twice_delay_step(abs_a, before, excursion, rtt_c, corr_a, corr_c, non_dc),
    })
}

/// The error [`walk`]'s checks of slave `c`'s hop mean, in the order of the formula: the first
/// that fails names the error.
fn hop_result(hop: &HopChecks<u64>, c: u16) -> Result<(), DelayError> {
    let overflow = DelayError::Overflow { slave: c };
    let inconsistent = DelayError::Inconsistent { slave: c };
    let step = &hop.step;
    let checks = [
        (hop.non_dc_overflow, overflow),
        (hop.stale, inconsistent),
        (step.measured_overflow, overflow),
        (step.inconsistent, inconsistent),
        (step.hop_overflow, overflow),
        (step.negative_hop, DelayError::NegativeHop { slave: c }),
        (step.sum_overflow, overflow),
    ];
    match checks.iter().find(|(failed, _)| *failed) {
        Some(&(_, e)) => Err(e),
        None => Ok(()),
    }
}

/// Result of [`twice_delay_step`]: the doubled delay and the checks, as N-bit words and flags.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::twice_delay_step;
///
/// // a is the root; the excursion behind its port is 1 200 ns, c's own round trip 200 ns.
/// let step = twice_delay_step::<u64>(0, 0, 1_200, 200, 0, 0, 0);
/// assert_eq!((step.hop2, step.abs2), (1_000, 1_000));
/// assert!(!step.inconsistent && !step.negative_hop);
/// ```
#[derive(Clone, Copy)]
pub struct HopStep<W: Word> {
    /// Twice the delay of `c` from the root: `abs_a + 2·before + hop2` (mod 2^N).
    pub abs2: W,
    /// Twice the hop from `a` to `c`: `measured + corr_a − corr_c + non_dc` (mod 2^N).
    pub hop2: W,
    /// `measured = excursion − rtt_c` left the signed range.
    pub measured_overflow: W::Bool,
    /// `measured < 0`: c's own round trip is longer than the excursion a saw (stale latches).
    pub inconsistent: W::Bool,
    /// One of the sums forming `hop2` left the signed range.
    pub hop_overflow: W::Bool,
    /// `hop2 < 0`: only the t_Diff corrections made the hop negative.
    pub negative_hop: W::Bool,
    /// `2·before` or one of the sums forming `abs2` left the signed range.
    pub sum_overflow: W::Bool,
}

/// REQ-DC-014..017: the arithmetic of one hop of the delay walk, written once against
/// [`Word`] (two's complement N-bit words) so the P3 SMT proof in `ecdc-proofs` runs this very
/// code; `compute` runs it on `u64`. Inputs (all signed): `abs_a` = twice a's delay from the
/// root, `before` = t_a(q) − t_a(e), `excursion` = t_a(p) − t_a(q), `rtt_c` = c's own round
/// trip, `corr_a`/`corr_c` = the t_Diff of a/c where its hop is a processing hop (else 0),
/// `non_dc` = the signed sum of the non-DC slaves' t_Diff between them (see the module doc).
/// Each overflow flag is exactly what the corresponding `i64::checked_*` would report.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::delay::twice_delay_step;
///
/// // a's own delay from the root is 300 ns (abs_a = 600), it held the frame 50 ns before
/// // sending towards c, and a's processing hop adds t_Diff = 20 ns.
/// let step = twice_delay_step::<u64>(600, 50, 1_000, 0, 20, 0, 0);
/// assert_eq!(step.hop2, 1_020);
/// assert_eq!(step.abs2, 600 + 2 * 50 + 1_020);
/// // c's round trip longer than the excursion a saw: stale latches.
/// assert!(twice_delay_step::<u64>(0, 0, 100, 200, 0, 0, 0).inconsistent);
/// ```
#[inline]
pub fn twice_delay_step<W: Word>(
    abs_a: W,
    before: W,
    excursion: W,
    rtt_c: W,
    corr_a: W,
    corr_c: W,
    non_dc: W,
) -> HopStep<W> {
    let zero = W::lit(0);
    let (measured, measured_overflow) = overflowing_sub(excursion, rtt_c);
    let (h, o1) = overflowing_add(measured, corr_a);
    let (h, o2) = overflowing_sub(h, corr_c);
    let (hop2, o3) = overflowing_add(h, non_dc);
    let (before2, o4) = overflowing_add(before, before);
    let (s, o5) = overflowing_add(abs_a, before2);
    let (abs2, o6) = overflowing_add(s, hop2);
    HopStep {
        abs2,
        hop2,
        measured_overflow,
        inconsistent: measured.slt(zero),
        hop_overflow: o1.or(o2).or(o3),
        negative_hop: hop2.slt(zero),
        sum_overflow: o4.or(o5).or(o6),
    }
}

/// Wrapping 32-bit difference `t(to) − t(from)` of one slave's stamps (32-bit values in a word
/// of at least 64 bits), and whether it is negative read as a signed 32-bit value (then the
/// latches are stale; the topology's latch-order check makes that impossible for consistent
/// input). When not negative the value is exact: `PortTime::wrapping_since` widened.
fn since<W: Word>(stamps: &[W; 4], to: Port, from: Port) -> (W, W::Bool) {
    let at = |p: Port| stamps.get(p.index()).copied().unwrap_or(W::lit(0));
    let mask = W::lit(1).shl(32).wrapping_sub(W::lit(1));
    let d = at(to).wrapping_sub(at(from)).bit_and(mask);
    (d, d.ult(W::lit(1).shl(31)).not())
}

fn stamps_of<W: Word>(slaves: &[WalkSlave<W>], i: u16) -> Result<&[W; 4], DelayError> {
    slaves
        .get(usize::from(i))
        .and_then(|s| s.stamps.as_ref())
        .ok_or(DelayError::Mismatch)
}

fn t_diff_of<W: Word>(slaves: &[WalkSlave<W>], i: u16) -> Result<W, DelayError> {
    slaves
        .get(usize::from(i))
        .map(|s| s.t_diff)
        .ok_or(DelayError::Mismatch)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Errors name the slave.
    #[test]
    fn error_messages() {
        assert_eq!(
            std::format!("{}", DelayError::NonDcJunction { slave: 3 }),
            "slave 3: non-DC junction between DC slaves"
        );
    }
    use crate::dc::port::PortSet;
    use crate::dc::topology::Latches;
    use crate::digest::Digest;

    /// 7 966 random lines and trees (2 571 with delays) and 60 lines over a wrapping phase.
    const WALK_DIGEST: u64 = 0x927f_3a0b_8bcb_0bd9;

    /// Folds a [`compute`] result into `d`: every delay exactly (sum and weight), or the error
    /// and the slave it names.
    fn fold<const N: usize>(d: &mut Digest, r: &Result<Delays<N>, DelayError>) {
        match r {
            Ok(x) => {
                d.word(0);
                d.word(x.len() as u64);
                d.word(u64::from(x.reference()));
                for i in 0..x.len() {
                    match x.exact(i) {
                        None => d.word(0),
                        Some((sum, weight)) => {
                            d.word(1);
                            d.int(sum);
                            d.int(weight);
                        }
                    }
                }
            }
            Err(e) => {
                let (kind, slave) = match *e {
                    DelayError::Mismatch => (1, 0),
                    DelayError::BadReference { slave } => (2, slave),
                    DelayError::NoUpstreamDc { slave } => (3, slave),
                    DelayError::NonDcJunction { slave } => (4, slave),
                    DelayError::Inconsistent { slave } => (5, slave),
                    DelayError::NegativeHop { slave } => (6, slave),
                    DelayError::Overflow { slave } => (7, slave),
                    DelayError::BeforeReference { slave } => (8, slave),
                    DelayError::RoundMismatch => (9, 0),
                };
                d.word(kind);
                d.word(u64::from(slave));
            }
        }
    }

    /// The hop arithmetic of [`hop`] as a plain-`i64` checked chain: the
    /// oracle that the Word-generic [`twice_delay_step`] (which SMT runs on bit-vectors) gives
    /// the same result and the same error.
    fn hop_i64(x: [i64; 7], c: u16) -> Result<i64, DelayError> {
        let [abs_a, before, excursion, rtt_c, corr_a, corr_c, non_dc] = x;
        let overflow = DelayError::Overflow { slave: c };
        let measured = excursion.checked_sub(rtt_c).ok_or(overflow)?;
        if measured < 0 {
            return Err(DelayError::Inconsistent { slave: c });
        }
        let hop2 = measured
            .checked_add(corr_a)
            .and_then(|v| v.checked_sub(corr_c))
            .and_then(|v| v.checked_add(non_dc))
            .ok_or(overflow)?;
        if hop2 < 0 {
            return Err(DelayError::NegativeHop { slave: c });
        }
        abs_a
            .checked_add(before.checked_mul(2).ok_or(overflow)?)
            .and_then(|v| v.checked_add(hop2))
            .ok_or(overflow)
    }

    fn hop_word(x: [i64; 7], c: u16) -> Result<i64, DelayError> {
        let w = x.map(|v| v as u64);
        let step = twice_delay_step(w[0], w[1], w[2], w[3], w[4], w[5], w[6]);
        let checks = HopChecks {
            non_dc_overflow: false,
            stale: false,
            step,
        };
        hop_result(&checks, c).map(|()| step.abs2 as i64)
    }

    /// Delays (exact values) or errors of the walk on random samples, as a golden digest: random
    /// open ports, DC flags, stamps near each other (consistent-looking) or anywhere, `t_Diff` of
    /// any size, any reference; then lines over a wrapping phase. The digest was recorded while
    /// the concrete walk the Word-generic one replaced still ran beside it with equal results
    /// (delays and error variants).
    #[test]
    fn walk_matches_its_golden_digest() {
        let mut seed = 0x0DDB_1A5E_5BAD_5EEDu64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let (mut compared, mut ok) = (0u32, 0u32);
        let mut digest = Digest::new();
        for _ in 0..60_000 {
            let n = 1 + (next() % 8) as usize;
            let base = next() as u32;
            let mut samples = [SlaveSample::default(); 8];
            for (i, s) in samples.iter_mut().enumerate().take(n) {
                let r = next();
                // Mostly 2-port slaves (lines), some forks/crosses, ends with one port.
                let ports = match r % 8 {
                    0 => 0b0111,
                    1 => 0b1011,
                    2 => 0b0001,
                    3 => (r >> 8) as u8 & 0x0F,
                    _ => 0b0011,
                };
                let ports = if i + 1 == n && r % 3 == 0 {
                    0b0001
                } else {
                    ports
                };
                let spread = if r % 5 == 0 { u32::MAX } else { 5_000 };
                let t0 = base.wrapping_add(1000 * i as u32);
                let stamps: [u32; 4] =
                    core::array::from_fn(|_| t0.wrapping_add((next() as u32) % spread.max(1)));
                let t_diff = match (r >> 16) % 6 {
                    0 => i32::MIN,
                    1 => i32::MAX,
                    2 => (r >> 20) as i32,
                    _ => ((r >> 24) % 200) as i32 - 50,
                };
                *s = SlaveSample {
                    ports: PortSet::from_bits(ports),
                    latches: (r % 7 != 0).then(|| Latches::from_raw(stamps, u64::from(t0))),
                    t_diff,
                };
            }
            let samples = &samples[..n];
            let Ok(topo) = Topology::<8>::build(samples) else {
                continue;
            };
            let reference = (next() % (n as u64 + 1)) as usize;
            let new = compute(samples, &topo, reference);
            fold(&mut digest, &new);
            compared += 1;
            ok += u32::from(new.is_ok());
        }
        for phase in [0u32, 0xFFFF_F000, 0x7FFF_FFFF] {
            for t_diff in [0, 20, -10, i32::MAX] {
                let s = line(&[3000, 2000, 900, 0], t_diff, phase);
                let t = Topology::<4>::build(&s).unwrap();
                for r in 0..5 {
                    fold(&mut digest, &compute(&s, &t, r));
                }
            }
        }
        assert!(compared > 5_000 && ok > 500, "compared {compared}, ok {ok}");
        digest.assert_golden("the walk's delays or errors", WALK_DIGEST);
    }

    #[test]
    fn word_step_equals_i64_chain() {
        let vals = [0i64, 1, -1, i64::MAX, i64::MIN, 1 << 62];
        let mut n = 0u32;
        for k in 0..vals.len().pow(7) {
            let mut r = k;
            let x: [i64; 7] = core::array::from_fn(|_| {
                let v = vals[r % vals.len()];
                r /= vals.len();
                v
            });
            assert_eq!(hop_word(x, 3), hop_i64(x, 3), "{x:?}");
            n += 1;
        }
        // Pseudo-random values of every magnitude (xorshift), and realistic ones.
        let mut seed = 0x2545_F491_4F6C_DD1Du64;
        for _ in 0..20_000 {
            let x: [i64; 7] = core::array::from_fn(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed as i64) >> (seed % 64)
            });
            assert_eq!(hop_word(x, 3), hop_i64(x, 3), "{x:?}");
            n += 1;
        }
        assert_eq!(n, 6u32.pow(7) + 20_000);
    }

    fn line(rtts: &[u32], t_diff: i32, phase: u32) -> [SlaveSample; 4] {
        let mut out = [SlaveSample::default(); 4];
        for (i, s) in out.iter_mut().enumerate() {
            let open = if i + 1 == rtts.len() {
                PortSet::EMPTY.with(Port::P0)
            } else {
                PortSet::EMPTY.with(Port::P0).with(Port::P1)
            };
            let t0 = phase.wrapping_add(1000 * i as u32);
            *s = SlaveSample {
                ports: open,
                latches: Some(Latches::from_raw(
                    [t0, t0.wrapping_add(rtts[i]), 0, 0],
                    u64::from(t0),
                )),
                t_diff,
            };
        }
        out
    }

    /// Seed 000 eq. 23 on a 4-slave line (derived form; see spec::seed000).
    #[test]
    fn line_matches_eq23() {
        for phase in [0u32, 0xFFFF_F000, 0x7FFF_FFFF] {
            let rtt = [3000u32, 2000, 900, 0];
            let s = line(&rtt, 20, phase);
            let t = Topology::<4>::build(&s).unwrap();
            let d = compute(&s, &t, 0).unwrap();
            assert_eq!(d.exact(0), Some((0, 2)));
            assert_eq!(d.exact(1), Some((3000 - 2000 + 20, 2)));
            assert_eq!(d.exact(2), Some((3000 - 900 + 40, 2)));
            assert_eq!(d.exact(3), Some((3000 + 40, 2)));
            assert_eq!(d.register_value(3), Ok(1520));
            // Relative to slave 1: slave 0 comes first.
            let d1 = compute(&s, &t, 1).unwrap();
            assert_eq!(d1.ns(0), Some(-510));
            assert_eq!(
                d1.register_value(0),
                Err(DelayError::BeforeReference { slave: 0 })
            );
            assert_eq!(d1.ns(2), Some(560));
        }
    }

    #[test]
    fn averaging_rounds_once() {
        let s1 = line(&[3001, 2000, 900, 0], 0, 5);
        let s2 = line(&[3002, 2000, 900, 0], 0, 9);
        let t = Topology::<4>::build(&s1).unwrap();
        let mut d = compute(&s1, &t, 0).unwrap();
        assert_eq!(d.ns(1), Some(501)); // 1001/2 → 500.5 → 501
        d.accumulate(&compute(&s2, &t, 0).unwrap()).unwrap();
        assert_eq!(d.rounds(), 2);
        assert_eq!(d.exact(1), Some((2003, 4)));
        assert_eq!(d.ns(1), Some(501)); // 500.75
    }

    #[test]
    fn inconsistent_latches_rejected() {
        let s = line(&[1000, 2000, 900, 0], 0, 0);
        let t = Topology::<4>::build(&s).unwrap();
        assert_eq!(
            compute(&s, &t, 0),
            Err(DelayError::Inconsistent { slave: 1 })
        );
        let s = line(&[3000, 2000, 900, 0], 0, 0);
        assert_eq!(
            compute(&s, &t, 4),
            Err(DelayError::BadReference { slave: 4 })
        );
        // A t_Diff larger than the hop itself.
        let s = line(&[3000, 2000, 1999, 0], -10, 0);
        assert_eq!(
            compute(&s, &t, 0),
            Err(DelayError::NegativeHop { slave: 2 })
        );
    }

    /// The accessors, and the round check of `accumulate` on each field alone: a round of
    /// another reference, or of another length, is refused and leaves the sum as it was.
    #[test]
    fn accessors_and_round_mismatch() {
        let s = line(&[3000, 2000, 900, 0], 0, 0);
        let t = Topology::<4>::build(&s).unwrap();
        let d0 = compute(&s, &t, 0).unwrap();
        let mut d2 = compute(&s, &t, 2).unwrap();
        assert_eq!((d0.reference(), d2.reference()), (0, 2));
        assert_eq!((d0.len(), d0.is_empty()), (4, false));
        assert!(Delays::<4>::new().is_empty());
        let before = d2.exact(3);
        assert_eq!(d2.accumulate(&d0), Err(DelayError::RoundMismatch));
        assert_eq!(d2.exact(3), before);
        // Three slaves: the last one's port 1 closed.
        let mut s3 = [SlaveSample::default(); 3];
        s3.copy_from_slice(&s[..3]);
        s3[2].ports = PortSet::EMPTY.with(Port::P0);
        let t3 = Topology::<4>::build(&s3).unwrap();
        let mut d3 = compute(&s3, &t3, 0).unwrap();
        assert_eq!((d3.len(), d3.reference()), (3, 0));
        assert_eq!(d3.accumulate(&d0), Err(DelayError::RoundMismatch));
        assert_eq!(d3.rounds(), 1);
    }

    /// `walk` returns what `walk_in_place` writes, and a clone of it is equal to it.
    #[test]
    fn walk_returns_the_in_place_walk() {
        let s = line(&[3000, 2000, 900, 0], 20, 7);
        let t = Topology::<4>::build(&s).unwrap();
        let w: [WalkSlave<u64>; 4] = core::array::from_fn(|i| WalkSlave::from_sample(&s[i]));
        let got = walk(&w, &t, 1).unwrap();
        let mut in_place = Walk::<u64, 4>::new();
        walk_in_place(&w, &t, 1, &mut in_place).unwrap();
        assert_eq!(got.twice, in_place.twice);
        assert_eq!(got.stopped, in_place.stopped);
        assert_eq!(got.twice[0], Some(((-1020i64) as u64, false)));
        assert!(got.hops[1].is_some());
        let c = got.clone();
        assert_eq!((c.twice, c.stopped), (got.twice, got.stopped));
        assert_eq!(c.hops.map(|h| h.is_some()), got.hops.map(|h| h.is_some()));
    }
}
