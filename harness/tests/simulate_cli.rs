//! The `ecdc simulate` binary: a scenario file in, the text report on stdout, the JSON and SVG
//! files where asked.

use std::process::Command;

fn tmpdir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("ecdc-simulate-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn scenario_file_to_json_and_svg() {
    let dir = tmpdir("cli");
    let sc = dir.join("four.toml");
    std::fs::write(
        &sc,
        "seed = 3\n[defaults]\nppm = { uniform = { min = -20.0, max = 20.0 } }\n[[slaves]]\nrepeat = 4\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_ecdc"))
        .args([
            "simulate",
            "--duration-ms",
            "500",
            "--no-progress",
            "--scenario",
        ])
        .arg(&sc)
        .arg("--out-dir")
        .arg(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for needle in [
        "offset compensation 0x0920",
        "delay compensation 0x0928",
        "drift comp. mean 0x092C",
        "clock error mean",
        "lock frames",
        "seed000",
        "seed000-printed",
        "given",
        "uncompensated",
        "targets",
    ] {
        assert!(stdout.contains(needle), "missing {needle:?} in\n{stdout}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("ecdc-simulate.json")).unwrap())
            .unwrap();
    assert_eq!(json["setup"]["slaves"], 4);
    assert_eq!(json["setup"]["seed"], 3);
    let svg = std::fs::read_to_string(dir.join("ecdc-simulate.svg")).unwrap();
    assert!(svg.starts_with("<svg"));
    assert!(svg.trim_end().ends_with("</svg>"));
    assert_eq!(
        svg.matches("<polyline").count(),
        4 * 3 + 3,
        "4 panels x 3 non-reference slaves + lock curves of ecdc and both seed000 schemes"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_scenario_is_an_error_not_a_panic() {
    let dir = tmpdir("bad");
    let sc = dir.join("bad.toml");
    std::fs::write(&sc, "frame_loss_rate = 3.0\n[[slaves]]\nrepeat = 2\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_ecdc"))
        .args(["simulate", "--no-progress", "--scenario"])
        .arg(&sc)
        .arg("--out-dir")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("frame_loss_rate"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--duration 500ms` and the older `--duration-ms 500` run the same simulation; giving both
/// is a usage error.
#[test]
fn duration_units_and_the_older_flag_agree() {
    let run = |args: &[&str], name: &str| {
        let dir = tmpdir(name);
        let out = Command::new(env!("CARGO_BIN_EXE_ecdc"))
            .args(["simulate", "--no-progress", "--slaves", "3"])
            .args(args)
            .arg("--out-dir")
            .arg(&dir)
            .output()
            .unwrap();
        (out, dir)
    };
    let (a, dir_a) = run(&["--duration", "500ms"], "dur-units");
    let (b, dir_b) = run(&["--duration-ms", "500"], "dur-ms");
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let json = |d: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("ecdc-simulate.json")).unwrap())
            .unwrap()
    };
    let (ja, jb) = (json(&dir_a), json(&dir_b));
    assert_eq!(ja["setup"]["duration_ns"], 500_000_000u64);
    assert_eq!(ja, jb);
    let (both, _) = run(&["--duration", "1s", "--duration-ms", "500"], "dur-both");
    assert_eq!(both.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&both.stderr).contains("cannot be used with"),
        "{}",
        String::from_utf8_lossy(&both.stderr)
    );
}
