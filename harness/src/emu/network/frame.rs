//! One frame through the chain: the master's port serialises it, the walk orders the visits,
//! each EPU processes the frame at its true time, receive times are latched, losses and
//! silences decide whether anything comes back (REQ-ESC-004, 030, 082, 092).

use rand::Rng;

use super::{Delivery, LossReason, Network, Returned, Visit};
use crate::emu::datagram::{self, FrameClass, CIRCULATING, IFG_NS, SRC_MAC};
use crate::emu::esc::EpuCtx;
use crate::emu::{EmuError, TrueTime};

impl Network {
    /// Sends `frame` with its first bit leaving the master at `send_time` (≥ now) and returns
    /// what comes back. All slave effects of the frame happen at their true times.
    pub fn transact(&mut self, frame: &[u8], send_time: TrueTime) -> Result<Delivery, EmuError> {
        if send_time < self.now {
            return Err(EmuError::TimeInPast {
                t: send_time,
                now: self.now,
            });
        }
        self.now = send_time;
        self.apply_net_events(send_time);
        self.stats.frames += 1;
        // REQ-ESC-082: the master's port serialises frames (frame time + gap).
        let t0 = send_time.max(self.tx_free);
        let dur = datagram::wire_duration_ns(frame.len());
        self.tx_free = t0 + dur + IFG_NS;
        if self.escs.is_empty() || !self.port_open_master(t0) {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::NoLink));
        }
        if self.silent_at(t0) {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::Silence));
        }
        let mut buf = frame.to_vec();
        let mut spans = core::mem::take(&mut self.spans);
        let class = datagram::walk(&buf, &mut spans);
        let mut c = match (class, spans.first()) {
            (FrameClass::Ecat, Some(s)) => {
                u16::from_le_bytes([buf[s.start + 6], buf[s.start + 7]]) & CIRCULATING != 0
            }
            _ => false,
        };
        self.visits.clear();
        let t_in = t0 + self.master_cable_ns + self.jitter(true);
        let back = if !self.any_forced && self.topo.is_static() {
            // Port receive visits matter only to a frame that can latch (REQ-ESC-030: BWR or
            // FPWR covering 0x0900) or to a loss cut (it draws over the full visit count).
            let stamps = self.loss_rate > 0.0
                || spans.iter().any(|s| {
                    let c = datagram::Cmd::from_code(buf[s.start]);
                    let ado = usize::from(u16::from_le_bytes([buf[s.start + 4], buf[s.start + 5]]));
                    let latch_cmd = matches!(c, Some(datagram::Cmd::Bwr | datagram::Cmd::Fpwr));
                    latch_cmd && ado <= 0x0900 && ado + s.len > 0x0900
                });
            Some(self.walk_static(t_in, true, stamps))
        } else {
            let mut budget = 8 * self.escs.len() + 8;
            self.walk(0, t_in, &mut c, &mut budget, true)
        };
        // REQ-ESC-092: a lost frame is cut at a uniformly chosen visit; later ones commit
        // nothing and the master gets nothing.
        let injected = self.loss_rate > 0.0 && self.loss_rng.gen::<f64>() < self.loss_rate;
        let cut = if injected {
            self.loss_rng.gen_range(0..=self.visits.len())
        } else {
            self.visits.len()
        };
        let visits = core::mem::take(&mut self.visits);
        let mut first = true;
        // DL status is only computed when some datagram can read 0x0110 (it costs a
        // topology query per port).
        let wants_dl = spans.iter().any(|s| {
            let c = buf[s.start];
            let ado = usize::from(u16::from_le_bytes([buf[s.start + 4], buf[s.start + 5]]));
            let physical = (1..=9).contains(&c) || (13..=14).contains(&c);
            physical && ado <= 0x0111 && ado + s.len > 0x0110
        });
        // Some EPU latched receive times (else every `latch` entry stays false).
        let mut any_latch = false;
        for (k, v) in visits.iter().enumerate() {
            match *v {
                Visit::Epu { slave, t, set_c } => {
                    self.latch[slave] = false;
                    if k >= cut {
                        continue;
                    }
                    let dl = if wants_dl {
                        self.dl_status(slave, t)
                    } else {
                        0
                    };
                    let esc = &mut self.escs[slave];
                    esc.advance_to(t, &mut self.edges[slave]);
                    if class != FrameClass::Ecat || !esc.powered() {
                        continue;
                    }
                    if first {
                        // REQ-ESC-004: the first slave marks the frame as processed.
                        buf[SRC_MAC] |= 0x02;
                        first = false;
                    }
                    if set_c {
                        if let Some(s) = spans.first() {
                            buf[s.start + 7] |= (CIRCULATING >> 8) as u8;
                        }
                    }
                    let ctx = EpuCtx {
                        t_sof: t,
                        t_eof: t + dur,
                        dl_status: dl,
                    };
                    let r = esc.process(&mut buf, &spans, ctx, &mut self.edges[slave]);
                    self.any_forced |= esc.loop_control() != 0;
                    self.latch[slave] = r.latch;
                    any_latch |= r.latch;
                }
                Visit::Rx { slave, port, t } => {
                    if self.latch[slave] {
                        self.escs[slave].stamp_port(port, t);
                    }
                }
            }
        }
        if any_latch {
            for v in &visits {
                if let Visit::Epu { slave, .. } = v {
                    self.latch[*slave] = false;
                }
            }
        }
        self.visits = visits;
        self.spans = spans;
        let Some(back) = back else {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::Circulated));
        };
        if injected {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::Injected));
        }
        let first_bit = back + self.master_cable_ns + self.jitter(true);
        if self.silent_at(first_bit) {
            self.stats.lost += 1;
            return Ok(Delivery::Lost(LossReason::Silence));
        }
        self.stats.returned += 1;
        Ok(Delivery::Returned(Returned {
            frame: buf,
            first_bit,
            arrival: first_bit + dur,
            sent: t0,
            unprocessed: match class {
                FrameClass::Ecat => None,
                FrameClass::Forward(r) => Some(r),
            },
        }))
    }
}
