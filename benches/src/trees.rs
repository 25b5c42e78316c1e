//! Trees of the spec crate's network model and the samples a master reads after one latch.
//!
//! Shape ("junction backbone"): every 8th slave is a 4-port junction; the junctions form a
//! line on their port 1, and each junction carries a branch of up to 7 slaves in a line on its
//! port 3 (an EK1122-style installation). All slaves are 64-bit DC, cables 50 ns, t_P 400 ns,
//! t_F 300 ns, random clock phases (half of them within 400 µs of a 32-bit wrap).

use ecdc_core::dc::topology::SlaveSample;
use ecdc_spec::network::{core_samples, renumber_in_processing_order, Dc, Esc, Network, SplitMix};

/// Slaves per junction group (the junction plus its branch).
pub const GROUP: usize = 8;

/// The junction-backbone tree of `n` slaves, numbered in auto-increment order.
pub fn junction_tree(n: usize, seed: u64) -> Network {
    let mut rng = SplitMix::new(seed);
    let mut escs: Vec<Esc> = Vec::with_capacity(n);
    let mut last_junction: Option<usize> = None;
    for i in 0..n {
        let parent = if i % GROUP == 0 {
            last_junction.map(|j| (j, 1u8))
        } else if i % GROUP == 1 {
            Some((i - 1, 3u8))
        } else {
            Some((i - 1, 1u8))
        };
        if i % GROUP == 0 {
            last_junction = Some(i);
        }
        let phase = if rng.chance(1, 2) {
            let low = (1u64 << 32) - u64::try_from(rng.range(1, 400_000)).unwrap_or(1);
            (rng.next_u64() & 0xFFFF_FFFF_0000_0000) | low
        } else {
            rng.next_u64()
        };
        escs.push(Esc {
            parent,
            entry: 0,
            cable: 50,
            t_p: 400,
            t_f: 300,
            dc: Dc::Bits64,
            phase,
            rate_ppb: 0,
            stale: [0xDEAD_BEEF; 4],
        });
    }
    renumber_in_processing_order(Network { escs })
}

/// The samples (DL status, features, latches, t_Diff) of one latch round on `net`, quantised
/// to 10 ns like a real ESC's receive-time latches.
pub fn samples(net: &Network) -> Vec<SlaveSample> {
    let latch = net.latch().expect("the junction tree is a valid tree");
    core_samples(net, &latch, 10, true)
}
