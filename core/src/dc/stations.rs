//! Where the slaves' station addresses come from (REQ-DC-100, REQ-DC-140): assigned by the
//! machine, or adopted from a host master that addressed the slaves already.

use crate::dc::error::Error;
use crate::dc::machine::{Item, Machine};
use crate::dc::request::{Op, Payload, Pending};
use crate::wire::register::{reg, typed};
use crate::wire::{Address, Command};

/// How the bring-up gets each slave's configured station address (0x0010).
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{Config, Machine, Stations};
///
/// // The host master (SOEM, IgH, ethercrab) assigned 0x0010 already: read and keep them.
/// let cfg = Config {
///     stations: Stations::Adopt,
///     ..Config::DEFAULT
/// };
/// let dc = Machine::<16>::new(cfg)?;
/// assert_eq!(dc.config().stations, Stations::Adopt);
/// assert_eq!(Config::default().stations, Stations::Assign);
/// # Ok::<(), ecdc_core::dc::ConfigError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Stations {
    /// APWR 0x0010 of position `i` with `Config::station_base + i` (REQ-DC-100).
    #[default]
    Assign,
    /// APRD 0x0010 of every position and address each slave by the value read, writing no
    /// station address (REQ-DC-140): for a host master (ethercrab, SOEM, IgH) that assigned
    /// the addresses itself and keeps using them. `Config::station_base` is then unused.
    Adopt,
}

impl<const N: usize> Machine<N> {
    /// The request of the address step for position `i`.
    pub(crate) fn station_item(&self, i: u16) -> Item {
        match self.sh.cfg.stations {
            Stations::Assign => Item::Send(Op {
                command: Command::Apwr,
                address: Address::position(i, reg::STATION_ADDRESS),
                len: 2,
                payload: Payload::Le(u64::from(self.station_of(i))),
            }),
            Stations::Adopt => Item::Send(Op {
                command: Command::Aprd,
                address: Address::position(i, reg::STATION_ADDRESS),
                len: 2,
                payload: Payload::Zero,
            }),
        }
    }

