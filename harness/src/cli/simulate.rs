//! `ecdc simulate`: runs ecdc, the seed 000 scheme (derived and as printed) and no compensation
//! on copies of the same emulated network (one [`Scenario`], same seed) and reports lock, SYNC0 skew and the
//! seed 000 Table 2 quantities (text on stdout, JSON and SVG files). Definitions:
//! docs/simulate.md and [`crate::schemes::measure`].

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use super::validate::{self, CYCLE_NS, MAX_DURATION_MS, MAX_PPM};
use crate::emu::{Network, PpmSpec, Scenario, SlaveSpec};
use crate::report::{self, table2, Report, Setup};
use crate::schemes::ecdc::{self, Ecdc};
use crate::schemes::measure::{summarize, TdiffRow};
use crate::schemes::run::{run_scheme, Record, RunOpts};
use crate::schemes::seed000::Seed000;
use crate::schemes::uncompensated::Uncompensated;
use crate::schemes::Scheme;

/// Topologies the command can build without a scenario file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Topology {
    /// Every slave on port 1 of the previous one.
    Line,
    /// Slave 1 is a 4-port junction; the others form three branches on ports 3, 1 and 2
    /// (listed in processing order).
    Tree,
}

/// Arguments of `ecdc simulate`. Without `--scenario` the default is seed 000's setup: 6 slaves
/// in a line with its Table 2 delays ([`Scenario::seed000_line`]), 1 ms cycle, ±50 ppm crystals.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Scenario file (TOML or JSON, the emulator's format); flags given explicitly override it.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Number of slaves, 2..=256 [default: 6] (SYNC0 skew is measured against the reference,
    /// so it needs a second slave).
    #[arg(long, allow_negative_numbers = true, value_parser = validate::simulate_slaves_flag)]
    pub slaves: Option<usize>,
    /// Topology [default: line].
    #[arg(long, value_enum)]
    pub topology: Option<Topology>,
    /// SYNC0 / cyclic period, ns (100000..=100000000).
    #[arg(long, default_value_t = 1_000_000, allow_negative_numbers = true,
          value_parser = validate::u32_in(CYCLE_NS.0, CYCLE_NS.1))]
    pub cycle_ns: u32,
    /// Simulated duration: a number and a unit (`10s`, `500ms`, `1min`; a bare number is
    /// seconds), whole ms from 1ms to 1h, at least one cycle [default: 10s].
    #[arg(long, allow_negative_numbers = true, conflicts_with = "duration_ms",
          value_parser = validate::duration_ms)]
    pub duration: Option<u64>,
    /// Simulated duration in ms (1..=3600000): the older spelling of `--duration`.
    #[arg(long, default_value_t = 10_000, allow_negative_numbers = true,
          value_parser = validate::u64_in(1, MAX_DURATION_MS))]
    pub duration_ms: u64,
    /// Crystal errors uniform in ±PPM, 0..=10000 [default: 50].
    #[arg(long, allow_negative_numbers = true, value_parser = validate::f64_in(0.0, MAX_PPM))]
    pub ppm: Option<f64>,
    /// Frame loss probability, 0..=1 [default: 0].
    #[arg(long, allow_negative_numbers = true, value_parser = validate::f64_in(0.0, 1.0))]
    pub loss: Option<f64>,
    /// Emulator seed, 0..=2^64-1 [default: 0].
    #[arg(long, allow_negative_numbers = true, value_parser = validate::u64_in(0, u64::MAX))]
    pub seed: Option<u64>,
    /// Directory for the default output files.
    #[arg(long, default_value = ".")]
    pub out_dir: PathBuf,
    /// SVG path [default: OUT_DIR/ecdc-simulate.svg].
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// JSON path [default: OUT_DIR/ecdc-simulate.json].
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Never show the progress bar.
    #[arg(long)]
    pub no_progress: bool,
    /// ecdc only: FRMW frames per static drift burst, 1..=65535 [default: the machine's
    /// default, 20].
    #[arg(long, allow_negative_numbers = true, value_parser = validate::u16_in(1, u16::MAX))]
    pub drift_burst_frames: Option<u16>,
    /// Exit with status 3 when a stated target (the `targets` block) is missed; the report
    /// and files are written either way. Without it a missed target still exits 0.
    #[arg(long)]
    pub check: bool,
}

impl Default for Args {
    fn default() -> Self {
        Args {
            scenario: None,
            slaves: None,
            topology: None,
            cycle_ns: 1_000_000,
            duration: None,
            duration_ms: 10_000,
            ppm: None,
            loss: None,
            seed: None,
            out_dir: PathBuf::from("."),
            svg: None,
            json: None,
            no_progress: true,
            drift_burst_frames: None,
            check: false,
        }
    }
}

