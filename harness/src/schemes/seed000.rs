//! The seed 000 scheme (Chen et al. 2025, §2, §3.1 and §3.2), reproduced as a small independent
//! master so ecdc can be compared with it on the same emulated network. Two variants:
//!
//! **`seed000`** ([`Variant::Derived`]), the flow the paper describes, with eq. 23 as its own
//! eq. 17–22 give it:
//! 1. count, address, one receive-time latch (BWR 0x0900), read the port and EPU times; the
//!    master stamps the latch frame with its own clock (`t_SYS,REF`, §2.2 "the system time when
//!    the master sent the frame", §3.2 "records the master's send time");
//! 2. delays by **eq. 23 derived**: the last case is `(t_1B − t_1A) + (n − 2)·t_DIFF`, what eq. 22
//!    (n = 4) and the sum of hops eq. 17–19 give (the printed `i·t_DIFF` is an erratum,
//!    spec/src/seed000.rs); `t_DIFF` = the scenario's nominal `t_P − t_F`, **given** to the
//!    scheme because the paper assumes it known (§2.1: "depends on the physical layer");
//! 3. offsets by **eq. 24 with the sign eq. 25 needs**, `t_OFF = t_SYS,REF − t_LOCAL`, for every
//!    slave including the reference (IgH's write-system-times step, which §3.2 calls), without
//!    the delay folded in (IgH leaves it to the ESC loops); one FPWR of 12 bytes to 0x0920
//!    (offset and delay, as IgH writes them), then **0x0930 ← 0x1000** to reset the ESC's
//!    filters (IgH `fsm_master.c`, after every offset write to a slave below SAFEOP). IgH
//!    writes no 0x0934, so neither does this scheme;
//! 4. a **fixed burst of 15 000 FRMW** frames back to back (§2.3);
//! 5. from then on one application cycle per `cycle_ns`, each frame carrying
//!    `ecrt_master_sync_reference_clock_to(app time)` (FPWR 4 bytes to the reference's 0x0910,
//!    the reference follows the master clock) and `ecrt_master_sync_slave_clocks()` (FRMW
//!    4 bytes to the reference's 0x0910), the calls §3.2 names;
//! 6. **§3.1 threshold gate**: the master reads the system time difference (0x092C) cyclically
//!    and starts SYNC only once it is below a threshold. The paper gives no threshold; the
//!    scheme uses IgH's `EC_DC_MAX_SYNC_DIFF_NS` = 10 µs and `EC_DC_SYNC_WAIT_MS` = 5 s, one
//!    slave after the other, one FPRD per cycle in the cyclic frame (IgH's slave-config FSM);
//! 7. SYNC0 start on the cycle grid, 100 ms ahead.
//!
//! **`seed000-printed`** ([`Variant::Printed`]), kept as a labelled extra row: eq. 23 exactly as
//! printed (`i·t_DIFF` in the last case, so the last slave's delay is `t_DIFF` too large), offsets
//! relative to the reference's own EPU time (the reference keeps offset 0), 0x0920 and 0x0928
//! written separately, no 0x0930 reset, the same burst, **no gate**, SYNC0 right after the burst,
//! then one 8-byte FRMW per cycle and the reference never written.

use ecdc_core::wire::register::{reg, SystemTimeDifference};
use ecdc_core::wire::{Address, Command};
use ecdc_spec::seed000 as spec;

use super::igh_steps::{self, station, Latched};
use super::link::SimLink;
use super::{Given, Scheme, Written};
use crate::emu::{Network, TrueTime};
use crate::schemes::cycle_grid::CycleGrid;
use crate::sim::DEFAULT_MASTER_EPOCH_NS;

