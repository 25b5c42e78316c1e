//! An ethercrab-like master (ethercrab HEAD `d4a7cfe`: `src/dc.rs`, `src/maindevice.rs`;
//! docs/bench.md), reproduced as a small independent master over the emulator. Written from a
//! description of that code; its documented bugs are **reproduced, not fixed**
//! (each marked `BUG (reproduced)` below and listed in docs/bench.md).
//!
//! Blocking bring-up, one PDU per frame, each awaited (as `init` does):
//! 1. reset (§3.6): BWR zeros to 0x0910, 0x0920, 0x0928, 0x092C, 0x0981, 0x0990, 0x09A0,
//!    0x09A4, then 0x0934 ← 0x0C00 and *after that* 0x0930 ← 0x1000;
//! 2. BRD count, APWR addresses, FPRD 0x0008 (None / RefOnly / Bits64 / Bits32), FPRD 0x0110
//!    (open ports = **physical link bits**);
//! 3. latch (§3.2): BWR 0x0900 (working counter must equal the number of DC devices), then per
//!    DC device FPRD 0x0918 (u64) and FPRD 0x0900 (4 × u32);
//! 4. parents and delays in list order over **all** devices (§3.1–§3.2): parent = the previous
//!    device, or, if that is a line end, the nearest earlier fork/cross; the parent's next free
//!    port after the entry port is assigned; per DC device an increment chosen by the parent's
//!    topology (Passthrough / Fork / Cross rules), added to **one running accumulator** in list
//!    order, in u32 with `saturating_sub`;
//! 5. offsets (§3.3): `now − 0x0918` written to 0x0920 (i64) and the accumulated delay to
//!    0x0928, working counters ignored; `now` is sampled once, after the latch and all reads;
//! 6. static drift (§3.4): **10 000 FRMW** (8 bytes, reference 0x0910), each awaited, no gate;
//! 7. SYNC0 (§3.7): read the reference's 0x0910 once, `start = ⌊(t + start_delay)/period⌋ ·
//!    period` (start_delay 100 ms as in ethercrab's example), per SYNC-capable device 0x0981 ←
//!    0, 0x0990 ← start (u64), 0x09A0 ← period **as u64** (zeroes 0x09A4), 0x0981 ← 0x03;
//!    0x0980 not written;
//! 8. cyclic (§3.5): one FRMW (8 bytes) to the reference's 0x0910 per cycle.
//!
//! Frame loss (docs/bench.md "Frame loss"; no loss handling of ethercrab's is documented, so
//! these are assumptions): a lost bring-up PDU is resent after the link's
//! timeout ([`super::link::RETRIES`] times at most); a lost static-sync or cyclic FRMW is not
//! resent, the loop goes on with the next one (it still counts as an iteration).

use anyhow::{bail, Context};
use ecdc_core::wire::register::{reg, DlStatus, EscFeatures};
use ecdc_core::wire::{Address, Command};

use super::igh_steps::{assign_addresses, count_slaves, station};
use super::link::{le_u32, le_u64, SimLink};
use super::{Given, Scheme, Written};
use crate::emu::{Network, TrueTime};
use crate::schemes::cycle_grid::CycleGrid;

/// `MainDeviceConfig::dc_static_sync_iterations` default.
pub const STATIC_SYNC_ITERATIONS: u64 = 10_000;
/// `DcConfiguration::start_delay` of ethercrab's DC example.
pub const START_DELAY_NS: u64 = 100_000_000;
/// `ethercat_now()` subtracts this from a nanosecond value (BUG (reproduced): it is the
/// 1970→2000 offset in *seconds*, so the DC epoch becomes host-monotonic nanoseconds).
pub const UNITS_SLIP_NS: u64 = 946_684_800;
/// Host uptime assumed for CLOCK_MONOTONIC at true time 0 (one day).
pub const MONOTONIC_AT_ZERO_NS: u64 = 86_400_000_000_000;

/// `DcSupport` from 0x0008.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DcSupport {
    #[default]
    None,
    /// DC without enhanced SYNC activation (bit 8): can be a reference, gets no SYNC0.
    RefOnly,
    Bits64,
    Bits32,
}

impl DcSupport {
    fn from_features(f: EscFeatures) -> Self {
        let enhanced = f.raw() & (1 << 8) != 0;
        match (f.dc_supported(), enhanced, f.dc_64bit()) {
            (false, _, _) => DcSupport::None,
            (true, false, _) => DcSupport::RefOnly,
            (true, true, true) => DcSupport::Bits64,
            (true, true, false) => DcSupport::Bits32,
        }
    }

