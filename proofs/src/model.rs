//! Explicit-state model checker for REQ-PROP P6 (spec/SPEC.md §2; REQ-DC-103, REQ-DC-110,
//! REQ-DC-113, REQ-CONV-008): breadth-first search with state hashing over
//! (real no_std [`Machine`], emulated ring, frames on the wire, master time).
//!
//! A [`World`] is one global state: the machine under test, a bounded line of `k ≤ 4` ideal DC
//! slaves (station addresses, truthful AL states, latch counter: the `Model` of
//! [`crate::machine`]) whose DC registers come from [`crate::clocks`] (a free-running local
//! clock per slave, 32- or 64-bit system time, the offset written), the replies of the last two transmitted frames (each already
//! processed by the ring, waiting on the wire) and the master clock. [`Action`]s are the
//! machine's inputs and the faults: transmit (alone or after a foreign datagram in the caller's
//! frame), deliver the newest or the older reply (reordering; a second delivery is a duplicate),
//! deliver with every working counter 0 or +1 (wrong WKC), lose the reply, a junk frame, a
//! foreign frame reusing our index with another command, a 10 µs tick, a jump to the machine's
//! deadline, a slave reset (station address lost, AL back to INIT), a 32-bit port-time wrap of
//! the next latch round, and the commands `reset`, `start`, `request_delay_measurement`.
//!
//! [`explore`] visits every state reachable within `depth` actions from each seed, deduplicated
//! by a 128-bit fingerprint of the state ([`World::fingerprint`]: the machine's
//! [`Machine::control_state`], an `Eq + Hash` value that leaves out the diagnostic counters,
//! which steer nothing, and the machine's caches — plus ring, wire and clock), and checks on
//! every transition:
//!
//! 1. no panic (`catch_unwind` around the step: a panic is a violation with its trace);
//! 2. every transmitted frame: indices in range and distinct, 0x0920 written only by FPWR of
//!    4/8 bytes to a station whose *current* ring AL state is INIT/PREOP/BOOT, register widths
//!    ([`crate::machine::check_tx`]);
//! 3. index matching (REQ-DC-032): a received frame is used (not counted foreign) only if it
//!    is the reply to the newest transmitted frame, that frame was not answered yet and no `reset`/`start`
//!    came after it, and the machine still awaited it; a frame that is not used leaves the
//!    control state unchanged; and the faithful reply to the frame awaited is used;
//! 4. the machine stops awaiting a reply once the master clock passed transmission time +
//!    `response_timeout_ns` and it was told the time;
//!
//! 5. lock is reported only on a reply produced while every slave's system time was within
//!    the lock threshold of the reference's (judged on the clocks, not on what the machine read);
//!
//! and on every state (liveness, bounded): the fault-free continuation (transmit, deliver,
//! advance to the deadline) reaches `Cyclic` within [`LIVENESS_STEPS`] steps, or the state is
//! `Idle` (only a `reset` leads there), or the continuation splits the running slaves between
//! two domains ([`World::split_domains`], exempt and counted). Typed errors on the way are
//! allowed (they restart). With the clocks, reaching `Cyclic` needs offsets that pass the drift
//! gate on the modelled 0x092C: a wrong offset shows as lost liveness.
//!
//! Limits: the clocks are ideal (no drift, so no time-control loop: the servo and the loop are
//! checked elsewhere, P5 and the harness end-to-end tests), AL states change only by a slave
//! reset or another master starting a slave, and the depth bound is per seed.
//! The seeds are the states of the fault-free bring-up, so every phase is a root of the search.
//!
//! verifies: P3, P4, P6, REQ-CONV-008, REQ-DC-032, REQ-DC-103, REQ-DC-110, REQ-DC-113

use crate::clocks::Clocks;
use crate::machine::{al_truth, check_tx, script_config, Model, Outcome, Violation, CAP};
use ecdc_core::dc::{Config, Error, Event, Machine, State};
use ecdc_core::time::SystemTime;
use ecdc_core::wire::{Address, Command, EthernetFrame, FrameBuilder};
use std::collections::hash_map::DefaultHasher;
use std::collections::HashSet;
use std::hash::{Hash, Hasher};

/// Bound of the fault-free continuation checked from every state.
pub const LIVENESS_STEPS: usize = 400;

/// Master time step of [`Action::Tick`], ns.
pub const TICK_NS: u64 = 10_000;

