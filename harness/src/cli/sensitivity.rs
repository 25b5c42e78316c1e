//! `ecdc bench sensitivity`: how much each scheme's precision depends on the emulator's
//! constants that have no source. Starting from seed 000's six-slave line (the `bench dc`
//! scenario `seed000-line6`), one axis is moved at a time and every scheme runs on its own copy
//! of the same network, measured as `bench dc` measures (true time, docs/simulate.md):
//!
//! | axis | values | why it is an axis |
//! |---|---|---|
//! | t_DIFF = t_P − t_F | 0, 20, 80, 150 ns | the split of an ESC's delay into processing and forwarding has no figure for the emulated ESC |
//! | ESC loop gains | ×0.25, ×1, ×4 | the ESC's update law from Δt to the rate is undocumented (a model PI) |
//! | 0x0934/0x0935 power-on depths | 0/0, 4/12, 15/15 | the reset values come from an unverified report |
//! | PHY jitter per hop | 0, 8, 20 ns | a model value |
//! | crystal spread | ±50, ±100 ppm | ±50 ppm is seed 000's assumption; ±100 ppm is the EtherCAT limit |
//!
//! Every scheme is told what its own method is told (`bench dc` builds it; docs/bench.md); a
//! cell where the t_DIFF axis moves tells the seed 000 scheme the cell's true value, as its
//! method assumes a known t_DIFF. The verdict per cell compares ecdc's mean |skew| with the best
//! other scheme's: ecdc must be best or within 1 ns of it. Writes `sensitivity.md`,
//! `sensitivity.json` and `sensitivity.svg`; deterministic (no wall-clock value in a file).

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use super::bench::{build_scheme, sync0_slaves, BenchScenario, SchemeName, SchemeResult};
use crate::emu::{PpmSpec, Scenario};
use crate::report::svg::{render_sensitivity, SensitivityPanel};
use crate::report::table::{given_text, markdown};
use crate::schemes::measure::summarize;
use crate::schemes::run::{run_scheme, RunOpts};

/// Arguments of `ecdc bench sensitivity`.
#[derive(Debug, Clone, clap::Args)]
pub struct SensitivityArgs {
    /// Output directory (created if missing).
    #[arg(long, default_value = "benches/results")]
    pub out: PathBuf,
    // Default: 10s, seed 000's Fig. 10 length.
    #[command(flatten)]
    pub duration: super::validate::DurationOverride,
}

impl Default for SensitivityArgs {
    fn default() -> Self {
        SensitivityArgs {
            out: PathBuf::from("benches/results"),
            duration: Default::default(),
        }
    }
}

/// Slack within which ecdc counts as matching the best scheme, ns of mean |skew|.
pub const TIE_NS: f64 = 1.0;

/// One axis of the grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// t_P − t_F of every slave (t_F kept, t_P moved).
    TDiff,
    /// Both ESC loop gains scaled by a factor.
    LoopGains,
    /// Power-on values of 0x0934 and 0x0935.
    FilterDepth,
    /// PHY jitter per hop.
    PhyJitter,
    /// Crystal errors uniform in ±spread.
    Crystals,
}

impl Axis {
    /// All axes, in report order.
    pub const ALL: [Axis; 5] = [
        Axis::TDiff,
        Axis::LoopGains,
        Axis::FilterDepth,
        Axis::PhyJitter,
        Axis::Crystals,
    ];

    /// Name used in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Axis::TDiff => "t_diff_ns",
            Axis::LoopGains => "loop_gain_factor",
            Axis::FilterDepth => "filter_depth_0934_0935",
            Axis::PhyJitter => "phy_jitter_ns",
            Axis::Crystals => "crystal_ppm",
        }
    }

    /// The values along the axis: (label, is the base scenario's value, apply to a scenario).
    fn values(self, base: &Scenario) -> Vec<(String, bool, Scenario)> {
        let f = base.defaults.t_f_ns;
        let base_diff = base.defaults.t_p_ns.saturating_sub(f);
        match self {
            Axis::TDiff => [0u64, 20, 80, 150]
                .into_iter()
                .map(|d| {
                    let mut s = base.clone();
                    s.defaults.t_p_ns = f + d;
                    (d.to_string(), d == base_diff, s)
                })
                .collect(),
            Axis::LoopGains => [0.25f64, 1.0, 4.0]
                .into_iter()
                .map(|k| {
                    let mut s = base.clone();
                    s.loop_gains.kp *= k;
                    s.loop_gains.ki *= k;
                    (format!("x{k}"), k == 1.0, s)
                })
                .collect(),
            Axis::FilterDepth => [(0u8, 0u8), (4, 12), (15, 15)]
                .into_iter()
                .map(|(d, sp)| {
                    let mut s = base.clone();
                    let is_base = s.loop_gains.diff_filter_reset == d
                        && s.loop_gains.speed_filter_reset == sp;
                    s.loop_gains.diff_filter_reset = d;
                    s.loop_gains.speed_filter_reset = sp;
                    (format!("{d}/{sp}"), is_base, s)
                })
                .collect(),
            Axis::PhyJitter => [0u64, 8, 20]
                .into_iter()
                .map(|j| {
                    let mut s = base.clone();
                    s.timing.phy_jitter_ns = j;
                    (j.to_string(), j == base.timing.phy_jitter_ns, s)
                })
                .collect(),
            Axis::Crystals => [50.0f64, 100.0]
                .into_iter()
                .map(|p| {
                    let mut s = base.clone();
                    s.defaults.ppm = PpmSpec::Uniform { min: -p, max: p };
                    let is_base = base.defaults.ppm == s.defaults.ppm;
                    (format!("±{p}"), is_base, s)
                })
                .collect(),
        }
    }
}

