//! The seed formulas (spec::seed000, spec::seed003, spec::esc_dc) and the register contract
//! (spec::register) checked against the network model, and the seed errata demonstrated
//! (REQ-DC-014, 020, 025, 090).
//!
//! verifies: REQ-DC-014

use ecdc_core::dc::{delay, offset, topology::Topology};
use ecdc_core::time::SystemTime;
use ecdc_spec::network::{core_samples, generate, Dc, Esc, GenParams, Network, Shape, SplitMix};
use ecdc_spec::{esc_dc, register, seed000, seed003};

fn esc(parent: Option<(usize, u8)>, cable: i128, dc: Dc, phase: u64) -> Esc {
    Esc {
        parent,
        entry: 0,
        cable,
        t_p: 420,
        t_f: 300,
        dc,
        phase,
        rate_ppb: 0,
        stale: [0x5A5A_5A5A; 4],
    }
}

/// Local receive time of ESC `i` at `port` as an unwrapped i128 relative to its entry stamp, so
/// the plain seed formulas see true differences.
fn t(net: &Network, latch: &ecdc_spec::network::Latch, i: usize, port: usize) -> i128 {
    let obs = net.observe(latch, i, 1);
    let entry = obs.port_times[usize::from(net.escs[i].entry)];
    i128::from(obs.port_times[port].wrapping_sub(entry))
}

/// Seed 000 §2.1 on a 4-slave line with equal t_P, t_F (its assumptions): eq. 5 and 13–16 give
/// the true hop delays of the model, eq. 14/16 the true return delays (t_F + cable).
#[test]
fn seed000_hops_on_model_line() {
    let net = Network {
        escs: vec![
            esc(None, 30, Dc::Bits64, 0xFFFF_FFFF_FFFF_F000),
            esc(Some((0, 1)), 55, Dc::Bits32, 123),
            esc(Some((1, 1)), 80, Dc::Bits64, 0x0000_0001_FFFF_FFF0),
            esc(Some((2, 1)), 25, Dc::Bits64, 9),
        ],
    };
    let latch = net.latch().unwrap();
    let d = 420 - 300;
    let r = |i: usize| t(&net, &latch, i, 1) - t(&net, &latch, i, 0);
    // eq. 13/15: forward hop i → i+1
    for i in 0..2 {
        let fwd = seed000::eq13_forward_x2(r(i), 0, r(i + 1), 0, d);
        assert_eq!(
            fwd,
            2 * (latch.arrival[i + 1] - latch.arrival[i]),
            "eq. 13 hop {i}"
        );
        // eq. 14/16: return hop i+1 → i = time from the frame coming back at i+1's port 1 to
        // its arrival at i's port 1
        let back = seed000::eq14_return_x2(r(i), 0, r(i + 1), 0, d);
        let true_back = latch.port_rx[i][1].unwrap() - latch.port_rx[i + 1][1].unwrap();
        assert_eq!(back, 2 * true_back, "eq. 14 hop {i}");
        assert_eq!(true_back, 300 + net.escs[i + 1].cable, "eq. 7: t_F + t_W");
    }
    // eq. 5: last hop
    assert_eq!(
        seed000::eq5_last_hop_x2(r(2), 0),
        2 * (latch.arrival[3] - latch.arrival[2])
    );
    // eq. 23 (derived) and eq. 17–19 agree with the model for every i
    let rtt: Vec<i128> = (0..4).map(|i| if i < 3 { r(i) } else { 0 }).collect();
    for i in 1..=4 {
        let x2 = seed000::eq23_t_ref_x2(&rtt, 4, i, d).unwrap();
        assert_eq!(x2, 2 * latch.delay(0, i - 1), "eq. 23 i={i}");
        assert_eq!(x2, seed000::eq17_19_sum_of_hops_x2(&rtt, 4, i, d).unwrap());
    }
}