/// One input or fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Action {
    /// `poll_transmit`; the ring processes the frame at once, its reply waits on the wire.
    Tx,
    /// `poll_transmit_into` a caller's frame that starts with a foreign LRW datagram.
    TxForeign,
    /// Deliver the reply to the newest frame (again: a duplicate).
    DeliverNewest,
    /// Deliver the reply to the older frame (reordering, late reply).
    DeliverOlder,
    /// Deliver the newest reply with every working counter 0 (not processed by any slave).
    DeliverWkc0,
    /// Deliver the newest reply with every working counter + 1.
    DeliverWkcPlus,
    /// The newest reply is lost.
    Lose,
    /// 8 bytes of junk arrive.
    Junk,
    /// A processed EtherCAT frame reusing the machine's next index with another command (LRD).
    ForeignSameIndex,
    /// `now += TICK_NS`, then `handle_timeout`.
    Tick,
    /// `now` jumps to `poll_timeout()` (if any), then `handle_timeout`.
    ToDeadline,
    /// The slave at this position power-cycles: station address lost, AL back to INIT.
    SlaveReset(u8),
    /// Someone else (another master, a configuration tool) moves the slave at this position
    /// to SAFE-OP (even positions) or OP (odd): an AL change at any point of the bring-up.
    SlaveRun(u8),
    /// The next latch round's 32-bit port times straddle 2^32 ns.
    Wrap,
    /// `reset()`.
    Reset,
    /// `start()`.
    Start,
    /// `request_delay_measurement()`.
    Remeasure,
}

impl Action {
    /// Every action for a line of `k` slaves.
    pub fn all(k: u16) -> Vec<Action> {
        let mut v = vec![
            Action::Tx,
            Action::TxForeign,
            Action::DeliverNewest,
            Action::DeliverOlder,
            Action::DeliverWkc0,
            Action::DeliverWkcPlus,
            Action::Lose,
            Action::Junk,
            Action::ForeignSameIndex,
            Action::Tick,
            Action::ToDeadline,
            Action::Wrap,
            Action::Reset,
            Action::Start,
            Action::Remeasure,
        ];
        for j in 0..k.min(CAP as u16) {
            v.push(Action::SlaveReset(j as u8));
            v.push(Action::SlaveRun(j as u8));
        }
        v
    }
}

/// A reply waiting on the wire.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
struct OnWire {
    reply: Vec<u8>,
    /// Master time at transmission.
    sent_at: u64,
    /// Bit j: slave j changed AL state after this reply was produced (its AL answer is old).
    moved: u8,
    /// Every slave's system time agreed with the reference's within the lock threshold when
    /// the reply was produced.
    agree: bool,
}

/// One global state of the model.
#[derive(Debug, Clone)]
pub struct World {
    m: Machine<CAP>,
    cfg: Config,
    line: Model,
    /// `None`: the ideal ring of [`crate::machine::Model`] alone (see [`World::without_clocks`]).
    clocks: Option<Clocks>,
    al: [u16; CAP],
    /// The AL status of each slave in the last reply to an FPRD 0x0130 the machine used in this
    /// bring-up (cleared whenever the machine is back before the slave count).
    known_al: [Option<u16>; CAP],
    /// Bit j: slave j changed AL state (reset or run) after the last such read.
    al_moved: u8,
    now: u64,
    /// Replies of the last two transmitted frames, newest last.
    wire: Vec<OnWire>,
    /// The newest frame may still be answered (no reply used, no reset/start since).
    live: bool,
    /// What the transmitted frames showed (check_tx counters).
    out: Outcome,
    /// Mutation knobs for the checker's own tests (0 in real runs): bit `j` of `lie` makes
    /// slave `j` report INIT in 0x0130 whatever its state; bit `j` of `dead` keeps slave `j`
    /// without a station address for ever.
    lie: u8,
    dead: u8,
    /// Whether the reply the last [`World::step`] delivered and the machine used was produced
    /// with every clock in agreement (not part of the state).
    used_agree: Option<bool>,
    /// Events and the frame transmitted by the last [`World::step`] (not part of the state).
    last_events: Vec<Event>,
    last_tx: Option<(State, Vec<u8>)>,
}

/// A property violation with the actions that led to it from the seed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Counterexample {
    /// What was violated.
    pub violation: ModelViolation,
    /// Seed number and actions from it.
    pub seed: usize,
    /// The actions.
    pub trace: Vec<Action>,
    /// Steps of the fault-free continuation after `trace` (liveness check) before the
    /// violation; 0 when the violation is on the last action of `trace`.
    pub continuation: usize,
}

