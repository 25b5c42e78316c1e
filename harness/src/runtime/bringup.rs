//! Drives the sans-IO DC machine through its request steps (count, address, read info, latch,
//! offsets, static drift compensation, SYNC start) over a transport, until a chosen point:
//! after the delay measurement (`ecdc scan`) or on entering cyclic operation (`ecdc run`).
//!
//! The machine decides what to send and validates every reply; this driver only moves
//! frames, keeps time (the machine's `now` is the host monotonic clock in the DC epoch, see
//! [`DcClock`]) and turns the machine's faults into errors a user can act on.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};

use ecdc_core::dc::{Error as DcError, Event, Machine, State};
use ecdc_core::time::SystemTime;

use super::clock::{self, DcClock};
use super::cyclic::RX_BUF;
use super::errors::RuntimeError;
use super::socket::Link;
use super::transport::{SendError, Transport};

/// Where to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Until {
    /// Once the propagation delays are measured, before anything but station addresses and
    /// the latch trigger has been written (`scan`). Also stops when the network has no DC
    /// reference clock (the slaves are then listed without delays).
    DelaysMeasured,
    /// On entering `Cyclic` (`run`).
    Cyclic,
}

/// Bring-up progress, reported ten times a second and on every state change.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    /// Machine state.
    pub state: State,
    /// Frames the machine sent since `start`.
    pub frames: u64,
    /// FRMW frames of the static drift compensation so far.
    pub drift_frames: u64,
    /// Upper bound of the drift frames (the machine gives up after it).
    pub drift_max: u32,
    /// Largest |0x092C| read at the last drift check, ns.
    pub max_diff_ns: Option<u64>,
}

/// How the bring-up ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Reached the requested point.
    Reached,
    /// The network has no DC reference clock (only with [`Until::DelaysMeasured`]).
    NoReferenceClock,
    /// Ctrl-C.
    Interrupted,
}

/// Why the bring-up failed.
#[derive(Debug)]
pub enum BringupError {
    /// Interface-level problem (no slaves, another master, I/O).
    Runtime(RuntimeError),
    /// The machine kept failing; the last DC error.
    Dc {
        /// Last error reported.
        error: DcError,
        /// Re-initialisations attempted.
        restarts: u32,
    },
    /// The overall time limit passed.
    Timeout {
        /// State at that moment.
        state: State,
    },
}

impl std::fmt::Display for BringupError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BringupError::Runtime(e) => write!(f, "{e}"),
            BringupError::Dc { error, restarts } => {
                write!(
                    f,
                    "DC bring-up failed after {restarts} re-initialisations: {error:?}"
                )
            }
            BringupError::Timeout { state } => {
                write!(f, "DC bring-up timed out in state {state:?}")
            }
        }
    }
}

impl std::error::Error for BringupError {}

impl From<RuntimeError> for BringupError {
    fn from(e: RuntimeError) -> Self {
        BringupError::Runtime(e)
    }
}

/// Limits of one bring-up.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Give up after this long (ns); `u64::MAX`: never.
    pub timeout_ns: u64,
    /// Give up after this many re-initialisations (`None`: retry, with the machine's
    /// backoff, for as long as the interface has carrier).
    pub max_restarts: Option<u32>,
    /// Frames without any reply before concluding nobody is there.
    pub no_reply_frames: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            timeout_ns: 60 * clock::NS_PER_S,
            max_restarts: Some(5),
            no_reply_frames: 5,
        }
    }
}

fn io_err(name: &str, e: io::Error) -> BringupError {
    BringupError::Runtime(RuntimeError::os("raw socket I/O", name, e))
}

