//! One ESC: its register file, clock, control loop and SYNC unit, and what its EtherCAT
//! processing unit (EPU) does to each datagram of a passing frame.
//!
//! Per-ESC time is lazy: [`Esc::advance_to`] moves this ESC's clock to a true time, on the way
//! firing SYNC pulses, applying scheduled power/frequency events and the *pending* effects of
//! earlier frames (port receive stamps, loop samples at end of frame) in time order. This lets
//! a frame's data path be computed at once while its timed side effects land when they
//! physically happen (e.g. a port-1 stamp after the next frame already passed port 0).

use super::al;
use super::control_loop::{ControlLoop, LoopGains};
use super::datagram::{Cmd, DgSpan};
use super::device::{sm_type, sync_managers_of, Application, Device, SmEntry};
use super::oscillator::{correction_rate, Oscillator, Wander};
use super::process_data::{ProcessImage, SmGate};
use super::registers::{addr, EscKind, RegisterFile};
use super::sii::{Completed, Identity, Sii, SiiImage, SiiTiming};
use super::sync_unit::{SyncSignal, SyncUnit};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// A SYNC output edge, recorded in true time (what an analyzer on the SYNC pins would see).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct SyncEdge {
    /// Slave index (position in the scenario).
    pub slave: usize,
    /// SYNC0 or SYNC1.
    pub signal: SyncSignal,
    /// True time of the rising edge, ns since simulation start (includes output jitter).
    pub true_time: u64,
    /// The system time the edge was programmed for (local copy of system time).
    pub system_time: u64,
}

/// Static configuration of one ESC (resolved from the scenario).
#[derive(Debug, Clone)]
pub struct EscConfig {
    pub kind: EscKind,
    pub ports: u8,
    pub t_p_ns: u64,
    pub t_f_ns: u64,
    pub ppb: f64,
    /// The EEPROM content at the start of the run (word 4 holds the station alias).
    pub sii: SiiImage,
    pub sii_timing: SiiTiming,
    /// The application behind the ESC (built images; `Bare` for image files).
    pub device: Device,
    pub initial_station: u16,
    pub esc_type: u8,
    pub ram_bytes: u16,
    pub pulse_len: u16,
    pub tick_ns: u64,
    pub wander: Wander,
    pub gains: LoopGains,
    pub sync_jitter_ns: u64,
    /// Raw local time at true time 0 (ns since this ESC powered up).
    pub initial_local_ns: u64,
    pub seed: u64,
}

/// Something scheduled for this ESC at a true time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scheduled {
    PowerOff,
    PowerOn,
    FrequencyPpb(f64),
}

#[derive(Debug, Clone, Copy)]
enum Pending {
    /// Latch the local time into a port receive-time register.
    Stamp { port: u8 },
    /// Commit port 0 / EPU stamps taken at SOF (not visible in the same frame).
    CommitSof { local: u64 },
    /// Apply a loop sample at end of frame.
    Sample { dt: i32 },
    /// The running SII command finishes (its busy period ends).
    SiiDone,
}

/// Per-visit context the network hands to the EPU.
#[derive(Debug, Clone, Copy)]
pub struct EpuCtx {
    /// True time of the frame's first bit at port 0 (SOF).
    pub t_sof: u64,
    /// True time the frame ends at this ESC.
    pub t_eof: u64,
    /// DL status (0x0110) as seen at SOF, computed from the topology.
    pub dl_status: u16,
}

/// What the EPU did that the network needs to know.
#[derive(Debug, Clone, Copy, Default)]
pub struct EpuResult {
    /// A BWR/FPWR to 0x0900 was processed: stamp the other ports of this frame.
    pub latch: bool,
}

/// One emulated ESC.
#[derive(Debug, Clone)]
pub struct Esc {
    pub(crate) index: usize,
    pub(crate) cfg: EscConfig,
    regs: RegisterFile,
    osc: Oscillator,
    lp: ControlLoop,
    sync: SyncUnit,
    powered: bool,
    sched: Vec<(u64, Scheduled)>,
    pending: std::collections::VecDeque<(u64, u64, Pending)>,
    pending_seq: u64,
    rng: ChaCha8Rng,
    power_ups: u64,
    /// Frames that wrote any byte of 0x0920..=0x0927 while the AL state was SAFEOP or OP:
    /// an observer for REQ-DC-103 (the offset must never move under a running application).
    offset_writes_running: u64,
    loop_ctl: u8,
    /// No SYNC pulse can fire before this true time (a conservative bound that survives loop
    /// samples; cleared by anything else that can move the next pulse). Skips the pulse search
    /// on most frame visits.
    quiet_until: u64,
    /// Last (S, D) → `correction_rate(S, D)`.
    dev_cache: Option<((u16, i16), i128)>,
    /// The EEPROM and its interface.
    sii: Sii,
    /// SyncManagers the firmware expects (the SII's SyncManager category at power-up).
    sms: Vec<SmEntry>,
    /// The configuration area loaded: process RAM is accessible and the firmware runs (it
    /// answers AL control). Section I, "SII EEPROM Errors": "the process memory is not
    /// accessible until the ESC Configuration Area is loaded successfully".
    firmware: bool,
    app: Application,
}