/// What the model checker can find.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ModelViolation {
    /// A transmitted frame broke a P6 frame property.
    Frame(Violation),
    /// A method panicked.
    Panic(String),
    /// A frame was used that is not the reply to the frame awaited.
    StaleAccepted(Action),
    /// A frame that was not used changed the control state.
    ForeignFrameUsed(Action),
    /// The faithful reply to the awaited frame was not used.
    LiveRejected(Action),
    /// Still awaiting a reply after its deadline was signalled.
    AwaitingPastDeadline,
    /// The fault-free continuation did not reach `Cyclic` (state reached).
    NoProgress(State),
    /// The machine reported `Error::Internal` (one of its consistency guards fired) in this
    /// state.
    Internal(State),
    /// An internal invariant of the machine broke (`Machine::invariant_violation`).
    Invariant(&'static str),
    /// The machine reported lock on a reply produced while some slave's system time was
    /// more than the lock threshold away from the reference's.
    LockedApart,
}

impl World {
    /// A started machine (`start` at a fixed epoch) and a line of `k` slaves with these AL
    /// states (0x01 INIT, 0x02 PREOP, 0x04 SAFEOP, 0x08 OP, 0x14 SAFEOP+error), every one with
    /// a 64-bit system time (see [`World::with_bits32`]); the slaves in SAFE-OP/OP run in a
    /// domain ahead of the master's clock ([`crate::clocks`]).
    pub fn new(k: u16, al: [u16; CAP]) -> Option<World> {
        let cfg = script_config();
        let mut m: Machine<CAP> = Machine::new(cfg).ok()?;
        let now = 800_000_000_000_000_000;
        m.start(SystemTime(now));
        Some(World {
            m,
            cfg,
            line: Model {
                k: k.clamp(1, CAP as u16),
                latch: 0,
                unaddressed: 0,
                wrap_base: 0,
            },
            clocks: Some(Clocks::new(now, &al, 0)),
            al,
            known_al: [None; CAP],
            al_moved: 0,
            now,
            wire: Vec::new(),
            live: false,
            out: Outcome::default(),
            lie: 0,
            dead: 0,
            used_agree: None,
            last_events: Vec::new(),
            last_tx: None,
        })
    }

    /// The slaves in bit set `bits32` have a 32-bit system time (a 32/64-bit mix).
    pub fn with_bits32(mut self, bits32: u8) -> World {
        self.clocks = Some(Clocks::new(self.now, &self.al, bits32));
        self
    }

    /// Mutation knob: slave `p`'s latch unit reports receive times `ns` late, so the offset
    /// written from them is `ns` off. The clocks must then never agree and the bounded liveness
    /// check must fail (a test of the checker's clocks).
    pub fn with_latch_error(mut self, p: usize, ns: u64) -> World {
        self.clocks = self.clocks.map(|c| c.with_latch_error(p, ns));
        self
    }

    /// Mutation knob: the slaves in bit set `lie` answer "INIT" to every AL status read.
    /// The checker must then find a 0x0920 write to a running slave (a test of the checker).
    pub fn with_lying_slaves(mut self, lie: u8) -> World {
        self.lie = lie;
        self
    }

    /// Mutation knob: the slaves in bit set `dead` never get a station address back after
    /// their reset. The bounded liveness check must then fail (a test of the checker).
    pub fn with_dead_slaves(mut self, dead: u8) -> World {
        self.dead = dead;
        self
    }

    /// The ideal ring without clocks: every slave's DC registers as [`crate::machine::Model`]
    /// answers them (a latch counter, one common time base), so time need not pass between two
    /// latches. For the model-based test against the reference model, which compares states
    /// and events, not clock values.
    pub fn without_clocks(mut self) -> World {
        self.clocks = None;
        self
    }

    /// The line's clocks (`None` without them).
    pub fn clocks(&self) -> Option<&Clocks> {
        self.clocks.as_ref()
    }

    /// Master time (true time) now.
    pub fn now(&self) -> u64 {
        self.now
    }

    /// Whether two slaves in SAFE-OP/OP disagree on the time by more than the lock
    /// threshold. Only faults make it so: an AL race lets the machine write an offset to a
    /// slave that another master started a moment before, in that master's domain. No
    /// bring-up can then converge without writing 0x0920 under a running application, which
    /// REQ-DC-030 forbids, so such states are exempt from the liveness check (the machine keeps
    /// retrying, as it should, until a slave leaves SAFE-OP/OP); the search counts them.
    pub fn split_domains(&self) -> bool {
        let k = usize::from(self.line.k).min(CAP);
        let running: Vec<usize> = (0..k)
            .filter(|&p| matches!(self.al[p] & 0x0F, 4 | 8))
            .collect();
        let tol = u64::from(self.cfg.monitor.lock_ns);
        running.iter().any(|&p| {
            running.iter().any(|&q| {
                self.clocks
                    .as_ref()
                    .is_some_and(|c| c.apart(p, q, self.now) > tol)
            })
        })
    }

