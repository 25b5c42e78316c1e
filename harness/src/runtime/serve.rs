//! The slave side of a link: receive masters' frames, let a [`Responder`] (the ESC emulator,
//! or the bare [`Reflector`]) process them with the host monotonic clock as true time, and
//! send the result back at the arrival time the responder computed.
//!
//! WHY a bare reflector too: it does what the C probe's slave did in docs/background/linux-runtime.md §6
//! (WKC + 1 per datagram, processed bit set), so round trips measured against it isolate the
//! socket path from emulator compute time and compare directly with the C figures.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};

use ecdc_core::wire::{Command, EthernetFrame, MAC_PROCESSED_BIT};

use super::clock;
use super::socket::Link;
use super::stats::{Histogram, Summary};

/// Turns a master's frame into the frame that returns to it.
pub trait Responder {
    /// Processes `frame` (the first `len` bytes of `buf`, received at host time `now_ns`)
    /// in place or by rewriting `buf`; returns the reply length and the host time at which
    /// it should leave (`<= now` means at once), or `None` to send nothing (the frame is
    /// lost in the emulated network, or was not ours to answer).
    fn respond(&mut self, now_ns: u64, buf: &mut [u8], len: usize) -> Option<(usize, u64)>;
}

/// One emulated slave without DC: adds 1 to every datagram's WKC, increments ADP of
/// position/broadcast datagrams, sets the processed bit. Frames that fail to parse are
/// returned untouched except for the processed bit (an ESC forwards what it cannot read).
#[derive(Debug, Default, Clone, Copy)]
pub struct Reflector;

impl Responder for Reflector {
    fn respond(&mut self, now_ns: u64, buf: &mut [u8], len: usize) -> Option<(usize, u64)> {
        let frame = buf.get_mut(..len)?;
        let mut eth = EthernetFrame::new_unchecked(frame);
        if let Ok(mut ecat) = eth.ecat_frame_mut() {
            for dg in ecat.iter_mut().flatten() {
                let mut dg = dg;
                dg.set_wkc(dg.wkc().wrapping_add(1));
                if Command::from_u8(dg.command_raw()).is_ok_and(|c| c.increments_adp()) {
                    dg.set_adp(dg.adp().wrapping_add(1));
                }
            }
        }
        eth.mark_processed_by_slave();
        Some((len, now_ns))
    }
}

/// What the server saw.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct ServeCounters {
    /// Frames received.
    pub received: u64,
    /// Frames answered.
    pub answered: u64,
    /// Frames already processed by a slave (another emulator's replies): ignored.
    pub already_processed: u64,
    /// Frames the responder chose not to answer (lost in the emulated network).
    pub dropped: u64,
    /// Frames longer than the buffer.
    pub truncated: u64,
    /// Failed sends.
    pub send_errors: u64,
    /// Answered frames whose true time came from a kernel receive stamp.
    pub stamped: u64,
}

/// Serving results.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ServeSummary {
    /// Frame accounting.
    pub frames: ServeCounters,
    /// Time from the frame's arrival (kernel stamp, else the read) to handing its reply to the
    /// kernel, ns.
    pub turnaround: Summary,
}

/// Serves until `stop` is raised or `until_ns` (monotonic) passes. `on_second` gets the
/// counters and the responder once a second (for a progress line).
pub fn serve<L: Link, R: Responder>(
    link: &mut L,
    responder: &mut R,
    stop: &AtomicBool,
    until_ns: Option<u64>,
    spin_ns: u64,
    mut on_second: impl FnMut(&ServeCounters, &R),
) -> io::Result<ServeSummary> {
    let mut buf = vec![0u8; 2048];
    let mut turnaround = Histogram::new();
    let mut c = ServeCounters::default();
    let mut next_line = clock::now_ns().saturating_add(clock::NS_PER_S);
    loop {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let now = clock::now_ns();
        if until_ns.is_some_and(|u| now >= u) {
            break;
        }
        if now >= next_line {
            on_second(&c, responder);
            next_line = next_line.saturating_add(clock::NS_PER_S);
        }
        // Wake at least every 100 ms to notice the stop flag and the duration.
        let wait_until = now
            .saturating_add(100_000_000)
            .min(until_ns.unwrap_or(u64::MAX));
        let Some(full) = link.recv(&mut buf, wait_until)? else {
            continue;
        };
        let read_at = clock::now_ns();
        // The frame's arrival at the interface (kernel stamp) is the emulated wire's true
        // time; the process may have been scheduled much later.
        let received_at = link
            .last_rx_time()
            .filter(|t| *t <= read_at)
            .unwrap_or(read_at);
        c.received += 1;
        if full > buf.len() {
            c.truncated += 1;
            continue;
        }
        if buf.get(6).is_some_and(|b| b & MAC_PROCESSED_BIT != 0) {
            c.already_processed += 1;
            continue;
        }
        let Some((len, send_at)) = responder.respond(received_at, &mut buf, full) else {
            c.dropped += 1;
            continue;
        };
        // The emulated wire time is microseconds: wait for it in place (sleep + spin).
        if send_at > clock::now_ns() {
            clock::sleep_until(send_at, spin_ns, stop);
        }
        match link.send(buf.get(..len).unwrap_or_default()) {
            Ok(()) => {
                c.answered += 1;
                turnaround.record(clock::now_ns().saturating_sub(received_at));
                c.stamped += u64::from(received_at != read_at);
            }
            Err(_) => c.send_errors += 1,
        }
    }
    Ok(ServeSummary {
        frames: c,
        turnaround: turnaround.summary(),
    })
}
