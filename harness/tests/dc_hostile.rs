//! Hostile wire in the emulator: while seed 000's line runs locked, every cycle the machine
//! also receives frames it did not send: replies of a second master (processed by the
//! slaves) at every datagram index with other commands, registers and lengths, their
//! truncations, oversize and VLAN-tagged copies, other EtherTypes and garbage. DC must not
//! act on any of them (REQ-DC-032): it stays locked, never restarts, the true-time skew stays
//! that of an undisturbed run, and the machine counts them as foreign.
//!
//! A second test delivers each of the machine's own replies twice, back to back, a quarter
//! cycle late and 1.5 cycles late (after the next cycle's reply): the copy matches nothing
//! in flight any more and is counted, not used.
//!
//! The second master only reads here. One that writes 0x0910 itself (its own FRMW drift
//! compensation) changes the slaves' control loops on the wire, which no reply matching can
//! undo: with it in the list the line lost lock, so it is not part of this test.

mod dc_support;

use dc_support::*;
use ecdc_core::dc::Event;
use ecdc_core::wire::{Address, Command, FrameBuilder};
use ecdc_harness::emu::Scenario;
use ecdc_harness::sim::Sim;

const CYCLE: u64 = 1_000_000;

/// A frame of a second master with one datagram, sent through the slaves: returns the reply
/// (processed bit set, WKC counted), as the machine would see it on a shared segment.
fn second_master_reply(s: &mut Sim<8>, idx: u8, c: Command, a: Address, len: usize) -> Vec<u8> {
    let mut buf = [0u8; 1514];
    let mut b = FrameBuilder::new(&mut buf).unwrap();
    b.push(c, idx, a, &vec![0u8; len]).unwrap();
    let n = b.finish().unwrap();
    s.side_channel(&buf[..n]).unwrap().expect("reply")
}

/// Every hostile variant of `reply`.
fn variants(reply: &[u8], k: u64) -> Vec<Vec<u8>> {
    let mut v = Vec::new();
    // Truncations at every length (headers, datagram header, data, WKC).
    for cut in [0, 1, 13, 14, 15, 16, 17, 25, reply.len().saturating_sub(2)] {
        v.push(reply[..cut.min(reply.len())].to_vec());
    }
    // Oversize: the same frame with 600 bytes of trailing junk, and a jumbo.
    let mut big = reply.to_vec();
    big.extend(std::iter::repeat_n(0xA5, 600));
    v.push(big);
    let mut jumbo = reply.to_vec();
    jumbo.resize(9000, 0x5A);
    v.push(jumbo);
    // VLAN-tagged copy (802.1Q tag between the MACs and the EtherType).
    let mut vlan = reply[..12].to_vec();
    vlan.extend_from_slice(&[0x81, 0x00, 0x00, 0x05]);
    vlan.extend_from_slice(&reply[12..]);
    v.push(vlan);
    // Other EtherTypes with the same payload.
    for et in [[0x08, 0x00], [0x86, 0xDD], [0x88, 0xF7]] {
        let mut o = reply.to_vec();
        o[12..14].copy_from_slice(&et);
        v.push(o);
    }
    // The ECAT header's length field lying (larger and smaller than the datagrams).
    let mut lie = reply.to_vec();
    lie[14] = 0xFF;
    lie[15] = 0x17;
    v.push(lie);
    // Garbage from a seeded generator.
    let mut x = k.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut g = vec![0u8; 64 + (k as usize % 200)];
    for b in &mut g {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        *b = x as u8;
    }
    v.push(g);
    v
}

#[test]
fn foreign_replies_truncations_vlan_and_other_ethertypes_are_ignored() {
    let mut s = sim::<8>(&Scenario::seed000_line(), seed000_config());
    lock(&mut s, 3_000_000_000);
    let t = s.now() + 200_000_000;
    s.run_until(t).unwrap();
    let events0 = s.events().len();
    let stats0 = *s.machine.stats();
    let reference = (0usize, true);
    let clocks: Vec<(usize, bool)> = (0..6).map(|i| (i, true)).collect();
    let mut injected = 0u64;
    let mut worst = 0i64;
    // Commands and registers a second master (or a copy of ours with another command or
    // length) uses; every index, so some collide with the machine's own in flight.
    let kinds: [(Command, Address, usize); 6] = [
        (Command::Brd, Address::broadcast(0x092C), 4),
        (Command::Brd, Address::broadcast(0x0130), 2),
        (Command::Brd, Address::broadcast(0x0130), 4),
        (Command::Fprd, Address::configured(0x1000, 0x0910), 4),
        (Command::Fprd, Address::configured(0x1001, 0x092C), 4),
        (Command::Brd, Address::broadcast(0x0910), 8),
    ];
    for k in 0..2_000u64 {
        let end = s.now() + CYCLE;
        s.run_until(end).unwrap();
        if k % 20 == 0 {
            let e = s.true_sync_error(reference, &clocks).unwrap().unwrap();
            worst = worst.max(e);
        }
        let (c, a, len) = kinds[(k % kinds.len() as u64) as usize];
        let reply = second_master_reply(&mut s, (k % 256) as u8, c, a, len);
        let at = s.master_time_at(s.now());
        s.machine.handle_frame(at, &reply);
        injected += 1;
        for h in variants(&reply, k) {
            s.machine.handle_frame(at, &h);
            injected += 1;
        }
    }
    let st = *s.machine.stats();
    let bad: Vec<_> = s.events()[events0..]
        .iter()
        .filter(|(_, e)| {
            matches!(
                e,
                Event::LockLost { .. } | Event::Restarting | Event::HoldoverStarted { .. }
            )
        })
        .collect();
    assert!(bad.is_empty(), "{bad:?}");
    assert!(s.machine.is_locked());
    assert_eq!(st.restarts, stats0.restarts);
    // Every injected frame was counted as foreign (whole frame or its datagrams).
    let foreign = (st.foreign_frames - stats0.foreign_frames)
        + (st.foreign_datagrams - stats0.foreign_datagrams);
    assert!(
        foreign >= injected,
        "foreign {foreign} < injected {injected}"
    );
    // Undisturbed seed-000 line: tens of ns.
    assert!(worst < 100, "true sync error {worst} ns");
    // The machine's own cycles still ran.
    assert!(
        st.cycles - stats0.cycles >= 1_900,
        "{}",
        st.cycles - stats0.cycles
    );
}

