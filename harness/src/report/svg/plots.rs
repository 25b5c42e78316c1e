//! Per-slave clock error against time: one panel per scheme (ecdc and
//! seed 000 like seed 000 Fig. 10, uncompensated like Fig. 9). Each series is reduced to a
//! min/max envelope per pixel column, so the file stays small for long runs; the compensated
//! panels clip their y-axis (stated on the panel) so the steady state stays readable.

use std::fmt::Write;

use super::{esc, open, Cell};
use crate::schemes::run::Record;

/// One panel: 900 px wide; a plot area 260 px high with 70 px below it for the x-axis labels
/// and the gap to the next panel; margins for the y-axis labels (left) and the legend (right).
const CELL: Cell = Cell::new(900.0, 260.0 + 70.0).with_margins(80.0, 140.0, 0.0, 70.0);
/// Page width, and the left edge of every plot area.
const W: f64 = CELL.width;
const LEFT: f64 = CELL.left;
/// Space above the first panel.
const TOP: f64 = 40.0;
const COLORS: [&str; 10] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];

/// First cycle sample from which every slave's error is below 100 µs (offsets written).
fn plot_start(r: &Record) -> usize {
    (0..r.cyc_t.len())
        .find(|&k| {
            r.cyc_err.iter().all(|v| {
                v.get(k)
                    .copied()
                    .flatten()
                    .is_some_and(|e| e.abs() < 100_000)
            })
        })
        .unwrap_or(0)
}

/// Symmetric y-range: the compensated panels show ±max(200 ns, 1.5 × the largest |error| in
/// the last half of the samples); the uncompensated panel shows everything.
fn y_range(r: &Record, from: usize, clip: bool) -> f64 {
    let n = r.cyc_t.len();
    let start = if clip { from + (n - from) / 2 } else { from };
    let m = r
        .cyc_err
        .iter()
        .flat_map(|v| v.iter().skip(start).flatten())
        .map(|e| e.unsigned_abs())
        .max()
        .unwrap_or(0) as f64;
    if clip {
        (m * 1.5).max(200.0)
    } else {
        m.max(100.0) * 1.05
    }
}

fn panel(out: &mut String, r: &Record, title: &str, y0: f64, clip: bool) {
    let from = plot_start(r);
    let n = r.cyc_t.len();
    let pw = CELL.plot_width();
    let ph = CELL.plot_height();
    panel_frame(out, y0, format_args!("{}", esc(title)));
    if from >= n {
        return;
    }
    let t0 = r.cyc_t[from] as f64;
    let t1 = (r.cyc_t[n - 1] as f64).max(t0 + 1.0);
    let yr = y_range(r, from, clip);
    let (unit, div) = if yr >= 5_000.0 {
        ("µs", 1000.0)
    } else {
        ("ns", 1.0)
    };
    let x = |t: f64| LEFT + (t - t0) / (t1 - t0) * pw;
    let y = |e: f64| y0 + ph / 2.0 - (e.clamp(-yr, yr) / yr) * (ph / 2.0);
    // Axes: zero line, y ticks, x ticks.
    let _ = writeln!(
        out,
        r##"<line x1="{LEFT}" y1="{0}" x2="{1}" y2="{0}" stroke="#bbb" stroke-dasharray="4 3"/>"##,
        y(0.0),
        LEFT + pw
    );
    for k in -2..=2 {
        let v = yr * f64::from(k) / 2.0;
        let _ = writeln!(
            out,
            r#"<text x="{}" y="{}" font-size="11" text-anchor="end">{:.0} {unit}</text>"#,
            LEFT - 6.0,
            y(v) + 4.0,
            v / div
        );
    }
    time_labels(out, y0, (t0, t1), x, (1e9, 2, "s"));
    if clip {
        let _ = writeln!(
            out,
            r##"<text x="{}" y="{}" font-size="11" text-anchor="end" fill="#666">y clipped at ±{:.0} ns</text>"##,
            LEFT + pw,
            y0 - 10.0,
            yr
        );
    }
    // Series: min/max envelope per pixel column.
    let cols = pw as usize;
    let mut legend = 0usize;
    for (s, errs) in r.cyc_err.iter().enumerate() {
        if s == r.reference {
            continue;
        }
        let mut pts = String::new();
        let mut k = from;
        for c in 0..cols {
            let end = from + (n - from) * (c + 1) / cols;
            let mut lo: Option<i64> = None;
            let mut hi: Option<i64> = None;
            let mut tk = 0f64;
            while k < end.min(n) {
                if let Some(e) = errs.get(k).copied().flatten() {
                    lo = Some(lo.map_or(e, |l| l.min(e)));
                    hi = Some(hi.map_or(e, |h| h.max(e)));
                    tk = r.cyc_t[k] as f64;
                }
                k += 1;
            }
            if let (Some(l), Some(h)) = (lo, hi) {
                let _ = write!(pts, "{:.1},{:.1} ", x(tk), y(l as f64));
                if h != l {
                    let _ = write!(pts, "{:.1},{:.1} ", x(tk), y(h as f64));
                }
            }
        }
        let color = COLORS[s % COLORS.len()];
        series(
            out,
            color,
            &pts,
            y0,
            pw,
            legend,
            &format!("slave {}", s + 1),
        );
        legend += 1;
    }
}