    /// The machine.
    pub fn machine(&self) -> &Machine<CAP> {
        &self.m
    }

    /// Events drained by the last [`World::step`], in order.
    pub fn last_events(&self) -> &[Event] {
        &self.last_events
    }

    /// The frame transmitted by the last [`World::step`], with the machine state right after
    /// the transmission.
    pub fn last_tx(&self) -> Option<&(State, Vec<u8>)> {
        self.last_tx.as_ref()
    }

    /// 128-bit fingerprint of the state (machine control state, ring, wire, clock, flags).
    pub fn fingerprint(&self) -> u128 {
        let key = (
            self.m.control_state(),
            &self.line,
            &self.clocks,
            &self.al,
            &self.known_al,
            self.al_moved,
            self.now,
            &self.wire,
            self.live,
            self.lie,
            self.dead,
        );
        let half = |salt: u8| {
            let mut h = DefaultHasher::new();
            salt.hash(&mut h);
            key.hash(&mut h);
            h.finish()
        };
        (u128::from(half(0)) << 64) | u128::from(half(1))
    }

    /// The ring processes a frame: modelled answers, truthful AL status.
    fn process(&mut self, frame: &[u8]) -> Vec<u8> {
        let base = self.cfg.station_base;
        let mut out = frame.to_vec();
        let mut eth = EthernetFrame::new_unchecked(&mut out[..]);
        eth.mark_processed_by_slave();
        if let Ok(mut ecat) = eth.ecat_frame_mut() {
            for mut d in ecat.iter_mut().flatten() {
                let (cmd, adp, ado) = (d.command_raw(), d.adp(), d.ado());
                let wkc = self
                    .line
                    .answer(cmd, adp, ado, base, self.now, d.data_mut());
                if wkc > 0 {
                    let pos = [Command::Fprd.code(), Command::Fpwr.code()]
                        .contains(&cmd)
                        .then(|| adp.wrapping_sub(base));
                    let (k, now) = (self.line.k, self.now);
                    if let Some(c) = self.clocks.as_mut() {
                        c.answer(cmd, pos, ado, k, now, d.data_mut());
                    }
                }
                if cmd == Command::Fprd.code() && ado == 0x0130 {
                    let pos = adp.wrapping_sub(base);
                    let lies = pos < 8 && self.lie & (1u8 << pos) != 0;
                    let al = if lies {
                        0x0001
                    } else {
                        al_truth(&self.al, base, adp)
                    };
                    let v = al.to_le_bytes();
                    for (b, v) in d.data_mut().iter_mut().zip(v) {
                        *b = v;
                    }
                }
                d.set_wkc(wkc);
            }
        }
        self.line.unaddressed |= self.dead;
        out
    }

    fn transmitted(&mut self, frame: Vec<u8>, foreign: Option<u8>) -> Result<(), ModelViolation> {
        check_tx(
            &frame,
            &self.cfg,
            &self.al,
            &mut self.out,
            foreign,
            Some((&self.known_al, self.al_moved)),
        )
        .map_err(ModelViolation::Frame)?;
        self.out.frames += 1;
        let (k, now, tol) = (self.line.k, self.now, u64::from(self.cfg.monitor.lock_ns));
        let agree = self.clocks.as_ref().is_none_or(|c| c.agree(k, now, tol));
        let reply = self.process(&frame);
        self.last_tx = Some((self.m.state(), frame));
        self.wire.push(OnWire {
            reply,
            sent_at: self.now,
            moved: 0,
            agree,
        });
        if self.wire.len() > 2 {
            self.wire.remove(0);
        }
        self.live = true;
        Ok(())
    }

    /// Delivers `bytes`; `newest`: it is the (possibly altered) reply to the newest frame;
    /// `faithful`: every datagram of that reply is intact apart from working counters.
    fn deliver(
        &mut self,
        a: Action,
        bytes: &[u8],
        newest: bool,
        faithful: bool,
    ) -> Result<(), ModelViolation> {
        let awaiting = self.m.is_awaiting_reply();
        let before = self.m.clone();
        let foreign_before = self.m.stats().foreign_frames;
        self.m.handle_frame(SystemTime(self.now), bytes);
        let used = self.m.stats().foreign_frames == foreign_before;
        let answerable = newest && self.live && awaiting;
        if used && !answerable {
            return Err(ModelViolation::StaleAccepted(a));
        }
        if !used && self.m.control_state() != before.control_state() {
            return Err(ModelViolation::ForeignFrameUsed(a));
        }
        if answerable && faithful && !used {
            return Err(ModelViolation::LiveRejected(a));
        }
        if used {
            self.live = false;
            // The reply (possibly with altered working counters) to the newest or older frame.
            let src = if newest {
                self.wire.last()
            } else {
                self.wire.first()
            };
            let since = src.map_or(0xFF, |w| w.moved);
            self.used_agree = Some(src.is_some_and(|w| w.agree));
            self.note_al_reads(bytes, since);
        }
        Ok(())
    }

