//! Register widths of the offset API, through the public interface only (the DC module's own
//! test blocks are not the place for these while that module is being reworked).

use ecdc_core::dc::offset::{ClockWidth, WidthValue};

/// REQ-CONV-003: a 32-bit DC slave keeps only the low 32 bits of a time-like register and is
/// written exactly 4 bytes of it; a 64-bit slave all 8. `bytes()`, the kept value and the
/// register image agree for both widths.
// verifies: REQ-CONV-003
#[test]
fn widths_bytes_and_values_agree() {
    let v = 0x1122_3344_5566_7788u64;
    for (w, bytes, kept) in [
        (ClockWidth::Bits32, 4usize, 0x5566_7788u64),
        (ClockWidth::Bits64, 8, v),
    ] {
        assert_eq!(w.bytes(), bytes, "{w:?}");
        let wv = WidthValue::new(v, w);
        assert_eq!(wv.as_u64(), kept, "{w:?}");
        let reg = wv.to_register();
        assert_eq!(reg.as_slice().len(), bytes, "{w:?}");
        assert_eq!(
            Some(reg.as_slice()),
            kept.to_le_bytes().get(..bytes),
            "{w:?}"
        );
    }
}

/// ESC features 0x0008 bit 3 alone decides the width: every other bit is ignored.
#[test]
fn width_from_features_bit_3_only() {
    assert_eq!(ClockWidth::from_features(0x0008), ClockWidth::Bits64);
    assert_eq!(ClockWidth::from_features(0xFFFF), ClockWidth::Bits64);
    assert_eq!(ClockWidth::from_features(0xFFF7), ClockWidth::Bits32);
    assert_eq!(ClockWidth::from_features(0x0000), ClockWidth::Bits32);
}
