//! ESC ports, the processing order and open-port sets.
//!
//! A frame visits an ESC's ports in the fixed order 0 → 3 → 1 → 2 → 0 (Beckhoff Section I
//! Table 9), starting after the port it came in through; closed ports are skipped by an internal
//! loopback. The EtherCAT Processing Unit (EPU) sits right after port 0's receiver, so the hop
//! that starts at port 0 (or crosses a closed port 0) costs the processing delay `t_P`, every
//! other hop the forwarding delay `t_F` (REQ-DC-010).
//!
//! ```text
//!            ┌──────────── ESC ────────────┐
//!  port 0 RX ─► EPU ─► port 3 ─► port 1 ─► port 2 ─► port 0 TX
//!                       ▲ out/in  ▲ out/in  ▲ out/in
//! ```

/// One of the four ports of an ESC.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::port::Port;
///
/// // A frame entering port 0 leaves through port 3 next (processing order 0, 3, 1, 2).
/// assert_eq!(Port::P0.next(), Port::P3);
/// // Port 1's receive time is at 0x0900 + 4 · 1.
/// assert_eq!(0x0900 + 4 * u16::from(Port::P1.number()), 0x0904);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Port {
    /// Port 0 (usually the upstream port, "A").
    P0,
    /// Port 1 ("B").
    P1,
    /// Port 2 ("C").
    P2,
    /// Port 3 ("D").
    P3,
}

impl Port {
    /// All ports in processing order, starting at port 0.
    pub const PROCESSING_ORDER: [Port; 4] = [Port::P0, Port::P3, Port::P1, Port::P2];

    /// Port number 0..=3 (register index: receive time at 0x0900 + 4·n).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    ///
    /// assert_eq!(Port::P3.number(), 3);
    /// ```
    #[inline]
    pub const fn number(self) -> u8 {
        match self {
            Port::P0 => 0,
            Port::P1 => 1,
            Port::P2 => 2,
            Port::P3 => 3,
        }
    }

    /// Port from its number; `None` above 3.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    ///
    /// assert_eq!(Port::from_number(2), Some(Port::P2));
    /// assert_eq!(Port::from_number(4), None);
    /// ```
    #[inline]
    pub const fn from_number(n: u8) -> Option<Port> {
        match n {
            0 => Some(Port::P0),
            1 => Some(Port::P1),
            2 => Some(Port::P2),
            3 => Some(Port::P3),
            _ => None,
        }
    }

    /// Array index 0..=3 (same as [`Port::number`]).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    ///
    /// let receive_times = [100u32, 900, 0, 300];
    /// assert_eq!(receive_times[Port::P3.index()], 300);
    /// ```
    #[inline]
    pub const fn index(self) -> usize {
        self.number() as usize
    }

    /// Bit of this port in a [`PortSet`].
    #[inline]
    const fn mask(self) -> u8 {
        match self {
            Port::P0 => 1,
            Port::P1 => 2,
            Port::P2 => 4,
            Port::P3 => 8,
        }
    }

    /// The next port in processing order: 0 → 3 → 1 → 2 → 0.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    ///
    /// let mut p = Port::P0;
    /// let mut order = [Port::P0; 4];
    /// for slot in &mut order {
    ///     *slot = p;
    ///     p = p.next();
    /// }
    /// assert_eq!(order, Port::PROCESSING_ORDER);
    /// assert_eq!(p, Port::P0);
    /// ```
    #[inline]
    pub const fn next(self) -> Port {
        match self {
            Port::P0 => Port::P3,
            Port::P3 => Port::P1,
            Port::P1 => Port::P2,
            Port::P2 => Port::P0,
        }
    }

    /// The previous port in processing order: 0 → 2 → 1 → 3 → 0.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    ///
    /// assert_eq!(Port::P0.prev(), Port::P2);
    /// for p in Port::PROCESSING_ORDER {
    ///     assert_eq!(p.next().prev(), p);
    /// }
    /// ```
    #[inline]
    pub const fn prev(self) -> Port {
        match self {
            Port::P0 => Port::P2,
            Port::P2 => Port::P1,
            Port::P1 => Port::P3,
            Port::P3 => Port::P0,
        }
    }