/// Runs the machine from `start` to `until`. `on_event` sees every machine event in order.
#[allow(clippy::too_many_arguments)]
pub fn bring_up<L: Link, const N: usize>(
    m: &mut Machine<N>,
    t: &mut Transport<L>,
    dc: &DcClock,
    iface: &str,
    until: Until,
    limits: &Limits,
    stop: &AtomicBool,
    mut on_event: impl FnMut(&Event),
    mut on_progress: impl FnMut(&Progress),
) -> Result<Outcome, BringupError> {
    let mut tx = vec![0u8; RX_BUF];
    let mut rx = vec![0u8; RX_BUF];
    let started = clock::now_ns();
    let give_up = started.saturating_add(limits.timeout_ns);
    let mut next_progress = started;
    let mut last_state = m.state();
    let mut restarts = 0u32;
    let mut last_error: Option<DcError> = None;
    let mut drift_start: Option<u64> = None;
    let response_timeout = m.config().response_timeout_ns;
    let drift_max = m.config().drift.max_frames;

    // A machine that left cyclic operation is already re-initialising, with its backoff:
    // let it go on rather than restart it from scratch.
    if m.state() != State::RestartWait {
        m.start(SystemTime(dc.now()));
    }
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(Outcome::Interrupted);
        }
        let mono = clock::now_ns();
        if limits.timeout_ns != u64::MAX && mono >= give_up {
            return Err(BringupError::Timeout { state: m.state() });
        }
        let now = SystemTime(dc.at(mono));
        m.handle_timeout(now);

        // Events first: they may end the bring-up.
        while let Some(e) = m.poll_event() {
            on_event(&e);
            match e {
                Event::DelaysMeasured { .. } if until == Until::DelaysMeasured => {
                    return Ok(Outcome::Reached)
                }
                Event::Error(DcError::NoReferenceClock) if until == Until::DelaysMeasured => {
                    return Ok(Outcome::NoReferenceClock)
                }
                Event::Error(err) => last_error = Some(err),
                Event::Restarting => {
                    restarts += 1;
                    let error = last_error.unwrap_or(DcError::Timeout { state: m.state() });
                    if limits.max_restarts.is_some_and(|max| restarts > max) {
                        return Err(classify_failure(error, restarts, t, iface));
                    }
                    // Retrying forever is for a network that may come back; an interface
                    // without carrier needs a person.
                    if limits.max_restarts.is_none() && !has_carrier(iface) {
                        return Err(RuntimeError::NoCarrier {
                            name: iface.to_owned(),
                        }
                        .into());
                    }
                }
                _ => {}
            }
        }
        let c = *t.counters();
        // Two masters on one segment overwrite each other's station addresses and DC
        // registers: refuse to bring DC up next to another master.
        if let Some(mac) = c.other_master_mac {
            return Err(RuntimeError::OtherMaster {
                name: iface.to_owned(),
                mac,
                frames: c.other_master,
            }
            .into());
        }
        if c.matched == 0 && c.sent >= limits.no_reply_frames {
            return Err(RuntimeError::NoSlaves {
                name: iface.to_owned(),
                sent: c.sent,
                ignored: c.ignored(),
            }
            .into());
        }
        match m.state() {
            State::Cyclic if until == Until::Cyclic => return Ok(Outcome::Reached),
            State::Failed => {
                let error = last_error.unwrap_or(DcError::Timeout {
                    state: State::Failed,
                });
                return Err(classify_failure(error, restarts, t, iface));
            }
            State::ReadAlStatus | State::WriteOffsets if until == Until::DelaysMeasured => {
                // Never write offsets during a scan (DelaysMeasured should have come first).
                return Ok(Outcome::Reached);
            }
            State::DriftBurst | State::DriftCheck => {
                drift_start.get_or_insert(m.stats().frames_sent);
            }
            _ => {}
        }

        // Report every 100 ms and on every state change (the drift phase alternates burst and
        // check every `burst_frames` frames, so the bar moves even when it lasts 50 ms).
        if mono >= next_progress || m.state() != last_state {
            last_state = m.state();
            let max_diff_ns = m
                .slaves()
                .iter()
                .filter_map(|s| s.last_diff_ns)
                .map(i64::unsigned_abs)
                .max();
            on_progress(&Progress {
                state: m.state(),
                frames: m.stats().frames_sent,
                drift_frames: drift_start.map_or(0, |d| m.stats().frames_sent.saturating_sub(d)),
                drift_max,
                max_diff_ns,
            });
            next_progress = mono.saturating_add(100_000_000);
        }

        t.expire(mono);
        if let Some(len) = m.poll_transmit(now, &mut tx) {
            let frame = tx.get(..len).unwrap_or_default();
            let deadline = clock::now_ns().saturating_add(response_timeout);
            match t.send(frame, deadline) {
                Ok(_) => {}
                Err(SendError::IndexInFlight(_)) | Err(SendError::TooManyInFlight) => {
                    // The machine has given up on those frames already: so do we.
                    t.abandon_all();
                    t.send(frame, deadline)
                        .map_err(|e| io_err(iface, io::Error::other(e.to_string())))?;
                }
                Err(SendError::Io(e)) => return Err(io_err(iface, e)),
                Err(e) => return Err(io_err(iface, io::Error::other(e.to_string()))),
            }
        }
        // Wait for a reply, but not past the machine's next timer.
        let mono = clock::now_ns();
        let wake = m
            .poll_timeout()
            .map_or(mono.saturating_add(1_000_000), |d| dc.to_mono(d.0));
        let wake = wake.min(mono.saturating_add(10_000_000)).min(give_up);
        if t.in_flight() > 0 {
            if let Some(r) = t.recv(&mut rx, wake).map_err(|e| io_err(iface, e))? {
                m.handle_frame(SystemTime(dc.now()), rx.get(..r.len).unwrap_or_default());
            }
        } else if wake > mono {
            clock::sleep_until(wake, 0, stop);
        }
    }
}

/// Whether `iface` reports carrier (`/sys/class/net/IF/carrier`); true when that cannot be
/// read (the raw socket worked, so assume the link is there).
pub fn has_carrier(iface: &str) -> bool {
    std::fs::read_to_string(format!("/sys/class/net/{iface}/carrier"))
        .map_or(true, |s| s.trim() != "0")
}

/// Turns the machine's last error into the most useful message.
fn classify_failure<L: Link>(
    error: DcError,
    restarts: u32,
    t: &Transport<L>,
    iface: &str,
) -> BringupError {
    let c = t.counters();
    if let Some(mac) = c.other_master_mac {
        return RuntimeError::OtherMaster {
            name: iface.to_owned(),
            mac,
            frames: c.other_master,
        }
        .into();
    }
    if matches!(error, DcError::NoSlaves) || c.matched == 0 {
        return RuntimeError::NoSlaves {
            name: iface.to_owned(),
            sent: c.sent,
            ignored: c.ignored(),
        }
        .into();
    }
    BringupError::Dc { error, restarts }
}
