//! Hostile wire in the emulator: while seed 000's line runs locked, every cycle the machine
//! also receives frames it did not send: replies of a second master (processed by the
//! slaves) at every datagram index with other commands, registers and lengths, their
//! truncations, oversize and VLAN-tagged copies, other EtherTypes and garbage. DC must not
//! act on any of them (REQ-DC-032): it stays locked, never restarts, the true-time skew stays
//! that of an undisturbed run, and the machine counts them as foreign.
//!
//! The second master only reads here. One that writes 0x0910 itself (its own FRMW drift
//! compensation) changes the slaves' control loops on the wire, which no reply matching can
//! undo: with it in the list the line lost lock, so it is not part of this test.

mod dc_support;

use dc_support::*;
use ecdc_core::dc::Event;
use ecdc_core::wire::{Address, Command, FrameBuilder};
use ecdc_harness::emu::{Scenario, SEED000_T_F_NS, SEED000_T_P_NS};
use ecdc_harness::sim::Sim;

const CYCLE: u64 = 1_000_000;

fn seed000_config() -> ecdc_core::dc::Config {
    ecdc_core::dc::Config {
        t_diff_ns: i32::try_from(SEED000_T_P_NS - SEED000_T_F_NS).unwrap(),
        ..ecdc_core::dc::Config::default()
    }
}

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
