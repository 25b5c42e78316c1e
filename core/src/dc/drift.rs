//! Static drift compensation with a convergence gate (REQ-DC-104): bursts of FRMW 0x0910 (one
//! per frame, each a loop sample in every slave) interleaved with 0x092C checks (per-slave FPRD
//! and/or the BRD upper bound), every check frame closed by one more FRMW so the loops keep
//! getting samples while a long line is read out (32 datagrams per frame: a 512-slave check is
//! 17 frames). Done when `consecutive` checks in a row have every reading ≤ `spike_ns` and,
//! over them, every slave's |mean 0x092C| ≤ `threshold_ns` and mean |0x092C| ≤ `scatter_ns`;
//! a `NotConverged` error with the worst slave after `max_frames`. SYNC is programmed only after this gate passed (REQ-DC-033).

use crate::dc::config::DriftCheck;
use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::{Item, Machine};
use crate::dc::phase::{DriftStep, Phase};
use crate::dc::request::{Op, Reply, Tag};
use crate::dc::shared::expect_wkc;
use crate::dc::state::State;
use crate::time::SystemTime;
use crate::wire::register::{reg, typed, SystemTimeDifference};
use crate::wire::{FrameBuilder, DATAGRAM_OVERHEAD};

/// The convergence gate's running data (REQ-DC-104).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct DriftGate {
    /// FRMW samples sent since the drift compensation began (bounded by `max_frames`).
    pub(crate) frames: u32,
    /// Checks passed in a row.
    pub(crate) passed: u8,
    /// The BRD 0x092C upper bound read in the current check.
    pub(crate) bound: Option<u32>,
    /// Sum of the BRD 0x092C bounds over the current passing streak.
    pub(crate) bound_sum: u64,
}

impl DriftGate {
    /// Before any drift compensation.
    pub(crate) const IDLE: DriftGate = DriftGate {
        frames: 0,
        passed: 0,
        bound: None,
        bound_sum: 0,
    };
}

impl<const N: usize> Machine<N> {
    /// Items of a drift step: the burst's FRMWs, or the bound and every slave's 0x092C.
    pub(crate) fn drift_count(&self, step: DriftStep) -> u16 {
        match step {
            DriftStep::Burst => self.burst_len(),
            DriftStep::Check => self.sh.line.count.saturating_add(1),
        }
    }

    /// Frames of the current burst: `burst_frames` back to back while the gate has not passed
    /// yet; once a check passed, single paused frames, so the remaining `consecutive − 1` checks
    /// watch the loops at the cyclic sample rate they will run at (a loop held tight by
    /// back-to-back samples can drift off once samples come only every cycle).
    pub(crate) fn burst_len(&self) -> u16 {
        if self.phase.drift_gate().is_some_and(|g| g.passed > 0) {
            1
        } else {
            self.sh.cfg.drift.burst_frames
        }
    }

    /// Earliest master time the next item of the current step may go out: the last FRMW of a
    /// burst waits `check_pause_ns` after the previous frame (REQ-DC-104).
    pub(crate) fn pace_until(&self) -> Option<SystemTime> {
        let last_of_burst = self.burst_len().saturating_sub(1);
        (matches!(self.phase, Phase::Drift(DriftStep::Burst, _))
            && self.sh.step.cursor == last_of_burst)
            .then(|| {
                self.sh
                    .last_sent
                    .wrapping_add(self.sh.cfg.drift.check_pause_ns)
            })
    }

    /// In `DriftCheck`, whether check datagram `op` still leaves room in the frame for the
    /// closing FRMW (always true in other states).
    pub(crate) fn drift_check_room(&self, now: SystemTime, b: &FrameBuilder<'_>, op: Op) -> bool {
        !matches!(self.phase, Phase::Drift(DriftStep::Check, _))
            || b.fits(
                usize::from(op.len)
                    .saturating_add(DATAGRAM_OVERHEAD)
                    .saturating_add(usize::from(self.sh.frmw_op(now).len)),
            )
    }