/// One cell: an axis value and every scheme's numbers there.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Cell {
    pub axis: &'static str,
    pub value: String,
    /// This is the base scenario's value of the axis.
    pub is_base: bool,
    pub schemes: Vec<SchemeResult>,
    /// ecdc's mean |skew| minus the best other scheme's, ns (negative: ecdc is best).
    pub ecdc_minus_best_ns: Option<f64>,
    /// The scheme with the smallest mean |skew| other than ecdc.
    pub best_other: Option<String>,
    /// ecdc is best or within [`TIE_NS`] of the best.
    pub ecdc_ok: bool,
}

/// Everything `ecdc bench sensitivity` writes into sensitivity.json.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SensitivityReport {
    pub command: String,
    pub base_scenario: &'static str,
    pub duration_ns: u64,
    pub tie_ns: f64,
    pub cells: Vec<Cell>,
}

/// The compared schemes: every scheme of `bench dc` but the uncompensated baseline, which is not
/// a contender, and `seed000-printed`, the misprint's labelled extra row (`seed000` is the
/// paper's intended method).
fn schemes() -> Vec<SchemeName> {
    SchemeName::ALL
        .into_iter()
        .filter(|s| !matches!(s, SchemeName::Uncompensated | SchemeName::Seed000Printed))
        .collect()
}

/// Runs every scheme on `sc`.
fn run_cell(sc: &Scenario, duration_ns: u64) -> anyhow::Result<Vec<SchemeResult>> {
    sc.resolve().map_err(|e| anyhow::anyhow!("{e}"))?;
    let cycle: u32 = 1_000_000;
    let opts = RunOpts {
        duration_ns,
        sample_ns: u64::from(cycle) / 10,
        cycle_ns: u64::from(cycle),
    };
    let mut out = Vec::new();
    for which in schemes() {
        let mut scheme = build_scheme(which, sc, cycle)?;
        let rec = run_scheme(scheme.as_mut(), opts, &mut |_| {})?;
        let summary = summarize(&rec);
        out.push(SchemeResult::from_summary(
            &summary,
            sync0_slaves(&rec, &summary),
        ));
    }
    Ok(out)
}

/// The verdict of one cell.
fn judge(schemes: &[SchemeResult]) -> (Option<f64>, Option<String>, bool) {
    let ecdc = schemes
        .iter()
        .find(|s| s.name == "ecdc")
        .and_then(|s| s.skew.mean_ns);
    let best = schemes
        .iter()
        .filter(|s| s.name != "ecdc" && s.error.is_none())
        .filter_map(|s| s.skew.mean_ns.map(|m| (m, s.name.clone())))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    match (ecdc, best) {
        (Some(e), Some((b, name))) => (Some(e - b), Some(name), e <= b + TIE_NS),
        (Some(_), None) => (None, None, true),
        (None, b) => (None, b.map(|b| b.1), false),
    }
}

/// The command line that reproduces a run with `args`.
pub fn command(args: &SensitivityArgs) -> String {
    let mut c = format!(
        "cargo run --release -p ecdc-harness --bin ecdc -- bench sensitivity --out {}",
        args.out.display()
    );
    if let Some(d) = args.duration.ms() {
        c.push_str(&format!(" --duration-ms {d}"));
    }
    c
}

