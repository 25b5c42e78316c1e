//! How much thread stack the core needs (issue 8 item 4, memory): the smallest stack a thread
//! can be given and still (a) construct a `Machine<N>` into a `Box` (`Machine::new` returns it
//! by value, so the value itself passes over the stack) and (b) run a whole bring-up to lock
//! plus cyclic operation on a machine that lives on the heap — the calls of a recorded
//! emulator run (`timed::try_bring_up`) replayed without the emulator, so only the core's own
//! frames count. Each size is tried in a child process (a stack overflow aborts the process);
//! the smallest working size is found by bisection to 1 KiB. Writes `benches/results/stack.md`.
//!
//! ```sh
//! cargo run --release -p ecdc-benches --bin stack
//! ```
//!
//! Setup: an emulated line of N default slaves (seed 0; 2 ms cycle above 512 slaves), the
//! configuration of `ecdc simulate`. The baseline row is a thread that does nothing (what the
//! platform needs for any thread).

use std::fmt::Write as _;
use std::process::Command;

use ecdc_benches::cyclic::{self, config_with_cycle, Shape};
use ecdc_benches::timed::{self, CallLog};
use ecdc_core::dc::Machine;

const LIMIT_NS: u64 = 300_000_000_000;

/// What a child process does inside the small-stack thread.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Work {
    /// Nothing (the platform's own need).
    Nothing,
    /// `Box::new(Machine::<N>::new(cfg))`.
    New,
    /// Replay a recorded bring-up to lock on a boxed machine.
    Run,
}

impl Work {
    fn parse(s: &str) -> Option<Work> {
        match s {
            "nothing" => Some(Work::Nothing),
            "new" => Some(Work::New),
            "run" => Some(Work::Run),
            _ => None,
        }
    }
    fn name(self) -> &'static str {
        match self {
            Work::Nothing => "nothing",
            Work::New => "new",
            Work::Run => "run",
        }
    }
}

fn child<const N: usize>(work: Work, stack: usize) -> anyhow::Result<()> {
    let cycle_ns = if N > 512 { 2_000_000 } else { 1_000_000 };
    let sc = cyclic::scenario(Shape::Line, N, 0);
    let cfg = config_with_cycle(&sc, cycle_ns);
    // Recorded on the main thread (the emulator's stack use is not measured).
    let mut log = CallLog::default();
    let fresh: Box<Machine<N>> = Box::new(Machine::new(cfg).map_err(|e| anyhow::anyhow!("{e:?}"))?);
    let mut expect = 1u64;
    if work == Work::Run {
        let m: Machine<N> = (*fresh).clone();
        let outcome = timed::try_bring_up(&sc, m, LIMIT_NS, Some(&mut log))?;
        expect = match outcome {
            Ok((_, _, b)) => b.frames_sent,
            Err(_) => anyhow::bail!("{N} slaves did not lock"),
        };
    }
    let handle = std::thread::Builder::new()
        .stack_size(stack)
        .spawn(move || -> u64 {
            match work {
                Work::Nothing => 0,
                Work::New => {
                    let m: Option<Box<Machine<N>>> = Machine::new(cfg).ok().map(Box::new);
                    std::hint::black_box(&m);
                    u64::from(m.is_some())
                }
                Work::Run => {
                    let (_, _, sent) = timed::replay_boxed(fresh, &log);
                    sent
                }
            }
        })?;
    let sent = handle
        .join()
        .map_err(|_| anyhow::anyhow!("thread panicked"))?;
    // The replay sent what the recorded run sent (construction: one machine built).
    anyhow::ensure!(
        work == Work::Nothing || sent == expect,
        "{sent} != {expect}"
    );
    Ok(())
}

fn run_child(n: usize, work: Work, stack: usize) -> anyhow::Result<bool> {
    let exe = std::env::current_exe()?;
    let st = Command::new(exe)
        .args(["--child", &n.to_string(), work.name(), &stack.to_string()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()?;
    Ok(st.success())
}

/// The smallest stack (bytes, to 1 KiB) with which `work` succeeds for `n` slaves.
fn smallest(n: usize, work: Work) -> anyhow::Result<usize> {
    let (mut lo, mut hi) = (16 * 1024usize, 64 * 1024 * 1024usize);
    anyhow::ensure!(
        run_child(n, work, hi)?,
        "{n} {work:?} fails even with {hi} bytes"
    );
    if run_child(n, work, lo)? {
        return Ok(lo);
    }
    while hi - lo > 1024 {
        let mid = (lo + hi) / 2 / 1024 * 1024;
        if run_child(n, work, mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok(hi)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--child") {
        let n: usize = args.get(1).map_or(Ok(0), |s| s.parse())?;
        let work = args
            .get(2)
            .and_then(|s| Work::parse(s))
            .ok_or_else(|| anyhow::anyhow!("work"))?;
        let stack: usize = args.get(3).map_or(Ok(0), |s| s.parse())?;
        return match n {
            64 => child::<64>(work, stack),
            256 => child::<256>(work, stack),
            1024 => child::<1024>(work, stack),
            _ => anyhow::bail!("N must be 64, 256 or 1024"),
        };
    }
    let started = std::time::Instant::now();
    let base = smallest(64, Work::Nothing)?;
    eprintln!("baseline thread: {base} bytes");
    let mut md = String::new();
    writeln!(md, "# Stack: what the core needs of a thread's stack\n")?;
    writeln!(
        md,
        "Produced by `cargo run --release -p ecdc-benches --bin stack` ({}; 0 s wall). \
         Release build, x86_64. For each capacity N: an emulated line of N default slaves \
         (seed 0, `ecdc simulate`'s configuration, 2 ms cycle above 512 slaves); the smallest \
         stack (bisection to 1 KiB, each size in a child process: an overflow aborts it) with \
         which a thread can\n\n\
         - *construct*: `Box::new(Machine::<N>::new(cfg))` (the machine is returned by value, \
         so it passes over the stack);\n\
         - *operate*: replay a whole recorded bring-up to lock and the cyclic cycles up to it \
         (every `start`, `handle_frame`, `handle_timeout`, `poll_transmit`, `poll_event`, \
         `poll_timeout` call of an emulator run) on a machine that lives on the heap.\n\n\
         The baseline is a thread that does nothing: {} bytes.\n",
        ecdc_benches::provenance::note(),
        base
    )?;
    writeln!(
        md,
        "| N | `size_of::<Machine<N>>()` | construct (bytes) | operate (bytes) | operate − baseline |"
    )?;
    writeln!(md, "|---:|---:|---:|---:|---:|")?;
    for (n, size) in [
        (64usize, std::mem::size_of::<Machine<64>>()),
        (256, std::mem::size_of::<Machine<256>>()),
        (1024, std::mem::size_of::<Machine<1024>>()),
    ] {
        let new = smallest(n, Work::New)?;
        let run = smallest(n, Work::Run)?;
        eprintln!("{n}: construct {new}, operate {run}");
        writeln!(
            md,
            "| {n} | {size} | {new} | {run} | {} |",
            run.saturating_sub(base)
        )?;
    }
    let wall = started.elapsed().as_secs_f64();
    let md = md.replacen("; 0 s wall)", &format!("; {wall:.0} s wall)"), 1);
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("results/stack.md");
    std::fs::write(&out, md)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}
