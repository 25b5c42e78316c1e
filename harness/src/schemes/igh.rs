//! An IgH-EtherLab-like master (IgH 1.5 with the Lambert patches: ribalda/ethercat `97e7ee6`,
//! `master/fsm_master.c`, `master/slave.c`, `master/fsm_slave_config.c`, `master/master.c`;
//! docs/bench.md), reproduced as a small independent master over the emulator so ecdc can be
//! compared with it. Written from a description of that code, not from IgH code.
//!
//! Idle phase (blocking, frames back to back, §2.1–§2.2):
//! 1. BRD count, APWR addresses, FPRD 0x0008 (DC supported, 32/64 bit), FPRD 0x0110 (ports),
//!    FPRD 0x0910 of every DC slave (working counter 1 = has a system time);
//! 2. reference clock = the first slave with DC and a system time;
//! 3. topology by the recursive port walk in position order, ports 3 → 1 → 2 (a port is open
//!    when its link is up and its loop is open);
//! 4. **one** BWR 0x0900 latch, FPRD 0x0900..0x090F of every DC slave;
//! 5. per DC slave and downstream port leading to a DC slave: `rtt(p) = t(p) − t(previous open
//!    port)`, `delay_to_next_dc = (rtt(p) − rtt_sum(next DC slave)) / 2` in **u32 wrapping
//!    arithmetic, no t_DIFF** (processing and forwarding delays are taken as equal); delays
//!    accumulated depth-first from the reference, adding the return leg of each branch.
//!
//! Operation phase (§2.3–§2.7): the application cycles at `cycle_ns` and every frame carries
//! `ecrt_master_sync_slave_clocks` (**FRMW of 4 bytes** to the reference's 0x0910, "master
//! follows reference": the reference is never written) plus the one datagram of the master /
//! slave configuration state machines for that cycle (IgH injects its FSM datagram into the
//! application's frame; one FSM step per cycle). The FSMs, one slave at a time:
//! - write system times: FPRD 28 bytes from 0x0910; `diff = app_time_sent − system_time`
//!   (app time = the cycle's application time, the same for every datagram of the cycle);
//!   `offset = old + diff` unless `|diff| ≤ 1 µs`; FPWR 12 bytes to 0x0920 (offset and the
//!   accumulated delay); then 0x0930 ← 0x1000 (Lambert filter reset). The propagation delay is
//!   **not** folded into the offset (left to the ESC loop, as IgH's manual says);
//! - slave configuration: 0x0980 ← 0; 0x09A0 ← SYNC0 cycle (8 bytes, SYNC1 = 0); **poll FPRD
//!   0x092C until |diff| ≤ 10 µs** (give up after 5 s and go on); start = app time + 100 ms,
//!   moved onto the cycle grid anchored at the **first** application time; 0x0990 ← start;
//!   0x0980 ← AssignActivate 0x0300.
//!
//! Not reproduced (not exercised by the bench scenarios): Lambert's bypassed-port detection and
//! upstream-port search (the emulator's upstream port is always 0), slaves running in
//! SAFEOP/OP (the offset-step guard), the 32-bit reference-clock read API.

use anyhow::{bail, Context};
use ecdc_core::wire::register::{reg, DlStatus, EscFeatures, SystemTimeDifference};
use ecdc_core::wire::{Address, Command};

use super::igh_steps::{assign_addresses, count_slaves, station};
use super::link::{le_u32, le_u64, SimLink};
use super::{Given, Scheme, Written};
use crate::emu::{Network, TrueTime};
use crate::schemes::cycle_grid::CycleGrid;
use crate::sim::DEFAULT_MASTER_EPOCH_NS;

/// `EC_SYSTEM_TIME_TOLERANCE_NS`: offset dead band.
pub const SYSTEM_TIME_TOLERANCE_NS: i64 = 1_000;
/// `EC_DC_MAX_SYNC_DIFF_NS`: the 0x092C gate before SYNC0 is programmed.
pub const MAX_SYNC_DIFF_NS: u32 = 10_000;
/// `EC_DC_SYNC_WAIT_MS`: how long the gate waits before going on anyway.
pub const SYNC_WAIT_NS: u64 = 5_000_000_000;
/// `EC_DC_START_OFFSET`: SYNC0 start lead.
pub const START_OFFSET_NS: u64 = 100_000_000;
/// AssignActivate word written to 0x0980 (SYNC0 only).
pub const ASSIGN_ACTIVATE: u16 = 0x0300;