/// Burst length of §2.3 ("about 15 000 ARMW/FRMW commands").
pub const BURST_FRAMES: u64 = 15_000;
/// §3.1 threshold on |0x092C| before SYNC starts. The paper names no value; ecdc choice: IgH's
/// `EC_DC_MAX_SYNC_DIFF_NS` (`master/fsm_slave_config.c`), because the paper's flow is built on
/// IgH's slave configuration.
pub const GATE_THRESHOLD_NS: u32 = 10_000;
/// How long the gate waits on one slave before going on anyway: IgH's `EC_DC_SYNC_WAIT_MS`.
pub const GATE_WAIT_NS: u64 = 5_000_000_000;
/// 0x0930 value written after the offsets: IgH's filter reset (`fsm_master.c`, 0x1000 = the
/// register's reset value).
pub const SPEED_COUNTER_START: u16 = 0x1000;

/// Which reading of the paper.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// Eq. 23 as eq. 22 implies it, plus the §3.1/§3.2 flow (`seed000`).
    Derived,
    /// Eq. 23 as printed, minimal flow (`seed000-printed`).
    Printed,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    BringUp,
    Burst,
    /// §3.1 gate: waiting for slave `slave`'s |0x092C| since true time `since`.
    Gate {
        slave: usize,
        since: TrueTime,
    },
    Sync,
    Cyclic,
}

/// The seed 000 master.
#[derive(Debug)]
pub struct Seed000 {
    variant: Variant,
    link: SimLink,
    phase: Phase,
    n: usize,
    t_diff_ns: i64,
    cycle_ns: u32,
    burst_sent: u64,
    dist_frames: u64,
    grid: CycleGrid,
    written: Vec<Written>,
    /// §3.1 gate threshold and per-slave wait, ns.
    gate_threshold_ns: u32,
    gate_wait_ns: u64,
    /// Slaves the gate gave up on (wait exceeded).
    gave_up: Vec<usize>,
    /// System time the SYNC0 start was programmed for, once it was.
    sync_start: Option<u64>,
}

/// Eq. 23 exactly as printed, halved with the spec's rounding rule. `i` is 0-based here.
pub fn eq23_as_printed(l: &Latched, n: usize, i: usize, t_diff: i128) -> Option<i128> {
    let rtt: Vec<i128> = (0..n).map(|k| l.rtt(k)).collect();
    Some(spec::half(spec::eq23_printed_x2(&rtt, n, i + 1, t_diff)?))
}

/// Eq. 23 in the form eq. 22 and eq. 17–19 give, halved with the spec's rounding rule. `i` is
/// 0-based here.
pub fn eq23_derived(l: &Latched, n: usize, i: usize, t_diff: i128) -> Option<i128> {
    let rtt: Vec<i128> = (0..n).map(|k| l.rtt(k)).collect();
    Some(spec::half(spec::eq23_t_ref_x2(&rtt, n, i + 1, t_diff)?))
}

impl Seed000 {
    /// The derived master (`seed000`) for `net`; `t_diff_ns` = nominal t_P − t_F, `cycle_ns` =
    /// SYNC0 and application cycle.
    pub fn new(net: Network, t_diff_ns: i64, cycle_ns: u32) -> Self {
        Self::with_variant(Variant::Derived, net, t_diff_ns, cycle_ns)
    }

    /// The printed-eq.-23 master (`seed000-printed`).
    pub fn printed(net: Network, t_diff_ns: i64, cycle_ns: u32) -> Self {
        Self::with_variant(Variant::Printed, net, t_diff_ns, cycle_ns)
    }

    /// Either variant.
    pub fn with_variant(variant: Variant, net: Network, t_diff_ns: i64, cycle_ns: u32) -> Self {
        Seed000 {
            variant,
            link: SimLink::new(net),
            phase: Phase::BringUp,
            n: 0,
            t_diff_ns,
            cycle_ns,
            burst_sent: 0,
            dist_frames: 0,
            grid: CycleGrid::new(cycle_ns),
            written: Vec::new(),
            gate_threshold_ns: GATE_THRESHOLD_NS,
            gate_wait_ns: GATE_WAIT_NS,
            gave_up: Vec::new(),
            sync_start: None,
        }
    }

    /// The derived variant with another §3.1 gate (threshold on |0x092C| and per-slave wait,
    /// ns) than IgH's; for tests of the gate.
    pub fn with_gate(mut self, threshold_ns: u32, wait_ns: u64) -> Self {
        self.gate_threshold_ns = threshold_ns;
        self.gate_wait_ns = wait_ns;
        self
    }