/// A panel's bold `title` above it and its frame, the panel's top at `y0`.
fn panel_frame(out: &mut String, y0: f64, title: std::fmt::Arguments) {
    let pw = CELL.plot_width();
    let ph = CELL.plot_height();
    let _ = writeln!(
        out,
        r#"<text x="{LEFT}" y="{}" font-size="15" font-weight="bold">{}</text>"#,
        y0 - 10.0,
        title
    );
    let _ = writeln!(
        out,
        r##"<rect x="{LEFT}" y="{y0}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>"##
    );
}

/// Six time labels under the panel at `y0`, evenly from `span.0` to `span.1` (ns), each placed
/// at `x(t)` and written as t / `unit.0` with `unit.1` decimals and the unit name `unit.2`.
fn time_labels(
    out: &mut String,
    y0: f64,
    span: (f64, f64),
    x: impl Fn(f64) -> f64,
    unit: (f64, usize, &str),
) {
    let (t0, t1) = span;
    let (per, prec, name) = unit;
    for k in 0..=5 {
        let t = t0 + (t1 - t0) * f64::from(k) / 5.0;
        let _ = writeln!(
            out,
            r#"<text x="{}" y="{}" font-size="11" text-anchor="middle">{:.prec$} {name}</text>"#,
            x(t),
            y0 + CELL.plot_height() + 16.0,
            t / per
        );
    }
}

/// Lock panel: the largest |clock error| over all slaves at every lock-detection sample, log
/// scale (1 ns .. 1 ms, clipped), for the schemes that distribute the reference time, with the
/// 100 ns lock threshold.
fn lock_panel(out: &mut String, records: &[&Record], y0: f64) {
    let pw = CELL.plot_width();
    let shown: Vec<&&Record> = records.iter().filter(|r| r.dist_frames > 0).collect();
    let t_end = shown
        .iter()
        .filter_map(|r| {
            let i = crate::schemes::measure::lock_index(&r.track)?;
            r.track.get(i).map(|x| x.0)
        })
        .max()
        .map_or(300_000_000, |t| (t * 2).max(100_000_000)) as f64;
    let every_us = shown
        .first()
        .and_then(|r| r.track.get(1).zip(r.track.first()))
        .map_or(0, |(b, a)| (b.0 - a.0) / 1000);
    panel_frame(
        out,
        y0,
        format_args!("Lock: max |clock error| over slaves (log scale, every {every_us} µs)"),
    );
    let x = |t: f64| LEFT + (t / t_end).min(1.0) * pw;
    let y = log_axis(out, y0, pw, 6);
    time_labels(out, y0, (0.0, t_end), x, (1e6, 0, "ms"));
    for (j, r) in shown.iter().enumerate() {
        let color = bench_color(r.name, j);
        let mut pts = String::new();
        for &(t, _, m) in r.track.iter().take_while(|p| (p.0 as f64) <= t_end) {
            if let Some(m) = m {
                let _ = write!(pts, "{:.1},{:.1} ", x(t as f64), y(m as f64));
            }
        }
        series(out, color, &pts, y0, pw, j, r.name);
    }
}

