//! Propagation-delay re-measurement during cyclic operation (REQ-DC-107, ETG.1500 "continuous
//! propagation delay measurement"): the latch/read steps of `measure.rs` spread over the room
//! left in cyclic frames, then a rewrite of 0x0928 only where the delay changed. 0x0920 is
//! never touched here: a delay change is slewed by the ESC, an offset change would step the
//! clock (Lambert, IgH patch 0009).

use crate::dc::cyclic::CyclicCx;
use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::measure::{latch_read, store_latch_reply, LATCH_TRIGGER};
use crate::dc::request::{Op, Reply, Tag};
use crate::dc::shared::expect_wkc;
use crate::dc::slave::LatchRead;
use crate::wire::register::reg;
use crate::wire::FrameBuilder;

/// Steps of a delay re-measurement running inside cyclic frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub(crate) enum Remeasure {
    /// Not running.
    #[default]
    Idle,
    /// FPRD 0x0900 (16 bytes) per latching slave.
    Before,
    /// BWR 0x0900.
    Trigger,
    /// FPRD 0x0900..0x091F per latching slave.
    After,
    /// FPWR 0x0928 per slave with a system time.
    Write,
}

/// A delay re-measurement inside cyclic operation: whether one is asked for, its step and how
/// far the step has got.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub(crate) struct RemeasureRun {
    /// Asked for; starts with the next cycle that has room.
    pub(crate) requested: bool,
    pub(crate) step: Remeasure,
    /// First work item of the step not yet answered.
    pub(crate) cursor: u16,
    /// One past the last work item the cycle in flight carries.
    pub(crate) sent_to: u16,
    /// The step's first error, reported when the step ends.
    pub(crate) error: Option<Error>,
}

/// Re-measurement datagrams per cycle at most. ecdc choice: 8 keeps the cyclic frame small.
const PER_CYCLE: u16 = 8;