    /// The SYNC0 start time programmed (system time), once SYNC0 has been programmed.
    pub fn sync_start(&self) -> Option<u64> {
        self.sync_start
    }

    /// Slaves the §3.1 gate gave up on (positions, 0-based).
    pub fn gate_gave_up(&self) -> &[usize] {
        &self.gave_up
    }

    /// The master's clock at true time `t` (the emulator's master epoch; the master's crystal
    /// is ideal).
    fn app_time(t: TrueTime) -> u64 {
        DEFAULT_MASTER_EPOCH_NS.wrapping_add(t)
    }

    fn bring_up(&mut self) -> anyhow::Result<()> {
        let n = igh_steps::require_line_of_dc64(&self.link)?;
        self.n = n;
        let l = igh_steps::discover_and_latch(&mut self.link, n)?;
        self.written = vec![Written::default(); n];
        match self.variant {
            Variant::Derived => self.write_derived(&l),
            Variant::Printed => self.write_printed(&l),
        }
    }

    fn write_derived(&mut self, l: &Latched) -> anyhow::Result<()> {
        let n = self.n;
        let t_sys_ref = i128::from(Self::app_time(l.latch_sent));
        for i in 0..n {
            let delay = eq23_derived(l, n, i, i128::from(self.t_diff_ns)).unwrap_or(0);
            let delay = u32::try_from(delay.max(0)).unwrap_or(u32::MAX);
            let local = i128::from(*l.epu.get(i).unwrap_or(&0));
            let off = spec::offset_consistent_with_eq25(local, t_sys_ref, 0);
            // Two's complement image of the 64-bit register.
            let off_reg = (off as i64) as u64;
            let mut data = [0u8; 12];
            data[..8].copy_from_slice(&off_reg.to_le_bytes());
            data[8..].copy_from_slice(&delay.to_le_bytes());
            self.link.one(
                Command::Fpwr,
                Address::configured(station(i), reg::SYSTEM_TIME_OFFSET),
                &data,
                1,
            )?;
            self.link.one(
                Command::Fpwr,
                Address::configured(station(i), reg::SPEED_COUNTER_START),
                &SPEED_COUNTER_START.to_le_bytes(),
                1,
            )?;
            self.written[i] = Written {
                offset: Some(off_reg as i64),
                delay: Some(delay),
            };
        }
        Ok(())
    }

    fn write_printed(&mut self, l: &Latched) -> anyhow::Result<()> {
        let n = self.n;
        let t_ref = *l.epu.first().unwrap_or(&0);
        for i in 1..n {
            let delay = eq23_as_printed(l, n, i, i128::from(self.t_diff_ns)).unwrap_or(0);
            let delay = u32::try_from(delay.max(0)).unwrap_or(u32::MAX);
            let local = i128::from(*l.epu.get(i).unwrap_or(&0));
            let off = spec::offset_consistent_with_eq25(local, i128::from(t_ref), 0);
            let off_reg = (off as i64) as u64;
            igh_steps::write_offset(&mut self.link, i, off_reg)?;
            igh_steps::write_delay(&mut self.link, i, delay)?;
            self.written[i] = Written {
                offset: Some(off_reg as i64),
                delay: Some(delay),
            };
        }
        Ok(())
    }

