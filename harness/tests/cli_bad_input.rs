//! Every bad input to the `ecdc` binary gets a clear error and the documented exit code
//! (README "Exit codes": 1 runtime, 2 usage, 3 `--check` target missed), table-wise. All
//! cases but one (a write that fails after the run, 1) are usage errors.
//!
//! Each case runs the built binary in a fresh temporary directory (also its working directory,
//! so a default output path would land there too) holding only the case's input files, with
//! every output option pointing into it. It asserts the exit code, that stderr contains the
//! given fragments (the offending flag or file and what is wrong), and that no file was
//! written. Cases on the interface subcommands (emulate, run, rtt, scan) name an interface
//! that does not exist: they must fail on the argument, before any interface is looked up.

use std::path::{Path, PathBuf};
use std::process::Command;

use ecdc_harness::capture::pcap::{LINKTYPE_ETHERNET, MAGIC_MICROS};

/// An interface name that does not exist: reaching the interface would fail differently.
const NO_IFACE: &str = "ecdcnone0";

/// What the kernel-side lookup says when an interface is missing; must never appear.
const IFACE_TOUCHED: &str = "no interface named";

struct Case {
    name: &'static str,
    /// Arguments; "{dir}" is replaced by the case's temporary directory.
    args: Vec<&'static str>,
    /// Input files created in the directory before the run.
    files: Vec<(&'static str, Vec<u8>)>,
    code: i32,
    /// Fragments stderr must contain.
    stderr: Vec<&'static str>,
}

fn case(name: &'static str, args: &[&'static str], code: i32, stderr: &[&'static str]) -> Case {
    Case {
        name,
        args: args.to_vec(),
        files: Vec::new(),
        code,
        stderr: stderr.to_vec(),
    }
}

fn with_file(mut c: Case, name: &'static str, content: impl Into<Vec<u8>>) -> Case {
    c.files.push((name, content.into()));
    c
}

/// A classic pcap global header (µs, little-endian) with this link type.
fn pcap_header(linktype: u32) -> Vec<u8> {
    let mut h = Vec::new();
    h.extend_from_slice(&MAGIC_MICROS.to_le_bytes());
    h.extend_from_slice(&2u16.to_le_bytes());
    h.extend_from_slice(&4u16.to_le_bytes());
    h.extend_from_slice(&[0; 8]);
    h.extend_from_slice(&65_535u32.to_le_bytes());
    h.extend_from_slice(&linktype.to_le_bytes());
    h
}

/// A pcap whose only record says 60 bytes but holds 10.
fn pcap_truncated() -> Vec<u8> {
    let mut f = pcap_header(LINKTYPE_ETHERNET);
    for w in [1u32, 0, 60, 60] {
        f.extend_from_slice(&w.to_le_bytes());
    }
    f.extend_from_slice(&[0xab; 10]);
    f
}

fn simulate(extra: &[&'static str]) -> Vec<&'static str> {
    let mut v = vec!["simulate", "--no-progress", "--out-dir", "{dir}"];
    v.extend_from_slice(extra);
    v
}

fn sim_case(name: &'static str, extra: &[&'static str], stderr: &[&'static str]) -> Case {
    case(name, &simulate(extra), 2, stderr)
}

/// `simulate --scenario bad.toml` with the given file content.
fn scenario_case(name: &'static str, toml: &str, stderr: &[&'static str]) -> Case {
    with_file(
        sim_case(
            name,
            &["--duration-ms", "100", "--scenario", "bad.toml"],
            stderr,
        ),
        "bad.toml",
        toml,
    )
}

fn iface_case(name: &'static str, args: &[&'static str], stderr: &[&'static str]) -> Case {
    case(name, args, 2, stderr)
}

fn cases() -> Vec<Case> {
    let two = "[[slaves]]\nrepeat = 2\n";
    vec![
        // simulate: every numeric flag, zero / negative / huge / not a number
        sim_case(
            "slaves 0",
            &["--slaves", "0"],
            &["--slaves", "valid: 2..=256"],
        ),
        sim_case(
            "slaves 1",
            &["--slaves", "1"],
            &["--slaves", "valid: 2..=256", "needs a second one"],
        ),
        sim_case(
            "slaves 300",
            &["--slaves", "300"],
            &["--slaves", "300 is out of range"],
        ),
        sim_case(
            "slaves -3",
            &["--slaves", "-3"],
            &["--slaves", "-3 is out of range"],
        ),
        sim_case(
            "slaves abc",
            &["--slaves", "abc"],
            &["--slaves", "not an integer"],
        ),
        sim_case(
            "duration 0",
            &["--duration-ms", "0"],
            &["--duration-ms", "valid: 1..=3600000"],
        ),
        sim_case(
            "duration -5",
            &["--duration-ms", "-5"],
            &["--duration-ms", "-5 is out"],
        ),
        sim_case(
            "duration huge",
            &["--duration-ms", "99999999999999"],
            &["--duration-ms", "out of range"],
        ),
        sim_case(
            "duration shorter than a cycle",
            &["--cycle-ns", "100000000", "--duration-ms", "50"],
            &["--duration-ms 50 is shorter than one cycle", "--cycle-ns"],
        ),
        sim_case(
            "cycle 0",
            &["--cycle-ns", "0"],
            &["--cycle-ns", "valid: 100000..=100000000"],
        ),
        sim_case(
            "cycle 5",
            &["--cycle-ns", "5"],
            &["--cycle-ns", "5 is out of range"],
        ),
        sim_case(
            "cycle > u32",
            &["--cycle-ns", "4294967296"],
            &["--cycle-ns", "out of range"],
        ),
        sim_case("ppm -1", &["--ppm", "-1"], &["--ppm", "valid: 0..=10000"]),
        sim_case(
            "ppm NaN",
            &["--ppm", "NaN"],
            &["--ppm", "NaN is out of range"],
        ),
        sim_case("ppm 1e9", &["--ppm", "1e9"], &["--ppm", "out of range"]),
        sim_case(
            "loss -0.5",
            &["--loss", "-0.5"],
            &["--loss", "-0.5 is out of range; valid: 0..=1"],
        ),
        sim_case(
            "loss=-0.5",
            &["--loss=-0.5"],
            &["--loss", "-0.5 is out of range; valid: 0..=1"],
        ),
        sim_case(
            "loss 2",
            &["--loss", "2"],
            &["--loss", "2 is out of range; valid: 0..=1"],
        ),
        sim_case("loss inf", &["--loss", "inf"], &["--loss", "out of range"]),
        sim_case(
            "loss text",
            &["--loss", "lots"],
            &["--loss", "not a number"],
        ),
        sim_case(
            "seed -1",
            &["--seed", "-1"],
            &["--seed", "-1 is out of range"],
        ),
        sim_case(
            "seed 1.5",
            &["--seed", "1.5"],
            &["--seed", "not an integer"],
        ),
        sim_case(
            "drift burst 0",
            &["--drift-burst-frames", "0"],
            &["--drift-burst-frames", "valid: 1..=65535"],
        ),
        sim_case(
            "drift burst 70000",
            &["--drift-burst-frames", "70000"],
            &["--drift-burst-frames", "out of range"],
        ),
        case(
            "out-dir missing",
            &[
                "simulate",
                "--duration-ms",
                "10",
                "--out-dir",
                "{dir}/nowhere",
            ],
            2,
            &["--out-dir", "nowhere", "no such directory"],
        ),
        sim_case(
            "json is a directory",
            &["--duration-ms", "10", "--json", "{dir}"],
            &["--json", "is a directory"],
        ),
        sim_case(
            "svg in a missing directory",
            &["--duration-ms", "10", "--svg", "{dir}/nowhere/x.svg"],
            &["--svg", "does not exist"],
        ),
        // a write that fails after the run is a runtime error (1), before any file is written
        case(
            "svg not writable",
            &[
                "simulate",
                "--no-progress",
                "--duration-ms",
                "10",
                "--out-dir",
                "{dir}",
                "--svg",
                "/proc/ecdc.svg",
            ],
            1,
            &["writing /proc/ecdc.svg"],
        ),
        // simulate: scenario files that are missing, unparsable or make no sense
        sim_case(
            "scenario missing",
            &["--scenario", "{dir}/absent.toml"],
            &["--scenario", "absent.toml", "no such file"],
        ),
        scenario_case(
            "scenario not TOML",
            "slaves = [[[",
            &["--scenario", "bad.toml"],
        ),
        scenario_case(
            "scenario 0 slaves",
            "seed = 1\n",
            &["bad.toml", "no slaves"],
        ),
        scenario_case(
            "scenario repeat 0",
            "[[slaves]]\nrepeat = 0\n",
            &["bad.toml", "repeat = 0"],
        ),
        scenario_case(
            "scenario 1 slave",
            "[[slaves]]\n",
            &["bad.toml", "at least 2 DC slaves"],
        ),
        scenario_case(
            "scenario 1 DC slave",
            "[[slaves]]\n[[slaves]]\nkind = \"no_dc\"\n",
            &["bad.toml", "1 with a DC system time"],
        ),
        scenario_case(
            "scenario parent missing",
            "[[slaves]]\nrepeat = 2\n[[slaves]]\nparent = 7\n",
            &[
                "bad.toml",
                "slave 2: parent 7 does not exist",
                "valid: 0..=1",
            ],
        ),
        scenario_case(
            "scenario parent on slave 0",
            "[[slaves]]\nparent = 0\n[[slaves]]\n",
            &["bad.toml", "slave 0 is cabled to the master"],
        ),
        scenario_case(
            "scenario port beyond the ESC",
            "[[slaves]]\n[[slaves]]\nparent = 0\nport = 5\n",
            &["bad.toml", "port 5 of slave 0", "valid: 1..=1"],
        ),
        scenario_case(
            "scenario 5 ports",
            "[[slaves]]\nports = 5\n[[slaves]]\n",
            &["bad.toml", "ports = 5", "2..=4"],
        ),
        scenario_case(
            "scenario loss 3",
            "frame_loss_rate = 3.0\n[[slaves]]\nrepeat = 2\n",
            &["bad.toml", "frame_loss_rate = 3", "0..=1"],
        ),
        scenario_case(
            "scenario ppm min > max",
            "[defaults]\nppm = { uniform = { min = 5.0, max = -5.0 } }\n[[slaves]]\nrepeat = 2\n",
            &["bad.toml", "min 5 > max -5"],
        ),
        scenario_case(
            "scenario negative cable",
            "[[slaves]]\nrepeat = 2\ncable_m = -1.0\n",
            &["bad.toml", "cable_m = -1", ">= 0"],
        ),
        scenario_case(
            "fault after the run",
            &format!("{two}[[faults]]\nat_ns = 5_000_000_000\nkind = \"power_off\"\nslave = 1\n"),
            &[
                "bad.toml",
                "faults[0] (power_off)",
                "after the end of the run",
            ],
        ),
        scenario_case(
            "fault of unknown kind",
            &format!("{two}[[faults]]\nat_ns = 1\nkind = \"meteor_strike\"\n"),
            &["bad.toml", "unknown variant `meteor_strike`", "link_break"],
        ),
        scenario_case(
            "fault on a missing slave",
            &format!("{two}[[faults]]\nat_ns = 1\nkind = \"link_break\"\nslave = 9\nport = 0\n"),
            &["bad.toml", "slave 9 does not exist", "valid: 0..=1"],
        ),
        scenario_case(
            "fault on a missing port",
            &format!("{two}[[faults]]\nat_ns = 1\nkind = \"link_break\"\nslave = 0\nport = 3\n"),
            &["bad.toml", "slave 0 has ports 0..=1, not 3"],
        ),
        scenario_case(
            "fault loss rate 2",
            &format!("{two}[[faults]]\nat_ns = 1\nkind = \"frame_loss_rate\"\nrate = 2.0\n"),
            &["bad.toml", "rate = 2", "0..=1"],
        ),
        with_file(
            sim_case(
                "JSON scenario with no slaves",
                &["--scenario", "bad.json"],
                &["bad.json", "no slaves"],
            ),
            "bad.json",
            "{\"seed\": 1}",
        ),
        // bench dc
        case(
            "bench duration 0",
            &["bench", "dc", "--out", "{dir}/b", "--duration-ms", "0"],
            2,
            &["--duration-ms", "valid: 1..=3600000"],
        ),
        case(
            "bench duration -1",
            &["bench", "dc", "--out", "{dir}/b", "--duration-ms", "-1"],
            2,
            &["--duration-ms", "-1 is out of range"],
        ),
        with_file(
            case(
                "bench out is a file",
                &["bench", "dc", "--out", "{dir}/plain", "--duration-ms", "10"],
                2,
                &["--out", "plain", "not a directory"],
            ),
            "plain",
            "x",
        ),
        case(
            "bench check without ecdc",
            &[
                "bench", "dc", "--out", "{dir}/b", "--check", "--scheme", "igh",
            ],
            2,
            &["--check", "--scheme ecdc"],
        ),
        // bench sensitivity
        case(
            "sensitivity duration 0",
            &[
                "bench",
                "sensitivity",
                "--out",
                "{dir}/s",
                "--duration-ms",
                "0",
            ],
            2,
            &["--duration-ms", "valid: 1..=3600000"],
        ),
        with_file(
            case(
                "sensitivity out is a file",
                &[
                    "bench",
                    "sensitivity",
                    "--out",
                    "{dir}/plain",
                    "--duration-ms",
                    "10",
                ],
                2,
                &["--out", "plain", "not a directory"],
            ),
            "plain",
            "x",
        ),
        // decode: files that are not (whole) captures, bad hex
        with_file(
            case(
                "decode empty file",
                &["decode", "{dir}/empty.pcap"],
                2,
                &["empty.pcap", "empty file: not a pcap capture"],
            ),
            "empty.pcap",
            Vec::new(),
        ),
        with_file(
            case(
                "decode short text file",
                &["decode", "{dir}/hostname"],
                2,
                &["hostname", "not a pcap capture (magic 0x6f68796d"],
            ),
            "hostname",
            "myhost\n",
        ),
        with_file(
            case(
                "decode 2-byte file",
                &["decode", "{dir}/two"],
                2,
                &[
                    "two",
                    "not a pcap capture: 2 bytes, shorter than the 24-byte pcap header",
                ],
            ),
            "two",
            "ab",
        ),
        with_file(
            case(
                "decode text file",
                &["decode", "{dir}/notes.txt"],
                2,
                &["notes.txt", "not a pcap capture (magic 0x73696874"],
            ),
            "notes.txt",
            "this is a text file, not a capture at all\n",
        ),
        with_file(
            case(
                "decode cut header",
                &["decode", "{dir}/cut.pcap"],
                2,
                &["cut.pcap", "truncated pcap capture: 10 bytes"],
            ),
            "cut.pcap",
            pcap_header(LINKTYPE_ETHERNET)[..10].to_vec(),
        ),
        with_file(
            case(
                "decode header only",
                &["decode", "{dir}/none.pcap"],
                2,
                &["none.pcap", "holds no frames"],
            ),
            "none.pcap",
            pcap_header(LINKTYPE_ETHERNET),
        ),
        with_file(
            case(
                "decode truncated record",
                &["decode", "{dir}/trunc.pcap"],
                2,
                &["trunc.pcap", "record 0: file ends inside the record"],
            ),
            "trunc.pcap",
            pcap_truncated(),
        ),
        with_file(
            case(
                "decode Linux cooked capture",
                &["decode", "{dir}/any.pcap"],
                2,
                &["any.pcap", "link type 113 is not Ethernet"],
            ),
            "any.pcap",
            pcap_header(113),
        ),
        with_file(
            case(
                "decode pcapng with a bad section header",
                &["decode", "{dir}/x.pcapng"],
                2,
                &["x.pcapng", "pcapng block 0"],
            ),
            "x.pcapng",
            {
                let mut v = vec![0x0a, 0x0d, 0x0d, 0x0a];
                v.resize(32, 0);
                v
            },
        ),
        case(
            "decode directory",
            &["decode", "{dir}"],
            2,
            &["is a directory"],
        ),
        case(
            "decode missing capture",
            &["decode", "{dir}/absent.pcap"],
            2,
            &["absent.pcap", "no such file"],
        ),
        case(
            "decode odd hex",
            &["decode", "abc"],
            2,
            &["\"abc\"", "odd number of hex digits"],
        ),
        case(
            "decode bad hex digit",
            &["decode", "zz"],
            2,
            &["\"zz\"", "invalid hex digit"],
        ),
        // emulate: flags and scenario, before the interface
        iface_case(
            "emulate slaves 0",
            &["emulate", "-i", NO_IFACE, "--slaves", "0"],
            &["--slaves", "valid: 1..=65535"],
        ),
        iface_case(
            "emulate slaves 70000",
            &["emulate", "-i", NO_IFACE, "--slaves", "70000"],
            &["--slaves", "out of range"],
        ),
        iface_case(
            "emulate loss -0.1",
            &["emulate", "-i", NO_IFACE, "--loss-rate", "-0.1"],
            &["--loss-rate", "-0.1 is out of range; valid: 0..=1"],
        ),
        iface_case(
            "emulate loss 1.5",
            &["emulate", "-i", NO_IFACE, "--loss-rate", "1.5"],
            &["--loss-rate", "out of range"],
        ),
        iface_case(
            "emulate duration 0",
            &["emulate", "-i", NO_IFACE, "--duration", "0"],
            &["--duration", "0 s is out of range", "omit the flag"],
        ),
        iface_case(
            "emulate duration -1",
            &["emulate", "-i", NO_IFACE, "--duration", "-1"],
            &["--duration", "-1 s is out of range"],
        ),
        iface_case(
            "emulate duration NaN",
            &["emulate", "-i", NO_IFACE, "--duration", "NaN"],
            &["--duration", "out of range"],
        ),
        iface_case(
            "emulate seed -1",
            &["emulate", "-i", NO_IFACE, "--seed", "-1"],
            &["--seed", "out of range"],
        ),
        with_file(
            iface_case(
                "emulate slaves with scenario",
                &[
                    "emulate",
                    "-i",
                    NO_IFACE,
                    "--slaves",
                    "3",
                    "--scenario",
                    "{dir}/ok.toml",
                ],
                &["--slaves", "cannot be used with", "--scenario"],
            ),
            "ok.toml",
            two,
        ),
        with_file(
            iface_case(
                "emulate scenario fault on a missing slave",
                &["emulate", "-i", NO_IFACE, "--scenario", "{dir}/bad.toml"],
                &["bad.toml", "slave 9 does not exist"],
            ),
            "bad.toml",
            format!("{two}[[faults]]\nat_ns = 1\nkind = \"power_off\"\nslave = 9\n"),
        ),
        with_file(
            iface_case(
                "emulate fault after --duration",
                &[
                    "emulate",
                    "-i",
                    NO_IFACE,
                    "--duration",
                    "1",
                    "--scenario",
                    "{dir}/late.toml",
                ],
                &["late.toml", "after the end of the run"],
            ),
            "late.toml",
            format!("{two}[[faults]]\nat_ns = 2_000_000_000\nkind = \"power_off\"\nslave = 1\n"),
        ),
        iface_case(
            "emulate reflect with a seed",
            &[
                "emulate", "-i", NO_IFACE, "--engine", "reflect", "--seed", "3",
            ],
            &["--seed", "no effect with --engine reflect"],
        ),
        iface_case(
            "emulate missing scenario",
            &["emulate", "-i", NO_IFACE, "--scenario", "{dir}/absent.toml"],
            &["--scenario", "absent.toml", "no such file"],
        ),
        iface_case(
            "priority 0",
            &["emulate", "-i", NO_IFACE, "--rt", "--priority", "0"],
            &["--priority", "1..=99"],
        ),
        iface_case(
            "priority 100",
            &["run", "-i", NO_IFACE, "--rt", "--priority", "100"],
            &["--priority", "1..=99"],
        ),
        iface_case(
            "priority -5",
            &["rtt", "-i", NO_IFACE, "--rt", "--priority", "-5"],
            &["--priority", "1..=99"],
        ),
        iface_case(
            "cpu -1",
            &["run", "-i", NO_IFACE, "--rt", "--cpu", "-1"],
            &["--cpu", "-1 is out of range"],
        ),
        iface_case(
            "cpu 4096",
            &["rtt", "-i", NO_IFACE, "--rt", "--cpu", "4096"],
            &["--cpu", "valid: 0..=1023"],
        ),
        iface_case(
            "cpu not online",
            &["emulate", "-i", NO_IFACE, "--rt", "--cpu", "1023"],
            &["--cpu 1023", "CPU(s) online"],
        ),
        iface_case(
            "iface empty",
            &["scan", "-i", ""],
            &["--iface", "empty interface name"],
        ),
        iface_case(
            "iface too long",
            &["scan", "--iface", "sixteen-chars-xx"],
            &["--iface", "at most 15 bytes"],
        ),
        iface_case(
            "iface with slash",
            &["run", "--iface", "a/b"],
            &["--iface", "not a valid interface name"],
        ),
        iface_case(
            "iface with space",
            &["rtt", "--iface", "eth 1"],
            &["--iface", "not a valid interface name"],
        ),
        // run
        iface_case(
            "run cycle 0",
            &["run", "-i", NO_IFACE, "--cycle-us", "0"],
            &["--cycle-us", "valid: 100..=100000"],
        ),
        iface_case(
            "run cycle 50",
            &["run", "-i", NO_IFACE, "--cycle-us", "50"],
            &["--cycle-us", "50 is out of range"],
        ),
        iface_case(
            "run cycle 200000",
            &["run", "-i", NO_IFACE, "--cycle-us", "200000"],
            &["--cycle-us", "out of range"],
        ),
        iface_case(
            "run duration 0",
            &["run", "-i", NO_IFACE, "--duration", "0"],
            &["--duration", "out of range"],
        ),
        iface_case(
            "run target beyond a cycle",
            &["run", "-i", NO_IFACE, "--target-ns", "2000000"],
            &["--target-ns 2000000", "within ± one cycle"],
        ),
        iface_case(
            "run target huge negative",
            &["run", "-i", NO_IFACE, "--target-ns", "-99999999999"],
            &["--target-ns", "out of range"],
        ),
        iface_case(
            "run max lost cycles 0",
            &["run", "-i", NO_IFACE, "--max-lost-cycles", "0"],
            &["--max-lost-cycles", "valid: 1..=65535"],
        ),
        iface_case(
            "run max lost cycles -1",
            &["run", "-i", NO_IFACE, "--max-lost-cycles", "-1"],
            &["--max-lost-cycles", "-1 is out of range"],
        ),
        iface_case(
            "run spin as long as the cycle",
            &["run", "-i", NO_IFACE, "--spin-us", "1000"],
            &["--spin-us 1000", "less than the cycle"],
        ),
        iface_case(
            "run pcap in a missing directory",
            &["run", "-i", NO_IFACE, "--pcap", "{dir}/nowhere/run.pcap"],
            &["--pcap", "does not exist"],
        ),
        iface_case(
            "run pcap is a directory",
            &["run", "-i", NO_IFACE, "--pcap", "{dir}"],
            &["--pcap", "is a directory"],
        ),
        // rtt
        iface_case(
            "rtt count -1",
            &["rtt", "-i", NO_IFACE, "--count", "-1"],
            &["--count", "-1 is out of range"],
        ),
        iface_case(
            "rtt cycles -5",
            &["rtt", "-i", NO_IFACE, "--cycles", "-5"],
            &["--cycles", "-5 is out of range"],
        ),
        iface_case(
            "rtt nothing to measure",
            &["rtt", "-i", NO_IFACE, "--count", "0", "--cycles", "0"],
            &["--count 0 and --cycles 0", "nothing to measure"],
        ),
        iface_case(
            "rtt cycle 0",
            &["rtt", "-i", NO_IFACE, "--cycle-us", "0"],
            &["--cycle-us", "valid: 100..=100000"],
        ),
        iface_case(
            "rtt timeout 0",
            &["rtt", "-i", NO_IFACE, "--timeout-us", "0"],
            &["--timeout-us", "valid: 1..=10000000"],
        ),
        iface_case(
            "rtt processed-bit MAC",
            &["rtt", "-i", NO_IFACE, "--source-mac", "02:00:00:00:00:01"],
            &["--source-mac", "bit 0x02"],
        ),
        iface_case(
            "rtt malformed MAC",
            &["rtt", "-i", NO_IFACE, "--source-mac", "zz:00"],
            &["--source-mac", "six hex octets"],
        ),
    ]
}

fn fresh_dir(k: usize) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ecdc-bad-input-{}-{k}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Every entry under `dir`, recursively, relative to it.
fn listing(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            out.push(p.strip_prefix(dir).unwrap().display().to_string());
            if p.is_dir() {
                stack.push(p);
            }
        }
    }
    out.sort();
    out
}

