//! Input checks shared by the subcommands, run before any work starts (no file written, no
//! interface opened), and the errors that choose the process exit code.
//!
//! Exit codes (README "Exit codes"): 0 success, 1 runtime or I/O error, 2 usage error (clap's
//! own parse errors and every [`UsageError`]), 3 a `--check` run that missed a stated target
//! ([`TargetsMissed`]). Value parsers for clap live here too, so that every numeric flag states
//! its valid range when it rejects a value; flags that may be given a negative number use
//! `allow_negative_numbers` so that `--loss -0.5` reaches the parser (and gets the range
//! message) instead of being taken for an unknown flag.

use std::fmt;
use std::path::Path;

use crate::emu::Scenario;

/// Exit code of a run that worked.
pub const EXIT_OK: u8 = 0;
/// Exit code of a runtime or I/O error (the input was acceptable, the run failed).
pub const EXIT_RUNTIME: u8 = 1;
/// Exit code of a usage error: a flag value, a file or a scenario rejected before the run.
/// The same code clap uses for its own parse errors.
pub const EXIT_USAGE: u8 = 2;
/// Exit code of `simulate --check` / `bench dc --check` when a stated target was missed.
/// ecdc choice: distinct from 1 so that CI can tell "worse than promised" from "broken".
pub const EXIT_TARGETS_MISSED: u8 = 3;

/// Bad input: the message says what is wrong and the valid range or the fix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsageError(pub String);

impl fmt::Display for UsageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// A `--check` run missed stated targets (the report was still printed and written).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TargetsMissed(pub Vec<String>);

impl fmt::Display for TargetsMissed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "--check: {} target(s) missed: ", self.0.len())?;
        f.write_str(&self.0.join("; "))
    }
}

impl std::error::Error for TargetsMissed {}

/// A [`UsageError`] as an `anyhow::Error`.
pub fn usage(msg: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(UsageError(msg.into()))
}

/// The process exit code for an error returned by a subcommand.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    if e.downcast_ref::<UsageError>().is_some() {
        EXIT_USAGE
    } else if e.downcast_ref::<TargetsMissed>().is_some() {
        EXIT_TARGETS_MISSED
    } else {
        EXIT_RUNTIME
    }
}

/// Parses an integer of any sign first, so that a negative or too large value is reported
/// against the range rather than as "invalid digit".
fn int_in(s: &str, lo: i128, hi: i128) -> Result<i128, String> {
    let t = s.trim().replace('_', "");
    let v: i128 = t
        .parse()
        .map_err(|_| format!("not an integer; valid: {lo}..={hi}"))?;
    if v < lo || v > hi {
        return Err(format!("{v} is out of range; valid: {lo}..={hi}"));
    }
    Ok(v)
}

/// Value parser for an unsigned integer flag with an inclusive range.
pub fn u64_in(lo: u64, hi: u64) -> impl Fn(&str) -> Result<u64, String> + Clone + Send + Sync {
    move |s| int_in(s, i128::from(lo), i128::from(hi)).map(|v| u64::try_from(v).unwrap_or(hi))
}

/// [`u64_in`] for `usize` flags.
pub fn usize_in(
    lo: usize,
    hi: usize,
) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync {
    move |s| {
        let (l, h) = (lo as i128, hi as i128);
        int_in(s, l, h).map(|v| usize::try_from(v).unwrap_or(hi))
    }
}

/// [`u64_in`] for `u32` flags.
pub fn u32_in(lo: u32, hi: u32) -> impl Fn(&str) -> Result<u32, String> + Clone + Send + Sync {
    move |s| int_in(s, i128::from(lo), i128::from(hi)).map(|v| u32::try_from(v).unwrap_or(hi))
}

/// [`u64_in`] for `u16` flags.
pub fn u16_in(lo: u16, hi: u16) -> impl Fn(&str) -> Result<u16, String> + Clone + Send + Sync {
    move |s| int_in(s, i128::from(lo), i128::from(hi)).map(|v| u16::try_from(v).unwrap_or(hi))
}

/// [`u64_in`] for signed `i64` flags.
pub fn i64_in(lo: i64, hi: i64) -> impl Fn(&str) -> Result<i64, String> + Clone + Send + Sync {
    move |s| int_in(s, i128::from(lo), i128::from(hi)).map(|v| i64::try_from(v).unwrap_or(hi))
}

