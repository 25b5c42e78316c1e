//! The bring-up steps the two comparison schemes share (IgH style, as seed 000 §3.2 describes
//! it): count, address, one receive-time latch, read the port and EPU receive times, and the
//! SYNC0 programming after drift compensation. Everything goes through [`SimLink`] and the
//! `core::wire` register addresses; no ecdc state machine code is used.

use anyhow::{bail, Context};
use ecdc_core::wire::register::reg;
use ecdc_core::wire::{Address, Command};

use super::link::{le_u32, le_u64, SimLink};

/// First configured station address (slave `i` gets `STATION_BASE + i`).
pub const STATION_BASE: u16 = 0x1001;

/// Lead time from reading the reference clock to the first SYNC0 pulse (IgH's
/// `EC_DC_START_OFFSET`, 100 ms).
pub const SYNC_START_LEAD_NS: u64 = 100_000_000;

/// Receive times of the latch frame, per slave (positions 0..n).
#[derive(Debug, Clone, Default)]
pub struct Latched {
    /// Port 0 (A) receive time, low 32 bits of local time.
    pub port_a: Vec<u32>,
    /// Port 1 (B) receive time, low 32 bits of local time.
    pub port_b: Vec<u32>,
    /// EPU receive time (0x0918, 64-bit local time).
    pub epu: Vec<u64>,
    /// True time the latching frame left the master (the instant a master stamps with its
    /// own clock as `t_SYS,REF`).
    pub latch_sent: u64,
}

impl Latched {
    /// `t_iB − t_iA` of slave `i` (0-based), wrap-safe on 32 bits.
    pub fn rtt(&self, i: usize) -> i128 {
        let a = self.port_a.get(i).copied().unwrap_or(0);
        let b = self.port_b.get(i).copied().unwrap_or(0);
        i128::from(b.wrapping_sub(a))
    }
}

/// Station address of position `i`.
pub fn station(i: usize) -> u16 {
    STATION_BASE.wrapping_add(u16::try_from(i).unwrap_or(u16::MAX))
}

/// Checks that the emulated chain is what eq. 23 is written for: a line of 64-bit DC slaves
/// in processing order. The comparison schemes refuse anything else rather than produce
/// numbers from formulas that do not apply.
pub fn require_line_of_dc64(link: &SimLink) -> anyhow::Result<usize> {
    let n = link.net.slave_count();
    if n < 2 {
        bail!("needs at least 2 slaves, scenario has {n}");
    }
    for i in 0..n {
        let s = link.net.slave_info(i).context("slave info")?;
        if !s.kind.has_system_time() || !s.kind.is_64bit() {
            bail!("slave {i} is not a 64-bit DC slave ({:?})", s.kind);
        }
        let expect = if i == 0 { None } else { Some((i - 1, 1)) };
        if s.parent != expect {
            bail!(
                "not a line: slave {i} hangs on {:?} (eq. 23 covers lines only)",
                s.parent
            );
        }
    }
    Ok(n)
}

/// BRD 0x0000: the number of slaves on the line (its working counter).
pub fn count_slaves(link: &mut SimLink) -> anyhow::Result<usize> {
    let r = link.txn(&[(Command::Brd, Address::broadcast(0x0000), &[0u8; 2])])?;
    Ok(usize::from(r.first().map_or(0, |r| r.wkc)))
}

/// APWR 0x0010: station address [`station`]`(i)` to each of the first `n` positions.
pub fn assign_addresses(link: &mut SimLink, n: usize) -> anyhow::Result<()> {
    for i in 0..n {
        let pos = u16::try_from(i).context("position")?;
        link.one(
            Command::Apwr,
            Address::position(pos, reg::STATION_ADDRESS),
            &station(i).to_le_bytes(),
            1,
        )?;
    }
    Ok(())
}

