//! An in-memory [`Link`] to the ESC emulator in host real time: true time is the host's
//! monotonic clock since the link was made, so the runtime's real-time code (bring-up driver,
//! cyclic loop, servos) and other masters' loops run against emulated slaves without sockets
//! or root. A sent frame goes through the network at once; its reply is received when its
//! last bit would arrive.

use std::collections::VecDeque;
use std::io;
use std::sync::atomic::AtomicBool;

use super::clock;
use super::socket::Link;
use crate::emu::{Delivery, Network};

/// The emulated chain behind an in-memory link.
pub struct EmuLink {
    /// The emulated chain.
    pub net: Network,
    /// A wait for a reply ends in a spin of this many ns (0: it only sleeps): replies come on
    /// time at the cost of a busy core.
    pub spin_ns: u64,
    /// A frame received before every reply, such as another master's.
    pub inject: Option<Vec<u8>>,
    start: u64,
    queue: VecDeque<(u64, Vec<u8>)>,
}

impl EmuLink {
    /// A link to `net`, whose true time 0 is now.
    pub fn new(net: Network) -> Self {
        EmuLink {
            net,
            spin_ns: 0,
            inject: None,
            start: clock::now_ns(),
            queue: VecDeque::new(),
        }
    }

    /// True time now, ns: the host time since the link was made, never before the network's.
    pub fn true_now(&self) -> u64 {
        clock::now_ns()
            .saturating_sub(self.start)
            .max(self.net.now())
    }
}

impl Link for EmuLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        let t = self.true_now();
        if let Some(f) = &self.inject {
            self.queue.push_back((0, f.clone()));
        }
        match self.net.transact(frame, t) {
            Ok(Delivery::Returned(r)) => self.queue.push_back((self.start + r.arrival, r.frame)),
            Ok(Delivery::Lost(_)) => {}
            Err(e) => return Err(io::Error::other(e.to_string())),
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], deadline_ns: u64) -> io::Result<Option<usize>> {
        let stop = AtomicBool::new(false);
        match self.queue.front() {
            Some(&(at, _)) if at <= deadline_ns => {
                clock::sleep_until(at, self.spin_ns, &stop);
                let Some((_, f)) = self.queue.pop_front() else {
                    return Ok(None);
                };
                let n = f.len().min(buf.len());
                buf[..n].copy_from_slice(&f[..n]);
                Ok(Some(f.len()))
            }
            _ => {
                clock::sleep_until(deadline_ns, 0, &stop);
                Ok(None)
            }
        }
    }
}