fn slaves_for(topology: Topology, n: usize) -> Vec<SlaveSpec> {
    match topology {
        Topology::Line => Scenario::line(n).slaves,
        Topology::Tree => Scenario::junction_tree(n).slaves,
    }
}

/// The scenario the arguments describe.
pub fn scenario(args: &Args) -> anyhow::Result<(Scenario, String)> {
    let mut sc = match &args.scenario {
        Some(p) => validate::load_scenario("--scenario", p)?,
        None => Scenario::seed000_line(),
    };
    let mut topo = match &args.scenario {
        Some(p) => format!("from {}", p.display()),
        None => "line".to_string(),
    };
    if args.slaves.is_some() || args.topology.is_some() {
        let t = args.topology.unwrap_or(Topology::Line);
        let n = args.slaves.unwrap_or(6);
        sc.slaves = slaves_for(t, n);
        topo = format!("{t:?}").to_lowercase();
    }
    if let Some(p) = args.ppm {
        sc.defaults.ppm = PpmSpec::Uniform { min: -p, max: p };
    }
    if let Some(l) = args.loss {
        sc.frame_loss_rate = l;
    }
    if let Some(s) = args.seed {
        sc.seed = s;
    }
    let run_ns = args.duration_ms.saturating_mul(1_000_000);
    validate::scenario(&sc, args.scenario.as_deref(), Some(run_ns))?;
    let resolved = sc.resolve().map_err(|e| anyhow::anyhow!("{e}"))?;
    validate::simulate_slaves(&resolved, args.scenario.as_deref())?;
    Ok((sc, topo))
}

/// A progress bar on stderr (indicatif), shown only on a terminal and only once a run has
/// taken > 1 s, so short runs and piped output stay clean.
struct Progress {
    bar: indicatif::ProgressBar,
    start: Instant,
    enabled: bool,
    shown: bool,
}

impl Progress {
    fn new(total: u64, enabled: bool) -> Self {
        let bar = indicatif::ProgressBar::with_draw_target(
            Some(total.max(1)),
            indicatif::ProgressDrawTarget::hidden(),
        );
        if let Ok(style) =
            indicatif::ProgressStyle::with_template("[{bar:40}] {percent:>3}% {msg:<15} {elapsed}")
        {
            bar.set_style(style.progress_chars("#>."));
        }
        Progress {
            bar,
            start: Instant::now(),
            enabled: enabled && std::io::stderr().is_terminal(),
            shown: false,
        }
    }

    fn update(&mut self, done: u64, label: &str) {
        if !self.enabled || self.start.elapsed().as_millis() < 1000 {
            return;
        }
        if !self.shown {
            self.shown = true;
            self.bar
                .set_draw_target(indicatif::ProgressDrawTarget::stderr());
        }
        if self.bar.message() != label {
            self.bar.set_message(label.to_owned());
        }
        self.bar.set_position(done);
    }

    fn finish(&self) {
        if self.shown {
            self.bar.finish();
        }
    }
}

/// The schemes `simulate` runs next to ecdc, each on its own copy of the network: seed 000 as
/// its eq. 22 implies eq. 23 (`seed000`), seed 000 with eq. 23 as printed (`seed000-printed`,
/// a labelled extra row), and no compensation. The seed 000 schemes are given `t_diff_ns`
/// because the paper assumes it known (each scheme reports it in `given`).
fn comparison_schemes(
    net: &dyn Fn() -> anyhow::Result<Network>,
    t_diff: i64,
    cycle: u32,
) -> anyhow::Result<Vec<Box<dyn Scheme>>> {
    Ok(vec![
        Box::new(Seed000::new(net()?, t_diff, cycle)),
        Box::new(Seed000::printed(net()?, t_diff, cycle)),
        Box::new(Uncompensated::new(net()?, cycle)),
    ])
}

