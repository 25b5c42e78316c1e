//! The `ecdc simulate` report: one serialisable structure ([`Report`]) written as JSON, printed
//! as text tables ([`table`]) and plotted as SVG ([`svg`], the project's one SVG writer).

pub mod svg;
pub mod table;
pub mod table2;

use std::collections::BTreeMap;

use crate::schemes::measure::{SlaveRow, Summary};

/// The run's setup, as reported.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Setup {
    pub slaves: usize,
    pub topology: String,
    pub cycle_ns: u32,
    pub duration_ns: u64,
    /// Crystal errors drawn per slave (ppm), in emulator order.
    pub crystal_ppm: Vec<f64>,
    pub frame_loss_rate: f64,
    pub seed: u64,
    /// t_DIFF = nominal t_P − t_F of the scenario, ns. Which scheme was given it: each
    /// scheme's `given`.
    pub t_diff_ns: i64,
    /// Lock-detection sampling period, ns.
    pub sample_ns: u64,
    /// ecdc's FRMW frames per static drift burst (`DriftConfig::burst_frames`).
    pub ecdc_drift_burst_frames: u16,
}

/// One stated target and whether this run met it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Target {
    pub name: String,
    pub target: String,
    pub measured: String,
    pub met: bool,
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Report {
    pub setup: Setup,
    /// Definitions of every reported quantity (same text as docs/simulate.md).
    pub definitions: BTreeMap<&'static str, &'static str>,
    /// `ecdc`, `seed000`, `seed000-printed`, `uncompensated`; each with `given` (what the
    /// scheme was told beyond what it measured).
    pub schemes: BTreeMap<String, Summary>,
    /// ecdc's per-slave table (seed 000 Table 2 rows), also under `schemes.ecdc.slaves`.
    pub table: Vec<SlaveRow>,
    /// ecdc ÷ seed000 for skew mean, p99, max, lock frames and lock ms (< 1 = ecdc better).
    pub ratios: BTreeMap<&'static str, Option<f64>>,
    pub targets: Vec<Target>,
    /// The emulator's true propagation delays (set by `ecdc simulate`, [`table2::truth`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<table2::Truth>,
    /// Seed 000's own Table 2 numbers, on the default scenario only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub paper: Option<table2::Paper>,
}

/// The definitions written into every report.
pub fn definitions() -> BTreeMap<&'static str, &'static str> {
    BTreeMap::from([
        (
            "skew",
            "for every SYNC0 pulse (same programmed system time) whose reference edge is in the \
             steady-state window: each other slave's edge true time minus the reference's; \
             mean |skew|, p99 |skew| (nearest rank) and max |skew| over all (slave, pulse) pairs",
        ),
        (
            "steady_state_window",
            "last half of the cyclic phase; cyclic phase = first SYNC0 edge of any slave to the \
             end of the run (per scheme)",
        ),
        (
            "lock",
            "first lock-detection sample from which every later sample has every slave's \
             system time within 100 ns (true time) of the reference's; lock_frames = frames \
             distributing the reference time sent until then, lock_ms = its true time since \
             the master started",
        ),
        (
            "clock_error",
            "true-time error: slave system time minus reference system time at the same true \
             instant, sampled once per cycle (emulator observer)",
        ),
        (
            "drift_compensation",
            "signed 0x092C (sign-magnitude decoded) sampled once per cycle in the window; \
             absent when the scheme never distributes the reference time",
        ),
        (
            "uncompensated",
            "offsets only (eq. 24, no delay folded, 0x0928 not written), SYNC0 started on a \
             common time, no drift compensation frames ever",
        ),
    ])
}

/// ecdc ÷ seed000 of an optional pair.
fn ratio(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) if b > 0.0 => Some(a / b),
        _ => None,
    }
}

