//! Real-time setup for the cyclic thread: SCHED_FIFO, mlockall, `/dev/cpu_dma_latency`,
//! CPU pinning, timer slack. Each step degrades to a warning when not permitted, because a
//! functional run without RT (CI, a laptop) is still useful; the summary says what was active.
//!
//! Checklist source: docs/background/linux-runtime.md §3 (mlockall, absolute sleeps, FIFO around 80,
//! cpu_dma_latency held at 0, pinning). The measured effect of cpu_dma_latency on this VM
//! (§6): wake lateness median 35 us -> 18 us.

use std::fs::File;
use std::io::Write;

use super::sys;

/// What to request.
#[derive(Debug, Clone, Default)]
pub struct RtOptions {
    /// SCHED_FIFO priority (1..=99); `None` keeps SCHED_OTHER.
    pub fifo_priority: Option<i32>,
    /// Pin the calling thread to this CPU.
    pub cpu: Option<usize>,
    /// `mlockall(MCL_CURRENT | MCL_FUTURE)`.
    pub lock_memory: bool,
    /// Hold `/dev/cpu_dma_latency` open at 0 (no deep C-states while we run).
    pub dma_latency_zero: bool,
}

impl RtOptions {
    /// Everything `--rt` asks for: FIFO `priority`, locked memory, cpu_dma_latency 0, and the
    /// given CPU (or the last CPU, leaving CPU 0 to housekeeping, when there are several).
    pub fn full(priority: i32, cpu: Option<usize>) -> Self {
        let cpus = sys::cpus_online();
        RtOptions {
            fifo_priority: Some(priority),
            cpu: cpu.or(if cpus > 1 { Some(cpus - 1) } else { None }),
            lock_memory: true,
            dma_latency_zero: true,
        }
    }
}

/// What was actually applied. Dropping it releases `/dev/cpu_dma_latency`.
#[derive(Debug, Default)]
pub struct RtState {
    /// Active SCHED_FIFO priority.
    pub fifo_priority: Option<i32>,
    /// CPU the thread is pinned to.
    pub cpu: Option<usize>,
    /// Memory is locked.
    pub memory_locked: bool,
    /// cpu_dma_latency is held at 0.
    pub dma_latency_zero: bool,
    /// Timer slack was reduced to 1 ns.
    pub timer_slack_1ns: bool,
    /// One line per step that could not be applied.
    pub warnings: Vec<String>,
    dma_latency: Option<File>,
}

impl RtState {
    /// Short description for logs and summaries, e.g. `FIFO 80, cpu 1, mlock, dma_latency 0`.
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        match self.fifo_priority {
            Some(p) => parts.push(format!("FIFO {p}")),
            None => parts.push("SCHED_OTHER".to_owned()),
        }
        if let Some(c) = self.cpu {
            parts.push(format!("cpu {c}"));
        }
        if self.memory_locked {
            parts.push("mlock".to_owned());
        }
        if self.dma_latency_zero {
            parts.push("cpu_dma_latency 0".to_owned());
        }
        if self.timer_slack_1ns {
            parts.push("timer slack 1 ns".to_owned());
        }
        parts.join(", ")
    }

    /// Whether the loop is stopped from freeing `/dev/cpu_dma_latency` (kept for the caller's lifetime).
    pub fn holds_dma_latency(&self) -> bool {
        self.dma_latency.is_some()
    }
}

/// Applies `opts` to the calling thread. Never fails: refused steps become warnings.
pub fn apply(opts: &RtOptions) -> RtState {
    let mut st = RtState::default();
    // Always: without this, every sleep and poll of a SCHED_OTHER thread may wake up to 50 us late.
    match sys::set_timer_slack_ns(1) {
        Ok(()) => st.timer_slack_1ns = true,
        Err(e) => st.warnings.push(format!("timer slack not reduced: {e}")),
    }
    if opts.lock_memory {
        match sys::mlockall() {
            Ok(()) => {
                st.memory_locked = true;
                prefault_stack();
            }
            Err(e) => st.warnings.push(format!(
                "mlockall failed ({e}): page faults may stall the loop; raise `ulimit -l` or run as root"
            )),
        }
    }
    if let Some(cpu) = opts.cpu {
        match sys::pin_to_cpu(cpu) {
            Ok(()) => st.cpu = Some(cpu),
            Err(e) => st.warnings.push(format!("could not pin to CPU {cpu}: {e}")),
        }
    }
    if let Some(prio) = opts.fifo_priority {
        let prio = prio.clamp(1, 99);
        match sys::set_fifo(prio) {
            Ok(()) => st.fifo_priority = Some(prio),
            Err(e) => st.warnings.push(format!(
                "SCHED_FIFO {prio} refused ({e}): running under SCHED_OTHER; needs root or CAP_SYS_NICE \
                 (and RLIMIT_RTPRIO), and may be blocked by a cgroup without an RT budget"
            )),
        }
    }
    if opts.dma_latency_zero {
        match File::options().write(true).open("/dev/cpu_dma_latency") {
            Ok(mut f) => match f.write_all(&0i32.to_ne_bytes()) {
                Ok(()) => {
                    st.dma_latency = Some(f);
                    st.dma_latency_zero = true;
                }
                Err(e) => st
                    .warnings
                    .push(format!("writing /dev/cpu_dma_latency failed: {e}")),
            },
            Err(e) => st
                .warnings
                .push(format!("/dev/cpu_dma_latency not available: {e}")),
        }
    }
    st
}

/// Touches 256 KiB of stack once, so with `MCL_FUTURE` those pages are mapped and locked
/// before the loop runs instead of faulting in on the first deep call inside it.
#[inline(never)]
fn prefault_stack() {
    let mut buf = [0u8; 256 * 1024];
    for b in buf.iter_mut().step_by(4096) {
        *b = 1;
    }
    std::hint::black_box(&buf);
}
