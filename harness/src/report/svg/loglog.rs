//! Panels of line plots with logarithmic axes (the scale plots span 1..1024 slaves).

use std::fmt::Write;

use super::{esc, open, Cell};

/// One series: name, colour, points (x, y), all positive.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// CSS colour.
    pub color: &'static str,
    /// Points; x and y > 0 (log axes).
    pub points: Vec<(f64, f64)>,
    /// Dashed line (fits, references).
    pub dashed: bool,
}

/// One panel.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Title above the panel.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// Series.
    pub series: Vec<Series>,
}

/// One panel: 460 × 300 px, margins left, right, top, bottom.
const CELL: Cell = Cell::new(460.0, 300.0).with_margins(70.0, 20.0, 40.0, 50.0);

fn decades(lo: f64, hi: f64) -> (f64, f64) {
    (
        lo.log10().floor(),
        hi.log10().ceil().max(lo.log10().floor() + 1.0),
    )
}

fn fmt_tick(e: f64) -> String {
    let v = 10f64.powf(e);
    if (0.0..6.0).contains(&e) {
        format!("{v:.0}")
    } else if (-3.0..0.0).contains(&e) {
        format!("{v}")
    } else {
        format!("1e{e:.0}")
    }
}

/// Renders `panels` side by side (two per row) under `title`, log-log axes.
pub fn render_panels(title: &str, panels: &[Panel]) -> String {
    let cols = panels.len().clamp(1, 2);
    let rows = panels.len().div_ceil(2).max(1);
    let total_w = CELL.width * cols as f64;
    let total_h = CELL.height * rows as f64 + 30.0;
    let mut s = open(total_w, total_h, Some(11), None);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="20" font-size="14" text-anchor="middle">{}</text>"#,
        total_w / 2.0,
        esc(title)
    );
    for (pi, p) in panels.iter().enumerate() {
        let ox = CELL.width * (pi % 2) as f64;
        let oy = 30.0 + CELL.height * (pi / 2) as f64;
        let pts = p.series.iter().flat_map(|s| s.points.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in pts {
            if x > 0.0 && y > 0.0 {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
        if x0 > x1 {
            continue;
        }
        let (dx0, dx1) = decades(x0, x1);
        let (dy0, dy1) = decades(y0, y1);
        let pw = CELL.plot_width();
        let ph = CELL.plot_height();
        let px = |x: f64| ox + CELL.left + (x.log10() - dx0) / (dx1 - dx0) * pw;
        let py = |y: f64| oy + CELL.top + ph - (y.log10() - dy0) / (dy1 - dy0) * ph;
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" font-size="12" text-anchor="middle">{}</text>"#,
            ox + CELL.left + pw / 2.0,
            oy + 20.0,
            esc(&p.title)
        );
        let _ = writeln!(
            s,
            r##"<rect x="{}" y="{}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>"##,
            ox + CELL.left,
            oy + CELL.top
        );
        let mut e = dx0;
        while e <= dx1 + 1e-9 {
            let x = px(10f64.powf(e));
            let _ = writeln!(
                s,
                r##"<line x1="{x}" y1="{}" x2="{x}" y2="{}" stroke="#ddd"/><text x="{x}" y="{}" text-anchor="middle">{}</text>"##,
                oy + CELL.top,
                oy + CELL.top + ph,
                oy + CELL.top + ph + 14.0,
                fmt_tick(e)
            );
            e += 1.0;
        }
        let mut e = dy0;
        while e <= dy1 + 1e-9 {
            let y = py(10f64.powf(e));
            let _ = writeln!(
                s,
                r##"<line x1="{}" y1="{y}" x2="{}" y2="{y}" stroke="#ddd"/><text x="{}" y="{}" text-anchor="end">{}</text>"##,
                ox + CELL.left,
                ox + CELL.left + pw,
                ox + CELL.left - 4.0,
                y + 4.0,
                fmt_tick(e)
            );
            e += 1.0;
        }
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            ox + CELL.left + pw / 2.0,
            oy + CELL.height - 12.0,
            esc(&p.x_label)
        );
        let _ = writeln!(
            s,
            r#"<text transform="translate({},{}) rotate(-90)" text-anchor="middle">{}</text>"#,
            ox + 16.0,
            oy + CELL.top + ph / 2.0,
            esc(&p.y_label)
        );
        for (si, ser) in p.series.iter().enumerate() {
            let path: Vec<String> = ser
                .points
                .iter()
                .filter(|(x, y)| *x > 0.0 && *y > 0.0)
                .map(|&(x, y)| format!("{:.1},{:.1}", px(x), py(y)))
                .collect();
            let dash = if ser.dashed {
                r#" stroke-dasharray="5,4""#
            } else {
                ""
            };
            let _ = writeln!(
                s,
                r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="1.6"{dash}/>"#,
                path.join(" "),
                ser.color
            );
            if !ser.dashed {
                for pt in &path {
                    let (x, y) = pt.split_once(',').unwrap_or(("0", "0"));
                    let _ = writeln!(
                        s,
                        r#"<circle cx="{x}" cy="{y}" r="2.5" fill="{}"/>"#,
                        ser.color
                    );
                }
            }
            let ly = oy + CELL.top + 12.0 + 14.0 * si as f64;
            let _ = writeln!(
                s,
                r#"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="{}" stroke-width="2"{dash}/><text x="{}" y="{}">{}</text>"#,
                ox + CELL.left + 8.0,
                ly - 4.0,
                ox + CELL.left + 26.0,
                ly - 4.0,
                ser.color,
                ox + CELL.left + 30.0,
                ly,
                esc(&ser.name)
            );
        }
    }
    s.push_str("</svg>\n");
    s
}
