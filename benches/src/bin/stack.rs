//! How much thread stack the core needs (issue 8 item 4, memory; issue 15): the smallest stack
//! a thread can be given and still (a) get a `Machine<N>`, by value (`Box::new(Machine::new
//! (cfg))`: the value passes over the stack) or in place (`Machine::configure` on a machine
//! in a `static` initialised by the `const fn Machine::idle`), and (b) run a whole bring-up to
//! lock plus cyclic operation on a machine that lives on the heap — the calls of a recorded
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
//! platform needs for any thread). Each kind of work is a function of its own, never inlined,
//! so that the thread's closure does not reserve the frames of the other kinds.

use std::fmt::Write as _;
use std::process::Command;

use ecdc_benches::cyclic::{self, config_with_cycle, Shape};
use ecdc_benches::timed::{self, CallLog};
use ecdc_core::dc::{Config, Machine};
use std::sync::Mutex;

const LIMIT_NS: u64 = 300_000_000_000;

/// What a child process does inside the small-stack thread.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Work {
    /// Nothing (the platform's own need).
    Nothing,
    /// `Box::new(Machine::<N>::new(cfg))`.
    New,
    /// `Machine::configure(cfg)` on a machine in a `static` (`Machine::idle()`).
    Configure,
    /// Replay a recorded bring-up to lock on a boxed machine.
    Run,
}

impl Work {
    fn parse(s: &str) -> Option<Work> {
        match s {
            "nothing" => Some(Work::Nothing),
            "new" => Some(Work::New),
            "configure" => Some(Work::Configure),
            "run" => Some(Work::Run),
            _ => None,
        }
    }
    fn name(self) -> &'static str {
        match self {
            Work::Nothing => "nothing",
            Work::New => "new",
            Work::Configure => "configure",
            Work::Run => "run",
        }
    }
}

static MACHINE_64: Mutex<Machine<64>> = Mutex::new(Machine::idle());
static MACHINE_256: Mutex<Machine<256>> = Mutex::new(Machine::idle());
static MACHINE_1024: Mutex<Machine<1024>> = Mutex::new(Machine::idle());

/// Bytes every measured thread first puts on its stack, so that the smallest stacks found lie
/// above the platform's minimum thread stack (16 KiB with glibc: a smaller request gets that
/// much anyway, which would hide the work's own need). It counts in the baseline too.
const BALLAST: usize = 64 * 1024;

/// Runs `work` above a frame of [`BALLAST`] bytes.
#[inline(never)]
fn on_ballast(work: impl FnOnce() -> u64) -> u64 {
    let ballast = [0u8; BALLAST];
    std::hint::black_box(&ballast);
    let r = work();
    std::hint::black_box(&ballast);
    r
}

/// Nothing: the platform's own need for a thread.
#[inline(never)]
fn nothing() -> u64 {
    std::hint::black_box(0)
}

/// A machine by value, moved into a `Box`.
#[inline(never)]
fn construct_by_value<const N: usize>(cfg: Config) -> u64 {
    let m: Option<Box<Machine<N>>> = Machine::new(cfg).ok().map(Box::new);
    std::hint::black_box(&m);
    u64::from(m.is_some())
}

/// The machine in `slot` (a `static`, const-initialised) configured in place.
#[inline(never)]
fn construct_in_place<const N: usize>(slot: &Mutex<Machine<N>>, cfg: Config) -> u64 {
    let Ok(mut m) = slot.lock() else { return 0 };
    let ok = m.configure(cfg).is_ok();
    std::hint::black_box(&*m);
    u64::from(ok)
}

/// The recorded calls replayed on a machine on the heap.
#[inline(never)]
fn operate<const N: usize>(m: Box<Machine<N>>, log: &CallLog) -> u64 {
    let (_, _, sent) = timed::replay_boxed(m, log);
    sent
}

fn child<const N: usize>(
    work: Work,
    stack: usize,
    slot: &'static Mutex<Machine<N>>,
) -> anyhow::Result<()> {
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
    let want = if work == Work::Configure {
        format!("{:?}", *fresh)
    } else {
        String::new()
    };
    let handle = std::thread::Builder::new()
        .stack_size(stack)
        .spawn(move || -> u64 {
            on_ballast(move || match work {
                Work::Nothing => nothing(),
                Work::New => construct_by_value::<N>(cfg),
                Work::Configure => construct_in_place(slot, cfg),
                Work::Run => operate(fresh, &log),
            })
        })?;
    let sent = handle
        .join()
        .map_err(|_| anyhow::anyhow!("thread panicked"))?;
    // The replay sent what the recorded run sent (construction: one machine built).
    anyhow::ensure!(
        work == Work::Nothing || sent == expect,
        "{sent} != {expect}"
    );
    if work == Work::Configure {
        // The machine configured in place is the one `new` returns.
        let m = slot.lock().map_err(|_| anyhow::anyhow!("poisoned"))?;
        anyhow::ensure!(format!("{:?}", *m) == want, "configure differs from new");
    }
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
            64 => child::<64>(work, stack, &MACHINE_64),
            256 => child::<256>(work, stack, &MACHINE_256),
            1024 => child::<1024>(work, stack, &MACHINE_1024),
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
         - *construct in place*: `configure(cfg)` on a machine in a `static` initialised by \
         `Machine::idle()` (a `const fn`, evaluated at compile time): the way to get a machine \
         without an O(N) value on the stack;\n\
         - *construct by value*: `Box::new(Machine::<N>::new(cfg))` (the machine is returned \
         by value, so it passes over the stack);\n\
         - *operate*: replay a whole recorded bring-up to lock and the cyclic cycles up to it \
         (every `start`, `handle_frame`, `handle_timeout`, `poll_transmit`, `poll_event`, \
         `poll_timeout` call of an emulator run) on a machine that lives on the heap.\n\n\
         Every thread first puts a {} KiB ballast on its stack (the platform gives no thread \
         less than 16 KiB, which would hide small needs); the baseline is such a thread that \
         then does nothing: {} bytes. The differences to it are what the work itself needs; the \
         platform hands out thread stacks in whole pages (4 KiB here), so a need below about \
         a page shows as 0 or 1024.\n",
        ecdc_benches::provenance::note(),
        BALLAST / 1024,
        base
    )?;
    writeln!(
        md,
        "| N | `size_of::<Machine<N>>()` | construct in place (bytes) | construct by value \
         (bytes) | operate (bytes) | construct in place − baseline | construct by value − \
         baseline | operate − baseline |"
    )?;
    writeln!(md, "|---:|---:|---:|---:|---:|---:|---:|---:|")?;
    for (n, size) in [
        (64usize, std::mem::size_of::<Machine<64>>()),
        (256, std::mem::size_of::<Machine<256>>()),
        (1024, std::mem::size_of::<Machine<1024>>()),
    ] {
        let configure = smallest(n, Work::Configure)?;
        let new = smallest(n, Work::New)?;
        let run = smallest(n, Work::Run)?;
        eprintln!("{n}: construct in place {configure}, by value {new}, operate {run}");
        writeln!(
            md,
            "| {n} | {size} | {configure} | {new} | {run} | {} | {} | {} |",
            configure.saturating_sub(base),
            new.saturating_sub(base),
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