impl<const N: usize> CyclicCx<'_, N> {
    fn remeasure_op(&self, pos: u16) -> Option<Op> {
        let s = self.sh.line.slave(pos)?;
        match self.c.remeasure.step {
            Remeasure::Idle => None,
            Remeasure::Trigger => Some(LATCH_TRIGGER),
            Remeasure::Before => latch_read(s, LatchRead::Before),
            Remeasure::After => latch_read(s, LatchRead::After),
            Remeasure::Write if s.dc.has_system_time() && s.delay_ns != s.delay_new => Some(
                Op::fpwr(s.station, reg::SYSTEM_TIME_DELAY, 4, u64::from(s.delay_new)),
            ),
            Remeasure::Write => None,
        }
    }

    fn remeasure_len(&self) -> u16 {
        match self.c.remeasure.step {
            Remeasure::Idle => 0,
            Remeasure::Trigger => 1,
            Remeasure::Before | Remeasure::After | Remeasure::Write => self.sh.line.count,
        }
    }

    pub(crate) fn fill_remeasure(&mut self, b: &mut FrameBuilder<'_>) {
        if self.c.remeasure.step == Remeasure::Idle {
            if !self.c.remeasure.requested {
                return;
            }
            self.c.remeasure.requested = false;
            self.c.remeasure.step = Remeasure::Before;
            self.c.remeasure.cursor = 0;
            self.c.remeasure.error = None;
        }
        // A range, not a loop condition: the walk ends after `len` positions whatever else
        // happens. `sent_to`: the first position not sent this cycle.
        let start = self.c.remeasure.cursor;
        let mut sent_to = start.max(self.remeasure_len());
        let mut pushed = 0u16;
        for pos in start..sent_to {
            if pushed == PER_CYCLE {
                sent_to = pos;
                break;
            }
            if let Some(op) = self.remeasure_op(pos) {
                if !self.sh.push_op(b, op, Tag::CycRemeasure(pos)) {
                    sent_to = pos;
                    break;
                }
                pushed = pushed.saturating_add(1);
            }
        }
        self.c.remeasure.sent_to = sent_to;
    }

    pub(crate) fn remeasure_reply(&mut self, r: Reply<'_>) {
        if let Err(e) = self.remeasure_store(r) {
            self.c.remeasure.error.get_or_insert(e);
        }
    }

    fn remeasure_store(&mut self, r: Reply<'_>) -> Result<(), Error> {
        let line = &mut self.sh.line;
        match self.c.remeasure.step {
            Remeasure::Trigger => {
                r.sent
                    .check_latch_wkc(r.wkc, line.latching_count(), line.count)?;
            }
            Remeasure::Before => store_latch_reply(line, r, LatchRead::Before)?,
            Remeasure::After => store_latch_reply(line, r, LatchRead::After)?,
            Remeasure::Write => expect_wkc(r.sent, 1, r.wkc)?,
            Remeasure::Idle => {}
        }
        Ok(())
    }

    /// Called when a cycle came back complete: move the re-measurement on.
    pub(crate) fn remeasure_advance(&mut self) {
        if self.c.remeasure.step == Remeasure::Idle {
            return;
        }
        self.c.remeasure.cursor = self.c.remeasure.sent_to;
        if self.c.remeasure.cursor < self.remeasure_len() {
            return;
        }
        self.c.remeasure.cursor = 0;
        self.c.remeasure.sent_to = 0;
        self.c.remeasure.step = match self.c.remeasure.step {
            Remeasure::Before => Remeasure::Trigger,
            Remeasure::Trigger => Remeasure::After,
            Remeasure::After => match self.remeasure_compute() {
                Ok(()) => Remeasure::Write,
                Err(e) => {
                    self.c.remeasure.step = Remeasure::Idle;
                    return self.fail(e);
                }
            },
            Remeasure::Write => {
                let mut max_change = 0u32;
                let count = self.sh.line.count;
                for s in self.sh.line.slaves.iter_mut().take(usize::from(count)) {
                    max_change = max_change.max(s.delay_new.abs_diff(s.delay_ns));
                    s.delay_ns = s.delay_new;
                }
                self.sh.push_event(Event::DelaysUpdated {
                    max_change_ns: max_change,
                });
                Remeasure::Idle
            }
            Remeasure::Idle => Remeasure::Idle,
        };
    }

    /// One latch round's delays into `delay_new`, range-checked. Out of line and cold: the
    /// topology and delay tables it builds (O(N) on the stack) must not enlarge the frame of
    /// `cyclic_complete`, which runs every cycle.
    #[cold]
    #[inline(never)]
    fn remeasure_compute(&mut self) -> Result<(), Error> {
        for s in self.sh.line.slaves.iter_mut() {
            s.delay_sum = 0;
        }
        self.sh.accumulate_round()?;
        let max = self.sh.cfg.max_delay_ns;
        let count = self.sh.line.count;
        for s in self.sh.line.slaves.iter_mut().take(usize::from(count)) {
            if !s.dc.has_system_time() {
                s.delay_new = s.delay_ns;
                continue;
            }
            s.delay_new = u32::try_from(s.delay_sum)
                .ok()
                .filter(|d| *d <= max)
                .ok_or(Error::OutOfRange {
                    station: s.station,
                    register: reg::SYSTEM_TIME_DELAY,
                })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    //! The datagrams of each re-measurement step, on a machine put straight into `Cyclic`.
    use super::*;
    use crate::dc::slave::DcKind;
    use crate::dc::testing::{self, closed, open};
    use crate::dc::{Event, Machine, State};
    use crate::time::SystemTime;
    use crate::wire::{Command, EthernetFrame};

    /// What `remeasure_op` gives at positions 0..3 of a line of a 64-bit DC slave whose delay
    /// is unchanged, a slave without DC and a 64-bit DC slave whose delay changed.
    fn ops(step: Remeasure) -> [Option<Op>; 3] {
        let mut m = testing::in_cyclic::<4>(&[DcKind::Bits64, DcKind::None, DcKind::Bits64]);
        for (i, s) in m.sh.line.slaves.iter_mut().take(3).enumerate() {
            s.delay_ns = 100;
            s.delay_new = if i == 2 { 130 } else { 100 };
        }
        m.in_cyclic(SystemTime(1_000_000), |cx| {
            cx.c.remeasure.step = step;
            [0, 1, 2].map(|pos| cx.remeasure_op(pos))
        })
        .unwrap()
    }

    /// REQ-DC-107: the latch reads before and after the trigger go to the slaves with latches,
    /// the trigger is one BWR 0x0900, and 0x0928 is rewritten only where the delay changed.
    // verifies: REQ-DC-107
    #[test]
    fn each_step_sends_its_datagrams() {
        assert_eq!(ops(Remeasure::Idle), [None, None, None]);
        let before = Some(Op::fprd(0x1001, reg::RECEIVE_TIME_PORT0, 16));
        let before_2 = Some(Op::fprd(0x1003, reg::RECEIVE_TIME_PORT0, 16));
        assert_eq!(ops(Remeasure::Before), [before, None, before_2]);
        assert_eq!(ops(Remeasure::Trigger)[0], Some(LATCH_TRIGGER));
        let after = Some(Op::fprd(0x1001, reg::RECEIVE_TIME_PORT0, 32));
        let after_2 = Some(Op::fprd(0x1003, reg::RECEIVE_TIME_PORT0, 32));
        assert_eq!(ops(Remeasure::After), [after, None, after_2]);
        let write = Some(Op::fpwr(0x1003, reg::SYSTEM_TIME_DELAY, 4, 130));
        assert_eq!(ops(Remeasure::Write), [None, None, write]);
    }

    /// Two 64-bit DC slaves in a line, in `Cyclic`: slave 0 (the reference) with ports 0 and
    /// 1 open, slave 1 a line end; slave 1's delay was `old_delay` ns.
    fn line_in_cyclic(old_delay: u32) -> Machine<4> {
        let mut m = testing::in_cyclic::<4>(&[DcKind::Bits64; 2]);
        let dl = [
            open(0) | open(1) | closed(2) | closed(3),
            open(0) | closed(1) | closed(2) | closed(3),
        ];
        for (i, (s, dl)) in m.sh.line.slaves.iter_mut().zip(dl).enumerate() {
            s.dl_status = dl;
            s.delay_ns = if i == 1 { old_delay } else { 0 };
        }
        m
    }

    /// Datagrams seen: command, ADP, ADO, length.
    type Log = std::vec::Vec<(Command, u16, u16, u16)>;

    /// Answers a frame as the two slaves would: every datagram's working counter, the latch
    /// reads from `before`/`after` (port times, then system time and EPU time); each
    /// datagram is recorded in `log`. The trigger frame passes slave 1 1 208 ns after
    /// slave 0 forwards it, so slave 1's delay is 604 ns.
    fn answer(frame: &[u8], log: &mut Log) -> std::vec::Vec<u8> {
        let before = [[7u32, 7, 7, 7], [9, 9, 9, 9]];
        let after = [[10_000u32, 11_208, 7, 7], [10_604, 9, 9, 9]];
        let mut out = frame.to_vec();
        let mut eth = EthernetFrame::new_unchecked(&mut out[..]);
        eth.mark_processed_by_slave();
        for d in eth.ecat_frame_mut().unwrap().iter_mut() {
            let mut d = d.unwrap();
            let (cmd, adp, ado, len) = (d.command().unwrap(), d.adp(), d.ado(), d.data_len());
            log.push((cmd, adp, ado, len));
            let slave = usize::from(adp.wrapping_sub(0x1001));
            let wkc = match (cmd, ado, len) {
                (Command::Fprd, 0x0900, 16) => {
                    for (b, t) in d.data_mut().chunks_mut(4).zip(before[slave]) {
                        b.copy_from_slice(&t.to_le_bytes());
                    }
                    1
                }
                (Command::Fprd, 0x0900, 32) => {
                    let data = d.data_mut();
                    for (b, t) in data.chunks_mut(4).zip(after[slave]) {
                        b.copy_from_slice(&t.to_le_bytes());
                    }
                    let epu = u64::from(after[slave][0]);
                    data[16..24].copy_from_slice(&epu.to_le_bytes());
                    data[24..32].copy_from_slice(&epu.to_le_bytes());
                    1
                }
                (Command::Bwr | Command::Brd | Command::Frmw, _, _) => 2,
                _ => 1,
            };
            d.set_wkc(wkc);
        }
        out
    }

    /// Runs a requested re-measurement for 20 cycles with `max_delay_ns`; the datagrams sent
    /// that are not the cycle's own, and the events.
    fn remeasure(max_delay_ns: u32) -> (Machine<4>, Log, std::vec::Vec<Event>) {
        let mut m = line_in_cyclic(590);
        m.sh.cfg.max_delay_ns = max_delay_ns;
        m.request_delay_measurement();
        let mut log = std::vec::Vec::new();
        let mut events = std::vec::Vec::new();
        let mut buf = [0u8; 1514];
        for k in 0..20u64 {
            let now = SystemTime(1_000_000_000 + k * 1_000_000);
            let Some(n) = m.poll_transmit(now, &mut buf) else {
                break;
            };
            let reply = answer(&buf[..n], &mut log);
            m.handle_frame(now.wrapping_add(10_000), &reply);
            events.extend(core::iter::from_fn(|| m.poll_event()));
        }
        log.retain(|(c, _, ado, _)| *ado != 0x092C && *ado != 0x0130 && *c != Command::Frmw);
        (m, log, events)
    }

    /// REQ-DC-107: a requested re-measurement reads the latches, triggers, reads them again,
    /// rewrites 0x0928 of the slave whose delay changed (only that one, only 0x0928) and
    /// reports the largest change; the cycle's own datagrams go on meanwhile.
    // verifies: REQ-DC-107
    #[test]
    fn remeasurement_rewrites_only_the_changed_delay() {
        let (m, log, events) = remeasure(604);
        assert_eq!(m.state(), State::Cyclic);
        assert!(
            events.contains(&Event::DelaysUpdated { max_change_ns: 14 }),
            "{events:?}"
        );
        assert_eq!(
            (m.sh.line.slaves[0].delay_ns, m.sh.line.slaves[1].delay_ns),
            (0, 604)
        );
        assert_eq!(
            log,
            [
                (Command::Fprd, 0x1001, 0x0900, 16),
                (Command::Fprd, 0x1002, 0x0900, 16),
                (Command::Bwr, 0, 0x0900, 4),
                (Command::Fprd, 0x1001, 0x0900, 32),
                (Command::Fprd, 0x1002, 0x0900, 32),
                (Command::Fpwr, 0x1002, 0x0928, 4),
            ]
        );
    }

    /// REQ-DC-112: a re-measured delay above `max_delay_ns` is a fault naming the slave and
    /// 0x0928, and nothing is written.
    // verifies: REQ-DC-112
    #[test]
    fn remeasured_delay_out_of_range_is_a_fault() {
        let (m, log, events) = remeasure(603);
        assert_ne!(m.state(), State::Cyclic);
        assert!(
            events.contains(&Event::Error(crate::dc::Error::OutOfRange {
                station: 0x1002,
                register: 0x0928
            })),
            "{events:?}"
        );
        assert!(log.iter().all(|(c, ..)| *c != Command::Fpwr), "{log:?}");
        assert_eq!(m.sh.line.slaves[1].delay_ns, 590);
    }

    /// At most `PER_CYCLE` (8) re-measurement datagrams ride in one cycle's frame; the rest
    /// follow in the next cycle, and only then does the step move on (to the trigger).
    #[test]
    fn at_most_eight_remeasurement_datagrams_a_cycle() {
        let mut m = testing::in_cyclic::<16>(&[DcKind::Bits64; 10]);
        m.request_delay_measurement();
        let mut buf = [0u8; 1514];
        let mut cycle = |m: &mut Machine<16>, k: u64| {
            let now = SystemTime(1_000_000_000 + k * 1_000_000);
            let n = m.poll_transmit(now, &mut buf).unwrap();
            let sent: std::vec::Vec<_> = testing::headers(&buf[..n])
                .into_iter()
                .filter(|h| h.3 == 0x0900)
                .map(|h| (h.0, h.2))
                .collect();
            let reply = testing::answer(&buf[..n], |cmd| if cmd == Command::Fprd { 1 } else { 10 });
            m.handle_frame(now.wrapping_add(10_000), &reply);
            sent
        };
        let first = cycle(&mut m, 0);
        assert_eq!(first.len(), usize::from(PER_CYCLE));
        assert!(first.iter().all(|(c, _)| *c == Command::Fprd));
        assert_eq!(
            cycle(&mut m, 1),
            [(Command::Fprd, 0x1009), (Command::Fprd, 0x100A)]
        );
        assert_eq!(cycle(&mut m, 2), [(Command::Bwr, 0)]);
    }
}