/// BRD 0x0000 (count), APWR 0x0010 (addresses), BWR 0x0900 (latch), FPRD 0x0900..0x091F.
pub fn discover_and_latch(link: &mut SimLink, n: usize) -> anyhow::Result<Latched> {
    let count = count_slaves(link)?;
    if count != n {
        bail!("BRD counted {count} slaves, expected {n}");
    }
    assign_addresses(link, n)?;
    let wkc = u16::try_from(n).context("count")?;
    link.one(
        Command::Bwr,
        Address::broadcast(reg::RECEIVE_TIME_PORT0),
        &[0u8; 4],
        wkc,
    )?;
    let mut out = Latched {
        latch_sent: link.last_sent,
        ..Latched::default()
    };
    for i in 0..n {
        let d = link.one(
            Command::Fprd,
            Address::configured(station(i), reg::RECEIVE_TIME_PORT0),
            &[0u8; 0x20],
            1,
        )?;
        out.port_a.push(le_u32(&d[0..4]));
        out.port_b.push(le_u32(&d[4..8]));
        out.epu.push(le_u64(&d[0x18..0x20]));
    }
    Ok(out)
}

/// FPWR 0x0920 (64 bit) on slave `i`.
pub fn write_offset(link: &mut SimLink, i: usize, offset: u64) -> anyhow::Result<()> {
    link.one(
        Command::Fpwr,
        Address::configured(station(i), reg::SYSTEM_TIME_OFFSET),
        &offset.to_le_bytes(),
        1,
    )?;
    Ok(())
}

/// FPWR 0x0928 on slave `i`.
pub fn write_delay(link: &mut SimLink, i: usize, delay: u32) -> anyhow::Result<()> {
    link.one(
        Command::Fpwr,
        Address::configured(station(i), reg::SYSTEM_TIME_DELAY),
        &delay.to_le_bytes(),
        1,
    )?;
    Ok(())
}

/// One FRMW 0x0910 from the reference (position 0) to every other slave; returns the WKC
/// (0 if the frame was lost: a drift frame is not resent, the next one carries a fresh time).
pub fn frmw(link: &mut SimLink) -> anyhow::Result<u16> {
    let Some(r) = link.try_txn(&[(
        Command::Frmw,
        Address::configured(station(0), reg::SYSTEM_TIME),
        &[0u8; 8],
    )])?
    else {
        return Ok(0);
    };
    Ok(r.first().map(|r| r.wkc).unwrap_or(0))
}

/// The SYNC0 lead for `n` slaves when one frame takes `per_frame_ns`: `SYNC_START_LEAD_NS`,
/// unless programming the slaves (4 frames each) would take longer than half of it — then
/// twice that programming time, so the start time is still ahead when the last slave is
/// activated (only long lines: 512 slaves need ~1.2 s; 6 slaves ~0.3 ms keep 100 ms).
pub fn sync0_lead(n: usize, per_frame_ns: u64) -> u64 {
    let programming = per_frame_ns.saturating_mul(4).saturating_mul(n as u64);
    if programming.saturating_mul(2) > SYNC_START_LEAD_NS {
        programming.saturating_mul(2)
    } else {
        SYNC_START_LEAD_NS
    }
}

/// Reads the reference's system time, puts the first SYNC0 pulse [`sync0_lead`] later
/// on the cycle grid, and programs and activates SYNC0 on every slave (0x0981 = 0, 0x0990,
/// 0x09A0, then 0x0980/0x0981 = AssignActivate 0x0300). Returns the start system time.
pub fn program_sync0(link: &mut SimLink, n: usize, cycle_ns: u32) -> anyhow::Result<u64> {
    let t0 = link.now;
    let d = link.one(
        Command::Fprd,
        Address::configured(station(0), reg::SYSTEM_TIME),
        &[0u8; 8],
        1,
    )?;
    let lead = sync0_lead(n, link.now.saturating_sub(t0));
    let now = le_u64(&d);
    let cycle = u64::from(cycle_ns.max(1));
    let start = (now.saturating_add(lead) / cycle + 1).saturating_mul(cycle);
    for i in 0..n {
        let st = station(i);
        link.one(
            Command::Fpwr,
            Address::configured(st, reg::SYNC_ACTIVATION),
            &[0],
            1,
        )?;
        link.one(
            Command::Fpwr,
            Address::configured(st, reg::SYNC0_START_TIME),
            &start.to_le_bytes(),
            1,
        )?;
        link.one(
            Command::Fpwr,
            Address::configured(st, reg::SYNC0_CYCLE),
            &cycle_ns.to_le_bytes(),
            1,
        )?;
    }
    for i in 0..n {
        link.one(
            Command::Fpwr,
            Address::configured(station(i), reg::CYCLIC_UNIT_CONTROL),
            &0x0300u16.to_le_bytes(),
            1,
        )?;
    }
    Ok(start)
}