/// Ports after port 0 in processing order.
const DOWNSTREAM: [usize; 3] = [3, 1, 2];

#[derive(Debug, Clone, Default)]
struct Slave {
    /// 0x0008 bit 2 (`base_dc_supported`).
    dc: bool,
    /// 0x0008 bit 3.
    dc64: bool,
    /// FPRD 0x0910 answered (`has_dc_system_time`).
    has_sys: bool,
    open: [bool; 4],
    times: [u32; 4],
    next: [Option<usize>; 4],
    delay_to_next_dc: [u32; 4],
    transmission_delay: u32,
}

/// One step of the master / slave configuration state machines (one datagram each).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    ReadTime(usize),
    WriteOffset(usize, u64),
    ResetFilter(usize),
    ClearSync(usize),
    WriteCycle(usize),
    CheckDiff(usize, TrueTime),
    WriteStart(usize),
    Activate(usize),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Idle,
    Operation,
}

/// The IgH-like master.
#[derive(Debug)]
pub struct Igh {
    link: SimLink,
    phase: Phase,
    cycle_ns: u32,
    slaves: Vec<Slave>,
    reference: usize,
    /// System-time slaves in position order (the FSMs' order).
    sys: Vec<usize>,
    step: Option<Step>,
    grid: CycleGrid,
    /// First application time (`dc_ref_time`, the phase anchor).
    dc_ref_time: Option<u64>,
    dist_frames: u64,
    static_frames: Option<u64>,
    written: Vec<Written>,
    /// Slaves whose 0x092C gate gave up after 5 s.
    pub gave_up: Vec<usize>,
}

fn fprd(link: &mut SimLink, i: usize, addr: u16, len: usize) -> anyhow::Result<(Vec<u8>, u16)> {
    let r = link.txn(&[(
        Command::Fprd,
        Address::configured(station(i), addr),
        &vec![0u8; len],
    )])?;
    let r = r.into_iter().next().context("no reply")?;
    Ok((r.data, r.wkc))
}

/// The first slave with receive times reached through `s` (itself if it has DC), depth first.
fn find_next_dc(slaves: &[Slave], s: usize) -> Option<usize> {
    let sl = slaves.get(s)?;
    if sl.dc {
        return Some(s);
    }
    DOWNSTREAM
        .iter()
        .filter_map(|&p| sl.next[p])
        .find_map(|c| find_next_dc(slaves, c))
}

/// The open port before `p` in processing order 0 → 3 → 1 → 2.
fn prev_open(sl: &Slave, p: usize) -> usize {
    let order = [0usize, 3, 1, 2];
    let k = order.iter().position(|&x| x == p).unwrap_or(0);
    order[..k]
        .iter()
        .rev()
        .copied()
        .find(|&q| sl.open[q])
        .unwrap_or(0)
}

/// Sum of the per-port round trips inside `s` (its ports that lead to another slave).
fn rtt_sum(sl: &Slave) -> u32 {
    DOWNSTREAM
        .iter()
        .filter(|&&p| sl.next[p].is_some())
        .fold(0u32, |acc, &p| {
            acc.wrapping_add(sl.times[p].wrapping_sub(sl.times[prev_open(sl, p)]))
        })
}

/// IgH's topology walk: `pos` is the next unassigned position; returns false if the ports
/// announce more slaves than were counted.
fn topology_rec(slaves: &mut [Slave], pos: &mut usize) -> bool {
    let me = *pos;
    for p in DOWNSTREAM {
        if !slaves[me].open[p] {
            continue;
        }
        *pos += 1;
        if *pos >= slaves.len() {
            return false;
        }
        slaves[me].next[p] = Some(*pos);
        if !topology_rec(slaves, pos) {
            return false;
        }
    }
    true
}

/// Per-port delays (IgH `calc_port_delays`, Lambert's previous-port rtt).
fn port_delays(slaves: &mut [Slave]) {
    for s in 0..slaves.len() {
        if !slaves[s].dc {
            continue;
        }
        for p in DOWNSTREAM {
            let Some(n) = slaves[s].next[p] else { continue };
            let Some(nd) = find_next_dc(slaves, n) else {
                continue;
            };
            let sl = &slaves[s];
            let rtt = sl.times[p].wrapping_sub(sl.times[prev_open(sl, p)]);
            let d = rtt.wrapping_sub(rtt_sum(&slaves[nd])) / 2;
            slaves[s].delay_to_next_dc[p] = d;
            slaves[nd].delay_to_next_dc[0] = d;
        }
    }
}