/// Runs the schemes and builds the report (no files written). `progress` shows the bar.
pub fn simulate(args: &Args) -> anyhow::Result<(Report, Vec<Record>)> {
    validate::simulate_args(args)?;
    let (sc, topology) = scenario(args)?;
    let t_diff = i64::try_from(sc.defaults.t_p_ns)? - i64::try_from(sc.defaults.t_f_ns)?;
    let duration_ns = args.duration_ms.saturating_mul(1_000_000);
    let cycle = args.cycle_ns;
    anyhow::ensure!(cycle > 0, "--cycle-ns must be > 0");
    let opts = RunOpts {
        duration_ns,
        sample_ns: (u64::from(cycle) / 10).clamp(1_000, 100_000),
        cycle_ns: u64::from(cycle),
    };
    let net = || Network::new(&sc).map_err(|e| anyhow::anyhow!("{e}"));
    let probe = net()?;
    let crystal_ppm: Vec<f64> = (0..probe.slave_count())
        .filter_map(|i| probe.slave_info(i).map(|s| s.ppm))
        .collect();
    let mut cfg = ecdc::config(i32::try_from(t_diff)?, cycle);
    if let Some(b) = args.drift_burst_frames {
        cfg.drift.burst_frames = b;
    }
    let mut schemes: Vec<Box<dyn Scheme>> = vec![Box::new(Ecdc::new(net()?, cfg)?)];
    schemes.extend(comparison_schemes(&net, t_diff, cycle)?);
    let mut bar = Progress::new(duration_ns * schemes.len() as u64, !args.no_progress);
    let mut records = Vec::new();
    let mut t_diffs = Vec::new();
    for (k, s) in schemes.iter_mut().enumerate() {
        let base = duration_ns * k as u64;
        let name = s.name();
        let rec = run_scheme(s.as_mut(), opts, &mut |t| bar.update(base + t, name))
            .with_context(|| format!("scheme {name}"))?;
        records.push(rec);
        t_diffs.push((name, s.t_diff_used()));
    }
    bar.finish();
    let setup = Setup {
        slaves: crystal_ppm.len(),
        topology,
        cycle_ns: cycle,
        duration_ns,
        crystal_ppm,
        frame_loss_rate: sc.frame_loss_rate,
        seed: sc.seed,
        t_diff_ns: t_diff,
        sample_ns: opts.sample_ns,
        ecdc_drift_burst_frames: cfg.drift.burst_frames,
    };
    let mut report = Report::new(setup, records.iter().map(summarize).collect());
    let true_t_diff: Vec<i64> = (0..probe.slave_count())
        .filter_map(|i| probe.slave_info(i))
        .map(|s| s.t_p_ns as i64 - s.t_f_ns as i64)
        .collect();
    for (name, used) in t_diffs {
        if let (Some(used), Some(summary)) = (used, report.schemes.get_mut(name)) {
            summary.t_diff_ns = Some(
                used.into_iter()
                    .zip(&true_t_diff)
                    .enumerate()
                    .map(|(k, ((measured, source), &truth))| TdiffRow {
                        slave: k + 1,
                        measured,
                        truth,
                        source,
                    })
                    .collect(),
            );
        }
    }
    table2_section(args, &sc, &mut report)?;
    Ok((report, records))
}

/// Whether the arguments describe seed 000's own line (the default scenario): no scenario file,
/// no topology or slave count given. Crystals, loss and seed may differ.
pub fn is_seed000_line(args: &Args) -> bool {
    args.scenario.is_none() && args.slaves.is_none() && args.topology.is_none()
}

/// The Table 2 data of the report: the emulator's true delays always, the paper's numbers on
/// seed 000's line.
fn table2_section(args: &Args, sc: &Scenario, report: &mut Report) -> anyhow::Result<()> {
    report.truth = Some(table2::truth(sc).map_err(|e| anyhow::anyhow!("{e}"))?);
    report.paper = is_seed000_line(args).then(table2::Paper::seed000);
    Ok(())
}

/// The Table 2 text section of a report and its records.
pub fn table2_text(report: &Report, records: &[Record]) -> String {
    let Some(truth) = &report.truth else {
        return String::new();
    };
    let pairs: Vec<(&crate::schemes::measure::Summary, &Record)> = records
        .iter()
        .filter_map(|r| report.schemes.get(r.name).map(|s| (s, r)))
        .collect();
    table2::render(truth, report.paper.as_ref(), &pairs)
}

/// Runs `ecdc simulate`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let svg_path = args
        .svg
        .clone()
        .unwrap_or_else(|| args.out_dir.join("ecdc-simulate.svg"));
    let json_path = args
        .json
        .clone()
        .unwrap_or_else(|| args.out_dir.join("ecdc-simulate.json"));
    if args.svg.is_none() || args.json.is_none() {
        validate::out_dir("--out-dir", &args.out_dir)?;
    }
    validate::out_file("--svg", &svg_path)?;
    validate::out_file("--json", &json_path)?;
    let (report, records) = simulate(args)?;
    let refs: Vec<&Record> = records.iter().collect();
    std::fs::write(&svg_path, report::svg::render(&refs))
        .with_context(|| format!("writing {}", svg_path.display()))?;
    std::fs::write(&json_path, report.to_json()?)
        .with_context(|| format!("writing {}", json_path.display()))?;
    print!("{}", report::table::render(&report));
    print!("{}", table2_text(&report, &records));
    println!("\nwrote {} and {}", json_path.display(), svg_path.display());
    if args.check {
        let missed: Vec<String> = report
            .targets
            .iter()
            .filter(|t| !t.met)
            .map(|t| format!("{}: {} (measured {})", t.name, t.target, t.measured))
            .collect();
        if !missed.is_empty() {
            return Err(validate::TargetsMissed(missed).into());
        }
    }
    Ok(())
}
