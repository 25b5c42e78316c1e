//! Faults scheduled at true times: link breaks and restores, power, frame loss, frequency
//! steps, cable changes, wire silences and master stalls (REQ-ESC-091..093), and the network
//! events (loss rate, cable length) they queue for the frame path.

use super::{NetEvent, Network};
use crate::emu::esc::Scheduled;
use crate::emu::fault::Fault;
use crate::emu::{EmuError, TrueTime};

impl Network {
    /// Schedules a fault at true time `at` (≥ now).
    pub fn schedule_fault(&mut self, at: TrueTime, fault: Fault) -> Result<(), EmuError> {
        if at < self.now {
            return Err(EmuError::TimeInPast {
                t: at,
                now: self.now,
            });
        }
        match fault {
            // REQ-ESC-091: link state is a function of true time.
            Fault::LinkBreak { slave, port } | Fault::LinkRestore { slave, port } => {
                self.check_slave(slave)?;
                let id = self
                    .topo
                    .link_id(slave, port)
                    .ok_or(EmuError::NoSuchPort { slave, port })?;
                let up = matches!(fault, Fault::LinkRestore { .. });
                self.topo.set_link(id, at, up);
            }
            // REQ-ESC-093: reference loss is this fault on the reference slave.
            Fault::PowerOff { slave } => {
                self.check_slave(slave)?;
                self.topo.set_power(slave, at, false);
                self.escs[slave].schedule(at, Scheduled::PowerOff);
            }
            Fault::PowerOn { slave } => {
                self.check_slave(slave)?;
                self.topo.set_power(slave, at, true);
                self.escs[slave].schedule(at, Scheduled::PowerOn);
            }
            Fault::PowerCycle { slave, off_ns } => {
                self.schedule_fault(at, Fault::PowerOff { slave })?;
                self.schedule_fault(at.saturating_add(off_ns.max(1)), Fault::PowerOn { slave })?;
            }
            Fault::FrameLossRate { rate } => {
                if !(0.0..=1.0).contains(&rate) {
                    return Err(EmuError::Scenario("loss rate must be in [0, 1]".into()));
                }
                self.push_net_event(at, NetEvent::LossRate(rate));
            }
            Fault::FrequencyStep { slave, ppm } => {
                self.check_slave(slave)?;
                self.escs[slave].schedule(at, Scheduled::FrequencyPpb(ppm * 1000.0));
            }
            Fault::CableLength { slave, meters } => {
                self.check_slave(slave)?;
                let ns = (meters.max(0.0) * self.cable_ns_per_m).round() as u64;
                self.push_net_event(at, NetEvent::Cable { slave, ns });
            }
            Fault::PortTimeWrap { .. } => return Err(EmuError::NotSchedulable),
            Fault::WireSilence { duration_ns } => {
                self.silences.push((at, at.saturating_add(duration_ns)));
            }
            Fault::MasterStall { duration_ns } => {
                self.stalls.push((at, at.saturating_add(duration_ns)));
            }
        }
        Ok(())
    }

    /// Whether the wire is silent at true time `t` ([`Fault::WireSilence`]).
    pub(super) fn silent_at(&self, t: TrueTime) -> bool {
        self.silences.iter().any(|&(a, b)| a <= t && t < b)
    }

    /// The end of the [`Fault::MasterStall`] that covers true time `t`, if one does: the
    /// master must not act before it.
    pub fn master_stalled(&self, t: TrueTime) -> Option<TrueTime> {
        self.stalls
            .iter()
            .filter(|&&(a, b)| a <= t && t < b)
            .map(|&(_, b)| b)
            .max()
    }

    pub(super) fn push_net_event(&mut self, at: u64, e: NetEvent) {
        let pos = self.net_events.partition_point(|(x, _)| *x <= at);
        self.net_events.insert(pos, (at, e));
    }

    pub(super) fn apply_net_events(&mut self, t: u64) {
        while let Some((at, e)) = self.net_events.first().copied() {
            if at > t {
                break;
            }
            self.net_events.remove(0);
            match e {
                NetEvent::LossRate(r) => self.loss_rate = r,
                NetEvent::Cable { slave, ns } => {
                    if let Some(c) = self.topo.cable_ns.get_mut(slave) {
                        *c = ns;
                    }
                    if let Some(i) = self.info.get_mut(slave) {
                        i.cable_ns = ns;
                    }
                }
            }
        }
    }
}