    /// Closes a `DriftCheck` frame that is not the check's last with an FRMW to the reference:
    /// a loop sample in every slave (counted in `DriftGate::frames`), so a check that needs many
    /// frames does not starve the loops. Last in the frame, so each slave's 0x092C read earlier
    /// in the same frame still shows the Δt accumulated since the previous sample, not the
    /// fresh one; a check of one frame (short networks) has none and reads exactly the Δt of
    /// the check pause.
    pub(crate) fn drift_check_epilogue(&mut self, now: SystemTime, b: &mut FrameBuilder<'_>) {
        if matches!(self.phase, Phase::Drift(DriftStep::Check, _))
            && self.sh.push_op(b, self.sh.frmw_op(now), Tag::Frmw)
        {
            if let Some(gate) = self.phase.drift_gate_mut() {
                gate.frames = gate.frames.saturating_add(1);
            }
        }
    }

    pub(crate) fn drift_item(&self, now: SystemTime, i: u16) -> Item {
        match self.phase {
            Phase::Drift(DriftStep::Burst, _) => Item::Send(self.sh.frmw_op(now)),
            Phase::Drift(DriftStep::Check, _) => {
                let check = self.sh.cfg.drift.check;
                if i == 0 {
                    if check == DriftCheck::PerSlave {
                        return Item::Skip;
                    }
                    return Item::Send(Op::brd(reg::SYSTEM_TIME_DIFFERENCE, 4));
                }
                if check == DriftCheck::Broadcast {
                    return Item::Skip;
                }
                match self.sh.line.slave(i.saturating_sub(1)) {
                    Some(s) if s.dc.has_system_time() => {
                        Item::Send(Op::fprd(s.station, reg::SYSTEM_TIME_DIFFERENCE, 4))
                    }
                    _ => Item::Skip,
                }
            }
            _ => Item::Skip,
        }
    }

