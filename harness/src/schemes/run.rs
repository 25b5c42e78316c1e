//! The recorder: drives one [`Scheme`] through a run and records, from the emulator's true-time
//! observers (never from what the master believes):
//!
//! - every `sample_ns`: the largest |system time of slave − system time of the reference| and
//!   the number of reference-time frames sent so far (for the lock instant);
//! - every cycle: each slave's signed clock error and its 0x092C register (side-effect-free
//!   peek, the value a master reading 0x092C would get);
//! - every SYNC0 edge (true time and the programmed system time, which identifies the pulse).

use ecdc_core::wire::register::{reg, SystemTimeDifference};

use super::{Given, Scheme, Written};
use crate::emu::{yardstick, SyncSignal, TrueTime};

/// Timing of a recorded run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunOpts {
    /// Length of the run, true ns from the master's start.
    pub duration_ns: u64,
    /// Lock-detection sampling period, ns.
    pub sample_ns: u64,
    /// Clock-error / 0x092C sampling period (the cycle), ns.
    pub cycle_ns: u64,
}

/// One SYNC0 edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    /// Programmed system time (same value on every slave for the same pulse).
    pub system_time: u64,
    /// Emulator index.
    pub slave: usize,
    /// True time of the edge.
    pub true_time: TrueTime,
}

/// Everything recorded about one scheme's run.
#[derive(Debug, Clone, Default)]
pub struct Record {
    /// Scheme name.
    pub name: &'static str,
    /// Emulator index of the reference clock.
    pub reference: usize,
    /// Number of slaves.
    pub slaves: usize,
    /// What was written to 0x0920 / 0x0928.
    pub written: Vec<Written>,
    /// Frames of the static drift compensation.
    pub static_drift_frames: Option<u64>,
    /// Reference-time frames sent over the whole run.
    pub dist_frames: u64,
    /// (true time, reference-time frames so far, max |clock error| over slaves with a system
    /// time; `None` while the reference has none).
    pub track: Vec<(TrueTime, u64, Option<u64>)>,
    /// Per-cycle sample instants.
    pub cyc_t: Vec<TrueTime>,
    /// `[slave][k]`: clock error (slave − reference) at `cyc_t[k]`, ns.
    pub cyc_err: Vec<Vec<Option<i64>>>,
    /// `[slave][k]`: signed 0x092C at `cyc_t[k]`, ns.
    pub cyc_diff: Vec<Vec<Option<i32>>>,
    /// SYNC0 edges of every slave.
    pub sync0: Vec<Edge>,
    /// True time the run ended.
    pub end: TrueTime,
    /// Why the scheme stopped early, if it did.
    pub error: Option<String>,
    /// Some slave has a 32-bit system time: clock errors involving it are compared on the low
    /// 32 bits (what its ESC loop compares) and SYNC0 pulses are matched by the low 32 bits of
    /// their programmed time (a 32-bit slave's copy of the 64-bit start time).
    pub has_32bit: bool,
    /// Only when `has_32bit`: the reference's system time at each `cyc_t` sample.
    pub ref_sys: Vec<Option<u64>>,
    /// Frames the master sent that the network lost.
    pub frames_lost: u64,
    /// What the scheme was told beyond what it measured ([`Scheme::given`]).
    pub given: Given,
}

pub use crate::emu::yardstick::clock_error;

/// Drives `s` for `opts.duration_ns`, calling `progress(t)` after each sample.
pub fn run_scheme(
    s: &mut dyn Scheme,
    opts: RunOpts,
    progress: &mut dyn FnMut(TrueTime),
) -> anyhow::Result<Record> {
    run_scheme_observed(s, opts, progress, &mut |_, _| Ok(()))
}

/// [`run_scheme`], also handing the network and the SYNC edges of every sample step to
/// `observe` (after the recorder's own sample), e.g. for a [`crate::emu::yardstick::Yardstick`]
/// watching the same run.
pub fn run_scheme_observed(
    s: &mut dyn Scheme,
    opts: RunOpts,
    progress: &mut dyn FnMut(TrueTime),
    observe: &mut dyn FnMut(
        &mut crate::emu::Network,
        &[crate::emu::SyncEdge],
    ) -> anyhow::Result<()>,
) -> anyhow::Result<Record> {
    let n = s.net().slave_count();
    let wide = yardstick::wide_slaves(s.net());
    let mut r = Record {
        name: s.name(),
        given: s.given(),
        slaves: n,
        has_32bit: wide.iter().any(|w| !w),
        cyc_err: vec![Vec::new(); n],
        cyc_diff: vec![Vec::new(); n],
        ..Record::default()
    };
    let sample = opts.sample_ns.max(1);
    let cycle = opts.cycle_ns.max(sample);
    let mut t: TrueTime = 0;
    let mut next_cycle: TrueTime = 0;
    let mut sys = vec![None; n];
    while t < opts.duration_ns {
        t = t.saturating_add(sample).min(opts.duration_ns);
        if let Err(e) = s.advance(t) {
            r.error = Some(format!("{e:#}"));
            break;
        }
        let reference = s.reference();
        let net = s.net();
        let ts = t.max(net.now()).max(yardstick::max_anchor(net));
        for (i, v) in sys.iter_mut().enumerate() {
            *v = net.clock(i, ts)?.system_time;
        }
        let rsys = sys.get(reference).copied().flatten();
        let errs = yardstick::clock_errors(&sys, &wide, reference);
        let max_abs = rsys.map(|_| {
            errs.iter()
                .flatten()
                .map(|e| e.unsigned_abs())
                .max()
                .unwrap_or(0)
        });
        r.track.push((ts, s.dist_frames(), max_abs));
        if ts >= next_cycle {
            next_cycle = (ts / cycle + 1) * cycle;
            r.cyc_t.push(ts);
            if r.has_32bit {
                r.ref_sys.push(rsys);
            }
            let net = s.net();
            for (i, e) in errs.iter().enumerate() {
                r.cyc_err[i].push(*e);
                let d = net
                    .peek(i, reg::SYSTEM_TIME_DIFFERENCE, 4)
                    .ok()
                    .and_then(|b| SystemTimeDifference::parse(&b).ok())
                    .map(SystemTimeDifference::to_ns);
                r.cyc_diff[i].push(d);
            }
        }
        let edges = s.net().take_sync_edges();
        for e in &edges {
            if e.signal == SyncSignal::Sync0 {
                r.sync0.push(Edge {
                    system_time: e.system_time,
                    slave: e.slave,
                    true_time: e.true_time,
                });
            }
        }
        observe(s.net(), &edges)?;
        r.end = ts;
        progress(t);
    }
    r.reference = s.reference();
    r.written = s.written();
    r.written.resize(n, Written::default());
    r.static_drift_frames = s.static_drift_frames();
    r.dist_frames = s.dist_frames();
    r.frames_lost = s.frames_lost();
    Ok(r)
}