/// One plotted series: its polyline, and its entry (row `row`) in the legend right of a panel
/// of width `pw` whose top is `y0`.
fn series(out: &mut String, color: &str, pts: &str, y0: f64, pw: f64, row: usize, label: &str) {
    let _ = writeln!(
        out,
        r#"<polyline fill="none" stroke="{color}" stroke-width="1" points="{pts}"/>"#
    );
    let ly = y0 + 14.0 + 16.0 * row as f64;
    let _ = writeln!(
        out,
        r#"<line x1="{0}" y1="{ly}" x2="{1}" y2="{ly}" stroke="{color}" stroke-width="2"/><text x="{2}" y="{3}" font-size="12">{4}</text>"#,
        LEFT + pw + 12.0,
        LEFT + pw + 32.0,
        LEFT + pw + 38.0,
        ly + 4.0,
        label
    );
}

/// The SVG document for the given records (in panel order), followed by the lock panel.
pub fn render(records: &[&Record]) -> String {
    let h = TOP + (records.len() + 1) as f64 * CELL.height + 10.0;
    let mut out = String::new();
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{h}" viewBox="0 0 {W} {h}" font-family="sans-serif">"#
    );
    let _ = writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        out,
        r#"<text x="{LEFT}" y="20" font-size="13">Clock error (slave system time − reference system time, true time), one sample per cycle</text>"#
    );
    for (i, r) in records.iter().enumerate() {
        let y0 = TOP + 30.0 + i as f64 * CELL.height;
        let clip = r.name != "uncompensated";
        let title = match r.name {
            "ecdc" => "ecdc (cf. seed 000 Fig. 10)".to_string(),
            "seed000" => {
                "seed 000 scheme: eq. 23 as eq. 22 implies, eq. 24, 15 000-frame burst, §3.1 gate"
                    .to_string()
            }
            "seed000-printed" => {
                "seed 000 scheme with eq. 23 as printed (last slave's delay t_DIFF too large)"
                    .to_string()
            }
            "uncompensated" => "no compensation: offsets only (cf. seed 000 Fig. 9)".to_string(),
            other => other.to_string(),
        };
        panel(&mut out, r, &title, y0, clip);
    }
    let y0 = TOP + 30.0 + records.len() as f64 * CELL.height;
    lock_panel(&mut out, records, y0);
    out.push_str("</svg>\n");
    out
}

/// One scheme's curves in a `ecdc bench dc` plot.
#[derive(Debug, Clone, Default)]
pub struct BenchSeries {
    /// Scheme name (legend).
    pub name: String,
    /// (true time ns, max |clock error| over slaves ns; `None` before the reference has a
    /// system time), every lock-detection sample.
    pub track: Vec<(u64, Option<u64>)>,
    /// |SYNC0 skew| of every pair in the steady-state window, ns, sorted ascending.
    pub skews: Vec<u64>,
}

/// Colour of a scheme in the bench plots.
fn bench_color(name: &str, k: usize) -> &'static str {
    match name {
        "ecdc" => "#1f77b4",
        "seed000" => "#d62728",
        "seed000-printed" => "#9467bd",
        "igh" => "#2ca02c",
        "ethercrab" => "#ff7f0e",
        "uncompensated" => "#7f7f7f",
        _ => COLORS[k % COLORS.len()],
    }
}

/// Log-scale y axis 1 ns .. 10^`decades` ns with grid lines, for a panel at `y0`.
fn log_axis(out: &mut String, y0: f64, pw: f64, decades: i32) -> impl Fn(f64) -> f64 {
    let ph = CELL.plot_height();
    let hi = f64::from(decades);
    let y = move |e: f64| y0 + ph - (e.max(1.0).log10().clamp(0.0, hi) / hi) * ph;
    let labels = [
        "1 ns", "10 ns", "100 ns", "1 µs", "10 µs", "100 µs", "1 ms", "10 ms",
    ];
    for (k, label) in labels.iter().enumerate().take(decades as usize + 1) {
        let v = 10f64.powi(k as i32);
        let dash = if k == 2 {
            ""
        } else {
            r#" stroke-dasharray="2 4""#
        };
        let _ = writeln!(
            out,
            r##"<line x1="{LEFT}" y1="{0:.1}" x2="{1}" y2="{0:.1}" stroke="#ccc"{dash}/><text x="{2}" y="{3:.1}" font-size="11" text-anchor="end">{label}</text>"##,
            y(v),
            LEFT + pw,
            LEFT - 6.0,
            y(v) + 4.0
        );
    }
    y
}