    pub(crate) fn drift_reply(&mut self, r: Reply<'_>) -> Result<(), Error> {
        let (i, p, wkc, data) = r.parts();
        match self.phase {
            Phase::Drift(DriftStep::Burst, _) => self.sh.check_frmw(p, wkc),
            Phase::Drift(DriftStep::Check, _) => {
                // BRD 0x092C: only ESCs with a system time have the register.
                let expected = if i == 0 { self.sh.line.sys_count } else { 1 };
                expect_wkc(p, expected, wkc)?;
                let raw = typed::SYSTEM_TIME_DIFFERENCE
                    .decode(data)
                    .map_err(|_| p.out_of_range())?;
                let d = SystemTimeDifference::from_raw(raw);
                if i == 0 {
                    if let Some(gate) = self.phase.drift_gate_mut() {
                        gate.bound = Some(d.magnitude());
                    }
                } else if let Some(s) = self.sh.line.slave_mut(i.saturating_sub(1)) {
                    s.last_diff_ns = Some(i64::from(d.to_ns()));
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    pub(crate) fn drift_done(&mut self) -> Result<State, Error> {
        match self.phase {
            Phase::Drift(DriftStep::Burst, _) => Ok(State::DriftCheck),
            Phase::Drift(DriftStep::Check, _) => self.drift_judge(),
            _ => Ok(self.state()),
        }
    }

    /// Judges one completed check (REQ-DC-104): the check passes when every reading is at
    /// most `spike_ns`; a streak of `consecutive` passing checks converges when every slave's
    /// |mean 0x092C| (its clock offset, the latch jitter averaged out) is at most
    /// `threshold_ns` and its mean |0x092C| at most `scatter_ns` (the bound's mean against
    /// `threshold_ns` in `Broadcast` mode), and otherwise starts over.
    fn drift_judge(&mut self) -> Result<State, Error> {
        let Machine { phase, sh } = self;
        let Some(gate) = phase.drift_gate_mut() else {
            return Ok(phase.state());
        };
        let d = sh.cfg.drift;
        let per_slave = d.check != DriftCheck::Broadcast;
        let by_bound = d.check != DriftCheck::PerSlave;
        let fresh = gate.passed == 0;
        let limit = d.spike_ns;
        let mut over = 0u16;
        let mut worst = (0u16, 0u32);
        if per_slave {
            for s in sh.line.found().iter().filter(|s| s.dc.has_system_time()) {
                let mag = diff_magnitude(s.last_diff_ns);
                if mag > limit {
                    over = over.saturating_add(1);
                }
                if mag >= worst.1 {
                    worst = (s.station, mag);
                }
            }
        }
        let bound = gate.bound.unwrap_or(u32::MAX);
        let bound_ok = !by_bound || bound <= limit;
        if by_bound && bound > worst.1 && worst.1 <= limit {
            worst = (0, bound);
        }
        let passed = over == 0 && bound_ok;
        // Running sums of the streak: restarted by its first check, kept only while it lasts.
        let keep = passed && !fresh;
        let count = usize::from(sh.line.count);
        for s in sh.line.slaves.iter_mut().take(count) {
            let mag = u64::from(diff_magnitude(s.last_diff_ns));
            let signed = s.last_diff_ns.unwrap_or(i64::MAX);
            if keep {
                s.diff_abs_sum = s.diff_abs_sum.saturating_add(mag);
                s.diff_sum = s.diff_sum.saturating_add(signed);
            } else {
                s.diff_abs_sum = mag;
                s.diff_sum = signed;
            }
        }
        gate.bound_sum = if keep {
            gate.bound_sum.saturating_add(u64::from(bound))
        } else {
            u64::from(bound)
        };
        gate.passed = if passed {
            gate.passed.saturating_add(1)
        } else {
            0
        };
        if gate.passed >= d.consecutive {
            let k = u64::from(gate.passed);
            let budget = u64::from(d.threshold_ns).saturating_mul(k);
            let scatter = u64::from(d.scatter_ns).saturating_mul(k);
            let means_ok = if per_slave {
                sh.line
                    .found()
                    .iter()
                    .filter(|s| s.dc.has_system_time())
                    .all(|s| s.diff_sum.unsigned_abs() <= budget && s.diff_abs_sum <= scatter)
            } else {
                gate.bound_sum <= budget
            };
            if means_ok {
                let max_diff_ns = if by_bound {
                    bound.max(worst.1)
                } else {
                    worst.1
                };
                sh.push_event(Event::DriftConverged {
                    frames: gate.frames,
                    max_diff_ns,
                });
                return Ok(if sh.cfg.sync.is_some() {
                    State::ReadReferenceTime
                } else {
                    State::Cyclic
                });
            }
            // Readings stayed in bounds but some mean did not settle: a new streak.
            gate.passed = 0;
        }
        if gate.frames >= d.max_frames {
            return Err(Error::NotConverged {
                frames: gate.frames,
                slaves_over: over.max(u16::from(!bound_ok)),
                worst_station: worst.0,
                worst_diff_ns: worst.1,
            });
        }
        Ok(State::DriftBurst)
    }
}

/// |0x092C| of a reading in ns, saturated; a missing reading counts as out of range.
fn diff_magnitude(d: Option<i64>) -> u32 {
    d.map_or(u32::MAX, |d| {
        u32::try_from(d.unsigned_abs()).unwrap_or(u32::MAX)
    })
}

#[cfg(test)]
mod tests {
    //! The convergence gate's streak rules and the FRMW that closes multi-frame checks
    //! (REQ-DC-104), on a machine put straight into `DriftCheck`.
    use crate::dc::config::{DriftCheck, DriftConfig};
    use crate::dc::slave::DcKind;
    use crate::dc::{Config, Event, Machine, State};
    use crate::time::SystemTime;
    use crate::wire::{Command, EthernetFrame};

    /// `slaves` 64-bit slaves (stations 0x1001, ...) in `DriftCheck`.
    fn in_check<const N: usize>(slaves: u16, check: DriftCheck) -> Machine<N> {
        let cfg = Config {
            drift: DriftConfig {
                threshold_ns: 100,
                scatter_ns: 200,
                spike_ns: 400,
                consecutive: 3,
                check,
                ..DriftConfig::default()
            },
            ..Config::default()
        };
        let kinds = std::vec![DcKind::Bits64; usize::from(slaves)];
        let mut m = crate::dc::testing::line_with::<N>(cfg, &kinds);
        m.phase = m.phase.enter(State::DriftCheck);
        m
    }

    /// One completed check with these per-slave readings (ns); the state it leads to.
    fn judge(m: &mut Machine<4>, readings: &[i64]) -> State {
        for (s, r) in m.sh.line.slaves.iter_mut().zip(readings) {
            s.last_diff_ns = Some(*r);
        }
        let next = m.drift_done().unwrap();
        m.phase = m.phase.enter(if next == State::DriftBurst {
            State::DriftCheck
        } else {
            next
        });
        next
    }

    #[test]
    fn streak_judges_signed_mean_scatter_and_spikes() {
        let mut m = in_check::<4>(2, DriftCheck::PerSlave);
        // A reading above the spike bound (400) does not open a streak.
        assert_eq!(judge(&mut m, &[401, 10]), State::DriftBurst);
        assert_eq!(m.phase.drift_gate().unwrap().passed, 0);
        // Noisy readings open and continue one ...
        assert_eq!(judge(&mut m, &[150, -80]), State::DriftBurst);
        assert_eq!(m.phase.drift_gate().unwrap().passed, 1);
        assert_eq!(judge(&mut m, &[-180, 20]), State::DriftBurst);
        assert_eq!(m.phase.drift_gate().unwrap().passed, 2);
        // ... and after K = 3 checks: slave 1's signed mean (150 − 180 + 90) / 3 = 20, its
        // mean |Δ| 140 ≤ 200; slave 2's −10 and 40. Converged (SYNC configured: the
        // reference time is read next).
        assert_eq!(judge(&mut m, &[90, 30]), State::ReadReferenceTime);
        assert!(matches!(
            m.poll_event(),
            Some(Event::DriftConverged {
                max_diff_ns: 90,
                ..
            })
        ));
    }

    #[test]
    fn streak_restarts_on_offset_swing_or_spike() {
        let mut m = in_check::<4>(2, DriftCheck::PerSlave);
        // Slave 2 sits 110 ns off on average: the offset misses the 100 ns threshold.
        assert_eq!(judge(&mut m, &[10, 100]), State::DriftBurst);
        assert_eq!(judge(&mut m, &[10, 120]), State::DriftBurst);
        assert_eq!(judge(&mut m, &[10, 110]), State::DriftBurst);
        assert_eq!(m.phase.drift_gate().unwrap().passed, 0);
        // Slave 1 swings ±300 around zero: signed mean 100 / 3, mean |Δ| 300 > 200.
        assert_eq!(judge(&mut m, &[300, 0]), State::DriftBurst);
        assert_eq!(judge(&mut m, &[-300, 0]), State::DriftBurst);
        assert_eq!(judge(&mut m, &[300, 0]), State::DriftBurst);
        assert_eq!(m.phase.drift_gate().unwrap().passed, 0);
        // A spike in the middle of a good streak restarts it.
        assert_eq!(judge(&mut m, &[10, 10]), State::DriftBurst);
        assert_eq!(judge(&mut m, &[10, -450]), State::DriftBurst);
        assert_eq!(m.phase.drift_gate().unwrap().passed, 0);
        assert!(m.poll_event().is_none());
    }

    #[test]
    fn broadcast_only_judges_the_bound_mean() {
        let mut m = in_check::<4>(2, DriftCheck::Broadcast);
        for (bound, ok) in [(100, 1), (190, 2)] {
            // Every bound within the spike bound (400) counts.
            m.phase.drift_gate_mut().unwrap().bound = Some(bound);
            assert_eq!(m.drift_done().unwrap(), State::DriftBurst);
            assert_eq!(m.phase.drift_gate().unwrap().passed, ok);
        }
        // Mean of 100, 190, 20 = 103 > 100: starts over.
        m.phase.drift_gate_mut().unwrap().bound = Some(20);
        assert_eq!(m.drift_done().unwrap(), State::DriftBurst);
        assert_eq!(m.phase.drift_gate().unwrap().passed, 0);
    }

    /// The error of a check judged at the frame limit, with these per-slave readings and
    /// broadcast bound.
    fn at_frame_limit(check: DriftCheck, readings: &[i64], bound: u32) -> crate::dc::Error {
        let mut m = in_check::<4>(2, check);
        let max = m.sh.cfg.drift.max_frames;
        let gate = m.phase.drift_gate_mut().unwrap();
        gate.frames = max;
        gate.bound = Some(bound);
        for (s, r) in m.sh.line.slaves.iter_mut().zip(readings) {
            s.last_diff_ns = Some(*r);
        }
        m.drift_done().unwrap_err()
    }

    /// `NotConverged` names the worst slave and its reading; the broadcast bound (station 0)
    /// only when no slave's own reading is out of range and the bound is strictly larger. A
    /// bound out of range counts as one slave over the limit when no slave's reading is.
    // verifies: REQ-DC-104
    #[test]
    fn not_converged_names_the_worst_reading() {
        use crate::dc::Error::NotConverged;
        let worst = |e| match e {
            NotConverged {
                slaves_over,
                worst_station,
                worst_diff_ns,
                ..
            } => (slaves_over, worst_station, worst_diff_ns),
            other => panic!("{other:?}"),
        };
        // A slave over the spike bound (400) is named, even beside a larger bound.
        assert_eq!(
            worst(at_frame_limit(DriftCheck::Both, &[-500, 0], 600)),
            (1, 0x1001, 500)
        );
        // In range: the larger bound is the worst reading ...
        assert_eq!(
            worst(at_frame_limit(DriftCheck::Both, &[100, -50], 300)),
            (0, 0, 300)
        );
        assert_eq!(
            worst(at_frame_limit(DriftCheck::Both, &[100, -50], 600)),
            (1, 0, 600)
        );
        // ... an equal one is not.
        assert_eq!(
            worst(at_frame_limit(DriftCheck::Both, &[100, -50], 100)),
            (0, 0x1001, 100)
        );
        // Per slave only, all readings 0: still a slave's station, never 0.
        let (over, station, ns) = worst(at_frame_limit(DriftCheck::PerSlave, &[0, 0], u32::MAX));
        assert_eq!(over, 0);
        assert!(matches!(station, 0x1001 | 0x1002), "{station:#x}");
        assert_eq!(ns, 0);
    }

    /// The check reads 0x092C only of slaves with a system time: an ESC with latches but no
    /// system time has no 0x092C to read.
    #[test]
    fn check_reads_only_slaves_with_a_system_time() {
        let mut m = in_check::<4>(3, DriftCheck::PerSlave);
        m.sh.line.slaves[1].dc = DcKind::DelayOnly;
        m.sh.line.sys_count = 2;
        let mut buf = [0u8; 1514];
        let n = m.poll_transmit(SystemTime(1_000_000), &mut buf).unwrap();
        let fprds: std::vec::Vec<u16> = crate::dc::testing::headers(&buf[..n])
            .into_iter()
            .filter(|h| h.0 == Command::Fprd)
            .map(|h| h.2)
            .collect();
        assert_eq!(fprds, [0x1001, 0x1003]);
    }

    /// A burst FRMW whose working counter is not the number of slaves with a system time is
    /// not counted as sent: the burst does not move on to the check.
    // verifies: REQ-DC-104
    #[test]
    fn burst_frmw_with_a_wrong_wkc_is_not_accepted() {
        for (wkc, next) in [(2, State::DriftCheck), (1, State::DriftBurst)] {
            let mut m = in_check::<4>(2, DriftCheck::PerSlave);
            m.sh.cfg.drift.burst_frames = 1;
            m.enter(State::DriftBurst);
            let mut buf = [0u8; 1514];
            let now = SystemTime(1_000_000);
            let n = m.poll_transmit(now, &mut buf).unwrap();
            assert_eq!(commands(&buf[..n]), [Command::Frmw]);
            answer(&mut m, now, &buf[..n], wkc);
            assert_eq!(m.state(), next, "WKC {wkc}");
        }
    }

    /// Commands of the datagrams in a frame, in order.
    fn commands(frame: &[u8]) -> std::vec::Vec<Command> {
        let eth = EthernetFrame::new_checked(frame).unwrap();
        let ecat = eth.ecat_frame().unwrap();
        ecat.iter().map(|d| d.unwrap().command().unwrap()).collect()
    }

    #[test]
    fn multi_frame_check_closes_all_but_its_last_frame_with_an_frmw() {
        // 40 slaves: BRD + 40 FPRD = 41 items; 31 fit beside the closing FRMW.
        let mut m = in_check::<64>(40, DriftCheck::Both);
        let mut buf = [0u8; 1514];
        let now = SystemTime::from_nanos(1_000_000);
        let n = m.poll_transmit(now, &mut buf).unwrap();
        let first = commands(&buf[..n]);
        assert_eq!(first.len(), 32);
        assert_eq!(first.first(), Some(&Command::Brd));
        assert_eq!(first.last(), Some(&Command::Frmw));
        assert_eq!(first.iter().filter(|c| **c == Command::Fprd).count(), 30);
        assert_eq!(m.phase.drift_gate().unwrap().frames, 1);
        // Answer it (WKC 1 per FPRD, 40 for BRD and FRMW), then the rest goes out without FRMW.
        let mut reply = buf[..n].to_vec();
        {
            let mut eth = EthernetFrame::new_unchecked(&mut reply[..]);
            eth.mark_processed_by_slave();
            let mut ecat = eth.ecat_frame_mut().unwrap();
            for d in ecat.iter_mut() {
                let mut d = d.unwrap();
                let wkc = if d.command().unwrap() == Command::Fprd {
                    1
                } else {
                    40
                };
                d.set_wkc(wkc);
            }
        }
        m.handle_frame(now, &reply);
        let n = m.poll_transmit(now, &mut buf).unwrap();
        let second = commands(&buf[..n]);
        assert_eq!(second.len(), 10);
        assert!(second.iter().all(|c| *c == Command::Fprd));
        assert_eq!(m.phase.drift_gate().unwrap().frames, 1);
    }

    /// The slaves' answer to `frame`, WKC `wkc` on every datagram, handed to `m`.
    fn answer(m: &mut Machine<4>, now: SystemTime, frame: &[u8], wkc: u16) {
        m.handle_frame(now, &crate::dc::testing::answer(frame, |_| wkc));
    }

    /// Polls every 10 µs from 1 ms while the machine stays in `state`; when each frame went
    /// out (every one a lone FRMW, answered at once).
    fn send_times(m: &mut Machine<4>, state: State) -> std::vec::Vec<u64> {
        let mut buf = [0u8; 1514];
        let mut sent = std::vec::Vec::new();
        let mut t = 1_000_000u64;
        while m.state() == state && t < 2_000_000 {
            if let Some(n) = m.poll_transmit(SystemTime(t), &mut buf) {
                assert_eq!(commands(&buf[..n]), [Command::Frmw]);
                sent.push(t);
                answer(m, SystemTime(t), &buf[..n], 2);
            }
            t += 10_000;
        }
        sent
    }

    /// Two slaves in a burst of 3 frames, the last paused until 50 µs after the one before.
    fn in_burst() -> Machine<4> {
        let mut m = in_check::<4>(2, DriftCheck::PerSlave);
        m.sh.cfg.drift.burst_frames = 3;
        m.sh.cfg.drift.check_pause_ns = 50_000;
        m.enter(State::DriftBurst);
        m
    }

    /// A burst is `burst_frames` FRMW frames back to back, its last one held back until
    /// `check_pause_ns` after the one before (REQ-DC-104); once a check has passed, a burst is
    /// that one paused frame.
    // verifies: REQ-DC-104
    #[test]
    fn burst_sends_its_frames_then_a_paused_last() {
        let mut m = in_burst();
        assert_eq!(m.drift_count(crate::dc::phase::DriftStep::Burst), 3);
        let times = send_times(&mut m, State::DriftBurst);
        assert_eq!(times, [1_000_000, 1_010_000, 1_060_000]);
        assert_eq!(m.state(), State::DriftCheck);
        // The check itself is not paced.
        let mut buf = [0u8; 1514];
        assert!(m.poll_transmit(SystemTime(1_070_000), &mut buf).is_some());
        // After a passed check the burst is one frame, paused after the last one sent.
        m.sh.stop_awaiting();
        m.phase.drift_gate_mut().unwrap().passed = 1;
        m.enter(State::DriftBurst);
        m.sh.last_sent = SystemTime(1_000_000);
        assert_eq!(m.drift_count(crate::dc::phase::DriftStep::Burst), 1);
        assert_eq!(send_times(&mut m, State::DriftBurst), [1_050_000]);
        assert_eq!(m.state(), State::DriftCheck);
    }

    /// While a burst frame's reply is awaited the next deadline is the reply's, even when the
    /// pause before the burst's last frame would end sooner.
    #[test]
    fn awaited_reply_outranks_the_burst_pause() {
        let mut m = in_burst();
        let mut buf = [0u8; 1514];
        for t in [1_000_000u64, 1_010_000] {
            let n = m.poll_transmit(SystemTime(t), &mut buf).unwrap();
            let timeout = m.sh.cfg.response_timeout_ns;
            assert_eq!(m.poll_timeout(), Some(SystemTime(t + timeout)));
            answer(&mut m, SystemTime(t), &buf[..n], 2);
        }
        // Answered: the pause before the last frame is the deadline.
        assert_eq!(m.poll_timeout(), Some(SystemTime(1_060_000)));
    }

    /// The FRMW closing a check frame is checked like any reply: a working counter other than
    /// the number of slaves with a system time fails the chunk, which is sent again.
    #[test]
    fn closing_frmw_with_a_wrong_wkc_is_retried() {
        for (frmw_wkc, retries) in [(40, 0), (39, 1)] {
            let mut m = in_check::<64>(40, DriftCheck::Both);
            let mut buf = [0u8; 1514];
            let now = SystemTime::from_nanos(1_000_000);
            let n = m.poll_transmit(now, &mut buf).unwrap();
            let reply = crate::dc::testing::answer(&buf[..n], |cmd| match cmd {
                Command::Fprd => 1,
                Command::Frmw => frmw_wkc,
                _ => 40,
            });
            m.handle_frame(now, &reply);
            assert_eq!(m.stats().retries, retries, "FRMW WKC {frmw_wkc}");
        }
    }

    /// A caller's frame with room for the closing FRMW but not for a read beside it gets
    /// nothing: no lone FRMW, and no `BufferTooSmall` (the frame was not empty).
    #[test]
    fn no_lone_frmw_in_a_full_caller_frame() {
        let mut m = in_check::<4>(2, DriftCheck::Both);
        let mut buf = [0u8; 1514];
        let mut b = crate::wire::FrameBuilder::new(&mut buf).unwrap();
        // 1 514 − 14 − 2 − 12 − 1 461 = 25 bytes left: an FRMW (20) fits, a BRD (16) and an
        // FRMW do not.
        let data = [0u8; 1461];
        b.push(Command::Lrw, 1, crate::wire::Address::logical(0), &data)
            .unwrap();
        assert!(!m.poll_transmit_into(SystemTime(1_000_000), &mut b));
        assert_eq!(b.datagram_count(), 1);
        assert!(m.poll_event().is_none());
        assert!(!m.is_awaiting_reply());
    }

    /// A check frame keeps room for its closing FRMW: in a buffer that holds the BRD, two
    /// FPRDs and an FRMW (16 + 16 + 16 + 20 bytes of datagrams), a third FPRD would fit but
    /// leave the FRMW out, so the frame stops before it.
    #[test]
    fn check_frame_keeps_room_for_its_frmw() {
        let mut m = in_check::<64>(40, DriftCheck::Both);
        let mut buf = [0u8; 14 + 2 + 16 * 3 + 20];
        let n = m.poll_transmit(SystemTime(1_000_000), &mut buf).unwrap();
        assert_eq!(
            commands(&buf[..n]),
            [Command::Brd, Command::Fprd, Command::Fprd, Command::Frmw]
        );
    }
}