fn fresh_regs(cfg: &EscConfig) -> RegisterFile {
    let mut regs = RegisterFile::new(
        cfg.kind,
        cfg.ram_bytes,
        cfg.ports,
        cfg.esc_type,
        cfg.pulse_len,
    );
    if cfg.kind.has_system_time() {
        // The filters' power-on depths are a scenario input (LoopGains), the loop starts
        // with the same depths (ControlLoop::new).
        regs.set_u8(addr::DIFF_FILTER_DEPTH, cfg.gains.diff_filter_reset);
        regs.set_u8(addr::SPEED_FILTER_DEPTH, cfg.gains.speed_filter_reset);
    }
    regs
}

impl Esc {
    /// An ESC powered since before true time 0.
    pub fn new(index: usize, cfg: EscConfig) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let osc_rng = ChaCha8Rng::seed_from_u64(rng.gen());
        let osc = Oscillator::new(
            0,
            cfg.initial_local_ns,
            cfg.ppb,
            cfg.tick_ns,
            cfg.wander.clone(),
            osc_rng,
        );
        let mut regs = fresh_regs(&cfg);
        let mut sii = Sii::new(cfg.sii.clone(), cfg.sii_timing);
        let (sms, firmware) = power_up_sii(&mut sii, &mut regs, cfg.kind);
        regs.set_u16(addr::STATION_ADDRESS, cfg.initial_station);
        Esc {
            index,
            lp: ControlLoop::new(cfg.gains),
            regs,
            osc,
            sync: SyncUnit::default(),
            powered: true,
            sched: Vec::new(),
            pending: std::collections::VecDeque::new(),
            pending_seq: 0,
            rng,
            power_ups: 0,
            offset_writes_running: 0,
            loop_ctl: 0,
            quiet_until: 0,
            dev_cache: None,
            sii,
            sms,
            firmware,
            app: Application::new(cfg.device),
            cfg,
        }
    }

    /// Schedules a power or frequency event.
    pub fn schedule(&mut self, t: u64, what: Scheduled) {
        let pos = self.sched.partition_point(|(x, _)| *x <= t);
        self.sched.insert(pos, (t, what));
    }

    #[inline]
    fn push_pending(&mut self, t: u64, p: Pending) {
        self.pending_seq += 1;
        let key = (t, self.pending_seq);
        // Almost always in time order: append; otherwise insert in place.
        if !matches!(self.pending.back(), Some((x, s, _)) if (*x, *s) > key) {
            self.pending.push_back((t, self.pending_seq, p));
        } else {
            let pos = self.pending.partition_point(|(x, s, _)| (*x, *s) <= key);
            self.pending.insert(pos, (t, self.pending_seq, p));
        }
    }

    /// Powered at the anchor.
    #[inline]
    pub fn powered(&self) -> bool {
        self.powered
    }

    /// DL control loop bits (0x0101), cached because every frame hop asks for them.
    #[inline]
    pub fn loop_control(&self) -> u8 {
        self.loop_ctl
    }

    /// Register file (read-only view, for observers).
    pub fn regs(&self) -> &RegisterFile {
        &self.regs
    }

    /// Current frequency error of the oscillator, ppb.
    pub fn ppb(&self) -> f64 {
        self.osc.ppb()
    }

    /// True time this ESC has been evaluated up to.
    #[inline]
    pub fn anchor(&self) -> u64 {
        self.osc.anchor()
    }

    #[inline]
    fn mask(&self) -> u64 {
        if self.cfg.kind.is_64bit() {
            u64::MAX
        } else {
            u32::MAX as u64
        }
    }

    /// Local time at the anchor (quantised), wrapped to 64 bits.
    #[inline]
    pub fn local(&self) -> u64 {
        self.osc.local()
    }

    /// Local copy of system time at the anchor (width-masked), if the ESC has system time.
    /// Computed from the offset register on every call, so a write to 0x0920 moves it at once
    /// and leaves the loop's rate alone (REQ-ESC-043).
    #[inline]
    pub fn system_time(&self) -> Option<u64> {
        if !self.cfg.kind.has_system_time() || !self.powered {
            return None;
        }
        let off = self.regs.get_u64(addr::SYSTEM_TIME_OFFSET);
        Some(self.osc.local().wrapping_add(off) & self.mask())
    }

    /// Moves this ESC to true time `t`, firing everything due on the way (in time order).
    pub fn advance_to(&mut self, t: u64, edges: &mut Vec<SyncEdge>) {
        let sched_due = matches!(self.sched.first(), Some(e) if e.0 <= t);
        if !sched_due {
            // Common case: only pending frame effects are due (the general loop below does
            // the same in the same order when no scheduled event intervenes).
            while let Some(&(tp, _, p)) = self.pending.front() {
                if tp > t {
                    break;
                }
                self.run_until(tp, edges);
                self.pending.pop_front();
                self.apply_pending(p);
            }
            self.run_until(t, edges);
            return;
        }
        loop {
            let ts = self.sched.first().map(|e| e.0).filter(|&x| x <= t);
            let tp = self.pending.front().map(|e| e.0).filter(|&x| x <= t);
            let next = match (ts, tp) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            let until = next.unwrap_or(t);
            self.run_until(until, edges);
            match (ts, tp) {
                (Some(a), _) if Some(a) == next => {
                    let (_, what) = self.sched.remove(0);
                    self.apply_scheduled(a, what);
                }
                (_, Some(_)) => {
                    if let Some((_, _, p)) = self.pending.pop_front() {
                        self.apply_pending(p);
                    }
                }
                _ => break,
            }
        }
    }

    /// Advances the clock to `until`, firing SYNC pulses due before or at it.
    #[inline(always)]
    fn run_until(&mut self, until: u64, edges: &mut Vec<SyncEdge>) {
        if !self.powered {
            return;
        }
        if !self.cfg.kind.has_system_time() || until < self.quiet_until {
            self.osc.advance(until);
            return;
        }
        self.run_until_pulses(until, edges);
    }

    /// [`Esc::run_until`] when a pulse may be due before `until`.
    #[inline(never)]
    fn run_until_pulses(&mut self, until: u64, edges: &mut Vec<SyncEdge>) {
        // `system_time()` at the anchor, with the offset read once: firing a pulse changes
        // SYNC registers only, never the offset, the power or the kind.
        let off = self.regs.get_u64(addr::SYSTEM_TIME_OFFSET);
        let mask = self.mask();
        loop {
            let local = self.osc.local_wide();
            let sys = (local as u64).wrapping_add(off) & mask;
            let Some((_, d)) = self.sync.next_due(&self.regs, sys) else {
                break;
            };
            // Cheap bound first: most calls ask about a pulse well after `until` (REQ-ESC-101:
            // skipping the exact inversion here is what keeps 100 slaves at 1 kHz fast).
            let span = until.saturating_sub(self.osc.anchor());
            if d > self.osc.max_advance(span) && self.osc.piece_end() > until {
                // Local time cannot run more than 1 % fast (crystal + loop ≪ 1 %).
                let slack = d.saturating_sub(2 * self.cfg.tick_ns + 2);
                self.quiet_until = self.osc.anchor().saturating_add(slack - slack / 100);
                break;
            }
            // Where to move next: to the pulse if it is reached before `until`, else to
            // `until`, never past the end of the clock's current linear piece (the inversion
            // works inside one piece).
            let to = match self.osc.time_to_advance_from(d, local) {
                Some(te) if te <= until => te,
                Some(_) => until,
                None => self.osc.piece_end().min(until),
            };
            self.osc.advance(to);
            // REQ-ESC-075: a pulse fires when the local copy *reaches* its time, and the local
            // copy moves in steps (10 ns ticks, ±1 ns loop corrections). Every pulse this move
            // passed over fires now, measured from the system time before the move: a search
            // from after it would see a passed pulse a whole wrap away (never, on a 64-bit DC)
            // and the unit would stop. A tick that falls exactly on a piece end is such a
            // case: the inversion in the old piece ends just before it, the new piece starts
            // after it.
            let stepped = u64::try_from(self.osc.local_wide() - local).unwrap_or(0);
            let mut fired = false;
            while let Some((sig, d)) = self.sync.next_due(&self.regs, sys) {
                if d > stepped {
                    break;
                }
                self.fire(sig, to, edges);
                fired = true;
            }
            if to == until && !fired {
                break;
            }
        }
        self.osc.advance(until);
    }

    /// Records each output edge with its true time `t` (plus pin jitter) and programmed system
    /// time; called from `run_until`, so edges come with or without frames. REQ-ESC-078.
    fn fire(&mut self, sig: SyncSignal, t: u64, edges: &mut Vec<SyncEdge>) {
        let (x, out) = self.sync.fire(sig, &mut self.regs);
        for (i, on) in out.iter().enumerate() {
            if *on {
                let j = if self.cfg.sync_jitter_ns > 0 {
                    self.rng.gen_range(0..=self.cfg.sync_jitter_ns)
                } else {
                    0
                };
                edges.push(SyncEdge {
                    slave: self.index,
                    signal: if i == 0 {
                        SyncSignal::Sync0
                    } else {
                        SyncSignal::Sync1
                    },
                    true_time: t + j,
                    system_time: x,
                });
            }
        }
    }

    fn apply_scheduled(&mut self, t: u64, what: Scheduled) {
        self.quiet_until = 0;
        match what {
            Scheduled::PowerOff => {
                self.osc.advance(t);
                self.powered = false;
                self.pending.clear();
            }
            Scheduled::PowerOn => {
                if self.powered {
                    return;
                }
                // REQ-ESC-090: power-up resets the clock (local time 0) and every register.
                self.power_ups += 1;
                let osc_rng = ChaCha8Rng::seed_from_u64(self.rng.gen());
                self.osc = Oscillator::new(
                    t,
                    0,
                    self.cfg.ppb,
                    self.cfg.tick_ns,
                    self.cfg.wander.clone(),
                    osc_rng,
                );
                // The EEPROM keeps its content (including SII writes) over the power cycle.
                self.regs = fresh_regs(&self.cfg);
                let (sms, firmware) = power_up_sii(&mut self.sii, &mut self.regs, self.cfg.kind);
                self.sms = sms;
                self.firmware = firmware;
                self.app = Application::new(self.cfg.device);
                self.lp = ControlLoop::new(self.cfg.gains);
                self.sync = SyncUnit::default();
                self.loop_ctl = 0;
                self.powered = true;
            }
            Scheduled::FrequencyPpb(ppb) => {
                self.osc.advance(t);
                self.cfg.ppb = ppb;
                self.osc.set_base_ppb(ppb);
            }
        }
    }

    fn apply_pending(&mut self, p: Pending) {
        if !self.powered {
            return;
        }
        match p {
            Pending::Stamp { port } => {
                let v = self.osc.local() as u32;
                self.regs
                    .set_u32(addr::RECEIVE_TIME_PORT0 + 4 * u16::from(port), v);
            }
            Pending::CommitSof { local } => {
                // REQ-ESC-032: 0x0918 (EPU) = port 0's stamp, 64-bit.
                self.regs.set_u32(addr::RECEIVE_TIME_PORT0, local as u32);
                if self.cfg.kind.has_system_time() {
                    self.regs.set_dc64(addr::RECEIVE_TIME_EPU, local);
                }
            }
            Pending::Sample { dt } => {
                self.lp.sample(dt);
                let key = (self.lp.start(), self.lp.speed_diff());
                // D is often unchanged from the last sample: skip the two divisions.
                let dev = match self.dev_cache {
                    Some((k, dev)) if k == key => dev,
                    _ => {
                        let dev = correction_rate(key.0, key.1);
                        self.dev_cache = Some((key, dev));
                        dev
                    }
                };
                self.osc.set_dev(dev);
                self.regs
                    .set_u32(addr::SYSTEM_TIME_DIFFERENCE, self.lp.difference_register());
                self.regs
                    .set_u16(addr::SPEED_COUNTER_DIFF, self.lp.speed_diff() as u16);
            }
            Pending::SiiDone => {
                if let Some(Completed::Reload(Some(area))) = self.sii.complete(&mut self.regs) {
                    // A reload takes over the configuration area again, except the station
                    // alias and 0x0141 bits 1, 4..7, which only the first load after
                    // power-on or reset transfers.
                    if self.cfg.kind.has_system_time() {
                        self.regs.set_u16(addr::SYNC_PULSE_LENGTH, area.pulse_len);
                    }
                    let keep = self.regs.get_u8(addr::PDI_CONTROL + 1) & RELOAD_KEEPS_0141;
                    let [lo, hi] = area.pdi_control.to_le_bytes();
                    self.regs.set_u8(addr::PDI_CONTROL, lo);
                    self.regs
                        .set_u8(addr::PDI_CONTROL + 1, (hi & !RELOAD_KEEPS_0141) | keep);
                    if !self.firmware {
                        // The PDI becomes operational: the firmware starts.
                        self.sms = sync_managers_of(self.sii.image());
                        al::apply_pdi_control(&mut self.regs, &self.sms, al::INIT);
                        self.firmware = true;
                    }
                }
            }
        }
    }

    /// Schedules a port receive-time stamp of the current latching frame (ports 1..3).
    pub fn stamp_port(&mut self, port: u8, t: u64) {
        self.push_pending(t, Pending::Stamp { port });
    }

    /// Processes every datagram of the frame at this ESC's EPU. The caller has advanced the
    /// ESC to `ctx.t_sof`. Returns what the network must finish (port stamps).
    pub fn process(
        &mut self,
        frame: &mut [u8],
        spans: &[DgSpan],
        ctx: EpuCtx,
        edges: &mut Vec<SyncEdge>,
    ) -> EpuResult {
        let mut res = EpuResult::default();
        if !self.powered {
            return res;
        }
        self.sii.on_sof(&mut self.regs);
        if self.cfg.device != Device::Bare {
            self.present_inputs();
        }
        let local_sof = self.osc.local();
        let sys_sof = if self.cfg.kind.has_system_time() {
            let off = self.regs.get_u64(addr::SYSTEM_TIME_OFFSET);
            local_sof.wrapping_add(off) & self.mask()
        } else {
            0
        };
        let delay = u64::from(self.regs.get_u32(addr::SYSTEM_TIME_DELAY));
        // REQ-ESC-042: ECAT read of 0x0910 = local copy at SOF − System Time Delay.
        let sys_read = sys_sof.wrapping_sub(delay) & self.mask();
        let mut st = Visit {
            ctx,
            sys_read,
            sys_sof,
            latch: false,
            sample: None,
            debug_pulse: false,
        };
        for s in spans {
            self.datagram(frame, *s, &mut st);
        }
        if st.latch {
            // REQ-ESC-030/031: port 0 and EPU are stamped with the SOF time, visible after
            // the frame.
            res.latch = true;
            self.push_pending(ctx.t_eof, Pending::CommitSof { local: local_sof });
        }
        if st.debug_pulse {
            // 0x0981 bit 7: one-shot debug pulse on both outputs, now (self-clearing).
            for signal in [SyncSignal::Sync0, SyncSignal::Sync1] {
                edges.push(SyncEdge {
                    slave: self.index,
                    signal,
                    true_time: ctx.t_sof,
                    system_time: sys_sof,
                });
            }
        }
        if self.cfg.device != Device::Bare {
            self.take_outputs();
        }
        if let Some(dt) = st.sample {
            // REQ-ESC-050: compared at end of frame.
            self.push_pending(ctx.t_eof, Pending::Sample { dt });
        }
        res
    }

    #[inline]
    fn datagram(&mut self, frame: &mut [u8], s: DgSpan, st: &mut Visit) {
        let Some(hdr) = frame.get(s.start..s.data()) else {
            return;
        };
        let Some(c) = Cmd::from_code(hdr[0]) else {
            // A reserved command: passed on untouched.
            return;
        };
        let adp = u16::from_le_bytes([hdr[2], hdr[3]]);
        let ado = u16::from_le_bytes([hdr[4], hdr[5]]);
        let logical = u32::from_le_bytes([hdr[2], hdr[3], hdr[4], hdr[5]]);
        let (data_range, wkc_at) = (s.data()..s.wkc(), s.wkc());
        let mut wkc_inc: u16 = 0;
        let mut adp_inc = false;
        match c {
            Cmd::Aprd | Cmd::Apwr | Cmd::Aprw | Cmd::Armw => {
                adp_inc = true;
                if adp == 0 {
                    wkc_inc = self.reg_access(c, ado, &mut frame[data_range], st, true);
                } else if c == Cmd::Armw {
                    wkc_inc = self.reg_access(c, ado, &mut frame[data_range], st, false);
                }
            }
            Cmd::Fprd | Cmd::Fpwr | Cmd::Fprw | Cmd::Frmw => {
                let station = self.regs.get_u16(addr::STATION_ADDRESS);
                // implements: REQ-ESC-003
                let alias_on = self.regs.get_u8(addr::DL_CONTROL + 3) & 0x01 != 0;
                let alias = self.regs.get_u16(addr::STATION_ALIAS);
                let hit = adp == station || (alias_on && adp == alias);
                if hit {
                    wkc_inc = self.reg_access(c, ado, &mut frame[data_range], st, true);
                } else if c == Cmd::Frmw {
                    wkc_inc = self.reg_access(c, ado, &mut frame[data_range], st, false);
                }
            }
            Cmd::Brd | Cmd::Bwr | Cmd::Brw => {
                adp_inc = true;
                wkc_inc = self.reg_access(c, ado, &mut frame[data_range], st, true);
            }
            Cmd::Lrd | Cmd::Lwr | Cmd::Lrw => {
                wkc_inc = self.logical(c, logical, &mut frame[data_range]);
            }
            Cmd::Nop => {}
        }
        if adp_inc {
            let v = adp.wrapping_add(1).to_le_bytes();
            frame[s.start + 2] = v[0];
            frame[s.start + 3] = v[1];
        }
        if wkc_inc != 0 {
            let w = u16::from_le_bytes([frame[wkc_at], frame[wkc_at + 1]]).wrapping_add(wkc_inc);
            frame[wkc_at..wkc_at + 2].copy_from_slice(&w.to_le_bytes());
        }
    }

    /// Physical (register/RAM) access. `addressed` false means "the non-addressed part of an
    /// ARMW/FRMW": a write. Returns the working-counter increment (REQ-ESC-002).
    #[inline(always)]
    fn reg_access(
        &mut self,
        c: Cmd,
        ado: u16,
        data: &mut [u8],
        st: &mut Visit,
        addressed: bool,
    ) -> u16 {
        match c {
            Cmd::Aprd | Cmd::Fprd => u16::from(self.read(ado, data, st, false)),
            Cmd::Brd => u16::from(self.read(ado, data, st, true)),
            Cmd::Apwr | Cmd::Fpwr | Cmd::Bwr => u16::from(self.write(c, ado, data, st)),
            Cmd::Aprw | Cmd::Fprw => {
                let input: Vec<u8> = data.to_vec();
                let r = self.read(ado, data, st, false);
                let w = self.write(c, ado, &input, st);
                u16::from(r) + 2 * u16::from(w)
            }
            Cmd::Brw => {
                let input: Vec<u8> = data.to_vec();
                let r = self.read(ado, data, st, true);
                let w = self.write(c, ado, &input, st);
                u16::from(r) + 2 * u16::from(w)
            }
            Cmd::Armw | Cmd::Frmw => {
                if addressed {
                    u16::from(self.read(ado, data, st, false))
                } else {
                    u16::from(self.write(c, ado, data, st))
                }
            }
            _ => 0,
        }
    }

    /// One byte as an ECAT read sees it at SOF.
    fn read_byte(&self, a: u16, st: &Visit) -> u8 {
        match a {
            0x0110..=0x0111 => st.ctx.dl_status.to_le_bytes()[usize::from(a - 0x0110)],
            0x0910..=0x0917 => st.sys_read.to_le_bytes()[usize::from(a - 0x0910)],
            _ => self.regs.get_u8(a),
        }
    }

    #[inline]
    fn read(&mut self, ado: u16, data: &mut [u8], st: &Visit, or: bool) -> bool {
        // Fast path: a range with no computed bytes (not 0x0110, not 0x0910..0x0917) that
        // exists entirely.
        let a0 = usize::from(ado);
        let end = a0 + data.len();
        let computed = (a0 <= 0x0111 && end > 0x0110) || (a0 <= 0x0917 && end > 0x0910);
        let gate = self.ram_gate(end);
        if !computed && !data.is_empty() && gate.is_open() {
            let last = u16::try_from(end - 1).ok();
            if let Some(last) = last {
                if self.regs.implemented(ado)
                    && self.regs.implemented(last)
                    && (end <= 0x0900 || a0 > 0x09FF)
                    && (self.firmware || end <= usize::from(addr::PROCESS_RAM))
                {
                    let src = &self.regs.bytes()[a0..end];
                    if or {
                        data.iter_mut().zip(src).for_each(|(d, s)| *d |= *s);
                    } else {
                        data.copy_from_slice(src);
                    }
                    return true;
                }
            }
        }
        let mut any = false;
        // Byte by byte up to the end of the address space; bytes beyond it are not touched.
        for (a, b) in (ado..=u16::MAX).zip(data.iter_mut()) {
            if !self.accessible(a) || !gate.access(a).0 {
                continue;
            }
            any = true;
            let v = self.read_byte(a, st);
            *b = if or { *b | v } else { v };
        }
        any
    }

    #[inline(always)]
    fn write(&mut self, c: Cmd, ado: u16, data: &[u8], st: &mut Visit) -> bool {
        // Fast path for the drift-compensation sample (FRMW/ARMW/BWR to 0x0910, 4 or 8
        // bytes): nothing is stored, only the lower 32 bits are compared.
        if ado == addr::SYSTEM_TIME
            && self.cfg.kind.has_system_time()
            && (4..=8).contains(&data.len())
        {
            let received = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
            st.sample = Some((st.sys_read as u32).wrapping_sub(received) as i32);
            return true;
        }
        self.write_general(c, ado, data, st)
    }

    /// [`Esc::write`] beyond the drift-compensation fast path.
    #[inline(never)]
    fn write_general(&mut self, c: Cmd, ado: u16, data: &[u8], st: &mut Visit) -> bool {
        let kind = self.cfg.kind;
        // Offset, SYNC configuration or a 0x0930 reset may move the next pulse.
        self.quiet_until = 0;
        let sync_owner_ecat = self.regs.get_u8(addr::CYCLIC_UNIT_CONTROL) & 0x01 == 0;
        let sync_active = SyncUnit::active(&self.regs);
        let old_act = self.regs.get_u8(addr::SYNC_ACTIVATION);
        let mut any = false;
        let mut touched = Touched::default();
        let mut recv = (st.sys_read as u32).to_le_bytes();
        let mut sii_staged = [None; 16];
        let gate = self.ram_gate(usize::from(ado) + data.len());
        // AL states 4 (SAFEOP) and 8 (OP); the state before this frame's bytes land.
        let running = matches!(self.al_state(), 4 | 8);
        let mut offset_written = false;
        for (a, b) in (ado..=u16::MAX).zip(data) {
            if !self.accessible(a) || !gate.access(a).1 {
                continue;
            }
            any = true;
            match a {
                0x0900 => touched.latch = true,
                0x0500..=0x050F => {
                    sii_staged[usize::from(a - 0x0500)] = Some(*b);
                    touched.sii = true;
                }
                0x0910..=0x0913 if kind.has_system_time() => {
                    recv[usize::from(a - 0x0910)] = *b;
                    if a == 0x0910 {
                        touched.system_time = true;
                    }
                }
                _ => {}
            }
            if !self.regs.ecat_writable(a) {
                continue;
            }
            // REQ-ESC-071: SYNC configuration is ECAT-writable only when ECAT owns the unit;
            // REQ-ESC-072: the start time only while the unit is inactive.
            if (0x0981..=0x09A7).contains(&a) && !sync_owner_ecat {
                continue;
            }
            if (0x0990..=0x0997).contains(&a) && sync_active {
                continue;
            }
            self.regs.set_u8(a, *b);
            match a {
                0x0920..=0x0927 => offset_written = true,
                0x0120 => touched.al_control = true,
                0x0930..=0x0931 => touched.speed_start = true,
                0x0981 => touched.activation = true,
                0x0990..=0x0993 => touched.start_low = true,
                0x0994..=0x0997 => touched.start_high = true,
                _ => {}
            }
        }
        if !any {
            return false;
        }
        if offset_written && running {
            self.offset_writes_running = self.offset_writes_running.saturating_add(1);
        }
        // REQ-ESC-030: only BWR/FPWR covering 0x0900 trigger the receive-time latch.
        // REQ-ESC-083: a non-DC slave never latches (it still adds its delays in the walk).
        if touched.latch && (c == Cmd::Bwr || c == Cmd::Fpwr) && kind.has_receive_times() {
            st.latch = true;
        }
        if touched.system_time {
            // REQ-ESC-050: wrap-safe signed difference of the lower 32 bits.
            let received = u32::from_le_bytes(recv);
            let dt = (st.sys_read as u32).wrapping_sub(received) as i32;
            st.sample = Some(dt);
        }
        if touched.speed_start && kind.has_system_time() {
            // REQ-ESC-053: any write to 0x0930 resets 0x092C, 0x0932 and the filters.
            self.lp.reset(
                self.regs.get_u16(addr::SPEED_COUNTER_START),
                self.regs.get_u8(addr::DIFF_FILTER_DEPTH),
                self.regs.get_u8(addr::SPEED_FILTER_DEPTH),
            );
            self.osc.set_dev(0);
            self.regs.set_u32(addr::SYSTEM_TIME_DIFFERENCE, 0);
            self.regs.set_u16(addr::SPEED_COUNTER_DIFF, 0);
        }
        if kind.has_system_time() {
            if touched.start_low || touched.start_high {
                self.sync
                    .on_start_time_write(&mut self.regs, st.sys_sof, touched.start_high);
            }
            if touched.activation {
                let debug = self
                    .sync
                    .on_activation_write(old_act, &mut self.regs, st.sys_sof);
                st.debug_pulse |= debug;
            }
        }
        if touched.sii {
            if let Some(d) = self.sii.ecat_write(&sii_staged, &mut self.regs) {
                // REQ-ESC-021: busy from this frame for the command's duration.
                self.push_pending(st.ctx.t_sof.saturating_add(d), Pending::SiiDone);
            }
        }
        if touched.al_control {
            self.al_control();
        }
        self.loop_ctl = self.regs.get_u8(addr::DL_CONTROL + 1);
        any
    }

    /// AL control written: the firmware acts on it (emu/al.rs, REQ-ESC-020/022). Without a
    /// loaded configuration area the firmware does not run and the request stays unanswered.
    fn al_control(&mut self) {
        if self.firmware {
            al::control(&mut self.regs, &self.sms);
        }
    }

    /// Whether ECAT reaches byte `a`: it exists, and it is a register or the configuration
    /// area has loaded.
    #[inline]
    fn accessible(&self, a: u16) -> bool {
        self.regs.implemented(a) && (self.firmware || a < addr::PROCESS_RAM)
    }

    /// The SyncManager access rules for a physical access ending before `end` (only process
    /// RAM is guarded; register accesses skip the table).
    #[inline]
    fn ram_gate(&self, end: usize) -> SmGate {
        if end <= usize::from(addr::PROCESS_RAM) {
            return SmGate::default();
        }
        SmGate::from_regs(
            &self.regs,
            usize::from(self.regs.get_u8(addr::SYNC_MANAGERS_SUPPORTED)),
        )
    }

    /// SyncManager `n` of type `t` in the SII: its configured (start, length) now.
    fn sm_area(&self, t: u8) -> Option<(u16, u16)> {
        let n = self.sms.iter().position(|e| e.typ == t)?;
        let b = al::sm_base(n);
        Some((self.regs.get_u16(b), self.regs.get_u16(b + 2)))
    }

    fn al_state(&self) -> u16 {
        self.regs.get_u16(addr::AL_STATUS) & 0x0F
    }

    /// AL state (0x0130 bits 3:0).
    pub fn al(&self) -> u8 {
        self.al_state() as u8
    }

    /// The application writes its inputs into the input buffer (SAFEOP and OP: inputs are
    /// valid there, ETG.1000.6). REQ-ESC-027.
    fn present_inputs(&mut self) {
        if !matches!(self.al_state(), al::SAFEOP | al::OP) {
            return;
        }
        if let Some((start, len)) = self.sm_area(sm_type::PD_IN) {
            for (k, b) in self.app.inputs().iter().take(usize::from(len)).enumerate() {
                self.regs.set_u8(start.wrapping_add(k as u16), *b);
            }
        }
    }

    /// The application takes the outputs the master wrote (OP) or holds the safe state
    /// (REQ-ESC-027).
    fn take_outputs(&mut self) {
        let out = match (self.al_state(), self.sm_area(sm_type::PD_OUT)) {
            (al::OP, Some((start, len))) => Some(
                (0..len)
                    .map(|k| self.regs.get_u8(start.wrapping_add(k)))
                    .collect::<Vec<u8>>(),
            ),
            _ => None,
        };
        self.app.take_outputs(out.as_deref());
    }

    /// The slave's identity as its EEPROM holds it now.
    pub fn identity(&self) -> Identity {
        self.sii.image().identity()
    }

    /// The EEPROM content now (SII writes included).
    pub fn sii_image(&self) -> &SiiImage {
        self.sii.image()
    }

    /// Whether the configuration area loaded (DL status bit 0).
    pub fn sii_loaded(&self) -> bool {
        self.sii.loaded(&self.regs)
    }

    /// The PDI takes or releases the EEPROM interface (0x0501 bit 0). No PDI is emulated;
    /// this is the hook a test uses to show ECAT locked out.
    pub fn set_sii_pdi_access(&mut self, on: bool) -> bool {
        self.sii.set_pdi_access(&mut self.regs, on)
    }

    /// AL state and what the application drives and presents.
    pub fn process_image(&self) -> ProcessImage {
        ProcessImage {
            al_state: self.al_state() as u8,
            outputs: self.app.applied().to_vec(),
            inputs: self.app.inputs(),
        }
    }

    /// LRD/LWR/LRW through the FMMU table (byte granularity; start/stop bits ignored).
    fn logical(&mut self, c: Cmd, laddr: u32, data: &mut [u8]) -> u16 {
        let mut read = false;
        let mut wrote = false;
        let dlen = data.len() as u64;
        let l0 = u64::from(laddr);
        if !self.regs.any_fmmu_enabled() {
            return 0;
        }
        let nf = usize::from(self.regs.get_u8(addr::FMMUS_SUPPORTED).min(16));
        let gate = SmGate::from_regs(
            &self.regs,
            usize::from(self.regs.get_u8(addr::SYNC_MANAGERS_SUPPORTED)),
        );
        for f in 0..nf {
            let base = addr::FMMU0 + 16 * f as u16;
            if self.regs.get_u8(base + 12) & 0x01 == 0 {
                continue;
            }
            let typ = self.regs.get_u8(base + 11);
            let ls = u64::from(self.regs.get_u32(base));
            let flen = u64::from(self.regs.get_u16(base + 4));
            let phys = u64::from(self.regs.get_u16(base + 8));
            let lo = l0.max(ls);
            let hi = (l0 + dlen).min(ls + flen);
            let do_read = typ & 0x01 != 0 && c != Cmd::Lwr;
            let do_write = typ & 0x02 != 0 && c != Cmd::Lrd;
            let mut j = lo;
            while j < hi {
                let k = (j - l0) as usize;
                let Ok(pa) = u16::try_from(phys + (j - ls)) else {
                    break;
                };
                let (may_read, may_write) = if gate.is_open() {
                    (true, true)
                } else {
                    gate.access(pa)
                };
                if self.accessible(pa) {
                    let inb = data[k];
                    if do_read && may_read {
                        data[k] = self.regs.get_u8(pa);
                        read = true;
                    }
                    if do_write && may_write {
                        if self.regs.ecat_writable(pa) {
                            self.regs.set_u8(pa, inb);
                            if pa < addr::PROCESS_RAM {
                                self.quiet_until = 0;
                            }
                        }
                        wrote = true;
                    }
                }
                j += 1;
            }
        }
        match c {
            Cmd::Lrw => u16::from(read) + 2 * u16::from(wrote),
            _ => u16::from(read || wrote),
        }
    }

    /// Debug read of the register file (no side effects). 0x0910 reads the local copy at the
    /// anchor (like a PDI read), 0x0110 reads as stored (the network fills it on ECAT reads).
    pub fn peek(&self, a: u16, len: usize) -> Vec<u8> {
        let sys = self.system_time().unwrap_or(0);
        (0..len)
            .map(|i| {
                let x = a.wrapping_add(i as u16);
                match x {
                    0x0910..=0x0917 if self.cfg.kind.has_system_time() => {
                        sys.to_le_bytes()[usize::from(x - 0x0910)]
                    }
                    _ => self.regs.get_u8(x),
                }
            })
            .collect()
    }

    /// Control-loop diagnostics.
    pub fn control_loop(&self) -> &ControlLoop {
        &self.lp
    }

    /// Number of power-ups after the initial one.
    pub fn power_ups(&self) -> u64 {
        self.power_ups
    }

    /// Frames that wrote the system time offset (0x0920..=0x0927) while this slave was in
    /// SAFEOP or OP (counted over power cycles).
    pub fn offset_writes_running(&self) -> u64 {
        self.offset_writes_running
    }
}

