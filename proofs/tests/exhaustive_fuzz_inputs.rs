//! Replays every committed fuzz input — seed corpora `fuzz/corpus/<target>/` and saved crashes
//! `fuzz/regressions/<target>/` — through the same property bodies the byte-level fuzz targets
//! call, on the stable toolchain, so `cargo test --workspace` keeps fixed crashes fixed even
//! where nightly/libFuzzer is unavailable. `.ci/layers/40-fuzz.sh` replays them through the real
//! fuzz binaries as well. Targets whose input is decoded with `arbitrary` ([`TYPED_TARGETS`]) are
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
        "registers" => Some(ecdc_proofs::wire::registers_target),
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

/// Targets whose input is decoded with `arbitrary` (a typed `Input`), replayed only by the
/// fuzz layer's real binaries.
const TYPED_TARGETS: [&str; 4] = ["dc_math", "num_kernels", "servo", "wire_roundtrip"];

/// Every `[[bin]]` of fuzz/Cargo.toml is either replayed here (a byte-level body) or listed as
/// typed, so a new byte-level target cannot silently miss the stable replay.
#[test]
fn every_fuzz_target_is_replayed_or_typed() {
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/Cargo.toml"))
            .expect("fuzz/Cargo.toml");
    let mut in_bin = false;
    let mut targets = Vec::new();
    for line in manifest.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            in_bin = line == "[[bin]]";
        } else if in_bin {
            if let Some(v) = line.strip_prefix("name") {
                targets.push(
                    v.trim_start_matches([' ', '='])
                        .trim_matches('"')
                        .to_string(),
                );
            }
        }
    }
    assert!(targets.len() >= 9, "parsed {targets:?}");
    for t in &targets {
        assert!(
            body(t).is_some() != TYPED_TARGETS.contains(&t.as_str()),
            "fuzz target {t}: add its body to `body` or list it in TYPED_TARGETS (exactly one)"
        );
    }
}