    /// Records the AL states that a used reply told the machine (FPRD 0x0130, WKC 1).
    /// `since`: the slaves that changed AL state after the reply was produced.
    fn note_al_reads(&mut self, bytes: &[u8], since: u8) {
        let Ok(eth) = EthernetFrame::new_checked(bytes) else {
            return;
        };
        let Ok(ecat) = eth.ecat_frame() else {
            return;
        };
        for d in ecat.iter().flatten() {
            if d.command_raw() == Command::Fprd.code() && d.ado() == 0x0130 && d.wkc() == 1 {
                let pos = d.adp().wrapping_sub(self.cfg.station_base);
                if let (Some(k), [lo, hi, ..]) = (self.known_al.get_mut(usize::from(pos)), d.data())
                {
                    *k = Some(u16::from_le_bytes([*lo, *hi]));
                    if pos < 8 {
                        let bit = 1u8 << pos;
                        self.al_moved = (self.al_moved & !bit) | (since & bit);
                    }
                }
            }
        }
    }

    fn altered_newest(&self, f: impl Fn(u16) -> u16) -> Option<Vec<u8>> {
        let mut bytes = self.wire.last()?.reply.clone();
        let mut eth = EthernetFrame::new_unchecked(&mut bytes[..]);
        if let Ok(mut ecat) = eth.ecat_frame_mut() {
            for mut d in ecat.iter_mut().flatten() {
                let w = d.wkc();
                d.set_wkc(f(w));
            }
        }
        Some(bytes)
    }

    fn advance(&mut self, to: u64) -> Result<(), ModelViolation> {
        self.now = self.now.max(to);
        self.m.handle_timeout(SystemTime(self.now));
        if self.m.is_awaiting_reply() {
            if let Some(w) = self.wire.last() {
                if self.live && self.now >= w.sent_at.saturating_add(self.cfg.response_timeout_ns) {
                    return Err(ModelViolation::AwaitingPastDeadline);
                }
            }
        }
        Ok(())
    }