/// REQ-DC-090 (a): eq. 23 as printed for i = n (`+ i·t_DIFF`) contradicts eq. 22 and the model
/// whenever t_DIFF ≠ 0; the derived `(n − 2)·t_DIFF` matches. Over many random lines.
// verifies: REQ-DC-090
#[test]
fn seed000_eq23_last_case_erratum() {
    let mut rng = SplitMix::new(23);
    for _ in 0..200 {
        let n = usize::try_from(rng.range(2, 40)).unwrap();
        let dd = rng.range(1, 300);
        let p = GenParams {
            t_f: (100, 600),
            t_diff: (dd, dd),
            cable: (0, 3000),
            ..GenParams::new(n, Shape::Line, 0, 50)
        };
        let net = generate(&mut rng, &p);
        let latch = net.latch().unwrap();
        let r1 = t(&net, &latch, 0, 1) - t(&net, &latch, 0, 0);
        let truth_x2 = 2 * latch.delay(0, n - 1);
        let mut rtt = vec![0i128; n];
        rtt[0] = r1;
        assert_eq!(seed000::eq23_t_ref_x2(&rtt, n, n, dd).unwrap(), truth_x2);
        assert_ne!(seed000::eq23_printed_last_x2(r1, n, dd), truth_x2);
    }
    // n = 4 is eq. 22: (t_1B − t_1A + 2·t_DIFF) / 2
    assert_eq!(
        seed000::eq23_t_ref_x2(&[1000, 0, 0, 0], 4, 4, 7),
        Some(1000 + 2 * 7)
    );
    assert_eq!(seed000::eq23_printed_last_x2(1000, 4, 7), 1000 + 4 * 7);
}

/// REQ-DC-090 (a): the derived last case of eq. 23 follows from eq. 22 and eq. 17–19 alone,
/// without the network model. Eq. 17–19 define `t_REF,n` as the sum of the hops; every hop but
/// the last is eq. 13/15 and carries `+t_DIFF`, the last is eq. 5 and carries none, and the
/// `t_iB − t_iA` of the inner slaves cancel in the sum. So `2·t_REF,n = (t_1B − t_1A) + k·t_DIFF`
/// with `k` = the number of eq. 13 hops = `n − 2`; eq. 22 is that with n = 4 (`k = 2`). The
/// printed `k = i = n` matches eq. 22 for no n (`n = n − 2` never holds), and the case
/// `1 < i < n` keeps the `(i − 1)` eq. 13 hops it has.
// verifies: REQ-DC-090
#[test]
fn seed000_eq23_derived_from_eq22() {
    let mut rng = SplitMix::new(22);
    for _ in 0..500 {
        let n = usize::try_from(rng.range(2, 64)).unwrap();
        let d = rng.range(-200, 400);
        // Arbitrary rtt values (no model): the identities are algebraic.
        let rtt: Vec<i128> = (0..n).map(|_| rng.range(0, 1_000_000)).collect();
        // k from the sum of hops, solved for the coefficient of t_DIFF.
        let sum = seed000::eq17_19_sum_of_hops_x2(&rtt, n, n, d).unwrap();
        let no_diff = seed000::eq17_19_sum_of_hops_x2(&rtt, n, n, 0).unwrap();
        assert_eq!(no_diff, rtt[0], "inner rtts cancel, n={n}");
        if d != 0 {
            assert_eq!((sum - no_diff) / d, n as i128 - 2, "k = n − 2, n={n}");
            assert_ne!(seed000::eq23_printed_x2(&rtt, n, n, d).unwrap(), sum);
        }
        assert_eq!(seed000::eq23_t_ref_x2(&rtt, n, n, d).unwrap(), sum);
        // The other cases are the same printed and derived, and equal the sum of hops.
        for i in 1..n {
            let derived = seed000::eq23_t_ref_x2(&rtt, n, i, d).unwrap();
            assert_eq!(seed000::eq23_printed_x2(&rtt, n, i, d).unwrap(), derived);
            assert_eq!(
                derived,
                seed000::eq17_19_sum_of_hops_x2(&rtt, n, i, d).unwrap()
            );
        }
    }
    // n = 4: the derived form is eq. 22 literally, the printed one is not.
    for (r1, d) in [(1000, 7), (0, 80), (52_345, -3)] {
        let rtt = [r1, 11, 22, 33];
        assert_eq!(
            seed000::eq23_t_ref_x2(&rtt, 4, 4, d).unwrap(),
            seed000::eq22_t_ref4_x2(r1, d)
        );
        assert_eq!(
            seed000::eq23_printed_x2(&rtt, 4, 4, d).unwrap() - seed000::eq22_t_ref4_x2(r1, d),
            2 * d
        );
    }
}

