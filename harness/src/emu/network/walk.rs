//! The frame's path through the chain: which ports are open at a true time (links, power,
//! DL control loops), the DL status a slave reports, and the walk that visits every EPU and
//! port in processing order with cable and PHY delays (REQ-ESC-081/082), recursive for any
//! topology state and iterative for the common static case.

use rand::RngCore;

use super::{Network, Visit};
use crate::emu::TrueTime;

impl Network {
    #[inline]
    pub(super) fn jitter(&mut self, on: bool) -> u64 {
        if on && self.phy_jitter_ns > 0 {
            // Multiply-shift mapping of a 32-bit draw onto [0, J] (bias < 2^-20 for small J).
            (u64::from(self.jitter_rng.next_u32()) * (self.phy_jitter_ns + 1)) >> 32
        } else {
            0
        }
    }

    pub(super) fn forced_closed(&self, s: usize, port: u8) -> bool {
        if !self.any_forced {
            return false;
        }
        // DL control 0x0101: two loop bits per port; 0b11 = always closed.
        let v = self.escs[s].loop_control();
        (v >> (2 * port)) & 0x03 == 0x03
    }

    /// Whether the frame can leave `s` through `port` at `t` (and reach the neighbour).
    pub(super) fn port_open(&self, s: usize, port: u8, t: u64) -> bool {
        if port >= self.hops[s].ports {
            return false;
        }
        if !self.any_forced && self.topo.is_static() {
            // Nothing scheduled, no forced loop: exactly the cabled ports are open.
            return port == 0 || self.topo.children[s][usize::from(port)].is_some();
        }
        if self.forced_closed(s, port) {
            return false;
        }
        if port == 0 {
            let parent_ok = match self.topo.parent[s] {
                Some((p, q)) => !self.forced_closed(p, q),
                None => true,
            };
            return parent_ok && self.topo.link_up(s, t);
        }
        match self.topo.children[s][usize::from(port)] {
            Some(c) => self.topo.link_up(c, t) && !self.forced_closed(c, 0),
            None => false,
        }
    }

    /// DL status (0x0110) of `s` at `t`: bit 0 PDI operational, bits 4..7 link on port 0..3,
    /// bit 8+2p loop closed, bit 9+2p communication. REQ-ESC-015.
    pub(super) fn dl_status(&self, s: usize, t: u64) -> u16 {
        // Bit 0: PDI operational / EEPROM loaded correctly.
        let mut v = u16::from(self.escs[s].sii_loaded());
        for p in 0..4u8 {
            let physical = p < self.info[s].ports
                && match p {
                    0 => self.topo.link_up(s, t),
                    _ => self.topo.children[s][usize::from(p)]
                        .is_some_and(|c| self.topo.link_up(c, t)),
                };
            let open = self.port_open(s, p, t);
            if physical {
                v |= 1 << (4 + p);
            }
            if !open {
                v |= 1 << (8 + 2 * p);
            }
            if open {
                v |= 1 << (9 + 2 * p);
            }
        }
        v
    }

    /// Walks the frame through slave `s` entering port 0 at `t`; returns the time the frame's
    /// first bit leaves port 0 back upstream, or `None` if it was destroyed (circulating).
    /// Order: 0 → EPU → 3 → 1 → 2 → 0; closed ports loop back at no cost. REQ-ESC-081/082.
    pub(super) fn walk(
        &mut self,
        s: usize,
        t_in: u64,
        c: &mut bool,
        budget: &mut usize,
        jit: bool,
    ) -> Option<u64> {
        let mut t = t_in;
        let mut reentry = false;
        loop {
            *budget = budget.checked_sub(1)?;
            if reentry {
                // Port 0 closed: the frame re-enters the EPU. First time it gets the
                // circulating bit; the second time it is destroyed. REQ-ESC-005.
                if *c {
                    return None;
                }
                *c = true;
            }
            self.visits.push(Visit::Epu {
                slave: s,
                t,
                set_c: reentry,
            });
            // REQ-ESC-082: t_P from port 0, t_F from port n, cable + PHY jitter per traversal.
            t += self.hops[s].t_p;
            for q in [3u8, 1, 2] {
                if !self.port_open(s, q, t) {
                    // A port forced closed by DL control may turn the frame round later than
                    // an unconnected one (`SlaveDefaults::forced_loop_ns`, model).
                    if q < self.hops[s].ports && self.forced_closed(s, q) {
                        t += self.hops[s].forced_loop;
                    }
                    continue;
                }
                let Some(child) = self.topo.children[s][usize::from(q)] else {
                    continue;
                };
                let down = t + self.topo.cable_ns[child] + self.jitter(jit);
                let back = self.walk(child, down, c, budget, jit)?;
                let rx = back + self.topo.cable_ns[child] + self.jitter(jit);
                self.visits.push(Visit::Rx {
                    slave: s,
                    port: q,
                    t: rx,
                });
                t = rx + self.hops[s].t_f;
            }
            if self.port_open(s, 0, t) {
                return Some(t);
            }
            reentry = true;
        }
    }

