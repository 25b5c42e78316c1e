//! What the machine's unit tests share: DL status bits, a slave table filled in place, and the
//! answer the slaves would give to a frame.

use crate::dc::slave::DcKind;
use crate::dc::{Config, Machine};
use crate::wire::{Command, EthernetFrame};

/// DL status (0x0110): port `n` open (loop open, communication established).
pub(crate) const fn open(n: u16) -> u16 {
    1 << (9 + 2 * n)
}

/// DL status (0x0110): port `n` closed (loop closed).
pub(crate) const fn closed(n: u16) -> u16 {
    1 << (8 + 2 * n)
}

/// A machine in `Idle` whose slave table holds one slave of each of `kinds`, at stations
/// 0x1001, 0x1002, ... (the phase is the caller's to set).
pub(crate) fn line<const N: usize>(kinds: &[DcKind]) -> Machine<N> {
    line_with(Config::default(), kinds)
}

/// [`line`] with configuration `cfg`.
pub(crate) fn line_with<const N: usize>(cfg: Config, kinds: &[DcKind]) -> Machine<N> {
    let mut m = Machine::<N>::new(cfg).unwrap();
    let count = u16::try_from(kinds.len()).unwrap();
    m.sh.line.count = count;
    m.sh.line.sys_count =
        u16::try_from(kinds.iter().filter(|k| k.has_system_time()).count()).unwrap();
    for (i, (s, dc)) in m.sh.line.slaves.iter_mut().zip(kinds).enumerate() {
        s.station = 0x1001 + u16::try_from(i).unwrap();
        s.dc = *dc;
    }
    m
}

/// The slaves' answer to `frame`: marked processed, each datagram's working counter `wkc` of
/// its command.
pub(crate) fn answer(frame: &[u8], wkc: impl Fn(Command) -> u16) -> std::vec::Vec<u8> {
    let mut out = frame.to_vec();
    let mut eth = EthernetFrame::new_unchecked(&mut out[..]);
    eth.mark_processed_by_slave();
    for d in eth.ecat_frame_mut().unwrap().iter_mut() {
        let mut d = d.unwrap();
        let w = wkc(d.command().unwrap());
        d.set_wkc(w);
    }
    out
}

/// [`line`] put straight into `Cyclic`, its first cycle due at once.
pub(crate) fn in_cyclic<const N: usize>(kinds: &[DcKind]) -> Machine<N> {
    let mut m = line::<N>(kinds);
    m.phase = m.phase.enter(crate::dc::State::Cyclic);
    m.sh.timers
        .set(crate::dc::timer::Timer::Cycle, crate::time::SystemTime(0));
    m
}

/// Command, index, ADP, ADO and data length of every datagram of `frame`, in order.
pub(crate) fn headers(frame: &[u8]) -> std::vec::Vec<(Command, u8, u16, u16, u16)> {
    let eth = EthernetFrame::new_checked(frame).unwrap();
    let ecat = eth.ecat_frame().unwrap();
    ecat.iter()
        .map(|d| {
            let d = d.unwrap();
            (
                d.command().unwrap(),
                d.index(),
                d.adp(),
                d.ado(),
                d.data_len(),
            )
        })
        .collect()
}
