//! Transport and cyclic-loop behaviour over an in-memory link (no sockets, no root):
//! reply matching by index, per-kind frame accounting, loss and stale handling, deadline
//! adjustment by the task.

use std::collections::VecDeque;
use std::io;
use std::sync::atomic::AtomicBool;

use ecdc_harness::runtime::clock;
use ecdc_harness::runtime::cyclic::{self, CycleConfig, CycleReport, CycleTask, LoopSummary};
use ecdc_harness::runtime::socket::Link;
use ecdc_harness::runtime::transport::{classify, Class, Reply, SendError, Transport};

const MAC: [u8; 6] = [0x10; 6];

/// One BRD datagram (ADO 0x0130, 2 data bytes) with index `idx`, sent from `src`, padded to 60.
fn frame(src: [u8; 6], idx: u8) -> Vec<u8> {
    let mut f = vec![0xff; 6];
    f.extend_from_slice(&src);
    f.extend_from_slice(&[0x88, 0xa4]);
    let dg_len: u16 = 10 + 2 + 2;
    f.extend_from_slice(&(dg_len | 0x1000).to_le_bytes());
    f.extend_from_slice(&[7, idx, 0, 0, 0x30, 0x01, 2, 0, 0, 0, 0, 0, 0, 0]);
    f.resize(60, 0);
    f
}

/// What the in-memory "slave" does with each sent frame.
#[derive(Clone, Copy, PartialEq)]
enum Behaviour {
    Reflect,
    Drop,
    Duplicate,
}

/// A link whose far end is one slave that marks the frame processed and bumps the WKC.
struct LoopLink {
    queue: VecDeque<Vec<u8>>,
    behaviour: Behaviour,
}

impl LoopLink {
    fn new(behaviour: Behaviour) -> Self {
        LoopLink {
            queue: VecDeque::new(),
            behaviour,
        }
    }
}

fn process(mut f: Vec<u8>) -> Vec<u8> {
    f[6] |= 0x02;
    f[28] += 1; // WKC of the single datagram (14 + 2 + 10 + 2 data)
    f
}

impl Link for LoopLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        match self.behaviour {
            Behaviour::Reflect => self.queue.push_back(process(frame.to_vec())),
            Behaviour::Drop => {}
            Behaviour::Duplicate => {
                self.queue.push_back(process(frame.to_vec()));
                self.queue.push_back(process(frame.to_vec()));
            }
        }
        Ok(())
    }
    fn recv(&mut self, buf: &mut [u8], _deadline_ns: u64) -> io::Result<Option<usize>> {
        Ok(self.queue.pop_front().map(|f| {
            let n = f.len().min(buf.len());
            buf[..n].copy_from_slice(&f[..n]);
            f.len()
        }))
    }
}

fn far_future() -> u64 {
    clock::now_ns() + 10 * clock::NS_PER_S
}

#[test]
fn classify_by_source_mac_and_header() {
    let mine = frame(MAC, 5);
    assert_eq!(classify(&mine, &MAC), Class::OwnUnprocessed);
    assert_eq!(
        classify(&process(mine.clone()), &MAC),
        Class::Reply {
            index: 5,
            ecat_len: 14
        }
    );
    let other = frame([0x01, 1, 1, 1, 1, 1], 5);
    assert_eq!(
        classify(&other, &MAC),
        Class::OtherMaster([0x01, 1, 1, 1, 1, 1])
    );
    // A processed reply to the other master is attributed to it too (bit 0x02 cleared).
    assert_eq!(
        classify(&process(other), &MAC),
        Class::OtherMaster([0x01, 1, 1, 1, 1, 1])
    );
    let mut ip = mine.clone();
    ip[12..14].copy_from_slice(&[0x08, 0x00]);
    assert_eq!(classify(&ip, &MAC), Class::Foreign);
    let mut mailbox = mine.clone();
    mailbox[15] = 0x50; // type 5
    assert_eq!(classify(&mailbox, &MAC), Class::Foreign);
    assert_eq!(classify(&mine[..17], &MAC), Class::Foreign);
    assert_eq!(classify(&[], &MAC), Class::Foreign);
}

/// The transport's counters of frames sent, received, matched, stale and lost.
fn counts<L: Link>(t: &Transport<L>) -> [u64; 5] {
    let c = t.counters();
    [c.sent, c.received, c.matched, c.stale, c.lost]
}

