//! Static drift compensation with a convergence gate (REQ-DC-104): bursts of FRMW 0x0910 (one
//! per frame, each a loop sample in every slave) interleaved with 0x092C checks (per-slave FPRD
//! and/or the BRD upper bound). Done when every check of `consecutive` checks in a row is below
//! `threshold_ns`; a `NotConverged` error with the worst slave after `max_frames`. SYNC is
//! programmed only after this gate passed (REQ-DC-033).

use crate::dc::config::DriftCheck;
use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::{Item, Machine};
use crate::dc::request::{le, Op, Pending};
use crate::dc::state::State;
use crate::wire::register::{reg, SystemTimeDifference};

impl<const N: usize> Machine<N> {
    /// Frames of the current burst: `burst_frames` back to back while the gate has not passed
    /// yet; once a check passed, single paused frames, so the remaining `consecutive − 1` checks
    /// watch the loops at the cyclic sample rate they will run at (a loop held tight by
    /// back-to-back samples can drift off once samples come only every cycle).
    pub(crate) fn burst_len(&self) -> u16 {
        if self.drift_ok > 0 {
            1
        } else {
            self.cfg.drift.burst_frames
        }
    }

    /// Earliest master time the next item of the current step may go out: the last FRMW of a
    /// burst waits `check_pause_ns` after the previous frame (REQ-DC-104).
    pub(crate) fn pace_until(&self) -> u64 {
        let last_of_burst = self.burst_len().saturating_sub(1);
        if self.state == State::DriftBurst && self.cursor == last_of_burst {
            self.last_sent.saturating_add(self.cfg.drift.check_pause_ns)
        } else {
            0
        }
    }

    pub(crate) fn drift_item(&self, now: u64, i: u16) -> Item {
        match self.state {
            State::DriftBurst => Item::Send(self.frmw_op(now)),
            State::DriftCheck => {
                let check = self.cfg.drift.check;
                if i == 0 {
                    if check == DriftCheck::PerSlave {
                        return Item::Skip;
                    }
                    return Item::Send(Op::brd(reg::SYSTEM_TIME_DIFFERENCE, 4));
                }
                if check == DriftCheck::Broadcast {
                    return Item::Skip;
                }
                match self.slave(i.saturating_sub(1)) {
                    Some(s) if s.dc.has_system_time() => {
                        Item::Send(Op::fprd(s.station, reg::SYSTEM_TIME_DIFFERENCE, 4))
                    }
                    _ => Item::Skip,
                }
            }
            _ => Item::Skip,
        }
    }

    pub(crate) fn drift_reply(
        &mut self,
        i: u16,
        p: Pending,
        wkc: u16,
        data: &[u8],
    ) -> Result<(), Error> {
        match self.state {
            State::DriftBurst => self.check_frmw(p, wkc),
            State::DriftCheck => {
                // BRD 0x092C: only ESCs with a system time have the register.
                let expected = if i == 0 { self.sys_count } else { 1 };
                self.expect_wkc(p, expected, wkc)?;
                let raw =
                    le(data, 4)
                        .and_then(|v| u32::try_from(v).ok())
                        .ok_or(Error::OutOfRange {
                            station: p.station,
                            register: p.register,
                        })?;
                let d = SystemTimeDifference::from_raw(raw);
                if i == 0 {
                    self.drift_bound = Some(d.magnitude());
                } else if let Some(s) = self.slave_mut(i.saturating_sub(1)) {
                    s.last_diff_ns = Some(i64::from(d.to_ns()));
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    pub(crate) fn drift_done(&mut self) -> Result<State, Error> {
        match self.state {
            State::DriftBurst => Ok(State::DriftCheck),
            State::DriftCheck => {
                let thr = self.cfg.drift.threshold_ns;
                let check = self.cfg.drift.check;
                let mut over = 0u16;
                let mut worst = (0u16, 0u32);
                if check != DriftCheck::Broadcast {
                    for s in self.slaves().iter().filter(|s| s.dc.has_system_time()) {
                        let mag = s.last_diff_ns.map_or(u32::MAX, |d| {
                            u32::try_from(d.unsigned_abs()).unwrap_or(u32::MAX)
                        });
                        if mag > thr {
                            over = over.saturating_add(1);
                        }
                        if mag >= worst.1 {
                            worst = (s.station, mag);
                        }
                    }
                }
                let bound = self.drift_bound.unwrap_or(u32::MAX);
                let bound_ok = check == DriftCheck::PerSlave || bound <= thr;
                if check != DriftCheck::PerSlave && bound > worst.1 && worst.1 <= thr {
                    worst = (0, bound);
                }
                if over == 0 && bound_ok {
                    self.drift_ok = self.drift_ok.saturating_add(1);
                } else {
                    self.drift_ok = 0;
                }
                if self.drift_ok >= self.cfg.drift.consecutive {
                    let max_diff_ns = if check == DriftCheck::PerSlave {
                        worst.1
                    } else {
                        bound.max(worst.1)
                    };
                    self.push_event(Event::DriftConverged {
                        frames: self.drift_frames,
                        max_diff_ns,
                    });
                    return Ok(if self.cfg.sync.is_some() {
                        State::ReadReferenceTime
                    } else {
                        State::Cyclic
                    });
                }
                if self.drift_frames >= self.cfg.drift.max_frames {
                    return Err(Error::NotConverged {
                        frames: self.drift_frames,
                        slaves_over: over.max(u16::from(!bound_ok)),
                        worst_station: worst.0,
                        worst_diff_ns: worst.1,
                    });
                }
                Ok(State::DriftBurst)
            }
            _ => Ok(self.state),
        }
    }
}
