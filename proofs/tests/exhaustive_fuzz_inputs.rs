//! Replays every committed fuzz input — seed corpora `fuzz/corpus/<target>/` and saved crashes
//! `fuzz/regressions/<target>/` — through the same property bodies the byte-level fuzz targets
//! call, on the stable toolchain, so `cargo test --workspace` keeps fixed crashes fixed even
//! where nightly/libFuzzer is unavailable. `.ci/layers/40-fuzz.sh` replays them through the real
//! fuzz binaries as well. Targets whose input is decoded with `arbitrary` (`wire_roundtrip`) are
//! replayed only there.

use std::path::{Path, PathBuf};

/// Byte-level targets and the body each calls (mirrors `fuzz/fuzz_targets/<target>.rs`).
fn body(target: &str) -> Option<fn(&[u8])> {
    match target {
        "wire_parse" => Some(ecdc_proofs::wire::parse_any),
        "wire_display" => Some(|d: &[u8]| {
            ecdc_proofs::wire::display_any(d);
            if let Some(payload) = d.get(14..) {
                ecdc_proofs::wire::display_any(payload);
            }
        }),
        "machine_script" => Some(ecdc_proofs::machine::check_script),
        "machine_actions" => Some(ecdc_proofs::model::check_actions),
        _ => None,
    }
}

/// Files (`dirs == false`) or subdirectories (`dirs == true`) of `dir`, sorted; none if absent.
fn entries(dir: &Path, dirs: bool) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.flatten()
                .map(|e| e.path())
                .filter(|p| p.is_dir() == dirs)
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn replay_committed_fuzz_inputs() {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz");
    let mut replayed = 0;
    for kind in ["corpus", "regressions"] {
        for target_dir in entries(&fuzz.join(kind), true) {
            let name = target_dir
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or("");
            let Some(f) = body(name) else { continue };
            for input in entries(&target_dir, false) {
                let bytes = std::fs::read(&input).expect("readable fuzz input");
                let r = std::panic::catch_unwind(|| f(&bytes));
                assert!(r.is_ok(), "{} fails its property", input.display());
                replayed += 1;
            }
        }
    }
    println!("replayed {replayed} committed fuzz inputs");
    // The wire targets ship seed corpora; an empty replay would mean the paths are wrong.
    assert!(replayed > 0, "no fuzz input found under {}", fuzz.display());
}
