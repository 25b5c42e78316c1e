//! How the core scales with the slave count (issue 8 item 4): bring-up (frames and simulated
//! time to lock, wall time, and the core's own CPU time apart from the emulator's), per-cycle
//! cost, and the memory footprint of the core state. Writes `benches/results/scale.md` and
//! `benches/results/scale.svg`.
//!
//! ```sh
//! cargo run --release -p ecdc-benches --bin scale            # 1, 4, 16, ..., 512, 1024
//! cargo run --release -p ecdc-benches --bin scale -- 1 4 16  # chosen counts
//! ```
//!
//! Setup per count n: the emulator's default ESCs (64-bit DC, t_P 540 ns, t_F 460 ns, 1 m
//! cables, ±50 ppm crystals, PHY jitter and wander on, seed 0) in a line; the machine is
//! `Machine<1024>` for every n (one capacity, as a master sized for the largest network would
//! be) with `ecdc simulate`'s configuration. Cycle 1 ms, except where the line's round trip
//! (≈ 1 µs per slave) exceeds it: 2 ms for n > 512.

use std::fmt::Write as _;
use std::time::Instant;

use ecdc_benches::cyclic::{self, capture_from, config_with_cycle, MasterLoop, Replay, Shape};
use ecdc_benches::timed::{self, thread_cpu_ns, CallLog};
use ecdc_core::dc::delay::Delays;
use ecdc_core::dc::topology::Topology;
use ecdc_core::dc::{Machine, SlaveInfo};
use ecdc_core::servo::master::MasterServo;
use ecdc_core::time::SystemTime;
use ecdc_harness::report::svg::{self, Panel, Series};
use ecdc_harness::sim::DEFAULT_MASTER_EPOCH_NS;

const CAP: usize = 1024;
/// Simulated time after which a bring-up is reported as not locking.
const LIMIT_NS: u64 = 300_000_000_000;
const DEFAULT_COUNTS: [usize; 8] = [1, 4, 16, 64, 128, 256, 512, 1024];

struct Row {
    n: usize,
    cycle_ns: u64,
    /// Frames, simulated ms and core CPU ms from `start` to the drift phase.
    to_drift: Option<(f64, f64, f64)>,
    wall_s: f64,
    core_ms: f64,
    restarts: u64,
    locked: Option<Locked>,
    failure: Option<String>,
}

struct Locked {
    lock_frames: u64,
    lock_ms: f64,
    cycle_ns_core: f64,
    cycle_ns_servo: f64,
}

fn cycle_for(n: usize) -> u64 {
    if n > 512 {
        2_000_000
    } else {
        1_000_000
    }
}

/// ns per cycle: the minimum over 41 batches of 5 000 cycles of this thread's CPU time (after
/// a warm-up), so time-slicing with other processes does not count.
fn per_cycle(cap: &cyclic::Capture<CAP>, servo: bool) -> anyhow::Result<f64> {
    let mut r = Replay::new(cap);
    let mut s = MasterLoop::new(cap.cycle_ns)?;
    for _ in 0..5_000 {
        let now = r.now();
        let t = r.cycle();
        s.step(now, t);
    }
    let per = 5_000u64;
    let mut best = f64::MAX;
    for _ in 0..41 {
        let t0 = thread_cpu_ns();
        for _ in 0..per {
            if servo {
                let now = r.now();
                let t = r.cycle();
                std::hint::black_box(s.step(now, t));
            } else {
                std::hint::black_box(r.cycle());
            }
        }
        let dt = thread_cpu_ns().saturating_sub(t0) as f64 / per as f64;
        best = best.min(dt);
    }
    anyhow::ensure!(r.healthy(), "replay left the locked path");
    Ok(best)
}

/// Least squares y = a + b·x; returns (a, b, R²).
fn fit(xs: &[f64], ys: &[f64]) -> (f64, f64, f64) {
    let n = xs.len() as f64;
    let mx = xs.iter().sum::<f64>() / n;
    let my = ys.iter().sum::<f64>() / n;
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let a = my - b * mx;
    let ss_res: f64 = xs
        .iter()
        .zip(ys)
        .map(|(x, y)| (y - a - b * x).powi(2))
        .sum();
    let ss_tot: f64 = ys.iter().map(|y| (y - my).powi(2)).sum();
    let r2 = if ss_tot > 0.0 {
        1.0 - ss_res / ss_tot
    } else {
        1.0
    };
    (a, b, r2)
}