/// Runs the whole grid.
pub fn run_grid(args: &SensitivityArgs) -> anyhow::Result<SensitivityReport> {
    let base = BenchScenario::Seed000Line6.scenario()?;
    let duration_ns = args
        .duration
        .ms()
        .unwrap_or_else(|| BenchScenario::Seed000Line6.duration_ms())
        .saturating_mul(1_000_000);
    let mut cells = Vec::new();
    for axis in Axis::ALL {
        for (value, is_base, sc) in axis.values(&base) {
            let wall = Instant::now();
            let schemes =
                run_cell(&sc, duration_ns).with_context(|| format!("{} = {value}", axis.name()))?;
            let (diff, best_other, ok) = judge(&schemes);
            let _ = writeln!(
                std::io::stderr().lock(),
                "[bench sensitivity] {} = {value}: {:.2} s wall",
                axis.name(),
                wall.elapsed().as_secs_f64()
            );
            cells.push(Cell {
                axis: axis.name(),
                value,
                is_base,
                schemes,
                ecdc_minus_best_ns: diff,
                best_other,
                ecdc_ok: ok,
            });
        }
    }
    Ok(SensitivityReport {
        command: command(args),
        base_scenario: BenchScenario::Seed000Line6.name(),
        duration_ns,
        tie_ns: TIE_NS,
        cells,
    })
}

fn optf(v: Option<f64>, prec: usize) -> String {
    v.map_or("–".to_string(), |v| format!("{v:.prec$}"))
}

/// One table row per cell: per scheme "mean / max ns, lock ms".
fn rows(rep: &SensitivityReport) -> (Vec<String>, Vec<Vec<String>>) {
    let names: Vec<String> = rep
        .cells
        .first()
        .map(|c| c.schemes.iter().map(|s| s.name.clone()).collect())
        .unwrap_or_default();
    let mut headers = vec!["axis".to_string(), "value".to_string()];
    headers.extend(names.iter().cloned());
    headers.push("ecdc − best ns".to_string());
    headers.push("ecdc best or within 1 ns".to_string());
    let rows = rep
        .cells
        .iter()
        .map(|c| {
            let mut row = vec![
                c.axis.to_string(),
                if c.is_base {
                    format!("{} (base)", c.value)
                } else {
                    c.value.clone()
                },
            ];
            for s in &c.schemes {
                row.push(match &s.error {
                    Some(_) => "stopped".to_string(),
                    None => format!(
                        "{} / {}, {}",
                        optf(s.skew.mean_ns, 1),
                        s.skew.max_ns.map_or("–".to_string(), |v| v.to_string()),
                        s.lock_ms
                            .map_or("no lock".to_string(), |v| format!("{v:.1} ms"))
                    ),
                });
            }
            row.push(optf(c.ecdc_minus_best_ns, 1));
            row.push(if c.ecdc_ok { "yes" } else { "**no**" }.to_string());
            row
        })
        .collect();
    (headers, rows)
}

/// The Markdown report.
pub fn markdown_report(rep: &SensitivityReport) -> String {
    let mut out = String::new();
    out.push_str(
        "# `ecdc bench sensitivity`: precision against the emulator's unsourced constants\n\n",
    );
    out.push_str(&format!(
        "Produced by `{}` (deterministic: the same command writes the same files). Base \
         scenario `{}` (seed 000's six-slave line, `bench dc`), {:.0} s simulated per run; one \
         axis moves at a time. Each cell: SYNC0 skew against the reference in true time, steady \
         state, mean / max |.| ns, and lock ms (every slave within 100 ns for the rest of the \
         run); definitions in [docs/simulate.md](../../docs/simulate.md), what each scheme does \
         and is told in [docs/bench.md](../../docs/bench.md). The last columns compare ecdc's \
         mean with the best other scheme's.\n\n",
        rep.command,
        rep.base_scenario,
        rep.duration_ns as f64 / 1e9
    ));
    let (headers, rows) = rows(rep);
    let h: Vec<&str> = headers.iter().map(String::as_str).collect();
    out.push_str(&markdown(&h, 2, &rows));
    let given: Vec<String> = rep
        .cells
        .iter()
        .find(|c| c.is_base)
        .map(|c| {
            c.schemes
                .iter()
                .map(|s| format!("{} {}", s.name, given_text(&s.given)))
                .collect()
        })
        .unwrap_or_default();
    out.push_str(&format!(
        "\nWhat each scheme is told beyond what it measures on the wire (base cell; on the \
         t_DIFF axis a scheme told t_DIFF is told the cell's value): {}.\n",
        given.join("; ")
    ));
    let bad: Vec<String> = rep
        .cells
        .iter()
        .filter(|c| !c.ecdc_ok)
        .map(|c| format!("{} = {}", c.axis, c.value))
        .collect();
    out.push_str(&format!(
        "\nCells where ecdc is neither best nor within {} ns of the best: {}.\n",
        rep.tie_ns,
        if bad.is_empty() {
            "none".to_string()
        } else {
            bad.join(", ")
        }
    ));
    if !bad.is_empty() {
        out.push_str(
            "Why, cell by cell: [docs/bench.md](../../docs/bench.md), section \
             \"`ecdc bench sensitivity`\".\n",
        );
    }
    out.push_str("\n![sensitivity: mean |skew| per scheme along each axis](sensitivity.svg)\n");
    out
}