/// Value parser for a finite floating-point flag in `[lo, hi]` (NaN and infinities rejected).
pub fn f64_in(lo: f64, hi: f64) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |s| {
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("not a number; valid: {lo}..={hi}"))?;
        if !v.is_finite() || v < lo || v > hi {
            return Err(format!("{v} is out of range; valid: {lo}..={hi}"));
        }
        Ok(v)
    }
}

/// One duration syntax for every subcommand: a number and a unit, `ns`, `us` (or `µs`), `ms`,
/// `s`, `min` or `h` (`10s`, `500ms`, `2.5s`, `1min`), or a bare number of seconds. Returns
/// ns; finite, > 0, and short enough that the ns fit a u64 (the runtime's time type).
pub fn duration_ns(s: &str) -> Result<u64, String> {
    /// u64::MAX ns in whole seconds.
    const MAX_S: f64 = 18_446_744_073.0;
    const HINT: &str = "give a number and a unit: ns, us, ms, s, min, h (10s, 500ms; a bare \
                        number is seconds)";
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E')))
        .filter(|&i| {
            // "1e3s": the exponent's e belongs to the number; "NaN"/"inf" have no unit.
            i > 0
        })
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let scale_ns = match unit.trim() {
        "" | "s" => 1e9,
        "ns" => 1.0,
        "us" | "µs" => 1e3,
        "ms" => 1e6,
        "min" => 60e9,
        "h" => 3600e9,
        other => return Err(format!("unknown unit {other:?}; {HINT}")),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("not a duration; {HINT}"))?;
    let secs = v * scale_ns / 1e9;
    if !secs.is_finite() || secs <= 0.0 || secs > MAX_S {
        return Err(format!(
            "{secs} s is out of range; valid: > 0 and <= {MAX_S} s (omit the flag to run until Ctrl-C)"
        ));
    }
    let ns = (v * scale_ns).round();
    if ns < 1.0 {
        return Err(format!("{s:?} is shorter than 1 ns"));
    }
    Ok(ns as u64)
}

/// Value parser for a run length in seconds ([`duration_ns`]'s syntax; a bare number is
/// seconds, as before units were accepted).
pub fn seconds(s: &str) -> Result<f64, String> {
    duration_ns(s).map(|ns| ns as f64 / 1e9)
}

/// `--duration` and its older spelling `--duration-ms`, for the commands whose runs each have
/// their own default length (`bench dc`, `bench sensitivity`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::Args)]
pub struct DurationOverride {
    /// Simulated duration of every run: `10s`, `500ms` (a bare number is seconds), whole ms
    /// from 1ms to 1h [default: each run's own length].
    #[arg(long, allow_negative_numbers = true, conflicts_with = "duration_ms",
          value_parser = duration_ms)]
    pub duration: Option<u64>,
    /// The same in ms (1..=3600000): the older spelling of `--duration`.
    #[arg(long, allow_negative_numbers = true, value_parser = u64_in(1, MAX_DURATION_MS))]
    pub duration_ms: Option<u64>,
}

impl DurationOverride {
    /// The duration given, in ms, whichever spelling gave it.
    pub fn ms(&self) -> Option<u64> {
        self.duration.or(self.duration_ms)
    }
}

/// Value parser for a simulated duration in whole ms, 1..=[`MAX_DURATION_MS`], written with
/// [`duration_ns`]'s syntax (`simulate --duration 10s`).
pub fn duration_ms(s: &str) -> Result<u64, String> {
    let ns = duration_ns(s)?;
    if ns % 1_000_000 != 0 {
        return Err(format!(
            "{s}: simulated runs last whole milliseconds (give e.g. 10s or 2500ms)"
        ));
    }
    let ms = ns / 1_000_000;
    if !(1..=MAX_DURATION_MS).contains(&ms) {
        return Err(format!(
            "{ms} ms is out of range; valid: 1ms..=1h ({MAX_DURATION_MS} ms)"
        ));
    }
    Ok(ms)
}