    /// REQ-DC-010: true when the ESC-internal walk from the receiver of `self` to the transmitter
    /// of `to` passes the EPU (port 0's position is `self` or lies strictly between them; for
    /// `self == to` the walk is the full circle). Such a hop costs `t_P`, any other `t_F`.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::Port;
    ///
    /// // In at port 0, out at port 1: the frame passes the EPU right after port 0 (t_P).
    /// assert!(Port::P0.hop_is_processing(Port::P1));
    /// // Back in at port 1, out at port 0 via port 2: no EPU on the way (t_F).
    /// assert!(!Port::P1.hop_is_processing(Port::P0));
    /// ```
    #[inline]
    pub const fn hop_is_processing(self, to: Port) -> bool {
        let mut p = self;
        let mut steps = 0u8;
        // At most four steps around the circle.
        while steps < 4 {
            if matches!(p, Port::P0) {
                return true;
            }
            p = p.next();
            if p.number() == to.number() {
                return false;
            }
            steps = steps.saturating_add(1);
        }
        false
    }
}

/// A set of ports (bit n = port n), e.g. the ports that are open according to DL status.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::port::{Port, PortSet};
///
/// // A slave with ports 0 and 1 open (a line topology's middle slave).
/// let open = PortSet::EMPTY.with(Port::P0).with(Port::P1);
/// assert_eq!(open.len(), 2);
/// // Entering at port 0, the frame leaves through port 1 (port 3 is closed).
/// assert_eq!(open.next_after(Port::P0), Some(Port::P1));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PortSet(u8);

impl PortSet {
    /// No port.
    pub const EMPTY: PortSet = PortSet(0);

    /// From a bit mask (bit n = port n); bits above 3 are ignored.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    ///
    /// let s = PortSet::from_bits(0b1111_0011);
    /// assert_eq!(s.bits(), 0b0011);
    /// assert!(s.contains(Port::P1));
    /// ```
    #[inline]
    pub const fn from_bits(bits: u8) -> PortSet {
        PortSet(bits & 0x0F)
    }

    /// The bit mask.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    ///
    /// assert_eq!(PortSet::EMPTY.with(Port::P3).bits(), 0b1000);
    /// ```
    #[inline]
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// REQ-DC-011: open ports from ESC DL Status 0x0110. A port counts as open (leads to a
    /// neighbour the frame visits) when its loop is open (bit 8+2n clear) and communication is
    /// established on it (bit 9+2n set); a link bit (4..7) alone is not enough: a port with link
    /// but a closed loop is bypassed by the ESC (same rule as SOEM's `(dl >> (8+2n)) & 3 == 2`).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    ///
    /// // DL status 0x5A30: ports 0 and 1 have link, open loops and communication; 2 and 3 are
    /// // looped back.
    /// let open = PortSet::from_dl_status(0x5A30);
    /// assert_eq!(open, PortSet::EMPTY.with(Port::P0).with(Port::P1));
    /// // A link with a closed loop is bypassed by the ESC: not open.
    /// assert!(PortSet::from_dl_status(0x0310).is_empty());
    /// ```
    pub fn from_dl_status(dl_status: u16) -> PortSet {
        let mut set = PortSet::EMPTY;
        for port in Port::PROCESSING_ORDER {
            let (loop_closed, communication) = match port {
                Port::P0 => (1u16 << 8, 1u16 << 9),
                Port::P1 => (1 << 10, 1 << 11),
                Port::P2 => (1 << 12, 1 << 13),
                Port::P3 => (1 << 14, 1 << 15),
            };
            if dl_status & loop_closed == 0 && dl_status & communication != 0 {
                set = set.with(port);
            }
        }
        set
    }

    /// Whether `port` is in the set.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    ///
    /// let s = PortSet::from_bits(0b0001);
    /// assert!(s.contains(Port::P0));
    /// assert!(!s.contains(Port::P2));
    /// ```
    #[inline]
    pub const fn contains(self, port: Port) -> bool {
        self.0 & port.mask() != 0
    }

    /// The set with `port` added.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    ///
    /// assert_eq!(PortSet::EMPTY.with(Port::P2), PortSet::from_bits(0b0100));
    /// ```
    #[inline]
    #[must_use]
    pub const fn with(self, port: Port) -> PortSet {
        PortSet(self.0 | port.mask())
    }