/// Depth-first accumulation from the reference (IgH `calc_transmission_delays_rec`).
fn transmission_delays_rec(slaves: &mut [Slave], s: usize, delay: &mut u32) {
    slaves[s].transmission_delay = *delay;
    for p in DOWNSTREAM {
        let Some(n) = slaves[s].next[p] else { continue };
        let Some(nd) = find_next_dc(slaves, n) else {
            continue;
        };
        *delay = delay.wrapping_add(slaves[s].delay_to_next_dc[p]);
        transmission_delays_rec(slaves, nd, delay);
        *delay = delay.wrapping_add(slaves[nd].delay_to_next_dc[0]);
    }
}

impl Igh {
    /// A master for `net` cycling (FRMW, SYNC0) at `cycle_ns`.
    pub fn new(net: Network, cycle_ns: u32) -> Self {
        Igh {
            link: SimLink::new(net),
            phase: Phase::Idle,
            cycle_ns,
            slaves: Vec::new(),
            reference: 0,
            sys: Vec::new(),
            step: None,
            grid: CycleGrid::new(cycle_ns),
            dc_ref_time: None,
            dist_frames: 0,
            static_frames: None,
            written: Vec::new(),
            gave_up: Vec::new(),
        }
    }

    /// The accumulated delays (`transmission_delay`) per slave.
    pub fn delays(&self) -> Vec<u32> {
        self.slaves.iter().map(|s| s.transmission_delay).collect()
    }

    /// The application (master) clock at true time `t`.
    fn app_time(t: TrueTime) -> u64 {
        DEFAULT_MASTER_EPOCH_NS.wrapping_add(t)
    }

    fn idle_phase(&mut self) -> anyhow::Result<()> {
        let link = &mut self.link;
        let n = count_slaves(link)?;
        if n == 0 {
            bail!("no slaves");
        }
        assign_addresses(link, n)?;
        let mut slaves = vec![Slave::default(); n];
        for (i, sl) in slaves.iter_mut().enumerate() {
            let (d, _) = fprd(link, i, reg::ESC_FEATURES, 2)?;
            let f = EscFeatures::parse(&d).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            sl.dc = f.dc_supported();
            sl.dc64 = f.dc_64bit();
            let (d, _) = fprd(link, i, reg::DL_STATUS, 2)?;
            let dl = DlStatus::parse(&d).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            for p in 0..4u8 {
                sl.open[usize::from(p)] = dl.link(p) && !dl.loop_closed(p);
            }
            if sl.dc {
                let (_, wkc) = fprd(link, i, reg::SYSTEM_TIME, if sl.dc64 { 8 } else { 4 })?;
                sl.has_sys = wkc == 1;
            }
        }
        let Some(reference) = slaves.iter().position(|s| s.has_sys) else {
            bail!("no slave with a DC system time");
        };
        let mut pos = 0usize;
        if !topology_rec(&mut slaves, &mut pos) || pos + 1 != n {
            bail!("topology walk does not match the slave count");
        }
        let dcs = slaves.iter().filter(|s| s.dc).count();
        link.one(
            Command::Bwr,
            Address::broadcast(reg::RECEIVE_TIME_PORT0),
            &[0u8; 4],
            u16::try_from(dcs).context("count")?,
        )?;
        for (i, sl) in slaves.iter_mut().enumerate() {
            if !sl.dc {
                continue;
            }
            let (d, _) = fprd(link, i, reg::RECEIVE_TIME_PORT0, 16)?;
            for p in 0..4 {
                sl.times[p] = le_u32(&d[4 * p..4 * p + 4]);
            }
        }
        port_delays(&mut slaves);
        let mut delay = 0u32;
        transmission_delays_rec(&mut slaves, reference, &mut delay);
        self.sys = (0..n).filter(|&i| slaves[i].has_sys).collect();
        self.written = vec![Written::default(); n];
        self.slaves = slaves;
        self.reference = reference;
        self.step = self.sys.first().map(|&i| Step::ReadTime(i));
        Ok(())
    }