    /// [`Network::walk`] from the master for the common case: no link or power change
    /// scheduled and no forced DL loop, so exactly the cabled ports are open, port 0 is always
    /// open and nothing circulates. Iterative; the visits and the jitter draws come in the same
    /// order as the recursive walk's. Returns the time the frame leaves slave 0's port 0.
    ///
    /// With `stamps` false the port receive visits are left out (for frames that cannot
    /// latch receive times, when no loss cut needs the full visit count).
    pub(super) fn walk_static(&mut self, t_in: u64, jit: bool, stamps: bool) -> u64 {
        const ORDER: [u8; 3] = [3, 1, 2];
        let mut stack = core::mem::take(&mut self.walk_stack);
        stack.clear();
        let mut s = 0;
        let mut t = t_in;
        self.visits.push(Visit::Epu {
            slave: 0,
            t,
            set_c: false,
        });
        t += self.hops[0].t_p;
        let mut qi = 0;
        let back = loop {
            if let Some(&q) = ORDER.get(qi) {
                qi += 1;
                if q >= self.hops[s].ports {
                    continue;
                }
                let Some(child) = self.topo.children[s][usize::from(q)] else {
                    continue;
                };
                let down = t + self.topo.cable_ns[child] + self.jitter(jit);
                stack.push((s, qi, q));
                s = child;
                self.visits.push(Visit::Epu {
                    slave: s,
                    t: down,
                    set_c: false,
                });
                t = down + self.hops[s].t_p;
                qi = 0;
                continue;
            }
            let Some((parent, pqi, q)) = stack.pop() else {
                break t;
            };
            let rx = t + self.topo.cable_ns[s] + self.jitter(jit);
            if stamps {
                self.visits.push(Visit::Rx {
                    slave: parent,
                    port: q,
                    t: rx,
                });
            }
            s = parent;
            t = rx + self.hops[s].t_f;
            qi = pqi;
        };
        self.walk_stack = stack;
        back
    }

    pub(super) fn port_open_master(&self, t: u64) -> bool {
        !self.forced_closed(0, 0) && self.topo.link_up(0, t)
    }

    /// True time at which a frame sent at `send_time` would reach each slave's EPU, without
    /// jitter and without side effects (`None` = not reached). For checking delay maths
    /// against the truth.
    pub fn epu_arrival_times(&mut self, send_time: TrueTime) -> Vec<Option<TrueTime>> {
        let mut out = vec![None; self.escs.len()];
        if self.escs.is_empty() || !self.port_open_master(send_time) {
            return out;
        }
        let saved = core::mem::take(&mut self.visits);
        let mut c = false;
        let mut budget = 8 * self.escs.len() + 8;
        let _ = self.walk(
            0,
            send_time + self.master_cable_ns,
            &mut c,
            &mut budget,
            false,
        );
        for v in &self.visits {
            if let Visit::Epu { slave, t, .. } = *v {
                if out[slave].is_none() {
                    out[slave] = Some(t);
                }
            }
        }
        self.visits = saved;
        out
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::emu::{Scenario, SlaveSpec};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The iterative walk for static topologies visits, stamps and draws jitter exactly like
    /// the general recursive walk (random trees of 2..4-port slaves).
    #[test]
    fn static_walk_matches_recursive_walk() {
        let mut r = ChaCha8Rng::seed_from_u64(5);
        for case in 0..200 {
            let n = r.gen_range(1..40);
            let mut sc = Scenario {
                seed: case,
                ..Scenario::default()
            };
            let mut free: Vec<(usize, u8)> = Vec::new();
            for i in 0..n {
                let ports = r.gen_range(2..=4u8);
                let mut spec = SlaveSpec {
                    ports: Some(ports),
                    cable_m: Some(r.gen_range(0.0..100.0)),
                    ..SlaveSpec::default()
                };
                if i > 0 {
                    let (p, q) = free.swap_remove(r.gen_range(0..free.len()));
                    spec.parent = Some(p);
                    spec.port = Some(q);
                }
                free.extend((1..ports).map(|q| (i, q)));
                sc = sc.with_slave(spec);
            }
            let mut net = Network::new(&sc).expect("scenario");
            let rng = net.jitter_rng.clone();
            let t = r.gen_range(0..1_000_000_000);
            let fast = net.walk_static(t, true, true);
            let fast_visits = core::mem::take(&mut net.visits);
            net.jitter_rng = rng;
            let (mut c, mut budget) = (false, 8 * n + 8);
            let slow = net.walk(0, t, &mut c, &mut budget, true);
            assert_eq!(Some(fast), slow, "case {case}");
            assert_eq!(
                format!("{fast_visits:?}"),
                format!("{:?}", net.visits),
                "case {case}"
            );
            assert_eq!(net.visits.len(), 2 * n - 1, "case {case}");
        }
    }
}
