//! `dc::delay` results and errors, through the public interface only (the DC module's own test
//! blocks are not the place for these while that module is being reworked).

use ecdc_core::dc::delay::DelayError;

/// Every variant prints its own message, and the ones about a slave name that slave: the
/// message is what a user sees of a failed delay measurement.
#[test]
fn every_delay_error_has_its_own_message() {
    let slave = 4711;
    let errors = [
        DelayError::Mismatch,
        DelayError::BadReference { slave },
        DelayError::NoUpstreamDc { slave },
        DelayError::NonDcJunction { slave },
        DelayError::Inconsistent { slave },
        DelayError::NegativeHop { slave },
        DelayError::Overflow { slave },
        DelayError::BeforeReference { slave },
        DelayError::RoundMismatch,
    ];
    let texts = errors.map(|e| e.to_string());
    for (e, t) in errors.iter().zip(&texts) {
        let names_slave = !matches!(e, DelayError::Mismatch | DelayError::RoundMismatch);
        assert_eq!(t.contains("4711"), names_slave, "{e:?}: {t}");
        assert!(t.len() > 10, "{e:?}: {t}");
    }
    for (i, a) in texts.iter().enumerate() {
        for b in texts.iter().skip(i + 1) {
            assert_ne!(a, b);
        }
    }
}

/// `Delays` reports its size: empty before a computation, one entry per slave after it (two
/// 64-bit slaves in a line, as in the `dc::delay` module example).
#[test]
fn delays_len_and_emptiness() {
    use ecdc_core::dc::delay::{self, Delays};
    use ecdc_core::dc::topology::{SlaveSample, Topology};
    let empty = Delays::<8>::new();
    assert!(empty.is_empty());
    assert_eq!(empty.len(), 0);
    let samples = [
        SlaveSample::from_registers(0x5A00, 0x000C, [1_000, 2_000, 0, 0], 0x7_0000_03E8, 0),
        SlaveSample::from_registers(0x5600, 0x000C, [90, 0, 0, 0], 0x2_0000_005A, 0),
    ];
    let topo = Topology::<8>::build(&samples).unwrap();
    let delays = delay::compute(&samples, &topo, 0).unwrap();
    assert!(!delays.is_empty());
    assert_eq!(delays.len(), 2);
    assert_eq!(delays.ns(1), Some(500));
}