    /// The datagram of a step: (command, address, data).
    fn datagram(&self, step: Step, app_time: u64) -> (Command, Address, Vec<u8>) {
        let at = |i: usize, a: u16| Address::configured(station(i), a);
        match step {
            Step::ReadTime(i) => (Command::Fprd, at(i, reg::SYSTEM_TIME), vec![0u8; 28]),
            Step::WriteOffset(i, off) => {
                let mut d = off.to_le_bytes().to_vec();
                d.extend_from_slice(&self.slaves[i].transmission_delay.to_le_bytes());
                (Command::Fpwr, at(i, reg::SYSTEM_TIME_OFFSET), d)
            }
            Step::ResetFilter(i) => (
                Command::Fpwr,
                at(i, reg::SPEED_COUNTER_START),
                0x1000u16.to_le_bytes().to_vec(),
            ),
            Step::ClearSync(i) => (Command::Fpwr, at(i, reg::CYCLIC_UNIT_CONTROL), vec![0, 0]),
            Step::WriteCycle(i) => {
                let mut d = self.cycle_ns.to_le_bytes().to_vec();
                d.extend_from_slice(&0u32.to_le_bytes());
                (Command::Fpwr, at(i, reg::SYNC0_CYCLE), d)
            }
            Step::CheckDiff(i, _) => (
                Command::Fprd,
                at(i, reg::SYSTEM_TIME_DIFFERENCE),
                vec![0u8; 4],
            ),
            Step::WriteStart(i) => {
                let cycle = u64::from(self.cycle_ns.max(1));
                let anchor = self.dc_ref_time.unwrap_or(app_time);
                let start = app_time.wrapping_add(START_OFFSET_NS);
                let rem = start.wrapping_sub(anchor) % cycle;
                let start = start.wrapping_add(cycle - rem);
                (
                    Command::Fpwr,
                    at(i, reg::SYNC0_START_TIME),
                    start.to_le_bytes().to_vec(),
                )
            }
            Step::Activate(i) => (
                Command::Fpwr,
                at(i, reg::CYCLIC_UNIT_CONTROL),
                ASSIGN_ACTIVATE.to_le_bytes().to_vec(),
            ),
        }
    }

    /// The step after the system-time slave `i`'s configuration, or the first configuration
    /// step once every offset is written.
    fn after_offsets(&self, i: usize) -> Option<Step> {
        let k = self.sys.iter().position(|&x| x == i)?;
        match self.sys.get(k + 1) {
            Some(&j) => Some(Step::ReadTime(j)),
            None => self.sys.first().map(|&j| Step::ClearSync(j)),
        }
    }

    fn after_config(&self, i: usize) -> Option<Step> {
        let k = self.sys.iter().position(|&x| x == i)?;
        self.sys.get(k + 1).map(|&j| Step::ClearSync(j))
    }

    /// Handles the reply of `step`; returns the next step.
    fn handle(
        &mut self,
        step: Step,
        data: &[u8],
        wkc: u16,
        app_time: u64,
        t: TrueTime,
    ) -> Option<Step> {
        if wkc != 1 {
            // IgH retries a datagram whose working counter is wrong (EC_FSM_RETRIES).
            return Some(step);
        }
        match step {
            Step::ReadTime(i) => {
                let sl = &self.slaves[i];
                let old = le_u64(data.get(16..24).unwrap_or(&[]));
                let new = if sl.dc64 {
                    let sys = le_u64(data);
                    let diff = app_time.wrapping_sub(sys) as i64;
                    if diff.abs() > SYSTEM_TIME_TOLERANCE_NS {
                        old.wrapping_add(diff as u64)
                    } else {
                        old
                    }
                } else {
                    let sys = le_u32(data);
                    let old32 = old as u32;
                    let diff = (app_time as u32).wrapping_sub(sys) as i32;
                    if i64::from(diff).abs() > SYSTEM_TIME_TOLERANCE_NS {
                        u64::from(old32.wrapping_add(diff as u32))
                    } else {
                        u64::from(old32)
                    }
                };
                Some(Step::WriteOffset(i, new))
            }
            Step::WriteOffset(i, off) => {
                self.written[i] = Written {
                    offset: Some(off as i64),
                    delay: Some(self.slaves[i].transmission_delay),
                };
                Some(Step::ResetFilter(i))
            }
            Step::ResetFilter(i) => self.after_offsets(i),
            Step::ClearSync(i) => Some(Step::WriteCycle(i)),
            Step::WriteCycle(i) => Some(Step::CheckDiff(i, t)),
            Step::CheckDiff(i, since) => {
                let d = SystemTimeDifference::parse(data)
                    .map(|d| d.to_ns().unsigned_abs())
                    .unwrap_or(u32::MAX);
                if d <= MAX_SYNC_DIFF_NS {
                    Some(Step::WriteStart(i))
                } else if t.saturating_sub(since) >= SYNC_WAIT_NS {
                    self.gave_up.push(i);
                    Some(Step::WriteStart(i))
                } else {
                    Some(step)
                }
            }
            Step::WriteStart(i) => Some(Step::Activate(i)),
            Step::Activate(i) => {
                let next = self.after_config(i);
                if next.is_none() {
                    self.static_frames = Some(self.dist_frames);
                }
                next
            }
        }
    }