/// Value parser for `--iface`: the kernel's rule for interface names (Linux net/core/dev.c
/// `dev_valid_name`: 1 to 15 bytes, IFNAMSIZ 16 with the NUL; not "." or ".."; no '/', ':' or
/// whitespace; docs/background/cli-inputs.md). Checked here so a bad name fails before any
/// socket is opened.
pub fn iface_name(s: &str) -> Result<String, String> {
    const IFNAMSIZ: usize = 16;
    if s.is_empty() {
        return Err("empty interface name; give one such as eth1 (see `ip link`)".into());
    }
    if s.len() >= IFNAMSIZ {
        return Err(format!(
            "interface names are at most {} bytes on Linux, {s:?} has {}",
            IFNAMSIZ - 1,
            s.len()
        ));
    }
    if s == "." || s == ".." || s.chars().any(|c| c == '/' || c == ':' || c.is_whitespace()) {
        return Err(format!(
            "{s:?} is not a valid interface name (no '/', ':' or whitespace, not . or ..)"
        ));
    }
    Ok(s.to_owned())
}

/// `--cpu` must name an online CPU (checked before an interface is opened).
pub fn cpu(flag: &str, cpu: Option<usize>) -> anyhow::Result<()> {
    if let Some(c) = cpu {
        let n = crate::runtime::sys::cpus_online();
        if c >= n {
            return Err(usage(format!(
                "{flag} {c}: this machine has {n} CPU(s) online; valid: 0..={}",
                n.saturating_sub(1)
            )));
        }
    }
    Ok(())
}

/// A file an option will create: its directory must exist and the path must not be a
/// directory. Checked before the run so that a long run does not end in a write error.
pub fn out_file(flag: &str, path: &Path) -> anyhow::Result<()> {
    if path.is_dir() {
        return Err(usage(format!(
            "{flag} {}: is a directory; give a file path",
            path.display()
        )));
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(usage(format!(
            "{flag} {}: directory {} does not exist; create it first",
            path.display(),
            dir.display()
        )));
    }
    Ok(())
}

/// A directory an option writes into: it must exist and be a directory.
pub fn out_dir(flag: &str, path: &Path) -> anyhow::Result<()> {
    if !path.exists() {
        return Err(usage(format!(
            "{flag} {}: no such directory; create it first",
            path.display()
        )));
    }
    if !path.is_dir() {
        return Err(usage(format!("{flag} {}: not a directory", path.display())));
    }
    Ok(())
}

/// A directory an option creates if missing: an existing non-directory is refused.
pub fn creatable_dir(flag: &str, path: &Path) -> anyhow::Result<()> {
    if path.exists() && !path.is_dir() {
        return Err(usage(format!(
            "{flag} {}: exists and is not a directory",
            path.display()
        )));
    }
    Ok(())
}

/// Loads a scenario file given with `flag`; a missing, unreadable or unparsable file is a
/// usage error naming the file.
pub fn load_scenario(flag: &str, path: &Path) -> anyhow::Result<Scenario> {
    if !path.is_file() {
        let what = if path.exists() {
            "not a regular file"
        } else {
            "no such file"
        };
        return Err(usage(format!("{flag} {}: {what}", path.display())));
    }
    Scenario::load(path).map_err(|e| usage(format!("{flag} {}: {e}", path.display())))
}

/// Checks a scenario after the command line's overrides: [`Scenario::validate`] against the
/// run length (`None` = until stopped), naming the file (or "the built-in scenario").
pub fn scenario(sc: &Scenario, source: Option<&Path>, run_ns: Option<u64>) -> anyhow::Result<()> {
    sc.validate(run_ns).map_err(|e| match source {
        Some(p) => usage(format!("--scenario {}: {e}", p.display())),
        None => usage(format!("scenario from the flags: {e}")),
    })
}

/// Fewest slaves `simulate` runs: SYNC0 skew is each slave's edge minus the reference's, so
/// one slave has nothing to be skewed against (ecdc choice: refuse rather than print an empty
/// skew table).
pub const SIMULATE_MIN_SLAVES: usize = 2;

/// Value parser for `simulate --slaves`: [`SIMULATE_MIN_SLAVES`]..=ecdc's capacity, with the
/// reason for the lower bound in the message.
pub fn simulate_slaves_flag(s: &str) -> Result<usize, String> {
    let cap = crate::schemes::ecdc::CAPACITY;
    usize_in(SIMULATE_MIN_SLAVES, cap)(s).map_err(|e| {
        format!(
            "{e} (SYNC0 skew is measured against the reference slave, so it needs a second one)"
        )
    })
}