    fn any(self) -> bool {
        self != DcSupport::None
    }
}

/// `Topology` from the number of open ports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Topology {
    LineEnd,
    Passthrough,
    Fork,
    Cross,
}

impl Topology {
    fn is_junction(self) -> bool {
        matches!(self, Topology::Fork | Topology::Cross)
    }
}

/// One port in ethercrab's storage order (0, 3, 1, 2).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Port {
    active: bool,
    time: u32,
    number: u8,
    downstream_to: Option<usize>,
}

/// Ports in processing order 0 → 3 → 1 → 2.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Ports([Port; 4]);

impl Ports {
    fn new(active: [bool; 4], times: [u32; 4]) -> Self {
        let mk = |n: u8| Port {
            active: active[usize::from(n)],
            time: times[usize::from(n)],
            number: n,
            downstream_to: None,
        };
        Ports([mk(0), mk(3), mk(1), mk(2)])
    }

    fn active(&self) -> impl Iterator<Item = (usize, &Port)> + Clone {
        self.0.iter().enumerate().filter(|(_, p)| p.active)
    }

    fn topology(&self) -> Topology {
        match self.active().count() {
            0 | 1 => Topology::LineEnd,
            2 => Topology::Passthrough,
            3 => Topology::Fork,
            _ => Topology::Cross,
        }
    }

    /// BUG (reproduced, #374): the entry port is the open port with the smallest raw 32-bit
    /// receive time, not wrap-safe.
    fn entry(&self) -> usize {
        self.active()
            .min_by_key(|(_, p)| p.time)
            .map_or(0, |(k, _)| k)
    }

    fn last(&self) -> Option<usize> {
        self.active().last().map(|(k, _)| k)
    }

    /// Next open, unassigned port after the entry port (cycling); assigns it.
    fn assign_next_downstream(&mut self, child: usize) -> Option<u8> {
        let entry = self.entry();
        let act: Vec<usize> = self.active().map(|(k, _)| k).collect();
        let k = act
            .iter()
            .cycle()
            .skip(entry + 1)
            .take(4)
            .copied()
            .find(|&k| self.0[k].downstream_to.is_none())?;
        self.0[k].downstream_to = Some(child);
        Some(self.0[k].number)
    }

    fn assigned_to(&self, child: usize) -> Option<usize> {
        self.active()
            .find(|(_, p)| p.downstream_to == Some(child))
            .map(|(k, _)| k)
    }

    /// max − min of the open ports' times (`None` if 0).
    fn total(&self) -> Option<u32> {
        let t = self.active().map(|(_, p)| p.time);
        let (mx, mn) = (t.clone().max()?, t.min()?);
        Some(mx.saturating_sub(mn)).filter(|&x| x > 0)
    }

    /// max − min over the open ports from the entry port up to storage index `k`.
    fn propagation_time_to(&self, k: usize) -> Option<u32> {
        let e = self.entry();
        let t = self
            .active()
            .filter(|(j, _)| *j >= e && *j <= k)
            .map(|(_, p)| p.time);
        let (mx, mn) = (t.clone().max()?, t.min()?);
        Some(mx.saturating_sub(mn)).filter(|&x| x > 0)
    }

    /// Sum of the deltas of adjacent (storage order) open port pairs before storage index `k`.
    fn intermediate_propagation_time_to(&self, k: usize) -> u32 {
        self.0
            .windows(2)
            .enumerate()
            .map(|(j, w)| {
                if j >= k || !(w[0].active && w[1].active) {
                    0
                } else {
                    w[1].time.saturating_sub(w[0].time)
                }
            })
            .fold(0u32, u32::saturating_add)
    }
}

#[derive(Debug, Clone, Default)]
struct Device {
    dc: DcSupport,
    ports: Ports,
    receive_time: u64,
    parent: Option<usize>,
    delay: u32,
}

/// ethercrab's parent rule: the previous device, or — if that one is a line end — the nearest
/// earlier junction. BUG (reproduced, #373): non-DC devices are parents like any other.
fn find_parent(devs: &[Device], i: usize) -> anyhow::Result<Option<usize>> {
    let Some(prev) = i.checked_sub(1) else {
        return Ok(None);
    };
    if devs[prev].ports.topology() == Topology::LineEnd {
        let split = (0..prev)
            .rev()
            .find(|&k| devs[k].ports.topology().is_junction())
            .with_context(|| format!("no fork parent for device {i}"))?;
        Ok(Some(split))
    } else {
        Ok(Some(prev))
    }
}