    /// The ports of `self` whose receive time differs between two reads of 0x0900..0x090F
    /// (`before`, `after`, indexed by port number): the ports a frame passed in between. An
    /// open port whose time did not move was bypassed (REQ-DC-101).
    #[inline]
    #[must_use]
    pub(crate) fn passed(self, before: &[u32; 4], after: &[u32; 4]) -> PortSet {
        let mut out = PortSet::EMPTY;
        for p in Port::PROCESSING_ORDER {
            if self.contains(p) && before.get(p.index()) != after.get(p.index()) {
                out = out.with(p);
            }
        }
        out
    }

    /// Number of ports in the set (0..=4).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::PortSet;
    ///
    /// assert_eq!(PortSet::from_bits(0b1011).len(), 3);
    /// ```
    #[inline]
    pub const fn len(self) -> u32 {
        self.0.count_ones()
    }

    /// Whether the set is empty.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::PortSet;
    ///
    /// assert!(PortSet::EMPTY.is_empty());
    /// assert!(!PortSet::from_bits(1).is_empty());
    /// ```
    #[inline]
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The first port of the set in processing order starting at port 0 (0, 3, 1, 2).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    ///
    /// // Port 3 comes before port 1 in processing order.
    /// assert_eq!(
    ///     PortSet::from_bits(0b1010).first_in_processing_order(),
    ///     Some(Port::P3)
    /// );
    /// assert_eq!(PortSet::EMPTY.first_in_processing_order(), None);
    /// ```
    pub fn first_in_processing_order(self) -> Option<Port> {
        Port::PROCESSING_ORDER
            .iter()
            .copied()
            .find(|p| self.contains(*p))
    }

    /// The next port of the set strictly after `from` in processing order, wrapping around; may
    /// return `from` itself if it is the only member. `None` for an empty set.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    ///
    /// let s = PortSet::from_bits(0b0111); // ports 0, 1, 2
    /// assert_eq!(s.next_after(Port::P0), Some(Port::P1));
    /// assert_eq!(s.next_after(Port::P2), Some(Port::P0));
    /// // The only member comes back to itself.
    /// assert_eq!(
    ///     PortSet::from_bits(0b0001).next_after(Port::P0),
    ///     Some(Port::P0)
    /// );
    /// ```
    pub fn next_after(self, from: Port) -> Option<Port> {
        self.first_from(from.next(), Port::next)
    }

    /// The member of the set visited just before `to` when walking from `from` (the entry port):
    /// the previous member in processing order, or `from` itself when nothing lies between.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::port::{Port, PortSet};
    ///
    /// let s = PortSet::from_bits(0b0111); // ports 0, 1, 2
    /// // Walking 0 → 1 → 2, the port visited before 2 is 1.
    /// assert_eq!(s.prev_before(Port::P2), Some(Port::P1));
    /// assert_eq!(s.prev_before(Port::P1), Some(Port::P0));
    /// ```
    pub fn prev_before(self, to: Port) -> Option<Port> {
        self.first_from(to.prev(), Port::prev)
    }