    /// Applies one action; checks the transition properties.
    pub fn step(&mut self, a: Action) -> Result<(), ModelViolation> {
        let mut buf = [0u8; 1514];
        self.last_events.clear();
        self.last_tx = None;
        self.used_agree = None;
        match a {
            Action::Tx => {
                if let Some(n) = self.m.poll_transmit(SystemTime(self.now), &mut buf) {
                    let f = buf.get(..n).unwrap_or(&[]).to_vec();
                    self.transmitted(f, None)?;
                }
            }
            Action::TxForeign => {
                let foreign = self.cfg.index_first.wrapping_sub(1);
                let Ok(mut b) = FrameBuilder::new(&mut buf) else {
                    return Ok(());
                };
                let _ = b.push(
                    Command::Lrw,
                    foreign,
                    Address::logical(0x0001_0000),
                    &[0u8; 8],
                );
                if self.m.poll_transmit_into(SystemTime(self.now), &mut b) {
                    if let Ok(n) = b.finish() {
                        let f = buf.get(..n).unwrap_or(&[]).to_vec();
                        self.transmitted(f, Some(foreign))?;
                    }
                }
            }
            Action::DeliverNewest => {
                if let Some(w) = self.wire.last() {
                    let r = w.reply.clone();
                    self.deliver(a, &r, true, true)?;
                }
            }
            Action::DeliverOlder => {
                if self.wire.len() == 2 {
                    if let Some(w) = self.wire.first() {
                        let r = w.reply.clone();
                        self.deliver(a, &r, false, true)?;
                    }
                }
            }
            Action::DeliverWkc0 => {
                if let Some(r) = self.altered_newest(|_| 0) {
                    self.deliver(a, &r, true, true)?;
                }
            }
            Action::DeliverWkcPlus => {
                if let Some(r) = self.altered_newest(|w| w.wrapping_add(1)) {
                    self.deliver(a, &r, true, true)?;
                }
            }
            Action::Lose => {
                self.wire.pop();
                // The reply to the newest frame can no longer come: the older one is not newest.
                self.live = false;
            }
            Action::Junk => {
                let junk = [0xFFu8, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x88, 0xA4];
                self.deliver(a, &junk, false, false)?;
            }
            Action::ForeignSameIndex => {
                // Processed frame (source MAC bit set) with one LRD datagram at the index the
                // machine used last: index matches, command does not.
                let idx = self
                    .wire
                    .last()
                    .and_then(|w| {
                        let eth = EthernetFrame::new_checked(&w.reply[..]).ok()?;
                        let f = eth.ecat_frame().ok()?;
                        let d = f.iter().flatten().next()?;
                        Some(d.index())
                    })
                    .unwrap_or(self.cfg.index_first);
                let Ok(mut b) = FrameBuilder::new(&mut buf) else {
                    return Ok(());
                };
                let _ = b.push(Command::Lrd, idx, Address::logical(0x0002_0000), &[0u8; 4]);
                if let Ok(n) = b.finish() {
                    let mut f = buf.get(..n).unwrap_or(&[]).to_vec();
                    EthernetFrame::new_unchecked(&mut f[..]).mark_processed_by_slave();
                    self.deliver(a, &f, false, false)?;
                }
            }
            Action::Tick => self.advance(self.now.saturating_add(TICK_NS))?,
            Action::ToDeadline => {
                if let Some(t) = self.m.poll_timeout() {
                    self.advance(t.as_nanos())?;
                }
            }
            Action::SlaveReset(j) => {
                if let Some(x) = self.al.get_mut(usize::from(j)) {
                    *x = 0x0001;
                    self.line.unaddressed |= 1u8 << j;
                    if let Some(c) = self.clocks.as_mut() {
                        c.reset(usize::from(j), self.now);
                    }
                    self.al_moved |= 1u8 << j;
                    for w in &mut self.wire {
                        w.moved |= 1u8 << j;
                    }
                }
            }
            Action::SlaveRun(j) => {
                // A slave already in SAFE-OP or OP stays as it is (no new state to explore).
                if let Some(x) = self
                    .al
                    .get_mut(usize::from(j))
                    .filter(|x| !matches!(**x & 0x0F, 4 | 8))
                {
                    *x = if j % 2 == 0 { 0x0004 } else { 0x0008 };
                    if let Some(c) = self.clocks.as_mut() {
                        c.join_running(usize::from(j), self.now);
                    }
                    self.al_moved |= 1u8 << j;
                    for w in &mut self.wire {
                        w.moved |= 1u8 << j;
                    }
                }
            }
            Action::Wrap => {
                let next = u64::from(self.line.latch.wrapping_add(1)) * 1_000_000;
                let below_wrap = u32::MAX - 1_499;
                self.line.wrap_base = u64::from(below_wrap.wrapping_sub(next as u32));
                if let Some(c) = self.clocks.as_mut() {
                    c.wrap();
                }
            }
            Action::Reset => {
                self.m.reset();
                self.live = false;
            }
            Action::Start => {
                self.m.start(SystemTime(self.now));
                self.live = false;
            }
            Action::Remeasure => self.m.request_delay_measurement(),
        }
        while let Some(e) = self.m.poll_event() {
            self.last_events.push(e);
        }
        // A new bring-up must read the AL states again before it may write 0x0920.
        if matches!(
            self.m.state(),
            State::Idle | State::RestartWait | State::Failed | State::CountSlaves
        ) {
            self.known_al = [None; CAP];
            self.al_moved = 0;
        }
        // The machine's own consistency guards (REQ-CONV-008) must never fire.
        if let Some(Event::Error(Error::Internal { state })) = self
            .last_events
            .iter()
            .find(|e| matches!(e, Event::Error(Error::Internal { .. })))
        {
            return Err(ModelViolation::Internal(*state));
        }
        if let Some(broken) = self.m.invariant_violation() {
            return Err(ModelViolation::Invariant(broken));
        }
        // Lock is reported only on a reply whose clocks agreed (within the lock threshold).
        if self.used_agree == Some(false)
            && self
                .last_events
                .iter()
                .any(|e| matches!(e, Event::Locked { .. }))
        {
            return Err(ModelViolation::LockedApart);
        }
        self.out.reached_cyclic |= self.m.state() == State::Cyclic;
        Ok(())
    }

