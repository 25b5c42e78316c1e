//! Property bodies for the machine area: REQ-PROP P6 (spec/SPEC.md §2), REQ-DC-103, REQ-DC-113.
//!
//! [`run_script`] drives a [`Machine`] from an arbitrary byte script: time steps, transmissions,
//! replies with arbitrary working counters and data, replies to older frames (reordering),
//! lost frames, raw garbage, foreign frames, `start`/`reset`. It checks, on every frame the
//! machine writes and after every input:
//!
//! 1. no panic (the body would unwind);
//! 2. index matching: every datagram of the machine carries an index of its configured range,
//!    distinct within the frame; a frame without any datagram matching one the machine sent
//!    leaves the machine's observable state unchanged and is counted as foreign;
//! 3. REQ-DC-103, REQ-DC-030: 0x0920 is written only by FPWR, with 4 or 8 bytes, and only to a
//!    station whose (truthful) AL status is INIT, PRE-OP or BOOT; nothing else ever covers 0x0920;
//! 4. REQ-CONV-003 widths: 0x0990 with 4 or 8 bytes, 0x09A0/0x09A4/0x0928 with 4 bytes
//!    (REQ-DC-053), 0x0982 never written (REQ-DC-035).
//!
//! The simulated slaves are truthful about one thing only: every FPRD 0x0130 (AL status) reply
//! carries the station's fixed AL state chosen at the start of the script. Everything else
//! (working counters, data, timing, order, loss, garbage) is arbitrary. Without that one truth
//! the property could not hold for any master: a slave that lies "INIT" while in OP gets its
//! offset written by construction.
//!
//! Callers: the proptest `proofs/tests/machine.rs`, the fuzz target
//! `fuzz/fuzz_targets/machine_script.rs`, and the Kani harness [`kani_machine_script`] (small
//! bound; Kani is not installed on the build machine, so it has not been run here).
//!
//! verifies: P6, REQ-CONV-003, REQ-DC-030, REQ-DC-035, REQ-DC-053, REQ-DC-103, REQ-DC-113

#[cfg(not(kani))]
use crate::kani_shim as kani;
use ecdc_core::dc::{Config, DriftCheck, Machine, SyncConfig};
use ecdc_core::time::SystemTime;
use ecdc_core::wire::{Address, Command, EthernetFrame, FrameBuilder};

/// Slave capacity of the machine under test: small, so scripts reach every state.
pub const CAP: usize = 4;

/// What a script run observed (for coverage reporting in tests).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Outcome {
    /// Frames the machine produced.
    pub frames: u32,
    /// Offset (0x0920) writes seen.
    pub offset_writes: u32,
    /// Whether `Cyclic` was reached.
    pub reached_cyclic: bool,
    /// Deepest state index reached (position in `State::ALL`).
    pub deepest: usize,
    /// 0x0920 writes to a slave that was running at the write but had answered INIT, PRE-OP or
    /// BOOT to this bring-up's AL status read: the slave changed state in between (an AL race no
    /// master can see; counted, not a violation).
    pub al_races: u32,
}

/// A violated property.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Violation {
    /// A 0x0920 write to a slave whose AL status this bring-up had not read as INIT, PRE-OP or
    /// BOOT (REQ-DC-103): `known` is the last status the machine accepted, if any.
    OffsetWithoutRead {
        /// Station written.
        station: u16,
        /// Last AL status of that slave in a reply the machine used this bring-up.
        known: Option<u16>,
    },
    /// A datagram index outside the machine's range.
    IndexOutOfRange(u8),
    /// Two datagrams of the machine in one frame with the same index.
    DuplicateIndex(u8),
    /// 0x0920 written to a station whose AL state does not allow it.
    OffsetStep { station: u16, al: u16 },
    /// A write that covers 0x0920 with a command other than FPWR, or a width other than 4/8.
    OffsetWrite { command: u8, len: u16 },
    /// A register written with the wrong width.
    Width { register: u16, len: u16 },
    /// The machine changed state on a frame that matched nothing it sent.
    ForeignFrameUsed,
    /// The machine produced a frame that does not parse.
    Unparseable,
}