    /// One application cycle at true time `t`.
    fn cycle(&mut self, t: TrueTime) -> anyhow::Result<()> {
        let app_time = Self::app_time(t);
        self.dc_ref_time.get_or_insert(app_time);
        self.link.now = self.link.now.max(t);
        let frmw_data = [0u8; 4];
        let fsm = self.step.map(|s| (s, self.datagram(s, app_time)));
        let mut dgs: Vec<(Command, Address, &[u8])> = vec![(
            Command::Frmw,
            Address::configured(station(self.reference), reg::SYSTEM_TIME),
            &frmw_data,
        )];
        if let Some((_, (c, a, d))) = &fsm {
            dgs.push((*c, *a, d));
        }
        self.dist_frames += 1;
        let Some(replies) = self.link.try_txn(&dgs)? else {
            return Ok(()); // lost: the FSM resends its datagram next cycle
        };
        if let (Some((step, _)), Some(r)) = (fsm, replies.get(1)) {
            self.step = self.handle(step, &r.data, r.wkc, app_time, t);
        }
        Ok(())
    }
}

impl Scheme for Igh {
    fn name(&self) -> &'static str {
        "igh"
    }

    fn advance(&mut self, until: TrueTime) -> anyhow::Result<()> {
        if self.phase == Phase::Idle {
            self.idle_phase()?;
            self.grid.start_after(self.link.now);
            self.phase = Phase::Operation;
        }
        while let Some(t) = self.grid.take_before(until) {
            self.cycle(t)?;
        }
        self.link.advance_to(until)
    }

    sim_link_scheme!(fields);

    fn static_drift_frames(&self) -> Option<u64> {
        self.static_frames
    }

    fn given(&self) -> Given {
        // Delays without t_DIFF: the method has no per-ESC processing/forwarding split.
        Given::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(times: &[[u32; 4]]) -> Vec<Slave> {
        let n = times.len();
        times
            .iter()
            .enumerate()
            .map(|(i, t)| Slave {
                dc: true,
                dc64: true,
                has_sys: true,
                open: [true, i + 1 < n, false, false],
                times: *t,
                ..Slave::default()
            })
            .collect()
    }

    #[test]
    fn line_delays_are_half_round_trip_differences() {
        // Three slaves; port 1 returns 3000 / 1800 ns after port 0 on the first two.
        let mut s = line(&[[0, 3000, 0, 0], [500, 2300, 0, 0], [1100, 0, 0, 0]]);
        let mut pos = 0;
        assert!(topology_rec(&mut s, &mut pos));
        assert_eq!(pos, 2);
        assert_eq!(s[0].next[1], Some(1));
        port_delays(&mut s);
        let mut d = 0;
        transmission_delays_rec(&mut s, 0, &mut d);
        // (3000 − 1800) / 2 = 600; (1800 − 0) / 2 = 900.
        assert_eq!(s[1].transmission_delay, 600);
        assert_eq!(s[2].transmission_delay, 1500);
    }

    #[test]
    fn non_dc_slave_is_skipped_into_the_next_dc_slave() {
        let mut s = line(&[
            [0, 3000, 0, 0],
            [0, 0, 0, 0],
            [1100, 1900, 0, 0],
            [0, 0, 0, 0],
        ]);
        s[1].dc = false;
        s[1].has_sys = false;
        s[3].open = [true, false, false, false];
        let mut pos = 0;
        assert!(topology_rec(&mut s, &mut pos));
        port_delays(&mut s);
        let mut d = 0;
        transmission_delays_rec(&mut s, 0, &mut d);
        // Slave 2 is the next DC slave of slave 0: (3000 − 800) / 2.
        assert_eq!(s[2].transmission_delay, 1100);
        assert_eq!(s[1].transmission_delay, 0);
    }
}