/// Parents, port assignment and accumulated delays, in list order (`configure_subdevice_offsets`).
fn assign_delays(devs: &mut [Device]) -> anyhow::Result<()> {
    let mut accum = 0u32;
    for i in 0..devs.len() {
        let parent = find_parent(devs, i)?;
        devs[i].parent = parent;
        if let Some(p) = parent {
            devs[p]
                .ports
                .assign_next_downstream(i)
                .with_context(|| format!("no free port on device {p} for device {i}"))?;
        }
        if !devs[i].dc.any() {
            continue;
        }
        let Some(p) = parent else { continue };
        let pp = &devs[p].ports;
        let Some(port) = pp.assigned_to(i) else {
            continue;
        };
        // A device is the parent's "child" when it hangs on one of the junction's ports
        // before the last open one.
        let is_child = pp.topology().is_junction() && pp.last() != Some(port);
        let parent_total = pp.total().unwrap_or(0);
        let own_total = devs[i].ports.total().unwrap_or(0);
        let inc = match pp.topology() {
            Topology::Passthrough => parent_total.saturating_sub(own_total) / 2,
            Topology::Fork if is_child => {
                pp.propagation_time_to(port)
                    .unwrap_or(0)
                    .saturating_sub(own_total)
                    / 2
            }
            Topology::Fork => parent_total.saturating_sub(own_total) / 2,
            Topology::Cross if is_child => {
                pp.intermediate_propagation_time_to(port)
                    .saturating_sub(own_total)
                    / 2
            }
            // BUG (reproduced): not halved, and the absolute accumulator is subtracted.
            Topology::Cross => parent_total.saturating_sub(accum),
            Topology::LineEnd => 0,
        };
        accum = accum.saturating_add(inc);
        devs[i].delay = accum;
    }
    Ok(())
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    BringUp,
    Burst,
    Sync,
    Cyclic,
}

/// The ethercrab-like master.
#[derive(Debug)]
pub struct Ethercrab {
    link: SimLink,
    phase: Phase,
    cycle_ns: u32,
    devs: Vec<Device>,
    reference: usize,
    burst_sent: u64,
    dist_frames: u64,
    grid: CycleGrid,
    written: Vec<Written>,
}

impl Ethercrab {
    /// A master for `net` with SYNC0 / FRMW period `cycle_ns`.
    pub fn new(net: Network, cycle_ns: u32) -> Self {
        Ethercrab {
            link: SimLink::new(net),
            phase: Phase::BringUp,
            cycle_ns,
            devs: Vec::new(),
            reference: 0,
            burst_sent: 0,
            dist_frames: 0,
            grid: CycleGrid::new(cycle_ns),
            written: Vec::new(),
        }
    }

    /// Delays written to 0x0928, per device.
    pub fn delays(&self) -> Vec<u32> {
        self.devs.iter().map(|d| d.delay).collect()
    }

    /// Parents found, per device.
    pub fn parents(&self) -> Vec<Option<usize>> {
        self.devs.iter().map(|d| d.parent).collect()
    }

    fn bwr(&mut self, addr: u16, data: &[u8]) -> anyhow::Result<u16> {
        let r = self
            .link
            .txn(&[(Command::Bwr, Address::broadcast(addr), data)])?;
        Ok(r.first().map_or(0, |r| r.wkc))
    }

    fn fprd(&mut self, i: usize, addr: u16, len: usize) -> anyhow::Result<Vec<u8>> {
        let r = self.link.txn(&[(
            Command::Fprd,
            Address::configured(station(i), addr),
            &vec![0u8; len],
        )])?;
        Ok(r.into_iter().next().map(|r| r.data).unwrap_or_default())
    }

    /// FPWR, working counter ignored (as ethercrab's DC writes do).
    fn fpwr(&mut self, i: usize, addr: u16, data: &[u8]) -> anyhow::Result<()> {
        self.link
            .txn(&[(Command::Fpwr, Address::configured(station(i), addr), data)])?;
        Ok(())
    }