impl Report {
    /// Assembles the report and evaluates the targets.
    pub fn new(setup: Setup, summaries: Vec<Summary>) -> Report {
        let schemes: BTreeMap<String, Summary> =
            summaries.into_iter().map(|s| (s.name.clone(), s)).collect();
        let e = schemes.get("ecdc");
        let s = schemes.get("seed000");
        let f = |x: Option<u64>| x.map(|v| v as f64);
        let ratios = BTreeMap::from([
            (
                "skew_mean",
                ratio(
                    e.and_then(|x| x.skew.mean_ns),
                    s.and_then(|x| x.skew.mean_ns),
                ),
            ),
            (
                "skew_p99",
                ratio(
                    f(e.and_then(|x| x.skew.p99_ns)),
                    f(s.and_then(|x| x.skew.p99_ns)),
                ),
            ),
            (
                "skew_max",
                ratio(
                    f(e.and_then(|x| x.skew.max_ns)),
                    f(s.and_then(|x| x.skew.max_ns)),
                ),
            ),
            (
                "lock_frames",
                ratio(
                    f(e.and_then(|x| x.lock_frames)),
                    f(s.and_then(|x| x.lock_frames)),
                ),
            ),
            (
                "lock_ms",
                ratio(e.and_then(|x| x.lock_ms), s.and_then(|x| x.lock_ms)),
            ),
        ]);
        let fmt = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{v:.1}"));
        let mut targets = Vec::new();
        if let Some(e) = e {
            targets.push(Target {
                name: "ecdc skew mean".into(),
                target: "<= 10 ns".into(),
                measured: fmt(e.skew.mean_ns),
                met: e.skew.mean_ns.is_some_and(|v| v <= 10.0),
            });
            targets.push(Target {
                name: "ecdc skew max".into(),
                target: "<= 40 ns".into(),
                measured: fmt(f(e.skew.max_ns)),
                met: e.skew.max_ns.is_some_and(|v| v <= 40),
            });
            targets.push(Target {
                name: "ecdc lock frames".into(),
                target: "<= 3000 (0.2 x 15000)".into(),
                measured: fmt(f(e.lock_frames)),
                met: e.lock_frames.is_some_and(|v| v <= 3000),
            });
            if let Some(s) = s {
                // The time to lock, beside the frames: a scheme that sends fewer frames but
                // waits longer has not locked faster. Against the fastest other scheme that
                // locked in this run.
                let fastest = schemes
                    .values()
                    .filter(|x| x.name != "ecdc")
                    .filter_map(|x| x.lock_ms.map(|ms| (ms, x.name.clone())))
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                let r = ratio(e.lock_ms, fastest.as_ref().map(|f| f.0));
                targets.push(Target {
                    name: "ecdc lock ms vs the fastest other scheme".into(),
                    target: "ratio <= 0.5".into(),
                    measured: format!(
                        "{} ms vs {} {} ms, ratio {}",
                        fmt(e.lock_ms),
                        fastest.as_ref().map_or("none", |f| f.1.as_str()),
                        fmt(fastest.as_ref().map(|f| f.0)),
                        r.map_or("n/a".into(), |r| format!("{r:.3}"))
                    ),
                    met: r.is_some_and(|r| r <= 0.5),
                });
                let ok = match (e.skew.mean_ns, s.skew.mean_ns, e.skew.max_ns, s.skew.max_ns) {
                    (Some(a), Some(b), Some(c), Some(d)) => a <= b && c <= d,
                    _ => false,
                };
                targets.push(Target {
                    name: "ecdc skew no worse than seed000 (mean and max)".into(),
                    target: "ratio <= 1".into(),
                    measured: format!(
                        "mean ratio {}, max ratio {}",
                        ratios["skew_mean"].map_or("n/a".into(), |r| format!("{r:.3}")),
                        ratios["skew_max"].map_or("n/a".into(), |r| format!("{r:.3}"))
                    ),
                    met: ok,
                });
            }
        }
        Report {
            setup,
            definitions: definitions(),
            table: e.map(|x| x.slaves.clone()).unwrap_or_default(),
            schemes,
            ratios,
            targets,
            truth: None,
            paper: None,
        }
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> anyhow::Result<String> {
        Ok(serde_json::to_string_pretty(self)?)
    }
}