#[test]
fn reply_matched_by_index_with_rtt() {
    let mut t = Transport::new(LoopLink::new(Behaviour::Reflect), MAC);
    let sent_at = t.send(&frame(MAC, 9), far_future()).unwrap();
    assert_eq!(t.in_flight(), 1);
    let mut buf = [0u8; 128];
    let r: Reply = t.recv(&mut buf, far_future()).unwrap().expect("reply");
    assert_eq!(r.index, 9);
    assert_eq!(r.len, 60);
    assert_eq!(r.sent_at, sent_at);
    assert!(r.received_at >= sent_at);
    assert_eq!(buf[28], 1, "the reply bytes are in the caller's buffer");
    assert_eq!(t.in_flight(), 0);
    assert_eq!(counts(&t), [1, 1, 1, 0, 0]);
}

#[test]
fn duplicate_reply_is_stale_and_dropped() {
    let mut t = Transport::new(LoopLink::new(Behaviour::Duplicate), MAC);
    t.send(&frame(MAC, 1), far_future()).unwrap();
    let mut buf = [0u8; 128];
    assert!(t.recv(&mut buf, far_future()).unwrap().is_some());
    // The second copy is not in flight any more.
    assert!(t.recv(&mut buf, 0).unwrap().is_none());
    assert_eq!(counts(&t), [1, 2, 1, 1, 0]);
}

#[test]
fn missing_reply_counts_lost_after_deadline() {
    let mut t = Transport::new(LoopLink::new(Behaviour::Drop), MAC);
    let deadline = clock::now_ns() + 1_000_000;
    t.send(&frame(MAC, 3), deadline).unwrap();
    let mut buf = [0u8; 128];
    // recv returns None; the frame is not yet past its deadline, so it stays in flight.
    assert!(t.recv(&mut buf, 0).unwrap().is_none());
    assert_eq!(t.in_flight(), 1);
    assert_eq!(t.expire(deadline), 1);
    assert_eq!(counts(&t), [1, 0, 0, 0, 1]);
    assert_eq!(t.in_flight(), 0);
}

#[test]
fn late_reply_is_stale_not_matched() {
    let mut t = Transport::new(LoopLink::new(Behaviour::Reflect), MAC);
    // Deadline already passed when the reply is read.
    t.send(&frame(MAC, 4), clock::now_ns()).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1));
    let mut buf = [0u8; 128];
    assert!(t.recv(&mut buf, 0).unwrap().is_none());
    assert_eq!(counts(&t), [1, 1, 0, 1, 1]);
}

#[test]
fn send_refuses_foreign_frames_and_index_reuse() {
    let mut t = Transport::new(LoopLink::new(Behaviour::Drop), MAC);
    assert!(matches!(
        t.send(&frame([2; 6], 1), far_future()),
        Err(SendError::NotOurFrame)
    ));
    t.send(&frame(MAC, 1), far_future()).unwrap();
    assert!(matches!(
        t.send(&frame(MAC, 1), far_future()),
        Err(SendError::IndexInFlight(1))
    ));
    for i in 2..=16 {
        t.send(&frame(MAC, i), far_future()).unwrap();
    }
    assert!(matches!(
        t.send(&frame(MAC, 17), far_future()),
        Err(SendError::TooManyInFlight)
    ));
    assert_eq!(t.counters().sent, 16);
}

/// Link that injects unrelated traffic before each reply.
struct NoisyLink(LoopLink);

impl Link for NoisyLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.0.queue.push_back(frame.to_vec()); // our own frame, unprocessed
        self.0.queue.push_back(frame_from_other());
        let mut ip = frame.to_vec();
        ip[12] = 0x08;
        ip[13] = 0x00;
        self.0.queue.push_back(ip);
        self.0.queue.push_back(vec![0u8; 4000]); // longer than the buffer
        self.0.send(frame)
    }
    fn recv(&mut self, buf: &mut [u8], deadline_ns: u64) -> io::Result<Option<usize>> {
        self.0.recv(buf, deadline_ns)
    }
}

fn frame_from_other() -> Vec<u8> {
    frame([0x01, 0x01, 0x01, 0x01, 0x01, 0x01], 200)
}