/// Configuration used by the script runs: tiny bursts and thresholds so every state is reachable
/// in a short script.
pub fn script_config() -> Config {
    let mut c = Config {
        latch_rounds: 1,
        retries: 1,
        response_timeout_ns: 50_000,
        restart_delay_ns: 10_000,
        sync: Some(SyncConfig {
            start_delay_ns: 1_000_000,
            ..SyncConfig::default()
        }),
        ..Config::default()
    };
    c.drift.burst_frames = 1;
    c.drift.consecutive = 1;
    c.drift.max_frames = 4;
    c.drift.check = DriftCheck::Both;
    c.drift.check_pause_ns = 5_000;
    c.monitor.lock_cycles = 1;
    c.monitor.unlock_cycles = 1;
    c.monitor.lock_timeout_cycles = 3;
    c.monitor.max_lost_cycles = 2;
    c.monitor.max_wkc_errors = 1;
    c.monitor.cycle_ns = 100_000;
    // The scripted ring does not model DL control loop bits, so the t_Diff step (which closes
    // ports) is off here; harness/tests/tdiff.rs runs it on the ESC emulator.
    c.tdiff.mode = ecdc_core::dc::TdiffMode::Off;
    c
}

struct Reader<'a> {
    data: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn u8(&mut self) -> Option<u8> {
        let v = *self.data.get(self.at)?;
        self.at += 1;
        Some(v)
    }
    fn u8_or0(&mut self) -> u8 {
        self.u8().unwrap_or(0)
    }
    fn u16_or0(&mut self) -> u16 {
        u16::from_le_bytes([self.u8_or0(), self.u8_or0()])
    }
}

/// Truthful AL state of a station: stations `base..base+CAP` get script-chosen states, every
/// other station counts as OP (never writable).
pub(crate) fn al_truth(al: &[u16; CAP], base: u16, station: u16) -> u16 {
    station
        .checked_sub(base)
        .and_then(|i| al.get(usize::from(i)).copied())
        .unwrap_or(0x0008)
}

/// Checks one frame produced by the machine (properties 2–4); returns the indices it used.
pub(crate) fn check_tx(
    frame: &[u8],
    cfg: &Config,
    al: &[u16; CAP],
    out: &mut Outcome,
    foreign_idx: Option<u8>,
    known: Option<(&[Option<u16>; CAP], u8)>,
) -> Result<Vec<u8>, Violation> {
    let eth = EthernetFrame::new_checked(frame).map_err(|_| Violation::Unparseable)?;
    let ecat = eth.ecat_frame().map_err(|_| Violation::Unparseable)?;
    let mut seen = Vec::new();
    for d in ecat.iter() {
        let d = d.map_err(|_| Violation::Unparseable)?;
        let idx = d.index();
        if Some(idx) == foreign_idx {
            continue;
        }
        let off = idx.wrapping_sub(cfg.index_first);
        if off >= cfg.index_count {
            return Err(Violation::IndexOutOfRange(idx));
        }
        if seen.contains(&idx) {
            return Err(Violation::DuplicateIndex(idx));
        }
        seen.push(idx);
        let Ok(cmd) = d.command() else {
            return Err(Violation::Unparseable);
        };
        let (ado, len) = (d.ado(), d.data_len());
        let covers = |reg: u16, w: u16| {
            u32::from(ado) < u32::from(reg) + u32::from(w)
                && u32::from(reg) < u32::from(ado) + u32::from(len)
        };
        // Every command that may write, the read-modify-writes included: an FRMW or ARMW over
        // 0x0920 would step every slave but the addressed one.
        if cmd.is_write() && covers(0x0920, 8) {
            if cmd != Command::Fpwr || ado != 0x0920 || !(len == 4 || len == 8) {
                return Err(Violation::OffsetWrite {
                    command: cmd.code(),
                    len,
                });
            }
            let station = d.adp();
            let a = al_truth(al, cfg.station_base, station);
            let running = !matches!(a & 0x0F, 1..=3);
            match known {
                // Static AL states: the truth is what the machine read.
                None if running => return Err(Violation::OffsetStep { station, al: a }),
                None => {}
                // AL states may change at any point: the write must rest on this bring-up's
                // read; a slave that started running after it is a race, not a fault.
                // `moved`: bit j set if slave j changed AL state after the machine's last read.
                Some((known, moved)) => {
                    let pos = station.checked_sub(cfg.station_base);
                    let k = pos
                        .and_then(|i| known.get(usize::from(i)).copied())
                        .flatten();
                    if !matches!(k.map(|k| k & 0x0F), Some(1..=3)) {
                        return Err(Violation::OffsetWithoutRead { station, known: k });
                    }
                    let moved = pos.is_some_and(|i| i < 8 && moved & (1u8 << i) != 0);
                    if running && !moved {
                        // Running when read and still running: the read was not believed, or
                        // the slave lied (the checker's own mutation test).
                        return Err(Violation::OffsetStep { station, al: a });
                    }
                    if running {
                        out.al_races += 1;
                    }
                }
            }
            out.offset_writes += 1;
        }
        if cmd.is_write() {
            let bad = match ado {
                0x0990 => !(len == 4 || len == 8),
                0x0928 | 0x09A0 | 0x09A4 => len != 4,
                _ => false,
            } || covers(0x0982, 2);
            if bad {
                return Err(Violation::Width { register: ado, len });
            }
        }
    }
    Ok(seen)
}

