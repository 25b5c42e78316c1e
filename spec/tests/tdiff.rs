//! The t_Diff measurement's derivation (REQ-DC-121, REQ-DC-122; docs/background/t-diff.md)
//! checked against the network model: for random lines, forks, crosses and trees with per-ESC
//! t_P and t_F, forcing a slave's downstream ports closed and comparing its upstream DC slave's
//! excursion before and after gives exactly that slave's own t_P − t_F whenever its return hop
//! is a forwarding hop (always so for an ESC entered at port 0) and exactly 0 otherwise; and
//! the delay formula uses the t_Diff of both the first slave and the line end, so those must
//! come from somewhere even though they cannot be measured this way.
//!
//! verifies: REQ-DC-121, REQ-DC-122

use ecdc_core::dc::delay;
use ecdc_core::dc::topology::Topology;
use ecdc_spec::esc_dc::{hop_is_processing, next_port};
use ecdc_spec::network::{core_samples, generate, Dc, Esc, GenParams, Network, Shape, SplitMix};

/// The network with `b`'s downstream ports closed: `b`'s subtree is simply gone. Returns the
/// new network and the new index of every old ESC that is kept.
fn close_downstream(net: &Network, b: usize) -> (Network, Vec<Option<usize>>) {
    net.with_closed_ports(|i, port| i == b && port != net.escs[b].entry)
}

/// Open ports of `i` in processing order starting after its entry port.
fn downstream_order(net: &Network, i: usize) -> Vec<u8> {
    let open = net.open_ports(i);
    let entry = net.escs[i].entry;
    let mut out = Vec::new();
    let mut p = next_port(entry);
    while p != entry {
        if open[usize::from(p)] {
            out.push(p);
        }
        p = next_port(p);
    }
    out
}

/// Nearest upstream DC ESC of `b` and its port on the path to `b`.
fn upstream_dc(net: &Network, b: usize) -> Option<(usize, u8)> {
    let (mut a, mut port) = net.escs[b].parent?;
    while net.escs[a].dc == Dc::None {
        (a, port) = net.escs[a].parent?;
    }
    Some((a, port))
}

fn check_network(net: &Network) -> usize {
    let latch = net.latch().expect("tree");
    let mut checked = 0;
    for b in 0..net.escs.len() {
        if net.escs[b].dc == Dc::None {
            continue;
        }
        let order = downstream_order(net, b);
        let Some(&last) = order.last() else { continue };
        let Some((a, p)) = upstream_dc(net, b) else {
            continue;
        };
        // q: the open port of `a` the frame left before it went out of p (p's predecessor).
        let a_order = downstream_order(net, a);
        let k = a_order.iter().position(|x| *x == p).expect("p is open");
        let q = if k == 0 {
            net.escs[a].entry
        } else {
            a_order[k - 1]
        };
        let rx = |l: &ecdc_spec::network::Latch, i: usize, port: u8| {
            l.port_rx[i][usize::from(port)].expect("port reached")
        };
        let x = rx(&latch, a, p) - rx(&latch, a, q);
        let entry = net.escs[b].entry;
        let rtt = rx(&latch, b, last) - rx(&latch, b, entry);
        let (cut, map) = close_downstream(net, b);
        let cl = cut.latch().expect("tree");
        let a2 = map[a].expect("a kept");
        let x_closed = rx(&cl, a2, p) - rx(&cl, a2, q);
        let esc = &net.escs[b];
        let expected = if hop_is_processing(last, entry) {
            0
        } else {
            esc.t_p - esc.t_f
        };
        assert_eq!(
            x_closed - x + rtt,
            expected,
            "slave {b} (entry {entry}, last {last}) below {a} (q {q}, p {p})"
        );
        if entry == 0 {
            assert_eq!(
                expected,
                esc.t_p - esc.t_f,
                "entered at port 0: forwarding return"
            );
        }
        checked += 1;
    }
    checked
}

#[test]
fn closing_the_downstream_ports_gives_the_slaves_own_t_diff() {
    let mut total = 0;
    for seed in 0..400u64 {
        let shape = match seed % 4 {
            0 => Shape::Line,
            1 => Shape::Fork,
            2 => Shape::Cross,
            _ => Shape::Any,
        };
        let mut rng = SplitMix::new(seed);
        let mut net = generate(
            &mut rng,
            &GenParams::new(2 + (seed % 23) as usize, shape, 20, 20),
        );
        // Per-ESC t_F too: the measurement does not need one common t_F.
        for e in &mut net.escs {
            let d = e.t_p - e.t_f;
            e.t_f = rng.range(100, 800);
            e.t_p = e.t_f + d;
        }
        total += check_network(&net);
    }
    println!("{total} slaves checked");
    assert!(total > 1_000, "only {total} measurable slaves generated");
}

/// Which t_Diff values enter the delays (core/src/dc/delay.rs): on a line, the first slave's
/// (its processing hop towards slave 1) and the line end's (its processing turn-round), not
/// only the middle slaves' — so the step must give the unmeasurable ones a value too.
#[test]
fn first_slave_and_line_end_t_diff_enter_the_delays() {
    let esc = |parent: Option<(usize, u8)>| Esc {
        parent,
        entry: 0,
        cable: 5,
        t_p: 540,
        t_f: 460,
        dc: Dc::Bits64,
        phase: 1_000_000,
        rate_ppb: 0,
        stale: [0; 4],
    };
    let net = Network {
        escs: vec![
            esc(None),
            esc(Some((0, 1))),
            esc(Some((1, 1))),
            esc(Some((2, 1))),
        ],
    };
    let latch = net.latch().unwrap();
    let base = core_samples(&net, &latch, 1, true);
    let delays = |s: &[ecdc_core::dc::topology::SlaveSample]| {
        let topo = Topology::<8>::build(s).unwrap();
        let d = delay::compute(s, &topo, 0).unwrap();
        (0..4).map(|i| d.exact(i).unwrap().0).collect::<Vec<i64>>()
    };
    let truth: Vec<i64> = (0..4)
        .map(|i| 2 * (latch.arrival[i] - latch.arrival[0]) as i64)
        .collect();
    assert_eq!(delays(&base), truth, "exact with every true t_Diff");
    for (k, what) in [
        (0usize, "first slave"),
        (3, "line end"),
        (1, "middle slave"),
    ] {
        let mut s = base.clone();
        s[k].t_diff = 0;
        assert_ne!(delays(&s), truth, "{what}'s t_Diff enters some delay");
    }
}