/// The opening of a bench plot of height `h`: the `svg` element, `command` as its description,
/// a white background and the bold title.
fn plot_header(title: &str, command: &str, h: f64) -> String {
    let mut out = open(W, h, None, Some(command));
    let _ = writeln!(
        out,
        r#"<text x="{LEFT}" y="18" font-size="14" font-weight="bold">{}</text>"#,
        esc(title)
    );
    out
}

/// The `ecdc bench dc` plot of one scenario: (1) lock — the largest |clock error| over all
/// slaves against true time for every scheme (log scale, min/max envelope per pixel column);
/// (2) the distribution of steady-state |SYNC0 skew| (empirical CDF, log x). `command` is
/// written into the file.
pub fn render_bench(title: &str, subtitle: &str, command: &str, series: &[BenchSeries]) -> String {
    let pw = CELL.plot_width();
    let ph = CELL.plot_height();
    let h = TOP + 2.0 * CELL.height + 50.0;
    let mut out = plot_header(title, command, h);
    let _ = writeln!(
        out,
        r#"<text x="{LEFT}" y="34" font-size="11">{}</text>"#,
        esc(subtitle)
    );
    let _ = writeln!(
        out,
        r##"<text x="{LEFT}" y="{}" font-size="11" fill="#666">{}</text>"##,
        h - 12.0,
        esc(command)
    );
    // Panel 1: lock.
    let y0 = TOP + 40.0;
    let t_end = series
        .iter()
        .filter_map(|s| s.track.last().map(|p| p.0))
        .max()
        .unwrap_or(1)
        .max(1) as f64;
    panel_frame(
        &mut out,
        y0,
        format_args!("Lock: max |clock error| over slaves (true time, log scale)"),
    );
    let y = log_axis(&mut out, y0, pw, 6);
    let x = |t: f64| LEFT + (t / t_end).min(1.0) * pw;
    time_labels(&mut out, y0, (0.0, t_end), x, (1e9, 2, "s"));
    let cols = pw as usize;
    for (k, s) in series.iter().enumerate() {
        let mut pts = String::new();
        let mut j = 0usize;
        for c in 0..cols {
            let end_t = t_end * (c + 1) as f64 / cols as f64;
            let (mut lo, mut hi): (Option<u64>, Option<u64>) = (None, None);
            let mut tk = 0f64;
            while j < s.track.len() && (s.track[j].0 as f64) <= end_t {
                if let Some(m) = s.track[j].1 {
                    lo = Some(lo.map_or(m, |l| l.min(m)));
                    hi = Some(hi.map_or(m, |h| h.max(m)));
                    tk = s.track[j].0 as f64;
                }
                j += 1;
            }
            if let (Some(l), Some(h)) = (lo, hi) {
                let _ = write!(pts, "{:.1},{:.1} ", x(tk), y(l as f64));
                if h != l {
                    let _ = write!(pts, "{:.1},{:.1} ", x(tk), y(h as f64));
                }
            }
        }
        series_line(&mut out, bench_color(&s.name, k), &pts, y0, pw, k, &s.name);
    }
    // Panel 2: skew CDF.
    let y0 = TOP + 40.0 + CELL.plot_height() + CELL.bottom;
    panel_frame(
        &mut out,
        y0,
        format_args!("Steady-state |SYNC0 skew| vs the reference: fraction of pairs ≤ x"),
    );
    let decades = 7f64;
    let xs = |v: f64| LEFT + (v.max(1.0).log10().clamp(0.0, decades) / decades) * pw;
    let yf = |f: f64| y0 + ph - f.clamp(0.0, 1.0) * ph;
    for (k, label) in [
        "1 ns", "10 ns", "100 ns", "1 µs", "10 µs", "100 µs", "1 ms", "10 ms",
    ]
    .iter()
    .enumerate()
    {
        let v = 10f64.powi(k as i32);
        let _ = writeln!(
            out,
            r##"<line x1="{0:.1}" y1="{y0}" x2="{0:.1}" y2="{1}" stroke="#ccc" stroke-dasharray="2 4"/><text x="{0:.1}" y="{2}" font-size="11" text-anchor="middle">{label}</text>"##,
            xs(v),
            y0 + ph,
            y0 + ph + 16.0
        );
    }
    for f in [0.0, 0.25, 0.5, 0.75, 1.0] {
        let _ = writeln!(
            out,
            r#"<text x="{}" y="{:.1}" font-size="11" text-anchor="end">{f}</text>"#,
            LEFT - 6.0,
            yf(f) + 4.0
        );
    }
    for (k, s) in series.iter().enumerate() {
        let n = s.skews.len();
        let mut pts = String::new();
        if n > 0 {
            let steps = n.min(400);
            for q in 0..=steps {
                let idx = ((q * n) / steps).min(n - 1);
                let frac = (idx + 1) as f64 / n as f64;
                let _ = write!(pts, "{:.1},{:.1} ", xs(s.skews[idx] as f64), yf(frac));
            }
        }
        // A scheme without pairs (it stopped, or SYNC0 never fired) has no curve.
        series_line(&mut out, bench_color(&s.name, k), &pts, y0, pw, k, &s.name);
    }
    out.push_str("</svg>\n");
    out
}