/// A tiny consistent line of `k` ideal 64-bit DC slaves, used for "plausible" replies so that
/// scripts reach the deep states (offset write, drift gate, SYNC, cyclic) and the property is
/// exercised where it matters. It is not an emulator: no drift, 1 µs per hop.
///
/// Two faults change it: a **slave reset** (power cycle) clears that slave's station address,
/// so configured-address datagrams to it go unanswered (WKC 0) until an APWR to 0x0010
/// addresses it again, and its AL state falls back to INIT; a **port-time wrap** moves every
/// latch close below 2^32 ns so the 32-bit receive times of one measurement straddle the wrap.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct Model {
    pub(crate) k: u16,
    pub(crate) latch: u32,
    /// Bit `p` set: the slave at position `p` was reset and has no station address yet.
    pub(crate) unaddressed: u8,
    /// Added to every latch time (0, or just below 2^32 after a wrap fault).
    pub(crate) wrap_base: u64,
}

impl Model {
    fn is_unaddressed(&self, pos: u16) -> bool {
        pos < 8 && self.unaddressed & (1u8 << pos) != 0
    }

    pub(crate) fn answer(
        &mut self,
        cmd: u8,
        adp: u16,
        ado: u16,
        base: u16,
        now: u64,
        data: &mut [u8],
    ) -> u16 {
        let k = self.k;
        let put = |data: &mut [u8], v: u64| {
            for (b, v) in data.iter_mut().zip(v.to_le_bytes()) {
                *b = v;
            }
        };
        match Command::from_u8(cmd) {
            Ok(Command::Brd) => {
                data.iter_mut().for_each(|b| *b = 0);
                k
            }
            Ok(Command::Bwr) => {
                if ado == 0x0900 {
                    self.latch = self.latch.wrapping_add(1);
                }
                k
            }
            Ok(Command::Apwr) => {
                let pos = Address::position_of_adp(adp);
                if ado == 0x0010 && pos < 8 {
                    self.unaddressed &= !(1u8 << pos);
                }
                u16::from(pos < k)
            }
            Ok(Command::Frmw) => {
                put(data, now);
                // The reference reads; every other addressed-or-not slave compares.
                k
            }
            Ok(Command::Fpwr) => {
                let pos = adp.wrapping_sub(base);
                u16::from(pos < k && !self.is_unaddressed(pos))
            }
            Ok(Command::Fprd) => {
                let pos = adp.wrapping_sub(base);
                if pos >= k || self.is_unaddressed(pos) {
                    return 0;
                }
                let t = self.wrap_base + u64::from(self.latch) * 1_000_000;
                match ado {
                    0x0008 => put(data, 0x000C),
                    0x0110 => {
                        // Port 0 open; port 1 open except on the line end; ports 2, 3 closed.
                        let mut dl: u64 = 0x0010 | 0x0200 | (1 << 12) | (1 << 14);
                        if pos + 1 < k {
                            dl |= 0x0020 | 0x0800;
                        } else {
                            dl |= 1 << 10;
                        }
                        put(data, dl);
                    }
                    0x0900 => {
                        let p0 = t + u64::from(pos) * 1_000;
                        let p1 = t + u64::from(2 * (k - 1) - pos) * 1_000 + 500;
                        let mut v = [0u8; 32];
                        v[0..4].copy_from_slice(&(p0 as u32).to_le_bytes());
                        v[4..8].copy_from_slice(&(p1 as u32).to_le_bytes());
                        v[24..32].copy_from_slice(&p0.to_le_bytes());
                        for (b, v) in data.iter_mut().zip(v) {
                            *b = v;
                        }
                    }
                    0x0910 => put(data, now),
                    _ => data.iter_mut().for_each(|b| *b = 0),
                }
                1
            }
            _ => 0,
        }
    }
}

