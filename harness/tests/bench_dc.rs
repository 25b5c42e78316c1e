//! `ecdc bench dc` on seed 003's two-slave setup with a short window: the behaviour of each
//! scheme (ecdc locks and starts SYNC0 everywhere, the fixed bursts have their documented
//! lengths, IgH's gate ends its static phase long before a 10 000-frame burst would, the
//! uncompensated clock error grows) and the files the command writes (Markdown table, JSON,
//! SVG, each naming the command).

use std::process::Command;

use ecdc_harness::cli::bench::{run_scenario, BenchScenario, SchemeName};

fn scheme<'a>(
    r: &'a ecdc_harness::cli::bench::ScenarioResult,
    name: &str,
) -> &'a ecdc_harness::cli::bench::SchemeResult {
    r.schemes.iter().find(|s| s.name == name).unwrap()
}

#[test]
fn two_slave_scenario_behaviour() {
    let (r, series) =
        run_scenario(BenchScenario::Seed003Line2, &SchemeName::ALL, Some(2_000)).unwrap();
    assert_eq!(r.slaves, 2);
    assert_eq!(r.schemes.len(), 6);
    for s in &r.schemes {
        assert!(s.error.is_none(), "{}: {:?}", s.name, s.error);
    }
    // What each was told: t_DIFF for the seed 000 schemes only among the reproductions.
    for name in ["seed000", "seed000-printed"] {
        let g = &scheme(&r, name).given;
        assert_eq!(g.get("t_diff_ns"), Some(&r.t_diff_ns), "{name}");
    }
    for name in ["igh", "ethercrab", "uncompensated"] {
        assert!(scheme(&r, name).given.is_empty(), "{name}");
    }
    let e = scheme(&r, "ecdc");
    assert!(e.lock_frames.is_some(), "{e:?}");
    assert_eq!(e.sync0_slaves, 2, "{e:?}");
    assert!(e.skew.max_ns.unwrap() < 100, "{e:?}");
    // The fixed bursts are exactly their documented length (seed 000's gate comes after).
    assert_eq!(scheme(&r, "seed000").static_drift_frames, Some(15_000));
    assert_eq!(
        scheme(&r, "seed000-printed").static_drift_frames,
        Some(15_000)
    );
    assert_eq!(scheme(&r, "ethercrab").static_drift_frames, Some(10_000));
    // IgH has no burst: its 10 µs gate ends the static phase after a few cyclic frames.
    let igh = scheme(&r, "igh").static_drift_frames.unwrap();
    assert!(igh < 1_000, "igh static frames {igh}");
    // No compensation: no reference-time frames, and the clock error grows with time.
    let u = scheme(&r, "uncompensated");
    assert_eq!(u.dist_frames, 0);
    assert!(u.lock_frames.is_none());
    let track = &series
        .iter()
        .find(|s| s.name == "uncompensated")
        .unwrap()
        .track;
    let at = |t: u64| track.iter().find(|p| p.0 >= t).and_then(|p| p.1).unwrap();
    assert!(
        at(1_900_000_000) > 2 * at(500_000_000),
        "{} vs {}",
        at(1_900_000_000),
        at(500_000_000)
    );
    assert!(u.skew.mean_ns.unwrap() > 100.0 * e.skew.mean_ns.unwrap().max(1.0));
    // Every scheme's skew distribution is sorted and matches its pair count.
    for (s, res) in series.iter().zip(&r.schemes) {
        assert_eq!(s.skews.len(), res.skew_pairs, "{}", s.name);
        assert!(s.skews.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(s.skews.last().copied(), res.skew.max_ns);
    }
}

/// Tags of an SVG are balanced (a minimal well-formedness check).
fn balanced(svg: &str) -> bool {
    let mut stack: Vec<String> = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find('<') {
        rest = &rest[i + 1..];
        let Some(j) = rest.find('>') else {
            return false;
        };
        let tag = &rest[..j];
        rest = &rest[j + 1..];
        if tag.starts_with("!--") {
            continue;
        }
        if let Some(name) = tag.strip_prefix('/') {
            if stack.pop().as_deref() != Some(name.trim()) {
                return false;
            }
        } else if !tag.ends_with('/') {
            stack.push(tag.split_whitespace().next().unwrap_or("").to_string());
        }
    }
    stack.is_empty()
}

#[test]
fn command_writes_table_json_and_svg() {
    let dir = std::env::temp_dir().join(format!("ecdc-bench-dc-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_ecdc"))
        .args([
            "bench",
            "dc",
            "--scenario",
            "seed003-line2",
            "--duration-ms",
            "1500",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let cmd = format!(
        "cargo run --release -p ecdc-harness --bin ecdc -- bench dc --out {} --scenario seed003-line2 --duration-ms 1500",
        dir.display()
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("dc.json")).unwrap()).unwrap();
    assert_eq!(json["command"], cmd.as_str());
    let schemes = json["scenarios"][0]["schemes"].as_array().unwrap();
    let names: Vec<&str> = schemes
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "ecdc",
            "seed000",
            "seed000-printed",
            "igh",
            "ethercrab",
            "uncompensated"
        ]
    );
    for s in schemes {
        assert!(s["given"].is_object(), "{}", s["name"]);
    }

    let md = std::fs::read_to_string(dir.join("dc.md")).unwrap();
    assert!(md.contains(&cmd), "{md}");
    // The summary table: header, separator, one row per scheme with every column, and the
    // numbers agree with the JSON.
    let table: Vec<Vec<&str>> = md
        .lines()
        .skip_while(|l| !l.starts_with("| scenario"))
        .take_while(|l| l.starts_with('|'))
        .map(|l| l.trim_matches('|').split(" | ").map(str::trim).collect())
        .collect();
    assert_eq!(table.len(), 2 + 6, "{md}");
    let seps = table[1][0].split('|').count();
    assert_eq!(seps, table[0].len(), "{md}");
    assert!(
        table.iter().skip(2).all(|r| r.len() == table[0].len()),
        "{md}"
    );
    for (row, s) in table[2..].iter().zip(schemes) {
        assert_eq!(row[0], "seed003-line2");
        assert_eq!(row[1], s["name"].as_str().unwrap());
        let mean = s["skew_mean_ns"].as_f64().unwrap();
        assert_eq!(row[5], format!("{mean:.1}"));
    }

    let svg = std::fs::read_to_string(dir.join("dc-seed003-line2.svg")).unwrap();
    assert!(svg.starts_with("<svg"));
    assert!(svg.contains(&format!("<desc>produced by: {cmd}</desc>")));
    assert!(balanced(&svg));
    assert!(
        !svg.contains("<!--"),
        "an XML comment cannot hold the command's `--`"
    );
    for name in [
        "ecdc",
        "seed000",
        "seed000-printed",
        "igh",
        "ethercrab",
        "uncompensated",
    ] {
        assert!(svg.contains(&format!(">{name}</text>")), "legend {name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// 1 % frame loss on seed 000's line: every scheme runs to the end with its stated loss
/// behaviour (docs/bench.md "Frame loss"): none stops, stalls or loses SYNC0, and the schemes
/// that send bursts did lose frames on the way.
#[test]
fn every_scheme_survives_frame_loss() {
    let (r, _) = run_scenario(
        BenchScenario::Seed000Line6Loss,
        &SchemeName::ALL,
        Some(2_000),
    )
    .unwrap();
    assert_eq!(r.frame_loss_rate, Some(0.01));
    assert_eq!(r.schemes.len(), 6);
    for s in &r.schemes {
        assert!(s.error.is_none(), "{}: {:?}", s.name, s.error);
        assert_eq!(s.sync0_slaves, 6, "{s:?}");
        assert!(s.skew_pairs > 0, "{s:?}");
        // Ran to the end of the run (no blocking step stuck past it).
        assert_eq!(s.window_end_ns, 2_000_000_000, "{s:?}");
    }
    for name in ["ecdc", "seed000", "seed000-printed", "igh", "ethercrab"] {
        let s = scheme(&r, name);
        assert!(s.frames_lost.unwrap() > 0, "{s:?}");
        // Still distributing the reference time up to the end: at least one frame per cycle
        // after the static phase (minus the lost ones).
        assert!(
            s.dist_frames > s.static_drift_frames.unwrap() + 500,
            "{s:?}"
        );
    }
    // Lost burst frames still count: the bursts keep their documented length.
    assert_eq!(scheme(&r, "seed000").static_drift_frames, Some(15_000));
    assert_eq!(
        scheme(&r, "seed000-printed").static_drift_frames,
        Some(15_000)
    );
    assert_eq!(scheme(&r, "ethercrab").static_drift_frames, Some(10_000));
    let e = scheme(&r, "ecdc");
    assert!(e.lock_frames.is_some(), "{e:?}");
    assert!(e.skew.max_ns.unwrap() < 100, "{e:?}");
}

/// The 32-bit scenario: its full 10 s cross a wrap of the reference's 32-bit system time inside
/// the steady-state window; ecdc and the IgH-like master (wrap-safe comparisons, as in the
/// Lambert patches) keep every slave on SYNC0 across it; the ethercrab-like master starts none (docs/bench.md "32-bit DC
/// slaves": the 32-bit slaves are `RefOnly`, the 64-bit ones get a start time computed from
/// the 32-bit reference's time, far in their past).
#[test]
fn dc32_scenario_crosses_a_wrap() {
    let (r, _) = run_scenario(
        BenchScenario::Line6Dc32,
        &[SchemeName::Ecdc, SchemeName::Igh, SchemeName::Ethercrab],
        None,
    )
    .unwrap();
    assert_eq!(r.dc32_slaves, Some(3));
    assert_eq!(r.duration_ns, 10_000_000_000);
    for name in ["ecdc", "igh"] {
        let s = scheme(&r, name);
        assert!(s.error.is_none(), "{s:?}");
        assert!(s.ref_wraps_in_window.unwrap() >= 1, "{s:?}");
        assert_eq!(s.sync0_slaves, 6, "{s:?}");
    }
    let e = scheme(&r, "ecdc");
    assert!(e.lock_frames.is_some(), "{e:?}");
    assert!(e.skew.max_ns.unwrap() < 100, "{e:?}");
    assert!(scheme(&r, "igh").skew.max_ns.unwrap() < 300);
    let c = scheme(&r, "ethercrab");
    assert!(c.error.is_none(), "{c:?}");
    assert_eq!(c.sync0_slaves, 0, "{c:?}");
}