    /// The first member met walking from `start` (included) one `step` at a time, round the
    /// four ports once.
    fn first_from(self, start: Port, step: fn(Port) -> Port) -> Option<Port> {
        let mut p = start;
        for _ in 0..4 {
            if self.contains(p) {
                return Some(p);
            }
            p = step(p);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// REQ-DC-011 port by port: a port is open with its communication bit set and its loop bit
    /// clear, and only then; the other ports' bits and the link bits do not matter.
    // verifies: REQ-DC-011
    #[test]
    fn dl_status_port_by_port() {
        for p in Port::PROCESSING_ORDER {
            let n = u32::from(p.number());
            let loop_closed = 1u16 << (8 + 2 * n);
            let communication = 1u16 << (9 + 2 * n);
            let others = 0xFF00 & !(loop_closed | communication);
            for rest in [0u16, others, 0x00F0] {
                let open =
                    PortSet::from_dl_status(rest & !(loop_closed | communication) | communication);
                assert!(open.contains(p), "{p:?} open");
                let closed = PortSet::from_dl_status(rest | communication | loop_closed);
                assert!(!closed.contains(p), "{p:?} loop closed");
                let silent = PortSet::from_dl_status(rest & !communication);
                assert!(!silent.contains(p), "{p:?} without communication");
            }
        }
    }

    /// `with` adds a port (twice is once), `len` counts the members.
    #[test]
    fn with_and_len() {
        assert_eq!(PortSet::EMPTY.len(), 0);
        let one = PortSet::EMPTY.with(Port::P2);
        assert_eq!((one.len(), one.with(Port::P2)), (1, one));
        let three = one.with(Port::P0).with(Port::P3).with(Port::P0);
        assert_eq!(three.len(), 3);
        assert!(three.contains(Port::P0) && !three.contains(Port::P1));
        assert_eq!(PortSet::from_bits(0x0F).len(), 4);
    }

    /// `passed` keeps the ports of the set whose time moved, and no other.
    #[test]
    fn passed_ports() {
        let open = PortSet::EMPTY.with(Port::P0).with(Port::P1).with(Port::P3);
        let before = [10, 20, 30, 40];
        assert_eq!(open.passed(&before, &before), PortSet::EMPTY);
        let after = [11, 20, 31, 41];
        assert_eq!(
            open.passed(&before, &after),
            PortSet::EMPTY.with(Port::P0).with(Port::P3)
        );
        assert_eq!(PortSet::EMPTY.passed(&before, &after), PortSet::EMPTY);
    }

    /// `from_number` inverts `number` on 0..=3 and refuses every other number.
    #[test]
    fn port_from_number() {
        for p in Port::PROCESSING_ORDER {
            assert_eq!(Port::from_number(p.number()), Some(p));
        }
        assert_eq!(Port::from_number(2), Some(Port::P2));
        for n in 4..=u8::MAX {
            assert_eq!(Port::from_number(n), None);
        }
    }

    // verifies: REQ-DC-010
    #[test]
    fn processing_order_cycle() {
        let mut p = Port::P0;
        let mut seen = [0u8; 4];
        for (i, s) in seen.iter_mut().enumerate() {
            assert_eq!(p, Port::PROCESSING_ORDER[i]);
            *s = p.number();
            assert_eq!(p.next().prev(), p);
            p = p.next();
        }
        assert_eq!(p, Port::P0);
        assert_eq!(seen, [0, 3, 1, 2]);
    }

    // verifies: REQ-DC-010
    #[test]
    fn processing_hops() {
        use Port::*;
        // Port 0's receiver feeds the EPU.
        assert!(P0.hop_is_processing(P3));
        assert!(P0.hop_is_processing(P1)); // 3 closed
        assert!(P0.hop_is_processing(P0)); // line end
                                           // Forwarding hops.
        assert!(!P3.hop_is_processing(P1));
        assert!(!P1.hop_is_processing(P2));
        assert!(!P2.hop_is_processing(P0));
        assert!(!P1.hop_is_processing(P0)); // 2 closed
                                            // Crossing a closed port 0 passes the EPU.
        assert!(P2.hop_is_processing(P3));
        assert!(P1.hop_is_processing(P1));
        assert!(P3.hop_is_processing(P3));
    }

    // verifies: REQ-DC-011
    #[test]
    fn dl_status_decoding() {
        // Port 0 and 1 open (loop open + communication), 2 and 3 closed.
        let dl = (1 << 9) | (1 << 11) | (1 << 12) | (1 << 14) | 0x0030;
        let s = PortSet::from_dl_status(dl);
        assert_eq!(s.bits(), 0b0011);
        // Communication but loop closed: not open.
        assert!(PortSet::from_dl_status(0x0300).is_empty());
        // Link only: not open.
        assert!(PortSet::from_dl_status(0x00F0).is_empty());
        assert_eq!(PortSet::from_dl_status(0xAA00).bits(), 0b1111);
    }

    #[test]
    fn set_walks() {
        let s = PortSet::EMPTY.with(Port::P0).with(Port::P1).with(Port::P2);
        assert_eq!(s.next_after(Port::P0), Some(Port::P1));
        assert_eq!(s.next_after(Port::P2), Some(Port::P0));
        assert_eq!(s.prev_before(Port::P1), Some(Port::P0));
        assert_eq!(s.prev_before(Port::P2), Some(Port::P1));
        assert_eq!(s.first_in_processing_order(), Some(Port::P0));
        assert_eq!(PortSet::EMPTY.next_after(Port::P0), None);
        let one = PortSet::EMPTY.with(Port::P3);
        assert_eq!(one.next_after(Port::P3), Some(Port::P3));
        assert_eq!(one.prev_before(Port::P3), Some(Port::P3));
    }
}