/// Builds a reply to `frame`: processed-by-slave MAC; then either the [`Model`]'s consistent
/// answers (first script byte ≥ 0x80) or, per datagram, an arbitrary WKC and kept, zeroed or
/// arbitrary data. AL status reads are answered truthfully in both cases.
fn reply(
    frame: &[u8],
    r: &mut Reader<'_>,
    al: &[u16; CAP],
    base: u16,
    model: &mut Model,
    now: u64,
) -> Vec<u8> {
    let mut out = frame.to_vec();
    let mut eth = EthernetFrame::new_unchecked(&mut out[..]);
    eth.mark_processed_by_slave();
    let modelled = r.u8_or0() >= 0x80;
    if let Ok(mut ecat) = eth.ecat_frame_mut() {
        if modelled {
            for mut d in ecat.iter_mut().flatten() {
                let (cmd, adp, ado) = (d.command_raw(), d.adp(), d.ado());
                let wkc = model.answer(cmd, adp, ado, base, now, d.data_mut());
                if cmd == Command::Fprd.code() && ado == 0x0130 {
                    let v = al_truth(al, base, adp).to_le_bytes();
                    for (b, v) in d.data_mut().iter_mut().zip(v) {
                        *b = v;
                    }
                }
                d.set_wkc(wkc);
            }
            return out;
        }
        for d in ecat.iter_mut().flatten() {
            let mut d = d;
            let mode = r.u8_or0();
            let wkc = match mode & 3 {
                0 | 1 => 1,
                2 => u16::from(r.u8_or0() % 6),
                _ => r.u16_or0(),
            };
            let is_al = d.command_raw() == Command::Fprd.code() && d.ado() == 0x0130;
            let station = d.adp();
            let data = d.data_mut();
            match (mode >> 2) & 3 {
                0 => {}
                1 => data.iter_mut().for_each(|b| *b = 0),
                _ => data.iter_mut().for_each(|b| *b = r.u8_or0()),
            }
            if is_al {
                let v = al_truth(al, base, station).to_le_bytes();
                for (b, v) in data.iter_mut().zip(v) {
                    *b = v;
                }
            }
            d.set_wkc(wkc);
        }
    }
    out
}

/// Replaces the data of every FPRD 0x0130 in a raw frame by the truth (slaves do not lie about
/// AL status, see the module doc).
fn sanitise(bytes: &mut [u8], al: &[u16; CAP], base: u16) {
    let mut eth = EthernetFrame::new_unchecked(bytes);
    if let Ok(mut ecat) = eth.ecat_frame_mut() {
        for mut d in ecat.iter_mut().flatten() {
            if d.command_raw() == Command::Fprd.code() && d.ado() == 0x0130 {
                let v = al_truth(al, base, d.adp()).to_le_bytes();
                for (b, v) in d.data_mut().iter_mut().zip(v) {
                    *b = v;
                }
            }
        }
    }
}

