//! Text output of `ecdc simulate`: the per-slave table in the form of seed 000 Table 2 (one
//! column per non-reference slave, one row per quantity), the lock and skew comparison, and
//! the targets.

use std::fmt::Write;

use super::Report;
use crate::schemes::measure::{SlaveRow, Summary};

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or("-".to_string(), |v| v.to_string())
}

fn optf(v: Option<f64>, prec: usize) -> String {
    // A mean that rounds to zero prints as 0.0, not -0.0.
    v.map_or("-".to_string(), |v| {
        let s = format!("{v:.prec$}");
        if s.trim_start_matches('-')
            .chars()
            .all(|c| c == '0' || c == '.')
        {
            format!("{:.prec$}", 0.0)
        } else {
            s
        }
    })
}

/// Formats one cell of a row.
type Cell = Box<dyn Fn(&SlaveRow) -> String>;

/// Table 2 of one scheme: rows = quantities, columns = non-reference slaves.
pub fn slave_table(s: &Summary) -> String {
    let cols: Vec<&SlaveRow> = s.slaves.iter().filter(|r| !r.reference).collect();
    let rows: [(&str, Cell); 8] = [
        ("offset compensation 0x0920", Box::new(|r| opt(r.offset_ns))),
        ("delay compensation 0x0928", Box::new(|r| opt(r.delay_ns))),
        (
            "drift comp. mean 0x092C",
            Box::new(|r| optf(r.drift_mean_ns, 1)),
        ),
        ("drift comp. max", Box::new(|r| opt(r.drift_max_ns))),
        ("drift comp. min", Box::new(|r| opt(r.drift_min_ns))),
        (
            "clock error mean",
            Box::new(|r| optf(r.clock_error_mean_ns, 1)),
        ),
        (
            "clock error max |.|",
            Box::new(|r| opt(r.clock_error_max_abs_ns)),
        ),
        ("SYNC0 skew mean |.|", Box::new(|r| optf(r.skew_mean_ns, 1))),
    ];
    let w0 = 28;
    let mut widths: Vec<usize> = cols
        .iter()
        .map(|r| format!("slave {}", r.slave).len())
        .collect();
    for (_, f) in &rows {
        for (k, r) in cols.iter().enumerate() {
            widths[k] = widths[k].max(f(r).len());
        }
    }
    let mut out = String::new();
    let _ = write!(out, "{:<w0$}", "ns");
    for (k, r) in cols.iter().enumerate() {
        let _ = write!(out, "  {:>w$}", format!("slave {}", r.slave), w = widths[k]);
    }
    out.push('\n');
    for (name, f) in &rows {
        let _ = write!(out, "{name:<w0$}");
        for (k, r) in cols.iter().enumerate() {
            let _ = write!(out, "  {:>w$}", f(r), w = widths[k]);
        }
        out.push('\n');
    }
    out
}

/// The schemes of the text report, in order.
const SCHEMES: [&str; 4] = ["ecdc", "seed000", "seed000-printed", "uncompensated"];

/// What a scheme was told beyond what it measured, as `{key: value, …}` (`{}` = nothing).
pub fn given_text(g: &crate::schemes::Given) -> String {
    let items: Vec<String> = g.iter().map(|(k, v)| format!("{k}: {v}")).collect();
    format!("{{{}}}", items.join(", "))
}

/// One line per scheme: what it was given.
fn given_section(r: &Report) -> String {
    let mut out =
        String::from("\ngiven (what each scheme was told beyond what it measures on the wire)\n");
    for name in SCHEMES {
        if let Some(s) = r.schemes.get(name) {
            let _ = writeln!(out, "{:<15} {}", name, given_text(&s.given));
        }
    }
    out
}

/// Per slave, the t_DIFF each scheme that determines it itself used, against the truth.
fn t_diff_section(r: &Report) -> String {
    let mut out = String::new();
    for name in SCHEMES {
        let Some(rows) = r.schemes.get(name).and_then(|s| s.t_diff_ns.as_ref()) else {
            continue;
        };
        let _ = writeln!(
            out,
            "\n[{name}] t_DIFF used (ns; measured by forced port loops, docs/background/t-diff.md)"
        );
        let _ = writeln!(
            out,
            "{:<8} {:>8} {:>6} {:>6}  source",
            "slave", "used", "true", "error"
        );
        for t in rows {
            let _ = writeln!(
                out,
                "{:<8} {:>8} {:>6} {:>+6}  {}",
                t.slave,
                t.measured,
                t.truth,
                t.measured - t.truth,
                t.source
            );
        }
    }
    out
}