/// REQ-DC-090 (b), REQ-DC-025: the printed eq. 24 sign leaves a drift of 2·(local − ref) in
/// eq. 25; the datasheet sign (used by ecdc) gives zero. Seed 003 eq. 5/6 agree with the latter.
// verifies: REQ-DC-025, REQ-DC-090
#[test]
fn seed000_eq24_sign_erratum_and_drift() {
    let (local, sys_ref, delay) = (5_000_000i128, 1_234_567i128, 0i128);
    let printed = seed000::eq24_offset_printed(local, sys_ref);
    assert_ne!(seed000::eq25_drift(local, printed, delay, sys_ref), 0);
    let good = seed000::offset_consistent_with_eq25(local, sys_ref, delay);
    assert_eq!(seed000::eq25_drift(local, good, delay, sys_ref), 0);
    assert_eq!(good, seed003::eq5_offset(sys_ref, local));
    // With a delay folded in, eq. 25 is zero at the arrival instant, and seed 003 eq. 6 agrees.
    let delay = 777;
    let off = seed000::offset_consistent_with_eq25(local, sys_ref, delay);
    assert_eq!(seed000::eq25_drift(local, off, delay, sys_ref), 0);
    assert_eq!(seed003::eq6_drift(local + off, sys_ref, delay), 0);
    // and equals the ESC's own loop input (register contract)
    assert_eq!(register::time_loop_delta(local, off, delay, sys_ref), 0);
    assert_eq!(register::time_loop_delta(local + 5, off, delay, sys_ref), 5);
    assert_eq!(register::system_time_difference_encode(-5), 0x8000_0005);
}

/// Seed 003 eq. 1–4: two slaves with equal processing delays; eq. 4 gives the true delay.
#[test]
fn seed003_two_slaves() {
    let net = Network {
        escs: vec![
            esc(None, 10, Dc::Bits64, 1),
            Esc {
                t_p: 420,
                ..esc(Some((0, 1)), 95, Dc::Bits64, 0xFFFF_FFFF)
            },
        ],
    };
    let latch = net.latch().unwrap();
    let a1_a0 = t(&net, &latch, 0, 1);
    let x2 = seed003::eq4_delay_x2(a1_a0, 0);
    assert_eq!(x2, 2 * latch.delay(0, 1));
    assert_eq!(x2 / 2, seed003::eq2_forward(420, 95));
    assert_eq!(seed003::eq2_return(420, 95), x2 / 2, "eq. 3: t_p1 = t_p2");
}