/// The plot panels: one per axis, mean |skew| per scheme along it.
fn panels(rep: &SensitivityReport) -> Vec<SensitivityPanel> {
    Axis::ALL
        .into_iter()
        .map(|axis| {
            let cells: Vec<&Cell> = rep.cells.iter().filter(|c| c.axis == axis.name()).collect();
            let labels = cells.iter().map(|c| c.value.clone()).collect();
            let names: Vec<String> = cells
                .first()
                .map(|c| c.schemes.iter().map(|s| s.name.clone()).collect())
                .unwrap_or_default();
            let series = names
                .iter()
                .enumerate()
                .map(|(k, name)| {
                    let pts = cells
                        .iter()
                        .map(|c| c.schemes.get(k).and_then(|s| s.skew.mean_ns))
                        .collect();
                    (name.clone(), pts)
                })
                .collect();
            SensitivityPanel {
                title: axis.name().to_string(),
                labels,
                series,
            }
        })
        .collect()
}

/// Runs `ecdc bench sensitivity` and writes its files.
pub fn run(args: &SensitivityArgs) -> anyhow::Result<SensitivityReport> {
    super::validate::creatable_dir("--out", &args.out)?;
    let wall = Instant::now();
    let rep = run_grid(args)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let md = markdown_report(&rep);
    let p = args.out.join("sensitivity.md");
    std::fs::write(&p, &md).with_context(|| format!("writing {}", p.display()))?;
    let p = args.out.join("sensitivity.json");
    std::fs::write(&p, serde_json::to_string_pretty(&rep)? + "\n")
        .with_context(|| format!("writing {}", p.display()))?;
    let svg = render_sensitivity(
        "ecdc bench sensitivity — seed 000's line, one axis at a time",
        &format!("produced by: {}", rep.command),
        &panels(&rep),
    );
    let p = args.out.join("sensitivity.svg");
    std::fs::write(&p, svg).with_context(|| format!("writing {}", p.display()))?;
    let (headers, rows) = rows(&rep);
    let h: Vec<&str> = headers.iter().map(String::as_str).collect();
    print!("{}", markdown(&h, 2, &rows));
    println!(
        "\nwrote {}/sensitivity.md, sensitivity.json and sensitivity.svg ({:.1} s wall)",
        args.out.display(),
        wall.elapsed().as_secs_f64()
    );
    Ok(rep)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every axis changes exactly the field it names, contains the base value exactly once,
    /// and leaves the rest of the scenario as it was.
    #[test]
    fn each_axis_moves_one_thing_and_contains_the_base_once() {
        let base = BenchScenario::Seed000Line6.scenario().unwrap();
        for axis in Axis::ALL {
            let vals = axis.values(&base);
            assert!(vals.len() >= 2, "{}", axis.name());
            assert_eq!(
                vals.iter().filter(|v| v.1).count(),
                1,
                "{}: base value once",
                axis.name()
            );
            for (label, is_base, sc) in &vals {
                let mut back = sc.clone();
                back.defaults.t_p_ns = base.defaults.t_p_ns;
                back.loop_gains = base.loop_gains;
                back.defaults.ppm = base.defaults.ppm.clone();
                back.timing.phy_jitter_ns = base.timing.phy_jitter_ns;
                assert_eq!(back, base, "{} = {label}: only the axis moved", axis.name());
                assert_eq!(*is_base, *sc == base, "{} = {label}", axis.name());
            }
        }
    }

    fn res(name: &str, mean: Option<f64>, error: bool) -> SchemeResult {
        SchemeResult {
            name: name.to_string(),
            error: error.then(|| "stopped".to_string()),
            lock_frames: None,
            lock_ms: None,
            static_drift_frames: None,
            dist_frames: 0,
            given: Default::default(),
            skew: crate::emu::yardstick::SkewSummary {
                mean_ns: mean,
                ..Default::default()
            },
            skew_pairs: 0,
            sync0_slaves: 0,
            window_start_ns: None,
            window_end_ns: 0,
            frames_lost: None,
            ref_wraps_in_window: None,
        }
    }

    /// ecdc passes when best or within TIE_NS; a stopped scheme is no competitor; ecdc without
    /// a skew fails.
    #[test]
    fn verdict() {
        let j = judge(&[res("ecdc", Some(4.0), false), res("igh", Some(3.5), false)]);
        assert_eq!(j, (Some(0.5), Some("igh".to_string()), true));
        let j = judge(&[res("ecdc", Some(5.2), false), res("igh", Some(4.0), false)]);
        assert!(!j.2);
        let j = judge(&[res("ecdc", Some(5.2), false), res("igh", Some(1.0), true)]);
        assert_eq!(j, (None, None, true));
        let j = judge(&[res("ecdc", None, false), res("igh", Some(9.0), false)]);
        assert!(!j.2);
    }
}