/// Exponent k of y ∝ n^k from the two largest counts.
fn exponent(xs: &[f64], ys: &[f64]) -> Option<f64> {
    let k = xs.len();
    if k < 2 || ys[k - 2] <= 0.0 || ys[k - 1] <= 0.0 {
        return None;
    }
    Some((ys[k - 1] / ys[k - 2]).ln() / (xs[k - 1] / xs[k - 2]).ln())
}

fn main() -> anyhow::Result<()> {
    let mut counts: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    if counts.is_empty() {
        counts = DEFAULT_COUNTS.to_vec();
    }
    anyhow::ensure!(
        counts.iter().all(|&n| (1..=CAP).contains(&n)),
        "counts must be in 1..={CAP}"
    );
    let started = Instant::now();

    // The timed driver runs the same loop as the harness's Sim: same frames to lock.
    {
        let n = 16;
        let sc = cyclic::scenario(Shape::Line, n, 0);
        let m: Machine<CAP> = Machine::new(config_with_cycle(&sc, cycle_for(n)))
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let (_, via_sim) = cyclic::bring_up(&sc, m.clone())?;
        let (_, _, via_timed) = timed::bring_up(&sc, m, 60_000_000_000)?;
        anyhow::ensure!(
            via_sim.lock_frames == via_timed.lock_frames
                && via_sim.lock_true_ns == via_timed.lock_true_ns,
            "timed driver diverges from Sim: {via_sim:?} vs {via_timed:?}"
        );
        eprintln!(
            "check: timed driver = Sim on 16 slaves ({} frames, {} ns)",
            via_timed.lock_frames, via_timed.lock_true_ns
        );
    }

    let mut rows = Vec::new();
    for &n in &counts {
        let cycle_ns = cycle_for(n);
        let sc = cyclic::scenario(Shape::Line, n, 0);
        let m: Machine<CAP> =
            Machine::new(config_with_cycle(&sc, cycle_ns)).map_err(|e| anyhow::anyhow!("{e:?}"))?;
        eprint!("{n} slaves: bring-up ... ");
        let drift = |d: Option<(u64, u64, std::time::Duration)>, cpu: Option<u64>| {
            d.map(|(f, t, _)| {
                (
                    f as f64,
                    t as f64 / 1e6,
                    cpu.map_or(f64::NAN, |c| c as f64 / 1e6),
                )
            })
        };
        let fresh = m.clone();
        let mut log = CallLog::default();
        let outcome = timed::try_bring_up(&sc, m, LIMIT_NS, Some(&mut log))?;
        // The core's CPU time for this bring-up: replay the recorded calls on a fresh copy of
        // the machine, no emulator; best of 3 (thread CPU time).
        let mut core_cpu: Option<(Option<u64>, u64)> = None;
        for _ in 0..3 {
            let (mark, total, sent) = timed::replay(fresh.clone(), &log);
            let expect = match &outcome {
                Ok((_, _, b)) => b.frames_sent,
                Err(f) => f.frames,
            };
            anyhow::ensure!(
                sent == expect,
                "replay sent {sent} frames, run sent {expect}"
            );
            core_cpu = Some(match core_cpu {
                Some((m0, t0)) if t0 <= total => (m0, t0),
                _ => (mark, total),
            });
        }
        drop(log);
        let (core_mark, core_total) = core_cpu.unwrap_or((None, 0));
        match outcome {
            Ok((m, net, b)) => {
                eprint!(
                    "locked after {} frames, {:.1} ms simulated, {:.2} s wall; capture ... ",
                    b.lock_frames,
                    b.lock_true_ns as f64 / 1e6,
                    b.wall.as_secs_f64()
                );
                let cap =
                    capture_from(m, net, SystemTime(DEFAULT_MASTER_EPOCH_NS + b.lock_true_ns))?;
                let core_cycle = per_cycle(&cap, false)?;
                let servo_cycle = per_cycle(&cap, true)?;
                eprintln!(
                    "{core_cycle:.0} ns/cycle ({servo_cycle:.0} with servo; ring of {})",
                    cap.ring.len()
                );
                rows.push(Row {
                    n,
                    cycle_ns,
                    to_drift: drift(b.to_drift, core_mark),
                    wall_s: b.wall.as_secs_f64(),
                    core_ms: core_total as f64 / 1e6,
                    restarts: b.restarts,
                    locked: Some(Locked {
                        lock_frames: b.lock_frames,
                        lock_ms: b.lock_true_ns as f64 / 1e6,
                        cycle_ns_core: core_cycle,
                        cycle_ns_servo: servo_cycle,
                    }),
                    failure: b
                        .first_error
                        .map(|e| format!("first error before lock: {e:?}")),
                });
            }
            Err(f) => {
                eprintln!("{f}");
                rows.push(Row {
                    n,
                    cycle_ns,
                    to_drift: drift(f.to_drift, core_mark),
                    wall_s: f.wall.as_secs_f64(),
                    core_ms: core_total as f64 / 1e6,
                    restarts: f.restarts,
                    locked: None,
                    failure: Some(f.to_string()),
                });
            }
        }
    }

    let sizes = [
        ("Machine<64>", std::mem::size_of::<Machine<64>>()),
        ("Machine<256>", std::mem::size_of::<Machine<256>>()),
        ("Machine<1024>", std::mem::size_of::<Machine<1024>>()),
        ("SlaveInfo (per slave)", std::mem::size_of::<SlaveInfo>()),
        ("MasterServo", std::mem::size_of::<MasterServo>()),
        ("Topology<64>", std::mem::size_of::<Topology<64>>()),
        ("Topology<256>", std::mem::size_of::<Topology<256>>()),
        ("Topology<1024>", std::mem::size_of::<Topology<1024>>()),
        ("Delays<64>", std::mem::size_of::<Delays<64>>()),
        ("Delays<256>", std::mem::size_of::<Delays<256>>()),
        ("Delays<1024>", std::mem::size_of::<Delays<1024>>()),
    ];

    // Series over the rows that have the quantity.
    let series = |f: &dyn Fn(&Row) -> Option<f64>| -> (Vec<f64>, Vec<f64>) {
        rows.iter()
            .filter_map(|r| f(r).map(|y| (r.n as f64, y)))
            .unzip()
    };
    let drift_frames = series(&|r| r.to_drift.map(|d| d.0));
    let drift_ms = series(&|r| r.to_drift.map(|d| d.1));
    let drift_core = series(&|r| r.to_drift.map(|d| d.2));
    let lock_frames = series(&|r| r.locked.as_ref().map(|l| l.lock_frames as f64));
    let lock_ms = series(&|r| r.locked.as_ref().map(|l| l.lock_ms));
    let per_cyc = series(&|r| r.locked.as_ref().map(|l| l.cycle_ns_core));
    let per_cyc_servo = series(&|r| r.locked.as_ref().map(|l| l.cycle_ns_servo));
    let core_all = series(&|r| r.locked.as_ref().map(|_| r.core_ms));
    let wall_all = series(&|r| r.locked.as_ref().map(|_| r.wall_s));

    let mut md = String::new();
    let cmd = if counts == DEFAULT_COUNTS {
        "cargo run --release -p ecdc-benches --bin scale".to_string()
    } else {
        format!(
            "cargo run --release -p ecdc-benches --bin scale -- {}",
            counts
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        )
    };
    let _ = writeln!(
        md,
        "# Scale: bring-up, per-cycle cost and memory vs slave count\n"
    );
    let _ = writeln!(
        md,
        "Produced by `{cmd}` (total {:.0} s wall; {}).\n",
        started.elapsed().as_secs_f64(),
        ecdc_benches::provenance::note()
    );
    let _ = writeln!(
        md,
        "Emulated line of the emulator's default ESCs (64-bit DC, t_P 540 ns, t_F 460 ns, 1 m \
         cables, ±50 ppm crystals, 8 ns PHY jitter per hop, wander on, seed 0); `Machine<1024>` \
         for every count with `ecdc simulate`'s configuration (SYNC0 on, 20-frame drift bursts, \
         100 ns drift threshold). Cycle 1 ms, 2 ms above 512 slaves (the line's round trip is about \
         1 µs per slave). A run gives up after {} s simulated.\n\n\
         - *to drift phase*: from `start` to the first entry into `DriftBurst` (count, \
         addresses, ESC info, 4 latch rounds, delays, offsets, loop reset): the per-slave work, \
         chunked 32 datagrams per frame;\n\
         - *lock*: the machine's `Locked` event (BRD 0x092C bound ≤ 200 ns for 10 cycles); the \
         drift phase in between is static drift compensation until the drift gate passes (every \
         slave within the threshold);\n\
         - *core CPU*: the bring-up's recorded calls into the machine (`start`, `handle_frame` \
         with the received bytes, `handle_timeout`, `poll_transmit`, `poll_event`, \
         `poll_timeout`) replayed on a fresh copy of the machine without the emulator, thread \
         CPU time, best of 3 (the replay is checked to send the same number of frames); for a \
         run without lock, up to the time limit;\n\
         - *per-cycle*: the locked machine replaying one period of its captured cyclic frames \
         (`poll_transmit` + `handle_frame` + `poll_event`; \"+ servo\" adds the \
         master-follows-reference step), minimum over 41 batches of 5 000 cycles of the thread's CPU \
         time, on a shared machine (criterion figures for 1..256 slaves: criterion.md).\n",
        LIMIT_NS / 1_000_000_000
    );
    let _ = writeln!(md, "| slaves | cycle | frames to drift phase | ms to drift phase (simulated) | core CPU to drift phase (ms) | lock frames | lock (simulated ms) | restarts | bring-up wall (s) | core CPU, whole bring-up (ms) | per-cycle (ns) | per-cycle + servo (ns) |");
    let _ = writeln!(
        md,
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for r in &rows {
        let (df, dt, dc) = r
            .to_drift
            .map_or(("-".into(), "-".into(), "-".into()), |d| {
                (
                    format!("{:.0}", d.0),
                    format!("{:.1}", d.1),
                    format!("{:.2}", d.2),
                )
            });
        let l = r.locked.as_ref();
        let _ = writeln!(
            md,
            "| {} | {} ms | {df} | {dt} | {dc} | {} | {} | {} | {:.2} | {:.2} | {} | {} |",
            r.n,
            r.cycle_ns / 1_000_000,
            l.map_or("no lock".into(), |l| l.lock_frames.to_string()),
            l.map_or("-".into(), |l| format!("{:.1}", l.lock_ms)),
            r.restarts,
            r.wall_s,
            r.core_ms,
            l.map_or("-".into(), |l| format!("{:.0}", l.cycle_ns_core)),
            l.map_or("-".into(), |l| format!("{:.0}", l.cycle_ns_servo)),
        );
    }
    let notes: Vec<String> = rows
        .iter()
        .filter_map(|r| r.failure.as_ref().map(|f| format!("- {} slaves: {f}", r.n)))
        .collect();
    if !notes.is_empty() {
        let _ = writeln!(md, "\n{}", notes.join("\n"));
    }
    let _ = writeln!(md, "\n## Is bring-up linear in the slave count?\n");
    let _ = writeln!(md, "Least-squares fit y = a + b·n over the rows that have the quantity, R², and the growth exponent k (y ∝ n^k) between the two largest of those counts (k ≈ 1: linear; k ≈ 2: quadratic; k ≈ 0: flat):\n");
    let _ = writeln!(
        md,
        "| quantity | a | b (per slave) | R² | k (largest two) | counts |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---|");
    for (name, (xs, ys)) in [
        ("frames to drift phase", &drift_frames),
        ("simulated ms to drift phase", &drift_ms),
        ("core CPU to drift phase (ms)", &drift_core),
        ("lock frames", &lock_frames),
        ("lock time (simulated ms)", &lock_ms),
        ("core CPU, whole bring-up (ms)", &core_all),
        ("bring-up wall (s)", &wall_all),
        ("per-cycle cost (ns)", &per_cyc),
    ] {
        if xs.is_empty() {
            continue;
        }
        let (a, b, r2) = fit(xs, ys);
        let k = exponent(xs, ys).map_or("-".to_string(), |k| format!("{k:.2}"));
        let ns: Vec<String> = xs.iter().map(|x| format!("{x}")).collect();
        let _ = writeln!(
            md,
            "| {name} | {a:.4} | {b:.5} | {r2:.4} | {k} | {} |",
            ns.join(", ")
        );
    }
    // Verdicts from the fits above (linear: R² ≥ 0.99 and 0.8 ≤ k ≤ 1.2).
    let linear = |(xs, ys): &(Vec<f64>, Vec<f64>)| -> Option<(bool, f64, f64)> {
        if xs.len() < 3 {
            return None;
        }
        let (_, _, r2) = fit(xs, ys);
        let k = exponent(xs, ys)?;
        Some(((0.8..=1.2).contains(&k) && r2 >= 0.99, r2, k))
    };
    let verdict = |v: Option<(bool, f64, f64)>| match v {
        Some((true, r2, k)) => format!("**linear** (R² {r2:.4}, k {k:.2})"),
        Some((false, r2, k)) if k < 0.8 => {
            format!("**sub-linear**, dominated by a part independent of n (R² {r2:.4}, k {k:.2})")
        }
        Some((false, r2, k)) if k > 1.2 => format!("**super-linear** (R² {r2:.4}, k {k:.2})"),
        Some((false, r2, k)) => format!("**roughly linear** (R² {r2:.4}, k {k:.2})"),
        None => "not enough rows".to_string(),
    };
    let no_lock: Vec<String> = rows
        .iter()
        .filter(|r| r.locked.is_none())
        .map(|r| r.n.to_string())
        .collect();
    let _ = writeln!(md, "\nVerdict (computed from the fits):\n");
    let _ = writeln!(
        md,
        "- the core's per-slave bring-up work — frames to the drift phase: {}; core CPU to the \
         drift phase: {};",
        verdict(linear(&drift_frames)),
        verdict(linear(&drift_core))
    );
    let _ = writeln!(
        md,
        "- simulated time to the drift phase: {} — every frame's round trip grows with the \
         line (≈ 1 µs per slave), so frames ∝ n take time ∝ n²;",
        verdict(linear(&drift_ms))
    );
    let _ = writeln!(
        md,
        "- core CPU for the whole bring-up to lock: {};",
        verdict(linear(&core_all))
    );
    let _ = writeln!(
        md,
        "- whole bring-up to lock, frames: {}; simulated time: {}; the static drift \
         compensation before lock takes most frames and depends on the crystals and the \
         line's accumulated PHY jitter rather than on the per-slave work{};",
        verdict(linear(&lock_frames)),
        verdict(linear(&lock_ms)),
        if no_lock.is_empty() {
            String::new()
        } else {
            format!(
                "; no lock within the time limit for {} slaves (see the notes under the table)",
                no_lock.join(", ")
            )
        }
    );
    let _ = writeln!(
        md,
        "- per-cycle cost: flat beyond 16 slaves (the cyclic frame carries at most \
         `slaves_per_cycle` = 8 round-robin FPRDs), k {}.",
        exponent(&per_cyc.0, &per_cyc.1).map_or("-".into(), |k| format!("{k:.2}"))
    );
    let _ = writeln!(
        md,
        "\n## Memory footprint of the core state (size_of, bytes)\n"
    );
    let _ = writeln!(md, "| type | bytes |");
    let _ = writeln!(md, "|---|---:|");
    for (name, b) in sizes {
        let _ = writeln!(md, "| `{name}` | {b} |");
    }
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("results");
    std::fs::create_dir_all(&out)?;
    std::fs::write(out.join("scale.md"), &md)?;

    let fitted = |(xs, ys): &(Vec<f64>, Vec<f64>)| -> Vec<(f64, f64)> {
        let (a, b, _) = fit(xs, ys);
        xs.iter().map(|&x| (x, (a + b * x).max(1e-9))).collect()
    };
    let pts = |(xs, ys): &(Vec<f64>, Vec<f64>)| -> Vec<(f64, f64)> {
        xs.iter().copied().zip(ys.iter().copied()).collect()
    };
    let line = |name: &str, color: &'static str, points: Vec<(f64, f64)>| Series {
        name: name.into(),
        color,
        points,
        dashed: false,
    };
    let fit_line = |name: &str, color: &'static str, points: Vec<(f64, f64)>| Series {
        dashed: true,
        ..line(name, color, points)
    };
    let panel = |title: &str, x_label: &str, y_label: &str, series: Vec<Series>| Panel {
        title: title.into(),
        x_label: x_label.into(),
        y_label: y_label.into(),
        series,
    };
    let panels = vec![
        panel(
            "Bring-up frames",
            "slaves",
            "frames",
            vec![
                line("to drift phase", "#1f77b4", pts(&drift_frames)),
                fit_line("linear fit", "#1f77b4", fitted(&drift_frames)),
                line("to lock", "#d62728", pts(&lock_frames)),
            ],
        ),
        panel(
            "Bring-up time",
            "slaves",
            "ms",
            vec![
                line("simulated, to drift phase", "#1f77b4", pts(&drift_ms)),
                line("simulated, to lock", "#d62728", pts(&lock_ms)),
                line("core CPU, to drift phase", "#2ca02c", pts(&drift_core)),
                fit_line("core CPU, linear fit", "#2ca02c", fitted(&drift_core)),
            ],
        ),
        panel(
            "Per-cycle cost (locked)",
            "slaves",
            "ns per cycle",
            vec![
                line("core", "#9467bd", pts(&per_cyc)),
                line("core + servo", "#8c564b", pts(&per_cyc_servo)),
            ],
        ),
        panel(
            "Core state (size_of Machine<N>)",
            "capacity N",
            "bytes",
            vec![line(
                "Machine<N>",
                "#17becf",
                vec![
                    (64.0, std::mem::size_of::<Machine<64>>() as f64),
                    (256.0, std::mem::size_of::<Machine<256>>() as f64),
                    (1024.0, std::mem::size_of::<Machine<1024>>() as f64),
                ],
            )],
        ),
    ];
    std::fs::write(
        out.join("scale.svg"),
        svg::loglog::render_panels(&format!("ecdc scale ({cmd})"), &panels),
    )?;
    print!("{md}");
    eprintln!(
        "wrote {} and {}",
        out.join("scale.md").display(),
        out.join("scale.svg").display()
    );
    Ok(())
}