    fn bring_up(&mut self) -> anyhow::Result<()> {
        // Reset (maindevice.rs).
        for (a, w) in [
            (reg::SYSTEM_TIME, 8),
            (reg::SYSTEM_TIME_OFFSET, 8),
            (reg::SYSTEM_TIME_DELAY, 4),
            (reg::SYSTEM_TIME_DIFFERENCE, 4),
            (reg::SYNC_ACTIVATION, 1),
            (reg::SYNC0_START_TIME, 8),
            (reg::SYNC0_CYCLE, 4),
            (reg::SYNC0_CYCLE + 4, 4),
        ] {
            self.bwr(a, &vec![0u8; w])?;
        }
        self.bwr(reg::SYSTEM_TIME_DIFF_FILTER_DEPTH, &0x0C00u16.to_le_bytes())?;
        self.bwr(reg::SPEED_COUNTER_START, &0x1000u16.to_le_bytes())?;
        // Discovery.
        let n = count_slaves(&mut self.link)?;
        if n == 0 {
            bail!("no devices");
        }
        assign_addresses(&mut self.link, n)?;
        let mut devs = vec![Device::default(); n];
        let mut active = vec![[false; 4]; n];
        for i in 0..n {
            let f = EscFeatures::parse(&self.fprd(i, reg::ESC_FEATURES, 2)?)
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            devs[i].dc = DcSupport::from_features(f);
            let dl = DlStatus::parse(&self.fprd(i, reg::DL_STATUS, 2)?)
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            for p in 0..4u8 {
                active[i][usize::from(p)] = dl.link(p);
            }
        }
        // Latch.
        let dcs = devs.iter().filter(|d| d.dc.any()).count();
        let wkc = self.bwr(reg::RECEIVE_TIME_PORT0, &[0u8; 4])?;
        if usize::from(wkc) != dcs {
            bail!("latch BWR working counter {wkc}, expected {dcs} DC devices");
        }
        for i in 0..n {
            let mut times = [0u32; 4];
            if devs[i].dc.any() {
                devs[i].receive_time = le_u64(&self.fprd(i, reg::RECEIVE_TIME_EPU, 8)?);
                let d = self.fprd(i, reg::RECEIVE_TIME_PORT0, 16)?;
                for (p, t) in times.iter_mut().enumerate() {
                    *t = le_u32(d.get(4 * p..).unwrap_or(&[]));
                }
            }
            devs[i].ports = Ports::new(active[i], times);
        }
        assign_delays(&mut devs)?;
        let Some(reference) = devs.iter().position(|d| d.dc.any()) else {
            bail!("no DC device");
        };
        // Offsets: `now` sampled once, after the latch and the reads.
        let now = MONOTONIC_AT_ZERO_NS
            .wrapping_add(self.link.now)
            .wrapping_sub(UNITS_SLIP_NS) as i64;
        self.written = vec![Written::default(); n];
        for (i, d) in devs.iter().enumerate() {
            if !d.dc.any() {
                continue;
            }
            let off = now.wrapping_sub(d.receive_time as i64);
            self.fpwr(i, reg::SYSTEM_TIME_OFFSET, &off.to_le_bytes())?;
            self.fpwr(i, reg::SYSTEM_TIME_DELAY, &d.delay.to_le_bytes())?;
            self.written[i] = Written {
                offset: Some(off),
                delay: Some(d.delay),
            };
        }
        self.devs = devs;
        self.reference = reference;
        Ok(())
    }

    /// One FRMW (8 bytes) to the reference's 0x0910, awaited.
    fn frmw(&mut self) -> anyhow::Result<bool> {
        frmw(&mut self.link, self.reference)
    }

    fn configure_sync(&mut self) -> anyhow::Result<()> {
        let t = le_u64(&self.fprd(self.reference, reg::SYSTEM_TIME, 8)?);
        let period = u64::from(self.cycle_ns.max(1));
        let start = (t.wrapping_add(START_DELAY_NS) / period).wrapping_mul(period);
        for i in 0..self.devs.len() {
            if !matches!(self.devs[i].dc, DcSupport::Bits64 | DcSupport::Bits32) {
                continue;
            }
            self.fpwr(i, reg::SYNC_ACTIVATION, &[0])?;
            self.fpwr(i, reg::SYNC0_START_TIME, &start.to_le_bytes())?;
            self.fpwr(i, reg::SYNC0_CYCLE, &period.to_le_bytes())?;
            self.fpwr(i, reg::SYNC_ACTIVATION, &[0x03])?;
        }
        Ok(())
    }
}

/// One FRMW of the reference's system time; true when it came back.
fn frmw(link: &mut SimLink, reference: usize) -> anyhow::Result<bool> {
    let r = link.try_txn(&[(
        Command::Frmw,
        Address::configured(station(reference), reg::SYSTEM_TIME),
        &[0u8; 8],
    )])?;
    Ok(r.is_some())
}