struct Run {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    after: Vec<String>,
}

fn run_in(dir: &Path, args: &[String]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_ecdc"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    Run {
        code: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        after: listing(dir),
    }
}

fn expand(args: &[&str], dir: &Path) -> Vec<String> {
    let d = dir.display().to_string();
    args.iter().map(|a| a.replace("{dir}", &d)).collect()
}

#[test]
fn every_bad_input_is_a_usage_error_that_says_why() {
    let mut failures = Vec::new();
    for (k, c) in cases().iter().enumerate() {
        let dir = fresh_dir(k);
        for (name, content) in &c.files {
            std::fs::write(dir.join(name), content).unwrap();
        }
        let before = listing(&dir);
        let r = run_in(&dir, &expand(&c.args, &dir));
        // The message table of the issue (shown with --nocapture).
        println!(
            "{:<44} exit {:?}: {}",
            c.name,
            r.code,
            r.stderr.lines().next().unwrap_or("")
        );
        let mut why = Vec::new();
        if r.code != Some(c.code) {
            why.push(format!("exit {:?}, want {}", r.code, c.code));
        }
        for frag in &c.stderr {
            if !r.stderr.contains(frag) {
                why.push(format!("stderr lacks {frag:?}"));
            }
        }
        if r.stderr.contains(IFACE_TOUCHED) {
            why.push("reached the interface lookup".into());
        }
        if !r.stderr.starts_with("error: ") {
            why.push("stderr does not start with \"error: \"".into());
        }
        if r.after != before {
            why.push(format!("files changed: {before:?} -> {:?}", r.after));
        }
        if !why.is_empty() {
            failures.push(format!(
                "[{}] {:?}: {}\n--- stdout\n{}--- stderr\n{}",
                c.name,
                c.args,
                why.join("; "),
                r.stdout,
                r.stderr
            ));
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    assert!(
        failures.is_empty(),
        "{} case(s) failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The same harness accepts good input: a valid run exits 0 and writes its files, so the
/// table above fails for its inputs, not because every run fails.
#[test]
fn good_input_runs_and_writes() {
    let dir = fresh_dir(10_000);
    let r = run_in(
        &dir,
        &expand(&simulate(&["--slaves", "2", "--duration-ms", "50"]), &dir),
    );
    assert_eq!(r.code, Some(0), "{}\n{}", r.stdout, r.stderr);
    assert_eq!(r.after, ["ecdc-simulate.json", "ecdc-simulate.svg"]);
    // Without --check a missed target is reported and the exit status stays 0.
    assert!(r.stdout.contains("[MISSED]"), "{}", r.stdout);
    // Input that passes validation reaches the interface lookup, whose message the table
    // above must never show: a missing interface is a runtime error (1).
    let r = run_in(&dir, &expand(&["scan", "-i", NO_IFACE], &dir));
    assert_eq!(r.code, Some(1), "{}", r.stderr);
    assert!(r.stderr.contains(IFACE_TOUCHED), "{}", r.stderr);
    let r = run_in(&dir, &expand(&["decode", "0x00"], &dir));
    assert_eq!(
        r.code,
        Some(1),
        "a frame too short for Ethernet is invalid: {}",
        r.stderr
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--check`: a run too short to lock (20 ms: ecdc locks after ~50 ms) misses its targets,
/// writes its files anyway and exits 3.
#[test]
fn check_exits_3_on_a_missed_target() {
    let dir = fresh_dir(10_001);
    let r = run_in(
        &dir,
        &expand(&simulate(&["--duration-ms", "20", "--check"]), &dir),
    );
    assert_eq!(r.code, Some(3), "{}\n{}", r.stdout, r.stderr);
    assert!(
        r.stderr.contains("--check:") && r.stderr.contains("ecdc lock frames"),
        "{}",
        r.stderr
    );
    assert_eq!(r.after, ["ecdc-simulate.json", "ecdc-simulate.svg"]);
    let r = run_in(
        &dir,
        &expand(
            &[
                "bench",
                "dc",
                "--out",
                "{dir}/b",
                "--scenario",
                "seed003-line2",
                "--scheme",
                "ecdc",
                "--duration-ms",
                "50",
                "--check",
            ],
            &dir,
        ),
    );
    assert_eq!(r.code, Some(3), "{}\n{}", r.stdout, r.stderr);
    assert!(
        r.stderr.contains("seed003-line2: ecdc never locked"),
        "{}",
        r.stderr
    );
    assert!(r.after.contains(&"b/dc.json".to_string()), "{:?}", r.after);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The validator accepts every scenario file shipped in harness/scenarios (open-ended run).
#[test]
fn shipped_scenarios_validate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        let sc = ecdc_harness::emu::Scenario::load(&p).unwrap();
        sc.validate(None)
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        n += 1;
    }
    assert!(n >= 5, "{n} scenario files");
}