    /// One step of the fault-free continuation: transmit and deliver, else go to the deadline
    /// (or tick when nothing is scheduled).
    fn nominal_step(&mut self) -> Result<(), ModelViolation> {
        if self.m.is_awaiting_reply() && self.live && !self.wire.is_empty() {
            return self.step(Action::DeliverNewest);
        }
        let sent = self.out.frames;
        self.step(Action::Tx)?;
        if self.out.frames != sent {
            return self.step(Action::DeliverNewest);
        }
        match self.m.poll_timeout() {
            Some(t) if t.as_nanos() > self.now => self.step(Action::ToDeadline),
            _ => self.step(Action::Tick),
        }
    }
}

/// Runs `f` and turns a panic into a violation.
fn guarded(f: impl FnOnce() -> Result<(), ModelViolation>) -> Result<(), ModelViolation> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(p) => Err(ModelViolation::Panic(
            p.downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default(),
        )),
    }
}

/// States of the fault-free run from `w` until `Cyclic` plus `extra` steps into it.
pub fn nominal_path(w: &World, extra: usize) -> Vec<World> {
    let mut w = w.clone();
    let mut v = vec![w.clone()];
    let mut after = None;
    for i in 0..LIVENESS_STEPS {
        if w.nominal_step().is_err() {
            break;
        }
        v.push(w.clone());
        if w.m.state() == State::Cyclic && after.is_none() {
            after = Some(i);
        }
        if after.is_some_and(|a| i >= a + extra) {
            break;
        }
    }
    v
}

/// What a search saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Report {
    /// Distinct states (fingerprints) visited.
    pub states: u64,
    /// Transitions taken (actions applied, including to known states).
    pub transitions: u64,
    /// Distinct states whose machine is in `Cyclic`.
    pub cyclic_states: u64,
    /// Distinct machine states (`State`) seen, as a bit set over `State::ALL`.
    pub machine_states: u32,
    /// Transmitted frames that wrote 0x0920 (checked against the ring's AL states).
    pub offset_writes: u64,
    /// Of those, writes to a slave that started running after the machine read its AL state
    /// (the explored AL races).
    pub al_races: u64,
    /// States whose fault-free continuation was followed to `Cyclic` (liveness).
    pub liveness_checked: u64,
    /// Of the states, those exempt from liveness: their fault-free continuation splits the
    /// running slaves between two domains ([`World::split_domains`]).
    pub split_domains: u64,
    /// Transitions on which the machine reported lock, each judged against the clocks (every
    /// slave within the lock threshold of the reference when the reply was produced).
    pub locks_judged: u64,
    /// Deepest level searched.
    pub depth: usize,
}

/// Breadth-first search from all seeds at once (level 0) up to `depth` actions, deduplicated
/// by fingerprint: every state within `depth` actions of some seed is visited once, every
/// transition out of it and every visited state is checked. Deterministic (one thread, fixed
/// action order, fixed hash keys).
///
/// Memory: a state is checked when it is first reached, while its world is at hand; the
/// frontier keeps only how to reach it (seed and actions) and the next level replays that
/// path. The worlds of a level never coexist, so the depth is bounded by time and by the
/// fingerprint sets (16 bytes a state), not by a level's worlds (kilobytes each).
pub fn explore(seeds: &[World], depth: usize) -> Result<Report, Box<Counterexample>> {
    let mut seen: HashSet<u128> = HashSet::new();
    // Liveness memo: fingerprints known to reach `Cyclic`, or a split of domains, without faults.
    let mut live_ok = LiveMemo::default();
    let mut r = Report::default();
    let fail = |(violation, continuation), seed: usize, trace: &[Action]| {
        Box::new(Counterexample {
            violation,
            seed,
            trace: trace.to_vec(),
            continuation,
        })
    };
    // The checks of a state, when it is first reached.
    let mut visit = |w: &World, r: &mut Report| -> Result<(), (ModelViolation, usize)> {
        r.states += 1;
        let st = w.m.state();
        r.cyclic_states += u64::from(st == State::Cyclic);
        if let Some(i) = State::ALL.iter().position(|s| *s == st) {
            r.machine_states |= 1 << i;
        }
        match liveness(w, &mut live_ok)? {
            Liveness::Live => r.liveness_checked += 1,
            Liveness::Exempt => r.split_domains += 1,
        }
        Ok(())
    };
    let mut level: Vec<(usize, Vec<Action>)> = Vec::new();
    for (si, seed) in seeds.iter().enumerate() {
        if seen.insert(seed.fingerprint()) {
            visit(seed, &mut r).map_err(|v| fail(v, si, &[]))?;
            level.push((si, Vec::new()));
        }
    }
    r.depth = 0;
    for d in 0..depth {
        if level.is_empty() {
            break;
        }
        let mut next = Vec::new();
        let mut reached = false;
        for (si, trace) in &level {
            let mut w = seeds[*si].clone();
            for (n, a) in trace.iter().enumerate() {
                guarded(|| w.step(*a)).map_err(|v| fail((v, 0), *si, &trace[..=n]))?;
            }
            for a in Action::all(w.line.k) {
                let mut w2 = w.clone();
                let (writes, races) = (w2.out.offset_writes, w2.out.al_races);
                let mut t = trace.clone();
                t.push(a);
                guarded(|| w2.step(a)).map_err(|v| fail((v, 0), *si, &t))?;
                r.transitions += 1;
                r.locks_judged += u64::from(
                    w2.last_events
                        .iter()
                        .any(|e| matches!(e, Event::Locked { .. })),
                );
                r.offset_writes += u64::from(w2.out.offset_writes - writes);
                r.al_races += u64::from(w2.out.al_races - races);
                if seen.insert(w2.fingerprint()) {
                    visit(&w2, &mut r).map_err(|v| fail(v, *si, &t))?;
                    reached = true;
                    if d + 1 < depth {
                        next.push((*si, t));
                    }
                }
            }
        }
        if !reached {
            break;
        }
        r.depth = d + 1;
        level = next;
    }
    Ok(r)
}