#[derive(Default)]
struct Touched {
    latch: bool,
    system_time: bool,
    speed_start: bool,
    activation: bool,
    start_low: bool,
    start_high: bool,
    al_control: bool,
    sii: bool,
}

/// 0x0141 bits a reload leaves alone (enhanced link detection; Section I, "SII EEPROM").
const RELOAD_KEEPS_0141: u8 = 0xF2;

/// Power-up of the EEPROM side: the interface loads the configuration area; with a correct
/// CRC the ESC takes over the station alias (word 4), the SYNC pulse length (word 2) and PDI
/// control (word 0) and the firmware starts, with the SyncManagers of the SII's category.
fn power_up_sii(sii: &mut Sii, regs: &mut RegisterFile, kind: EscKind) -> (Vec<SmEntry>, bool) {
    let Some(area) = sii.power_up(regs) else {
        return (Vec::new(), false);
    };
    regs.set_u16(addr::STATION_ALIAS, area.alias);
    regs.set_u16(addr::PDI_CONTROL, area.pdi_control);
    if kind.has_system_time() {
        regs.set_u16(addr::SYNC_PULSE_LENGTH, area.pulse_len);
    }
    let sms = sync_managers_of(sii.image());
    al::apply_pdi_control(regs, &sms, al::INIT);
    (sms, true)
}

/// Per-visit state while one frame passes this ESC's EPU.
struct Visit {
    ctx: EpuCtx,
    sys_read: u64,
    sys_sof: u64,
    latch: bool,
    sample: Option<i32>,
    debug_pulse: bool,
}