/// `simulate --cycle-ns` range, ns: 100 µs ..= 100 ms, the range `ecdc run --cycle-us`
/// accepts (ecdc choice: the cycles the runtime is built and tested for; below 100 µs a
/// 6-slave frame and the emulator's sampling period no longer fit a cycle comfortably).
pub const CYCLE_NS: (u32, u32) = (100_000, 100_000_000);

/// `ecdc run` / `ecdc rtt --cycle-us` range, µs (the same range as [`CYCLE_NS`]).
pub const CYCLE_US: (u64, u64) = (100, 100_000);

/// Longest `simulate` / `bench dc --duration-ms`: one hour of simulated time. ecdc choice:
/// the run keeps every cycle's samples in memory (about 10 bytes per slave and cycle per
/// scheme), so an hour of the default scenario is a few hundred MB; a longer value is far
/// more likely a unit slip (µs or ns for ms) than an experiment.
pub const MAX_DURATION_MS: u64 = 3_600_000;

/// Largest `simulate --ppm`. ecdc choice: 13 × the ESC's ≈ ±763 ppm rate-correction range
/// (REQ-ESC-056); beyond it no scheme can hold the clocks, so a larger value is a typo (ppb
/// given for ppm) rather than an experiment. Scenario files may go further
/// ([`crate::emu::scenario::MAX_ABS_PPM`]).
pub const MAX_PPM: f64 = 10_000.0;

/// The checks `simulate`'s clap parsers make, repeated for callers that build
/// [`super::simulate::Args`] in code, plus the ones that involve two flags.
pub fn simulate_args(a: &super::simulate::Args) -> anyhow::Result<()> {
    if let Some(n) = a.slaves {
        let cap = crate::schemes::ecdc::CAPACITY;
        if !(SIMULATE_MIN_SLAVES..=cap).contains(&n) {
            return Err(usage(format!(
                "--slaves {n}: valid: {SIMULATE_MIN_SLAVES}..={cap} (SYNC0 skew is measured \
                 between slaves, so it needs at least {SIMULATE_MIN_SLAVES})"
            )));
        }
    }
    if !(CYCLE_NS.0..=CYCLE_NS.1).contains(&a.cycle_ns) {
        return Err(usage(format!(
            "--cycle-ns {}: valid: {}..={}",
            a.cycle_ns, CYCLE_NS.0, CYCLE_NS.1
        )));
    }
    if !(1..=MAX_DURATION_MS).contains(&a.duration_ms) {
        return Err(usage(format!(
            "--duration-ms {}: valid: 1..={MAX_DURATION_MS}",
            a.duration_ms
        )));
    }
    if a.duration_ms.saturating_mul(1_000_000) < u64::from(a.cycle_ns) {
        return Err(usage(format!(
            "--duration-ms {} is shorter than one cycle (--cycle-ns {})",
            a.duration_ms, a.cycle_ns
        )));
    }
    if let Some(p) = a.ppm {
        if !(p.is_finite() && (0.0..=MAX_PPM).contains(&p)) {
            return Err(usage(format!("--ppm {p}: valid: 0..={MAX_PPM}")));
        }
    }
    if let Some(l) = a.loss {
        if !(0.0..=1.0).contains(&l) {
            return Err(usage(format!("--loss {l}: valid: 0..=1")));
        }
    }
    if a.drift_burst_frames == Some(0) {
        return Err(usage("--drift-burst-frames 0: valid: 1..=65535"));
    }
    Ok(())
}

/// `simulate`'s requirement on the resolved scenario: between [`SIMULATE_MIN_SLAVES`] and
/// ecdc's capacity slaves, at least two of them with a DC system time (the reference and one
/// slave to compare with it).
pub fn simulate_slaves(
    slaves: &[crate::emu::scenario::ResolvedSlave],
    source: Option<&Path>,
) -> anyhow::Result<()> {
    let from = match source {
        Some(p) => format!("--scenario {}", p.display()),
        None => "the scenario".to_string(),
    };
    let cap = crate::schemes::ecdc::CAPACITY;
    let dc = slaves.iter().filter(|s| s.kind.has_system_time()).count();
    if slaves.len() > cap {
        return Err(usage(format!(
            "{from}: {} slaves; ecdc simulate runs at most {cap}",
            slaves.len()
        )));
    }
    if dc < SIMULATE_MIN_SLAVES {
        return Err(usage(format!(
            "{from}: {} slave(s), {dc} with a DC system time; SYNC0 skew needs at least \
             {SIMULATE_MIN_SLAVES} DC slaves (the reference and one to compare with it)",
            slaves.len()
        )));
    }
    Ok(())
}

