//! Discovery (REQ-DC-100): count the slaves, give each a station address (or adopt the host
//! master's, REQ-DC-140), read what each one can do (0x0008 features, 0x0110 DL status) and
//! which DC slaves really have a system time.

use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::{Item, Machine};
use crate::dc::phase::{DiscoveryStep, Phase};
use crate::dc::request::{Op, Reply};
use crate::dc::shared::expect_wkc;
use crate::dc::slave::{DcKind, SlaveInfo};
use crate::dc::state::State;
use crate::dc::work::PerSlave;
use crate::wire::register::{reg, typed, DlStatus, EscFeatures};

/// The reads of `ReadInfo`, per slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum InfoRead {
    /// 0x0008.
    Features,
    /// 0x0110.
    DlStatus,
}

impl PerSlave for InfoRead {
    const ALL: &'static [Self] = &[InfoRead::Features, InfoRead::DlStatus];
}

impl InfoRead {
    const fn register(self) -> u16 {
        match self {
            InfoRead::Features => reg::ESC_FEATURES,
            InfoRead::DlStatus => reg::DL_STATUS,
        }
    }
}

impl<const N: usize> Machine<N> {
    /// Items of a discovery step.
    pub(crate) fn discovery_count(&self, step: DiscoveryStep) -> u16 {
        let n = self.sh.line.count;
        match step {
            DiscoveryStep::CountSlaves => 1u16.saturating_add(u16::from(self.sh.tdiff.recovering)),
            DiscoveryStep::AssignAddresses | DiscoveryStep::ProbeSystemTime => n,
            DiscoveryStep::ReadInfo => InfoRead::items(n),
        }
    }

    pub(crate) fn discovery_item(&self, i: u16) -> Item {
        match self.phase {
            // BRD of the 2-byte type/revision word: every slave increments the WKC.
            Phase::Discovery(DiscoveryStep::CountSlaves) => Item::Send(Op::brd(0x0000, 2)),
            Phase::Discovery(DiscoveryStep::AssignAddresses) => self.station_item(i),
            Phase::Discovery(DiscoveryStep::ReadInfo) => match InfoRead::of(i) {
                Some((pos, read)) => {
                    let station = self.sh.line.slave(pos).map_or(0, |s| s.station);
                    Item::Send(Op::fprd(station, read.register(), 2))
                }
                None => Item::Skip,
            },
            Phase::Discovery(DiscoveryStep::ProbeSystemTime) => match self.sh.line.slave(i) {
                Some(s) if s.dc.has_latches() => {
                    Item::Send(Op::fprd(s.station, reg::SYSTEM_TIME, 4))
                }
                _ => Item::Skip,
            },
            _ => Item::Skip,
        }
    }

    /// Station address given to position `pos`; `Config::validate` keeps it in range.
    pub(crate) fn station_of(&self, pos: u16) -> u16 {
        self.sh.cfg.station_base.wrapping_add(pos)
    }

    pub(crate) fn discovery_reply(&mut self, r: Reply<'_>) -> Result<(), Error> {
        let (i, p, wkc, data) = r.parts();
        match self.phase {
            Phase::Discovery(DiscoveryStep::CountSlaves) => {
                if wkc == 0 {
                    return Err(Error::NoSlaves);
                }
                let cap = u16::try_from(N).unwrap_or(u16::MAX);
                if wkc > cap {
                    return Err(Error::TooManySlaves {
                        found: wkc,
                        capacity: cap,
                    });
                }
                self.sh.line.count = wkc;
                for s in self.sh.line.slaves.iter_mut() {
                    *s = SlaveInfo::default();
                }
                Ok(())
            }
            Phase::Discovery(DiscoveryStep::AssignAddresses) => {
                expect_wkc(p, 1, wkc)?;
                let station = self.station_reply(i, p, data)?;
                if let Some(s) = self.sh.line.slave_mut(i) {
                    s.station = station;
                }
                Ok(())
            }
            Phase::Discovery(DiscoveryStep::ReadInfo) => {
                expect_wkc(p, 1, wkc)?;
                let Some((pos, read)) = InfoRead::of(i) else {
                    return Ok(());
                };
                let v = match read {
                    InfoRead::Features => typed::ESC_FEATURES.decode(data),
                    InfoRead::DlStatus => typed::DL_STATUS.decode(data),
                }
                .map_err(|_| p.out_of_range())?;
                if let Some(s) = self.sh.line.slave_mut(pos) {
                    match read {
                        InfoRead::Features => {
                            s.features = v;
                            let f = EscFeatures(v);
                            s.dc = match (f.dc_supported(), f.dc_64bit()) {
                                (false, _) => DcKind::None,
                                (true, false) => DcKind::Bits32,
                                (true, true) => DcKind::Bits64,
                            };
                        }
                        InfoRead::DlStatus => s.dl_status = v,
                    }
                }
                Ok(())
            }
            Phase::Discovery(DiscoveryStep::ProbeSystemTime) => {
                // IgH `fsm_slave_scan.c`: WKC 1 = system time present, 0 = latches only.
                if wkc > 1 {
                    return expect_wkc(p, 1, wkc);
                }
                if let Some(s) = self.sh.line.slave_mut(i) {
                    if wkc == 0 {
                        s.dc = DcKind::DelayOnly;
                    }
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    pub(crate) fn discovery_done(&mut self) -> Result<State, Error> {
        match self.phase {
            Phase::Discovery(DiscoveryStep::CountSlaves) => Ok(State::AssignAddresses),
            Phase::Discovery(DiscoveryStep::AssignAddresses) => Ok(State::ReadInfo),
            Phase::Discovery(DiscoveryStep::ReadInfo) => {
                // A slave's own entry port must show a link, or the DL status is garbage.
                for pos in self.positions() {
                    if let Some(s) = self.sh.line.slave(pos) {
                        if !DlStatus(s.dl_status).any_link() {
                            return Err(Error::OutOfRange {
                                station: s.station,
                                register: reg::DL_STATUS,
                            });
                        }
                    }
                }
                Ok(State::ProbeSystemTime)
            }
            Phase::Discovery(DiscoveryStep::ProbeSystemTime) => {
                let mut sys = 0u16;
                // implements: REQ-DC-003
                let mut reference = None;
                for pos in self.positions() {
                    if let Some(s) = self.sh.line.slave(pos) {
                        if s.dc.has_system_time() {
                            sys = sys.saturating_add(1);
                            reference.get_or_insert(pos);
                        }
                    }
                }
                let reference = reference.ok_or(Error::NoReferenceClock)?;
                self.sh.line.reference = reference;
                self.sh.line.sys_count = sys;
                self.sh.push_event(Event::SlavesFound {
                    count: self.sh.line.count,
                    dc: sys,
                });
                Ok(State::TdiffRead)
            }
            _ => Ok(self.state()),
        }
    }
}