/// What a used frame may change, compared by value (no `Debug` formatting, so the same code is
/// cheap under Kani).
fn snapshot<const N: usize>(m: &Machine<N>) -> impl PartialEq {
    (
        m.state(),
        m.slaves().to_vec(),
        m.reference(),
        m.is_locked(),
        m.sync_start(),
    )
}

/// REQ-PROP P6: runs `script` against a fresh machine; `Err` on the first violated property.
pub fn run_script(script: &[u8]) -> Result<Outcome, Violation> {
    let cfg = script_config();
    let base = cfg.station_base;
    let mut m: Machine<CAP> = match Machine::new(cfg) {
        Ok(m) => m,
        Err(_) => return Ok(Outcome::default()),
    };
    let mut r = Reader {
        data: script,
        at: 0,
    };
    let mut al = [0u16; CAP];
    for a in al.iter_mut() {
        *a = match r.u8_or0() % 8 {
            0..=3 => 0x0001,
            4 => 0x0002,
            5 => 0x0004,
            6 => 0x0008,
            _ => 0x0014,
        };
    }
    let mut model = Model {
        k: 1 + u16::from(r.u8_or0()) % CAP as u16,
        latch: 0,
        unaddressed: 0,
        wrap_base: 0,
    };
    let mut now: u64 = 800_000_000_000_000_000;
    m.start(SystemTime(now));
    let mut out = Outcome::default();
    let mut sent: Vec<Vec<u8>> = Vec::new(); // last frames, newest last
    let mut sent_idx: Vec<u8> = Vec::new();
    let mut buf = [0u8; 1514];
    while let Some(op) = r.u8() {
        match op % 8 {
            0 => {
                now = now.wrapping_add(u64::from(r.u16_or0()) * 100);
                m.handle_timeout(SystemTime(now));
            }
            1 | 2 => {
                if let Some(n) = m.poll_transmit(SystemTime(now), &mut buf) {
                    let f = buf.get(..n).unwrap_or(&[]).to_vec();
                    sent_idx.extend(check_tx(&f, &cfg, &al, &mut out, None, None)?);
                    out.frames += 1;
                    sent.push(f);
                    if sent.len() > 3 {
                        sent.remove(0);
                    }
                }
            }
            3 | 4 => {
                // Reply to the newest frame (3) or an older one (4: reordering / late reply).
                let pick = if op % 8 == 3 {
                    sent.len().checked_sub(1)
                } else {
                    sent.len().checked_sub(1 + usize::from(r.u8_or0() % 2))
                };
                if let Some(f) = pick.and_then(|i| sent.get(i)).cloned() {
                    now = now.wrapping_add(u64::from(r.u8_or0()) * 50);
                    let rep = reply(&f, &mut r, &al, base, &mut model, now);
                    m.handle_frame(SystemTime(now), &rep);
                }
            }
            5 => {
                // Raw garbage (or a mangled copy of a sent frame).
                let len = usize::from(r.u8_or0());
                let mut g: Vec<u8> = if r.u8_or0().is_multiple_of(2) {
                    // The next `len` script bytes, fewer when the script ends: the loop is
                    // bounded by the script, not by the 255 a length byte allows.
                    let take = len.min(r.data.len().saturating_sub(r.at));
                    (0..take).map(|_| r.u8_or0()).collect()
                } else {
                    let mut f = sent.last().cloned().unwrap_or_default();
                    for _ in 0..(len % 8) {
                        let at = r.u16_or0();
                        if !f.is_empty() {
                            // In u16 (frames are at most 1514 bytes, so the length fits): a
                            // 16-bit remainder, where `usize` would give Kani a 64-bit divider
                            // by a symbolic frame length.
                            let n = u16::try_from(f.len()).unwrap_or(u16::MAX);
                            let i = usize::from(at % n);
                            f[i] = r.u8_or0();
                        }
                    }
                    f
                };
                sanitise(&mut g, &al, base);
                let ours = EthernetFrame::new_checked(&g[..])
                    .ok()
                    .and_then(|e| {
                        e.ecat_frame()
                            .ok()
                            .map(|f| f.iter().flatten().any(|d| sent_idx.contains(&d.index())))
                    })
                    .unwrap_or(false);
                let before = snapshot(&m);
                let foreign_before = m.stats().foreign_frames;
                m.handle_frame(SystemTime(now), &g);
                if !ours
                    && (snapshot(&m) != before || m.stats().foreign_frames != foreign_before + 1)
                {
                    return Err(Violation::ForeignFrameUsed);
                }
            }
            6 => {
                // The embedding master's frame: one foreign datagram first, then ours.
                let foreign = cfg.index_first.wrapping_sub(1);
                let mut b = match FrameBuilder::new(&mut buf) {
                    Ok(b) => b,
                    Err(_) => continue,
                };
                let _ = b.push(
                    Command::Lrw,
                    foreign,
                    Address::logical(0x0001_0000),
                    &[0u8; 8],
                );
                if m.poll_transmit_into(SystemTime(now), &mut b) {
                    if let Ok(n) = b.finish() {
                        let f = buf.get(..n).unwrap_or(&[]).to_vec();
                        sent_idx.extend(check_tx(&f, &cfg, &al, &mut out, Some(foreign), None)?);
                        out.frames += 1;
                        sent.push(f);
                        if sent.len() > 3 {
                            sent.remove(0);
                        }
                    }
                }
            }
            _ => {
                match r.u8_or0() % 8 {
                    0 => m.reset(),
                    1 => m.start(SystemTime(now)),
                    2 => m.request_delay_measurement(),
                    4 => {
                        // A slave resets (power cycle): station address gone, AL back to
                        // INIT. The machine must notice and re-initialise without writing a
                        // wrong value anywhere.
                        let j = usize::from(r.u8_or0()) % CAP;
                        if let Some(a) = al.get_mut(j) {
                            *a = 0x0001;
                        }
                        if j < 8 {
                            model.unaddressed |= 1u8 << j;
                        }
                    }
                    5 => {
                        // The slaves' 32-bit port times are about to wrap: the next latch
                        // rounds straddle 2^32 ns.
                        // The next latch (latch + 1) lands 1.5 µs below a multiple of 2^32.
                        let next = u64::from(model.latch.wrapping_add(1)) * 1_000_000;
                        let below_wrap = u32::MAX - 1_499;
                        model.wrap_base = u64::from(below_wrap.wrapping_sub(next as u32));
                    }
                    _ => {
                        // Skip straight to the machine's deadline.
                        if let Some(t) = m.poll_timeout() {
                            now = now.max(t.as_nanos());
                            m.handle_timeout(SystemTime(now));
                        }
                    }
                }
            }
        }
        while m.poll_event().is_some() {}
        let depth = ecdc_core::dc::State::ALL
            .iter()
            .position(|s| *s == m.state())
            .unwrap_or(0);
        if depth < ecdc_core::dc::State::ALL.len() - 2 {
            out.deepest = out.deepest.max(depth);
        }
        out.reached_cyclic |= m.state() == ecdc_core::dc::State::Cyclic;
        if sent_idx.len() > 256 {
            sent_idx.drain(..128);
        }
    }
    Ok(out)
}

/// Panicking form for fuzzers: any violation is a crash, with the violation.
pub fn check_script(script: &[u8]) {
    if let Err(v) = run_script(script) {
        panic!("machine property violated: {v:?}");
    }
}

/// Kani harness: every 8-byte script (small bound: one start, a few transmissions and
/// replies). Not run under Kani here (Kani is not installed); under the shim it runs as a random
/// test (`proofs/tests/machine.rs`).
// Loop bounds with an 8-byte script: the script loop and the garbage copy run at most 8 times,
// the mangling loop at most 7, `Machine::fill`'s step loop at most 64 (its own bound); the
// unwind covers the largest. Byte copies of frames are bounded by the 1514-byte buffer and are
// the reason this harness is the most expensive one (never run here).
#[cfg_attr(kani, kani::proof)]
#[cfg_attr(kani, kani::unwind(66))]
pub fn kani_machine_script() {
    let script: [u8; 8] = kani::any();
    // No `Debug` formatting of the violation: Kani reports the failing assertion and its trace.
    assert!(run_script(&script).is_ok(), "machine property violated");
}