#[test]
fn every_received_frame_is_accounted_once() {
    let mut t = Transport::new(NoisyLink(LoopLink::new(Behaviour::Reflect)), MAC);
    let mut buf = [0u8; 1536];
    for i in 0..10u8 {
        t.send(&frame(MAC, i), far_future()).unwrap();
        assert_eq!(
            t.recv(&mut buf, far_future()).unwrap().map(|r| r.index),
            Some(i)
        );
    }
    let c = *t.counters();
    assert_eq!(c.received, 50);
    assert_eq!(c.matched, 10);
    assert_eq!(c.own_unprocessed, 10);
    assert_eq!(c.other_master, 10);
    assert_eq!(c.other_master_mac, Some([0x01; 6]));
    assert_eq!(c.foreign, 10);
    assert_eq!(c.truncated, 10);
    assert_eq!(
        c.matched
            + c.stale
            + c.mismatched
            + c.foreign
            + c.own_unprocessed
            + c.other_master
            + c.truncated,
        c.received
    );
}

/// A task that sends one frame per cycle, counts WKC errors and asks for a fixed adjustment.
struct Probe {
    completed: u64,
    missing: u64,
    adjust: i64,
}

impl Probe {
    /// A probe that has seen nothing yet and moves every next deadline by `adjust` ns.
    fn adjusting(adjust: i64) -> Self {
        Probe {
            completed: 0,
            missing: 0,
            adjust,
        }
    }
}

impl CycleTask for Probe {
    fn build(&mut self, cycle: u64, _deadline: u64, _now: u64, buf: &mut [u8]) -> Option<usize> {
        let f = frame(MAC, (cycle % 256) as u8);
        buf[..f.len()].copy_from_slice(&f);
        Some(f.len())
    }
    fn complete(&mut self, _cycle: u64, reply: Option<(&[u8], &Reply)>) -> CycleReport {
        match reply {
            Some((bytes, _)) => {
                self.completed += 1;
                CycleReport {
                    adjust_ns: self.adjust,
                    wkc_error: bytes[28] != 1,
                    locked: Some(true),
                    ..Default::default()
                }
            }
            None => {
                self.missing += 1;
                CycleReport {
                    wkc_error: false,
                    ..Default::default()
                }
            }
        }
    }
}

/// The cyclic loop over a loop link that behaves as `b`, with a task that moves each deadline
/// by `adjust_ns`, the stop flag set or not from the start: its summary and the task.
fn run_loop(b: Behaviour, adjust_ns: i64, cfg: &CycleConfig, stop: bool) -> (LoopSummary, Probe) {
    let mut t = Transport::new(LoopLink::new(b), MAC);
    let mut task = Probe::adjusting(adjust_ns);
    let s = cyclic::run(&mut t, &mut task, cfg, &AtomicBool::new(stop), |_| {}).unwrap();
    (s, task)
}

#[test]
fn cyclic_loop_runs_fixed_cycles_and_applies_adjustment() {
    let mut cfg = CycleConfig::new(1_000_000);
    cfg.max_cycles = Some(40);
    let started = clock::now_ns();
    let (s, task) = run_loop(Behaviour::Reflect, 100_000, &cfg, false);
    let elapsed = clock::now_ns() - started;
    assert_eq!(s.cycles, 40);
    assert_eq!(task.completed, 40);
    assert_eq!(s.frames.sent, 40);
    assert_eq!(s.frames.matched, 40);
    assert_eq!(s.wkc_errors, 0);
    assert_eq!(s.rtt.count, 40);
    assert_eq!(s.locked_at_end, Some(true));
    assert_eq!(s.locked_cycles, 40);
    assert!(!s.interrupted);
    // +100 us per cycle on a 1 ms cycle: 40 cycles take about 1 + 39 * 1.1 ms, well over 40 ms.
    assert!(
        elapsed >= 43_000_000,
        "deadline adjustment not applied: {elapsed} ns"
    );
}

#[test]
fn cyclic_loop_counts_lost_replies_as_lost_not_wkc_errors() {
    let mut cfg = CycleConfig::new(1_000_000);
    cfg.max_cycles = Some(5);
    cfg.reply_timeout_ns = 100_000;
    let (s, task) = run_loop(Behaviour::Drop, 0, &cfg, false);
    assert_eq!(task.missing, 5);
    assert_eq!(s.wkc_errors, 0);
    assert_eq!(s.rtt.count, 0);
    assert_eq!(s.frames.lost, 5);
    assert_eq!(s.frames.sent, 5);
}

#[test]
fn stop_flag_ends_loop_as_interrupted() {
    let (s, _) = run_loop(Behaviour::Reflect, 0, &CycleConfig::new(1_000_000), true);
    assert!(s.interrupted);
    assert_eq!(s.cycles, 0);
}