impl Scheme for Ethercrab {
    fn name(&self) -> &'static str {
        "ethercrab"
    }

    /// The phases run in order; a call picks up where the last one stopped.
    fn advance(&mut self, until: TrueTime) -> anyhow::Result<()> {
        if self.phase == Phase::BringUp {
            self.bring_up()?;
            self.phase = Phase::Burst;
        }
        if self.phase == Phase::Burst {
            // A lost FRMW times out and the loop goes on with the next iteration
            // (ASSUMPTION: what a timed-out static-sync PDU does is not documented;
            // docs/bench.md "Frame loss").
            let reference = self.reference;
            let send = |link: &mut SimLink| frmw(link, reference);
            let done = self.link.burst(
                &mut self.burst_sent,
                STATIC_SYNC_ITERATIONS,
                &mut self.dist_frames,
                until,
                send,
            )?;
            if !done {
                return self.link.advance_to(until);
            }
            self.phase = Phase::Sync;
        }
        if self.phase == Phase::Sync {
            self.configure_sync()?;
            self.grid.start_after(self.link.now);
            self.phase = Phase::Cyclic;
        }
        while let Some(t) = self.grid.take_before(until) {
            self.link.now = self.link.now.max(t);
            self.frmw()?;
            self.dist_frames += 1;
        }
        self.link.advance_to(until)
    }

    sim_link_scheme!(fields);

    fn static_drift_frames(&self) -> Option<u64> {
        matches!(self.phase, Phase::Sync | Phase::Cyclic).then_some(self.burst_sent)
    }

    fn given(&self) -> Given {
        // Delays without t_DIFF: the method has no per-ESC processing/forwarding split.
        Given::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dev(dc: bool, active: [bool; 4], times: [u32; 4]) -> Device {
        Device {
            dc: if dc {
                DcSupport::Bits64
            } else {
                DcSupport::None
            },
            ports: Ports::new(active, times),
            ..Device::default()
        }
    }

    #[test]
    fn line_delays_accumulate_half_loop_differences() {
        let mut d = vec![
            dev(true, [true, true, false, false], [0, 3000, 0, 0]),
            dev(true, [true, true, false, false], [500, 2300, 0, 0]),
            dev(true, [true, false, false, false], [1100, 0, 0, 0]),
        ];
        assign_delays(&mut d).unwrap();
        assert_eq!(d[1].parent, Some(0));
        assert_eq!(d[1].delay, 600);
        // The line end's total is None → 0: (1800 − 0) / 2.
        assert_eq!(d[2].delay, 1500);
    }

    #[test]
    fn non_dc_parent_gives_a_zero_increment() {
        // #373: the DC device behind a non-DC one gets the non-DC device (no receive times) as
        // its parent; total(parent) = 0 saturates the increment to 0.
        let mut d = vec![
            dev(true, [true, true, false, false], [0, 3000, 0, 0]),
            dev(false, [true, true, false, false], [0, 0, 0, 0]),
            dev(true, [true, true, false, false], [1100, 1900, 0, 0]),
            dev(true, [true, false, false, false], [1500, 0, 0, 0]),
        ];
        assign_delays(&mut d).unwrap();
        assert_eq!(d[2].parent, Some(1));
        assert_eq!(d[2].delay, 0);
        assert_eq!(d[3].delay, 400);
    }

    #[test]
    fn entry_port_search_is_not_wrap_safe() {
        // #374 (reproduced): the latch frame reaches port 0 just before the 32-bit port time
        // wraps and comes back on port 1 just after it; the smallest raw time is port 1's.
        let p = Ports::new([true, true, false, false], [u32::MAX - 100, 900, 0, 0]);
        assert_eq!(p.0[p.entry()].number, 1);
        let q = Ports::new([true, true, false, false], [100, 1100, 0, 0]);
        assert_eq!(q.0[q.entry()].number, 0);
    }

    #[test]
    fn fork_child_and_line_end_parent_walk() {
        // Fork 0: child 1 on port 3 (line end), device 2 on port 1 (line end).
        let mut d = vec![
            dev(true, [true, true, false, true], [0, 2000, 0, 1000]),
            dev(true, [true, false, false, false], [300, 0, 0, 0]),
            dev(true, [true, false, false, false], [1400, 0, 0, 0]),
        ];
        assign_delays(&mut d).unwrap();
        assert_eq!(d[1].parent, Some(0));
        assert_eq!(d[2].parent, Some(0));
        assert_eq!(d[0].ports.assigned_to(1), Some(1)); // storage index 1 = port 3
                                                        // Child on port 3: propagation_time_to(port 3) = 1000 → 500.
        assert_eq!(d[1].delay, 500);
        // Last port: total(fork) = 2000 → 1000, added to the running accumulator.
        assert_eq!(d[2].delay, 1500);
    }
}