/// [`series`] for the bench plots (same drawing).
fn series_line(
    out: &mut String,
    color: &str,
    pts: &str,
    y0: f64,
    pw: f64,
    row: usize,
    label: &str,
) {
    series(out, color, pts, y0, pw, row, &esc(label));
}

/// One axis of the `ecdc bench sensitivity` plot: categorical x values and, per scheme, the
/// mean |skew| at each (`None` = no pairs).
#[derive(Debug, Clone, Default)]
pub struct SensitivityPanel {
    /// Axis name (panel title).
    pub title: String,
    /// The axis values, left to right.
    pub labels: Vec<String>,
    /// (scheme, mean |skew| ns per label).
    pub series: Vec<(String, Vec<Option<f64>>)>,
}

/// The `ecdc bench sensitivity` plot: one panel per axis, the mean |SYNC0 skew| of every scheme
/// at each value of the axis (log scale 1 ns .. 1 µs, larger values drawn at the top). `command` is written into the file.
pub fn render_sensitivity(title: &str, command: &str, panels: &[SensitivityPanel]) -> String {
    let pw = CELL.plot_width();
    let ph = CELL.plot_height();
    let h = TOP + panels.len() as f64 * CELL.height + 50.0;
    let mut out = plot_header(title, command, h);
    let _ = writeln!(
        out,
        r##"<text x="{LEFT}" y="{}" font-size="11" fill="#666">{}</text>"##,
        h - 12.0,
        esc(command)
    );
    for (p, panel) in panels.iter().enumerate() {
        let y0 = TOP + 30.0 + p as f64 * CELL.height;
        panel_frame(
            &mut out,
            y0,
            format_args!("mean |SYNC0 skew| vs {}", esc(&panel.title)),
        );
        let y = log_axis(&mut out, y0, pw, 3);
        let n = panel.labels.len().max(1);
        let x = |i: usize| LEFT + (i as f64 + 0.5) / n as f64 * pw;
        for (i, l) in panel.labels.iter().enumerate() {
            let _ = writeln!(
                out,
                r#"<text x="{:.1}" y="{}" font-size="11" text-anchor="middle">{}</text>"#,
                x(i),
                y0 + ph + 16.0,
                esc(l)
            );
        }
        for (k, (name, pts)) in panel.series.iter().enumerate() {
            let mut line = String::new();
            for (i, v) in pts.iter().enumerate() {
                if let Some(v) = v {
                    let _ = write!(line, "{:.1},{:.1} ", x(i), y(*v));
                }
            }
            series_line(&mut out, bench_color(name, k), &line, y0, pw, k, name);
        }
    }
    out.push_str("</svg>\n");
    out
}