/// Drives a locked line by hand (the machine's own frames through the emulator, as
/// `Sim::step` does) and delivers every reply twice: once on time and once more `late_ns`
/// later (0 = back to back), so the copy lands while the next cycle is in flight or after it.
/// Returns (cycles run, foreign frames + datagrams counted, worst true sync error in ns).
fn duplicated_replies(late_ns: u64) -> (u64, u64, i64) {
    let mut s = sim::<8>(&Scenario::seed000_line(), seed000_config());
    lock(&mut s, 3_000_000_000);
    let t0 = s.now() + 200_000_000;
    s.run_until(t0).unwrap();
    let stats0 = *s.machine.stats();
    // The emulator may already be a few ns past the driver's clock (its last frame's walk).
    let mut t = s.now().max(s.net.now());
    let end = t + 2_000 * CYCLE;
    let mut flight: Vec<(u64, Vec<u8>)> = Vec::new();
    let mut buf = vec![0u8; 1514];
    let clocks: Vec<(usize, bool)> = (0..6).map(|i| (i, true)).collect();
    let mut worst = 0i64;
    let mut next_check = t;
    let mut samples = 0u64;
    let mut bad = Vec::new();
    while t < end {
        flight.sort_by_key(|f| f.0);
        while flight.first().is_some_and(|f| f.0 <= t) {
            let (at, f) = flight.remove(0);
            s.machine.handle_frame(s.master_time_at(at), &f);
        }
        if t >= next_check {
            next_check = t + 20 * CYCLE;
            // The emulator refuses a sample before a frame it already walked (a few ns
            // ahead of the driver); such instants are skipped and the samples counted.
            let mut sample = |i: usize| s.net.clock(i, t).ok().and_then(|c| c.system_time);
            if let Some(r) = sample(0) {
                let mut ok = true;
                let mut w = 0i64;
                for &(i, _) in &clocks {
                    match sample(i) {
                        Some(x) => w = w.max((x.wrapping_sub(r) as i64).abs()),
                        None => ok = false,
                    }
                }
                if ok {
                    worst = worst.max(w);
                    samples += 1;
                }
            }
        }
        let m = s.master_time_at(t);
        s.machine.handle_timeout(m);
        while let Some(n) = s.machine.poll_transmit(m, &mut buf) {
            if let ecdc_harness::emu::Delivery::Returned(r) = s.net.transact(&buf[..n], t).unwrap()
            {
                let at = r.arrival.max(t);
                flight.push((at + late_ns, r.frame.clone()));
                flight.push((at, r.frame));
            }
        }
        while let Some(e) = s.machine.poll_event() {
            if matches!(
                e,
                Event::LockLost { .. } | Event::Restarting | Event::HoldoverStarted { .. }
            ) {
                bad.push((t, e));
            }
        }
        let next_arrival = flight.iter().map(|f| f.0).min();
        let next_timeout = s.machine.poll_timeout().map(|x| {
            // master clock is ideal here (Sim::new default): true = master − epoch
            x.as_nanos() - s.master_time_at(0).as_nanos()
        });
        let next = match (next_arrival, next_timeout) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => break,
        };
        t = next.max(t + 1).max(s.net.now());
    }
    assert!(bad.is_empty(), "late {late_ns}: {bad:?}");
    assert!(samples >= 50, "late {late_ns}: {samples} true-time samples");
    assert!(s.machine.is_locked());
    let st = *s.machine.stats();
    (
        st.cycles - stats0.cycles,
        (st.foreign_frames - stats0.foreign_frames)
            + (st.foreign_datagrams - stats0.foreign_datagrams),
        worst,
    )
}

#[test]
fn duplicated_and_late_replies_are_ignored() {
    // Back to back, a quarter cycle late (next cycle not sent yet), 1.5 cycles late (after
    // the next cycle's reply: reordered).
    for late in [0, CYCLE / 4, CYCLE * 3 / 2] {
        let (cycles, foreign, worst) = duplicated_replies(late);
        eprintln!("late {late} ns: cycles {cycles}, foreign {foreign}, worst {worst} ns");
        assert!(cycles >= 1_900, "late {late}: {cycles} cycles");
        // Every copy was counted as not matching anything in flight.
        assert!(
            foreign >= cycles,
            "late {late}: foreign {foreign} < cycles {cycles}"
        );
        assert!(worst < 100, "late {late}: true sync error {worst} ns");
    }
}