/// A table with a row per scheme in `r`: `title` after a blank line, then the scheme name in
/// 15 columns and each of `columns` (header, width) right-aligned, with `cells` giving a row.
fn scheme_table(
    out: &mut String,
    r: &Report,
    title: &str,
    columns: &[(&str, usize)],
    cells: impl Fn(&Summary) -> Vec<String>,
) {
    let _ = writeln!(out, "\n{title}");
    let line = |out: &mut String, name: &str, values: &mut dyn Iterator<Item = &str>| {
        let _ = write!(out, "{name:<15}");
        for ((_, width), v) in columns.iter().zip(values) {
            let _ = write!(out, " {v:>width$}");
        }
        out.push('\n');
    };
    line(out, "scheme", &mut columns.iter().map(|(h, _)| *h));
    for name in SCHEMES {
        if let Some(s) = r.schemes.get(name) {
            let row = cells(s);
            line(out, name, &mut row.iter().map(String::as_str));
        }
    }
}

/// The whole text report.
pub fn render(r: &Report) -> String {
    let mut out = String::new();
    let su = &r.setup;
    let _ = writeln!(
        out,
        "ecdc simulate: {} slaves ({}), cycle {} ns, {:.3} s, seed {}, loss {}, t_DIFF {} ns, ecdc drift burst {} frames",
        su.slaves,
        su.topology,
        su.cycle_ns,
        su.duration_ns as f64 / 1e9,
        su.seed,
        su.frame_loss_rate,
        su.t_diff_ns,
        su.ecdc_drift_burst_frames
    );
    let ppm: Vec<String> = su.crystal_ppm.iter().map(|p| format!("{p:+.1}")).collect();
    let _ = writeln!(out, "crystals (ppm): {}", ppm.join(" "));
    for name in SCHEMES {
        let Some(s) = r.schemes.get(name) else {
            continue;
        };
        let _ = writeln!(out, "\n[{name}] per-slave table (seed 000 Table 2 form; steady-state window {}..{} ms; reference = slave {})",
            optf(s.window_start_ns.map(|v| v as f64 / 1e6), 1),
            format_args!("{:.1}", s.window_end_ns as f64 / 1e6),
            s.slaves.iter().find(|x| x.reference).map_or(0, |x| x.slave));
        if let Some(e) = &s.error {
            let _ = writeln!(out, "  stopped early: {e}");
        }
        out.push_str(&slave_table(s));
    }
    out.push_str(&given_section(r));
    out.push_str(&t_diff_section(r));
    scheme_table(
        &mut out,
        r,
        "lock (every slave within 100 ns of the reference, true time, for the rest of the run)",
        &[("lock ms", 10), ("lock frames", 12), ("static drift", 14)],
        |s| {
            vec![
                optf(s.lock_ms, 1),
                opt(s.lock_frames),
                opt(s.static_drift_frames),
            ]
        },
    );
    scheme_table(
        &mut out,
        r,
        "steady-state SYNC0 skew vs the reference (true time, ns)",
        &[
            ("mean|.|", 10),
            ("p99|.|", 10),
            ("max|.|", 10),
            ("signed mean", 12),
            ("pairs", 9),
        ],
        |s| {
            vec![
                optf(s.skew.mean_ns, 1),
                opt(s.skew.p99_ns),
                opt(s.skew.max_ns),
                optf(s.skew.signed_mean_ns, 1),
                s.skew_samples.to_string(),
            ]
        },
    );
    let ratio = |k: &str| optf(r.ratios.get(k).copied().flatten(), 3);
    let _ = writeln!(
        out,
        "ecdc / seed000: skew mean {}, p99 {}, max {}, lock frames {}, lock ms {}",
        ratio("skew_mean"),
        ratio("skew_p99"),
        ratio("skew_max"),
        ratio("lock_frames"),
        ratio("lock_ms")
    );
    let _ = writeln!(out, "\ntargets");
    for t in &r.targets {
        let _ = writeln!(
            out,
            "  [{}] {}: {} (measured {})",
            if t.met { "met" } else { "MISSED" },
            t.name,
            t.target,
            t.measured
        );
    }
    out
}

/// A GitHub-flavoured Markdown table: the header row, the separator (numeric columns, i.e. all
/// but the first `left` ones, right-aligned) and one row per entry; `|` in cells is escaped.
pub fn markdown(headers: &[&str], left: usize, rows: &[Vec<String>]) -> String {
    let cell = |s: &str| s.replace('|', "\\|");
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| {} |",
        headers
            .iter()
            .map(|h| cell(h))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let seps: Vec<&str> = (0..headers.len())
        .map(|k| if k < left { "---" } else { "---:" })
        .collect();
    let _ = writeln!(out, "|{}|", seps.join("|"));
    for r in rows {
        let _ = writeln!(
            out,
            "| {} |",
            r.iter().map(|c| cell(c)).collect::<Vec<_>>().join(" | ")
        );
    }
    out
}