/// Datasheet example (docs/background/esc-registers.md §5): A – B (junction, ports 0/1/2) – C – D on B's port 1, E on
/// B's port 2. t_AB, t_BC, t_CD and the general hop rule equal the model, and so does core.
#[test]
fn datasheet_tree_formulas() {
    let net = Network {
        escs: vec![
            esc(None, 40, Dc::Bits64, 0x10),                          // A
            esc(Some((0, 1)), 60, Dc::Bits64, 0xFFFF_FFFF_FFFF_FFF0), // B
            esc(Some((1, 1)), 70, Dc::Bits32, 0xFFFF_FF00),           // C
            esc(Some((2, 1)), 90, Dc::Bits64, 77),                    // D
            esc(Some((1, 2)), 45, Dc::Bits64, 5),                     // E
        ],
    };
    let latch = net.latch().unwrap();
    let d = 120;
    let tt = |i, p| t(&net, &latch, i, p);
    let t_ab = esc_dc::t_ab_x2(tt(0, 1), tt(0, 0), tt(1, 2), tt(1, 0), d);
    assert_eq!(t_ab, 2 * latch.delay(0, 1));
    let t_bc = esc_dc::t_bc_x2(tt(1, 1), tt(1, 0), tt(2, 1), tt(2, 0), d);
    assert_eq!(t_bc, 2 * latch.delay(1, 2));
    let t_cd = esc_dc::t_cd_x2(tt(2, 1), tt(2, 0));
    assert_eq!(t_cd, 2 * latch.delay(2, 3));
    // B → E: q = B's port 1 (forwarding hop 1 → 2), E is a line end (processing hop back).
    assert!(!esc_dc::hop_is_processing(1, 2));
    let b_e = esc_dc::tree_hop_x2(tt(1, 2) - tt(1, 1), 0, 0, d, 0);
    assert_eq!(b_e, 2 * (latch.arrival[4] - latch.port_rx[1][1].unwrap()));
    // core agrees everywhere
    let samples = core_samples(&net, &latch, 1, true);
    let topo = Topology::<8>::build(&samples).unwrap();
    let delays = delay::compute(&samples, &topo, 0).unwrap();
    for i in 0..5 {
        assert_eq!(i128::from(delays.ns(i).unwrap()), latch.delay(0, i));
    }
}

/// Register contract (REQ-DC-021, REQ-DC-040): after core's offsets and delays, an ECAT read of
/// 0x0910 at any slave returns the reference's system time at the instant the frame passed the
/// reference, and the drift loop input is zero; widths are 8/4 bytes.
// verifies: REQ-DC-021, REQ-DC-040
#[test]
fn register_contract_after_offsets() {
    let mut rng = SplitMix::new(910);
    for _ in 0..100 {
        let p = GenParams {
            t_f: (100, 600),
            t_diff: (-50, 200),
            cable: (0, 3000),
            ..GenParams::new(12, Shape::Any, 20, 40)
        };
        let net = generate(&mut rng, &p);
        let latch = net.latch().unwrap();
        let samples = core_samples(&net, &latch, 1, true);
        let topo = Topology::<16>::build(&samples).unwrap();
        let delays = delay::compute(&samples, &topo, 0).unwrap();
        let m = rng.next_u64();
        // a later frame passes the reference at true time T
        let big_t = latch.back_at_master + i128::from(rng.next_u64() % 1_000_000_000);
        for (s, e) in net.escs.iter().enumerate() {
            if e.dc == Dc::None {
                continue;
            }
            let w = if e.dc == Dc::Bits32 {
                offset::ClockWidth::Bits32
            } else {
                offset::ClockWidth::Bits64
            };
            let d = delays.ns(s).unwrap();
            let lat = samples[s].latches.unwrap();
            let off = offset::initial_offset(
                SystemTime(m),
                d,
                offset::entry_local_time(&lat, topo.node(s).unwrap().entry),
                w,
            );
            assert_eq!(
                off.to_register().as_slice().len(),
                register::offset_register_bytes(e.dc.width())
            );
            let local_at_sof = net.local_time(s, big_t + i128::from(d));
            let read = register::ecat_read_system_time(
                local_at_sof,
                i128::from(off.as_u64()),
                i128::from(d),
                e.dc.width(),
            );
            let ref_time = register::wrap(i128::from(m) + big_t - latch.arrival[0], e.dc.width());
            assert_eq!(read, ref_time, "slave {s}");
            assert_eq!(
                register::time_loop_delta(
                    local_at_sof,
                    i128::from(off.as_u64()),
                    i128::from(d),
                    i128::from(m) + big_t - latch.arrival[0]
                ),
                0
            );
        }
    }
}