/// What the bounded liveness check concluded for one state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Liveness {
    /// The fault-free continuation reaches `Cyclic` (or the state is `Idle`).
    Live,
    /// The continuation splits the running slaves between two domains
    /// ([`World::split_domains`]) before reaching `Cyclic`: exempt.
    Exempt,
}

/// Memo of the liveness check: fingerprints known to reach `Cyclic`, and those known to reach a
/// split of the running slaves first.
#[derive(Default)]
struct LiveMemo {
    live: HashSet<u128>,
    exempt: HashSet<u128>,
}

/// Bounded liveness from `w`: the fault-free continuation reaches `Cyclic`, or `w` is `Idle`,
/// or the continuation meets a state whose running slaves are split between domains.
fn liveness(w: &World, memo: &mut LiveMemo) -> Result<Liveness, (ModelViolation, usize)> {
    if w.m.state() == State::Idle {
        return Ok(Liveness::Live);
    }
    let mut w = w.clone();
    let mut path = Vec::new();
    let mut verdict = None;
    for _ in 0..LIVENESS_STEPS {
        if w.m.state() == State::Cyclic {
            verdict = Some(Liveness::Live);
            break;
        }
        let fp = w.fingerprint();
        if memo.live.contains(&fp) {
            verdict = Some(Liveness::Live);
            break;
        }
        if memo.exempt.contains(&fp) || w.split_domains() {
            verdict = Some(Liveness::Exempt);
            break;
        }
        path.push(fp);
        let n = path.len();
        guarded(|| w.nominal_step()).map_err(|v| (v, n))?;
    }
    let Some(verdict) = verdict else {
        return Err((ModelViolation::NoProgress(w.m.state()), path.len()));
    };
    match verdict {
        Liveness::Live => memo.live.extend(path),
        Liveness::Exempt => memo.exempt.extend(path),
    }
    Ok(verdict)
}

/// Body for fuzzing and property tests: byte 0 chooses the line size (k = 1 + b % 4) and
/// which slaves have a 32-bit system time (bits 2..5: positions 0..3), bytes
/// 1..=4 the AL states (INIT, PREOP, SAFEOP, OP), every further byte (at most 4096) one
/// [`Action`] of [`Action::all`]; then the bounded liveness of the final state. Panics with the
/// violation on any failed check.
pub fn check_actions(data: &[u8]) {
    let mut it = data.iter().copied();
    let first = it.next().unwrap_or(0);
    let k = 1 + u16::from(first % 4);
    let mut al = [0x0001u16; CAP];
    for a in al.iter_mut() {
        *a = [0x01, 0x02, 0x04, 0x08][usize::from(it.next().unwrap_or(0) % 4)];
    }
    let Some(w) = World::new(k, al) else {
        return;
    };
    let mut w = w.with_bits32((first >> 2) & 0x0F);
    let actions = Action::all(k);
    for (i, b) in it.take(4096).enumerate() {
        let Some(&a) = actions.get(usize::from(b) % actions.len()) else {
            return;
        };
        if let Err(v) = w.step(a) {
            panic!("P6 violated by action {i} ({a:?}): {v:?}");
        }
    }
    if let Err((v, n)) = liveness(&w, &mut LiveMemo::default()) {
        panic!("P6 liveness violated after {n} fault-free steps: {v:?}");
    }
}