    /// One application cycle of the derived variant at true time `t`:
    /// `sync_reference_clock_to` + `sync_slave_clocks`, and during the gate one FPRD of the
    /// gated slave's 0x092C. Returns that slave's |0x092C| when it was read.
    fn derived_cycle(&mut self, t: TrueTime, gate: Option<usize>) -> anyhow::Result<Option<u32>> {
        self.link.now = self.link.now.max(t);
        let app = (Self::app_time(t) as u32).to_le_bytes();
        let frmw = [0u8; 4];
        let diff = [0u8; 4];
        let ref_time = Address::configured(station(0), reg::SYSTEM_TIME);
        let mut dgs: Vec<(Command, Address, &[u8])> = vec![
            (Command::Fpwr, ref_time, &app),
            (Command::Frmw, ref_time, &frmw),
        ];
        if let Some(k) = gate {
            dgs.push((
                Command::Fprd,
                Address::configured(station(k), reg::SYSTEM_TIME_DIFFERENCE),
                &diff,
            ));
        }
        self.dist_frames += 1;
        let Some(replies) = self.link.try_txn(&dgs)? else {
            return Ok(None); // lost: the next cycle carries a fresh time and reads again
        };
        let Some(r) = replies.get(2).filter(|r| r.wkc == 1) else {
            return Ok(None);
        };
        Ok(SystemTimeDifference::parse(&r.data)
            .ok()
            .map(|d| d.to_ns().unsigned_abs()))
    }
}