    /// The station address of position `i` from the reply of its address step (`data` = the
    /// 2 bytes read back in `Adopt`). An adopted address of 0 (an unaddressed ESC's reset
    /// value) or one that an earlier position already has would make configured-address
    /// commands miss or hit two slaves, so it is rejected as out of range.
    pub(crate) fn station_reply(&self, i: u16, p: Pending, data: &[u8]) -> Result<u16, Error> {
        match self.sh.cfg.stations {
            Stations::Assign => Ok(self.station_of(i)),
            Stations::Adopt => {
                let bad = Error::OutOfRange {
                    station: 0,
                    register: p.register,
                };
                let station = typed::STATION_ADDRESS.decode(data).map_err(|_| bad)?;
                let taken =
                    (0..i).any(|q| self.sh.line.slave(q).is_some_and(|s| s.station == station));
                if station == 0 || taken {
                    return Err(Error::OutOfRange {
                        station,
                        register: p.register,
                    });
                }
                Ok(station)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    //! REQ-DC-140 on the wire: the address step reads, never writes, and the adopted
    //! addresses are what the machine uses; unaddressed and duplicate addresses are refused.

    use crate::dc::{Config, Error, Event, Machine, State, Stations};
    use crate::time::SystemTime;
    use crate::wire::{Command, EthernetFrame};
    use std::vec::Vec;

    const T0: u64 = 800_000_000_000_000_000;

    fn adopting() -> Machine<4> {
        Machine::new(Config {
            stations: Stations::Adopt,
            auto_restart: false,
            ..Config::default()
        })
        .unwrap()
    }

    /// Answers `frame` as ESCs would: processed MAC, WKC 1 per datagram (`wkc` for the
    /// first), and the datagram's data from `data(i)` for the i-th datagram.
    fn answer(frame: &[u8], wkc: u16, data: impl Fn(usize) -> Option<[u8; 2]>) -> Vec<u8> {
        let mut out = frame.to_vec();
        let mut eth = EthernetFrame::new_unchecked(&mut out[..]);
        eth.mark_processed_by_slave();
        let mut ecat = eth.ecat_frame_mut().unwrap();
        for (i, d) in ecat.iter_mut().enumerate() {
            let mut d = d.unwrap();
            d.set_wkc(wkc);
            if let Some(v) = data(i) {
                d.data_mut()[..2].copy_from_slice(&v);
            }
        }
        out
    }

    fn commands(frame: &[u8]) -> Vec<(Command, u16, u16)> {
        let eth = EthernetFrame::new_checked(frame).unwrap();
        let f = eth.ecat_frame().unwrap();
        f.iter()
            .map(|d| {
                let d = d.unwrap();
                (d.command().unwrap(), d.adp(), d.ado())
            })
            .collect()
    }

    /// Counts 3 slaves and returns the address step's frame.
    fn to_address_step(m: &mut Machine<4>, buf: &mut [u8]) -> Vec<u8> {
        m.start(SystemTime(T0));
        let n = m.poll_transmit(SystemTime(T0), buf).unwrap();
        let count = buf[..n].to_vec();
        m.handle_frame(SystemTime(T0 + 1_000), &answer(&count, 3, |_| None));
        let n = m.poll_transmit(SystemTime(T0 + 1_000), buf).unwrap();
        assert_eq!(m.state(), State::AssignAddresses);
        buf[..n].to_vec()
    }

    #[test]
    fn adopt_reads_the_addresses_and_uses_them() {
        let mut m = adopting();
        let mut buf = [0u8; 1514];
        let step = to_address_step(&mut m, &mut buf);
        // One APRD 0x0010 per position (ADP 0, −1, −2), no write.
        let c = commands(&step);
        assert_eq!(
            c,
            [
                (Command::Aprd, 0x0000, 0x0010),
                (Command::Aprd, 0xFFFF, 0x0010),
                (Command::Aprd, 0xFFFE, 0x0010),
            ]
        );
        // The host's scheme is not ecdc's: 0x1000 + 7·i.
        let host = |i: usize| Some((0x1000u16 + 7 * i as u16).to_le_bytes());
        m.handle_frame(SystemTime(T0 + 2_000), &answer(&step, 1, host));
        let stations: Vec<u16> = m.slaves().iter().map(|s| s.station).collect();
        assert_eq!(stations, [0x1000, 0x1007, 0x100E]);
        // The next step addresses the slaves by the adopted addresses.
        let n = m.poll_transmit(SystemTime(T0 + 2_000), &mut buf).unwrap();
        assert_eq!(m.state(), State::ReadInfo);
        let read: Vec<u16> = commands(&buf[..n])
            .iter()
            .map(|&(cmd, adp, _)| {
                assert_eq!(cmd, Command::Fprd);
                adp
            })
            .collect();
        assert_eq!(read, [0x1000, 0x1000, 0x1007, 0x1007, 0x100E, 0x100E]);
    }

    #[test]
    fn assign_still_writes_station_base_plus_position() {
        let mut m: Machine<4> = Machine::new(Config {
            station_base: 0x2000,
            ..Config::default()
        })
        .unwrap();
        let mut buf = [0u8; 1514];
        let step = to_address_step(&mut m, &mut buf);
        assert!(commands(&step)
            .iter()
            .all(|&(cmd, _, ado)| cmd == Command::Apwr && ado == 0x0010));
        m.handle_frame(SystemTime(T0 + 2_000), &answer(&step, 1, |_| None));
        let stations: Vec<u16> = m.slaves().iter().map(|s| s.station).collect();
        assert_eq!(stations, [0x2000, 0x2001, 0x2002]);
    }

    fn rejected(addresses: [u16; 3]) -> Vec<Event> {
        let mut m = adopting();
        let mut buf = [0u8; 1514];
        let mut t = T0 + 2_000;
        let mut step = to_address_step(&mut m, &mut buf);
        // The first try and every retry get the same addresses.
        while m.state() == State::AssignAddresses {
            m.handle_frame(
                SystemTime(t),
                &answer(&step, 1, |i| addresses.get(i).map(|a| a.to_le_bytes())),
            );
            t += 1_000;
            match m.poll_transmit(SystemTime(t), &mut buf) {
                Some(n) => step = buf[..n].to_vec(),
                None => break,
            }
        }
        assert_eq!(m.state(), State::Failed);
        core::iter::from_fn(|| m.poll_event()).collect()
    }

    #[test]
    fn adopt_rejects_unaddressed_and_duplicate_stations() {
        let zero = Error::OutOfRange {
            station: 0,
            register: 0x0010,
        };
        assert!(rejected([0x1000, 0, 0x1002]).contains(&Event::Error(zero)));
        let dup = Error::OutOfRange {
            station: 0x1000,
            register: 0x0010,
        };
        assert!(rejected([0x1000, 0x1001, 0x1000]).contains(&Event::Error(dup)));
    }
}