/// `bench dc`'s checks, before the output directory is created.
pub fn bench_dc_args(a: &super::bench::DcArgs) -> anyhow::Result<()> {
    if let Some(d) = a.duration.ms() {
        if !(1..=MAX_DURATION_MS).contains(&d) {
            return Err(usage(format!(
                "--duration-ms {d}: valid: 1..={MAX_DURATION_MS}"
            )));
        }
    }
    creatable_dir("--out", &a.out)?;
    if a.check && !a.schemes.is_empty() && !a.schemes.contains(&super::bench::SchemeName::Ecdc) {
        return Err(usage(
            "--check holds ecdc to its targets: add --scheme ecdc (or give no --scheme)",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_duration_syntax() {
        assert_eq!(duration_ns("10s"), Ok(10_000_000_000));
        assert_eq!(duration_ns("10"), Ok(10_000_000_000));
        assert_eq!(duration_ns(" 2.5 s "), Ok(2_500_000_000));
        assert_eq!(duration_ns("500ms"), Ok(500_000_000));
        assert_eq!(duration_ns("250us"), Ok(250_000));
        assert_eq!(duration_ns("250µs"), Ok(250_000));
        assert_eq!(duration_ns("7ns"), Ok(7));
        assert_eq!(duration_ns("1min"), Ok(60_000_000_000));
        assert_eq!(duration_ns("1h"), Ok(3_600_000_000_000));
        assert_eq!(duration_ns("1e3ms"), Ok(1_000_000_000));
        for bad in [
            "0",
            "-1",
            "0s",
            "NaN",
            "inf",
            "",
            "s",
            "10 parsecs",
            "1e20h",
            "0.1ns",
        ] {
            assert!(duration_ns(bad).is_err(), "{bad:?} accepted");
        }
        assert!(duration_ns("10 parsecs")
            .unwrap_err()
            .contains("unknown unit"));
        assert_eq!(seconds("1500ms"), Ok(1.5));
        assert_eq!(duration_ms("10s"), Ok(10_000));
        assert_eq!(duration_ms("1h"), Ok(MAX_DURATION_MS));
        assert!(duration_ms("1.5ms")
            .unwrap_err()
            .contains("whole milliseconds"));
        assert!(duration_ms("2h").unwrap_err().contains("out of range"));
    }

    #[test]
    fn integer_ranges() {
        let p = u64_in(1, 10);
        assert_eq!(p("7"), Ok(7));
        assert_eq!(p("1_0"), Ok(10));
        assert!(p("0").unwrap_err().contains("valid: 1..=10"));
        assert!(p("-3").unwrap_err().contains("-3 is out of range"));
        assert!(p("11").is_err());
        assert!(p("x").unwrap_err().contains("not an integer"));
        assert!(p("99999999999999999999999999").is_err());
        let q = i64_in(-5, 5);
        assert_eq!(q("-5"), Ok(-5));
        assert!(q("-6").is_err());
    }

    #[test]
    fn float_ranges() {
        let p = f64_in(0.0, 1.0);
        assert_eq!(p("0.25"), Ok(0.25));
        assert!(p("-0.5").unwrap_err().contains("valid: 0..=1"));
        for bad in ["NaN", "inf", "1.0001"] {
            assert!(p(bad).is_err(), "{bad}");
        }
        for bad in ["0", "-1", "nan"] {
            assert!(seconds(bad).is_err(), "{bad}");
        }
        assert_eq!(seconds("2.5"), Ok(2.5));
    }

    #[test]
    fn interface_names() {
        for good in ["eth1", "abcdefghijklmno"] {
            assert!(iface_name(good).is_ok(), "{good}");
        }
        for bad in ["", "a-very-long-name", "a/b", "..", "eth 1"] {
            assert!(iface_name(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn exit_codes() {
        assert_eq!(exit_code(&usage("x")), EXIT_USAGE);
        assert_eq!(
            exit_code(&anyhow::Error::new(TargetsMissed(vec!["a".into()]))),
            EXIT_TARGETS_MISSED
        );
        assert_eq!(exit_code(&anyhow::anyhow!("io")), EXIT_RUNTIME);
        let wrapped = usage("inner").context("outer");
        assert_eq!(exit_code(&wrapped), EXIT_USAGE);
    }
}
