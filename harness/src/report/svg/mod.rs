//! The one SVG writer of the project: every plot in `benches/results/` and every `--svg` file.
//!
//! - [`plots`]: clock error against time (`ecdc simulate`), lock and skew distribution
//!   (`ecdc bench dc`), and the sensitivity grid (`ecdc bench sensitivity`).
//! - [`loglog`]: panels of log-log line plots (`benches/src/bin/scale.rs`).
//!
//! Both build on the document opening and text escaping here.

use std::fmt::Write;

pub mod loglog;
pub mod plots;

pub use loglog::{Panel, Series};
pub use plots::{render, render_bench, render_sensitivity, BenchSeries, SensitivityPanel};

/// One panel's cell of a figure, px: its size and the margins around its plot area (title
/// above, axis labels to the left and below, legend to the right).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Cell {
    pub width: f64,
    pub height: f64,
    pub left: f64,
    pub right: f64,
    pub top: f64,
    pub bottom: f64,
}

impl Cell {
    /// A `width` × `height` cell whose plot area fills it.
    pub(crate) const fn new(width: f64, height: f64) -> Cell {
        Cell {
            width,
            height,
            left: 0.0,
            right: 0.0,
            top: 0.0,
            bottom: 0.0,
        }
    }

    /// The same cell with these margins around the plot area.
    pub(crate) const fn with_margins(self, left: f64, right: f64, top: f64, bottom: f64) -> Cell {
        Cell {
            left,
            right,
            top,
            bottom,
            ..self
        }
    }

    /// Width of the plot area.
    pub(crate) fn plot_width(&self) -> f64 {
        self.width - self.left - self.right
    }

    /// Height of the plot area.
    pub(crate) fn plot_height(&self) -> f64 {
        self.height - self.top - self.bottom
    }
}

/// Escapes text for SVG character data and attribute values.
pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The opening of a document `w` × `h` px: the `svg` element (sans-serif, `font_size` px when
/// given), `desc` (the command that made the plot) when given, and a white background.
pub(crate) fn open(w: f64, h: f64, font_size: Option<u32>, desc: Option<&str>) -> String {
    let mut out = String::new();
    let font = font_size.map_or(String::new(), |f| format!(r#" font-size="{f}""#));
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif"{font}>"#
    );
    if let Some(d) = desc {
        let _ = writeln!(out, "<desc>{}</desc>", esc(d));
    }
    let _ = writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_opens_a_document() {
        assert_eq!(esc(r#"a<b & "c">"#), "a&lt;b &amp; &quot;c&quot;&gt;");
        let doc = open(10.0, 20.0, Some(11), Some("ecdc bench <x>"));
        assert!(doc.starts_with("<svg "), "{doc}");
        assert!(doc.contains(r#"width="10" height="20""#), "{doc}");
        assert!(doc.contains(r#"font-size="11""#), "{doc}");
        assert!(doc.contains("<desc>ecdc bench &lt;x&gt;</desc>"), "{doc}");
    }
}