impl Scheme for Seed000 {
    fn name(&self) -> &'static str {
        match self.variant {
            Variant::Derived => "seed000",
            Variant::Printed => "seed000-printed",
        }
    }

    fn advance(&mut self, until: TrueTime) -> anyhow::Result<()> {
        loop {
            match self.phase {
                Phase::BringUp => {
                    self.bring_up()?;
                    self.phase = Phase::Burst;
                }
                Phase::Burst => {
                    let sent = &mut self.burst_sent;
                    let dist = &mut self.dist_frames;
                    if !self
                        .link
                        .burst(sent, BURST_FRAMES, dist, until, igh_steps::frmw)?
                    {
                        break;
                    }
                    self.grid.start_after(self.link.now);
                    self.phase = match self.variant {
                        Variant::Derived => Phase::Gate {
                            slave: 0,
                            since: self.grid.next(),
                        },
                        Variant::Printed => Phase::Sync,
                    };
                }
                Phase::Gate { slave, since } => {
                    if slave >= self.n {
                        self.phase = Phase::Sync;
                        continue;
                    }
                    let Some(t) = self.grid.take_before(until) else {
                        break;
                    };
                    let d = self.derived_cycle(t, Some(slave))?;
                    let passed = d.is_some_and(|d| d <= self.gate_threshold_ns);
                    let timed_out = t.saturating_sub(since) >= self.gate_wait_ns;
                    if timed_out && !passed {
                        self.gave_up.push(slave);
                    }
                    if passed || timed_out {
                        self.phase = Phase::Gate {
                            slave: slave + 1,
                            since: self.grid.next(),
                        };
                    }
                }
                Phase::Sync => {
                    let start = igh_steps::program_sync0(&mut self.link, self.n, self.cycle_ns)?;
                    self.sync_start = Some(start);
                    self.grid.start_after(self.link.now);
                    self.phase = Phase::Cyclic;
                }
                Phase::Cyclic => {
                    while let Some(t) = self.grid.take_before(until) {
                        match self.variant {
                            Variant::Derived => {
                                self.derived_cycle(t, None)?;
                            }
                            Variant::Printed => {
                                self.link.now = self.link.now.max(t);
                                igh_steps::frmw(&mut self.link)?;
                                self.dist_frames += 1;
                            }
                        }
                    }
                    break;
                }
            }
        }
        self.link.advance_to(until)
    }

    sim_link_scheme!();

    fn reference(&self) -> usize {
        0
    }

    fn dist_frames(&self) -> u64 {
        self.dist_frames
    }

    fn static_drift_frames(&self) -> Option<u64> {
        (!matches!(self.phase, Phase::BringUp | Phase::Burst)).then_some(self.burst_sent)
    }

    fn given(&self) -> Given {
        // The paper treats t_DIFF as known from the physical layer; both variants get the
        // scenario's nominal value.
        Given::from([("t_diff_ns", self.t_diff_ns)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emu::Scenario;

    fn net() -> Network {
        let sc = Scenario::line(6);
        sc.resolve().unwrap();
        Network::new(&sc).unwrap()
    }

    fn t_diff() -> i64 {
        let sc = Scenario::line(6);
        i64::try_from(sc.defaults.t_p_ns).unwrap() - i64::try_from(sc.defaults.t_f_ns).unwrap()
    }

    /// The network with every slave's 0x0930 set to `v` (a value no scheme writes), so a
    /// later write of IgH's 0x1000 is visible.
    fn net_with_speed_start(v: u16) -> Network {
        let mut l = SimLink::new(net());
        l.one(
            Command::Bwr,
            Address::broadcast(reg::SPEED_COUNTER_START),
            &v.to_le_bytes(),
            6,
        )
        .unwrap();
        l.net
    }

    fn speed_start(s: &mut Seed000, i: usize) -> u16 {
        let b = s.net().peek(i, reg::SPEED_COUNTER_START, 2).unwrap();
        u16::from_le_bytes([b[0], b[1]])
    }

    /// The derived variant writes offset and delay to every slave (the reference too), resets
    /// 0x0930 to IgH's 0x1000 on each, and its last delay is exactly t_DIFF below the printed
    /// variant's (`(n − 2)` against `n` halved t_DIFFs: the erratum), the others equal.
    #[test]
    fn derived_and_printed_bring_ups() {
        let mut d = Seed000::new(net_with_speed_start(0x0800), t_diff(), 1_000_000);
        let mut p = Seed000::printed(net_with_speed_start(0x0800), t_diff(), 1_000_000);
        d.advance(1).unwrap();
        p.advance(1).unwrap();
        let (wd, wp) = (d.written(), p.written());
        assert!(wd.iter().all(|w| w.offset.is_some() && w.delay.is_some()));
        assert_eq!(wd[0].delay, Some(0));
        assert_eq!(
            wp[0],
            Written::default(),
            "printed: the reference keeps offset 0"
        );
        for i in 1..5 {
            assert_eq!(wd[i].delay, wp[i].delay, "slave {}", i + 1);
        }
        let last = |w: &[Written]| i64::from(w[5].delay.unwrap());
        assert_eq!(last(&wp) - last(&wd), t_diff());
        for i in 0..6 {
            assert_eq!(
                speed_start(&mut d, i),
                SPEED_COUNTER_START,
                "slave {}",
                i + 1
            );
            assert_eq!(speed_start(&mut p, i), 0x0800, "printed writes no 0x0930");
        }
        assert_eq!(d.given(), Given::from([("t_diff_ns", t_diff())]));
        assert_eq!(p.given(), d.given());
    }

    /// §3.1: SYNC0 is programmed only after every slave's |0x092C| was read at or below the
    /// threshold or its wait ran out. IgH's 10 µs passes at once after the burst; a 0 ns
    /// threshold (rarely met with PHY jitter) makes the gate wait out the full 30 ms on the
    /// slaves whose reads were never exactly 0.
    #[test]
    fn gate_holds_sync_until_threshold_or_wait() {
        let cycle = 1_000_000;
        let mut open = Seed000::new(net(), t_diff(), cycle);
        let mut strict = Seed000::new(net(), t_diff(), cycle).with_gate(0, 30_000_000);
        let mut printed = Seed000::printed(net(), t_diff(), cycle);
        for s in [&mut open, &mut strict, &mut printed] {
            s.advance(600_000_000).unwrap();
        }
        assert!(open.gate_gave_up().is_empty(), "{:?}", open.gate_gave_up());
        let waited = strict.gate_gave_up().len() as u64;
        assert!(waited >= 2, "{:?}", strict.gate_gave_up());
        let (o, st, p) = (
            open.sync_start().unwrap(),
            strict.sync_start().unwrap(),
            printed.sync_start().unwrap(),
        );
        // The open gate costs one cycle per slave after the burst; the strict one 30 ms per
        // slave it gave up on.
        assert!(o > p, "gate reads before SYNC0: {o} vs {p}");
        assert!(st >= o + waited * 30_000_000, "{st} vs {o}");
        // Frames: burst + one cyclic frame per gate cycle, all counted as distribution frames.
        assert_eq!(open.static_drift_frames(), Some(BURST_FRAMES));
    }
}
