//! Precision-recall curves as SVG (`v2x-sim bench --dataset v2v4real --plots DIR`): one plot
//! per row, each ordering and threshold a line.

use std::fmt::Write;

/// One line of a plot: its label, SVG stroke style and (recall, precision) points.
#[derive(Clone, Debug, PartialEq)]
pub struct Line {
    /// Legend text.
    pub label: String,
    /// Colour (any SVG colour).
    pub colour: &'static str,
    /// Dashed when true.
    pub dashed: bool,
    /// (recall, precision) in [0, 1], in order.
    pub points: Vec<(f64, f64)>,
}

/// At most `n` points of a curve, evenly spaced along it, its last point kept.
pub fn thin(points: &[(f64, f64)], n: usize) -> Vec<(f64, f64)> {
    if points.len() <= n || n < 2 {
        return points.to_vec();
    }
    let step = (points.len() - 1) as f64 / (n - 1) as f64;
    (0..n)
        .map(|k| points[((k as f64 * step).round() as usize).min(points.len() - 1)])
        .collect()
}

/// A plot of the lines, titled.
pub fn svg(title: &str, lines: &[Line]) -> String {
    let (w, h, m) = (520.0, 420.0, 50.0);
    let (pw, ph) = (w - 2.0 * m, h - 2.0 * m - 20.0);
    let x = |r: f64| m + r.clamp(0.0, 1.0) * pw;
    let y = |p: f64| m + 20.0 + (1.0 - p.clamp(0.0, 1.0)) * ph;
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12"><rect width="{w}" height="{h}" fill="white"/><text x="{m}" y="24" font-size="14">{}</text>"#,
        escape(title)
    );
    for k in 0..=10 {
        let v = k as f64 / 10.0;
        let _ = write!(
            s,
            r##"<line x1="{x0}" y1="{yv}" x2="{x1}" y2="{yv}" stroke="#ddd"/><line x1="{xv}" y1="{y0}" x2="{xv}" y2="{y1}" stroke="#ddd"/><text x="{tx}" y="{ty}" text-anchor="end">{v:.1}</text><text x="{xv}" y="{bx}" text-anchor="middle">{v:.1}</text>"##,
            x0 = x(0.0),
            x1 = x(1.0),
            yv = y(v),
            xv = x(v),
            y0 = y(0.0),
            y1 = y(1.0),
            tx = x(0.0) - 6.0,
            ty = y(v) + 4.0,
            bx = y(0.0) + 16.0,
        );
    }
    let _ = write!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">recall</text><text x="14" y="{}" transform="rotate(-90 14 {})" text-anchor="middle">precision</text>"#,
        x(0.5),
        h - 8.0,
        y(0.5),
        y(0.5)
    );
    for (i, l) in lines.iter().enumerate() {
        let pts: Vec<String> = l
            .points
            .iter()
            .map(|&(r, p)| format!("{:.1},{:.1}", x(r), y(p)))
            .collect();
        let dash = if l.dashed {
            r#" stroke-dasharray="6 4""#
        } else {
            ""
        };
        let _ = write!(
            s,
            r#"<polyline fill="none" stroke="{c}" stroke-width="1.5"{dash} points="{}"/>"#,
            pts.join(" "),
            c = l.colour
        );
        let ly = y(0.3) + 16.0 * i as f64;
        let lx = x(0.05);
        let _ = write!(
            s,
            r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{c}" stroke-width="2"{dash}/><text x="{}" y="{}">{}</text>"#,
            lx + 24.0,
            lx + 30.0,
            ly + 4.0,
            escape(&l.label),
            c = l.colour
        );
    }
    s.push_str("</svg>\n");
    s
}

fn escape(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_the_ends_and_at_most_n_points() {
        let pts: Vec<(f64, f64)> = (0..1001).map(|i| (i as f64 / 1000.0, 1.0)).collect();
        let t = thin(&pts, 11);
        assert_eq!(t.len(), 11);
        assert_eq!((t[0], t[10]), (pts[0], pts[1000]));
        assert_eq!(t[5], pts[500]);
        assert_eq!(thin(&pts[..3], 11), pts[..3].to_vec());
    }

    #[test]
    fn a_plot_draws_each_line_with_its_legend() {
        let line = |label: &str, dashed| Line {
            label: label.into(),
            colour: "#1f77b4",
            dashed,
            points: vec![(0.0, 1.0), (0.5, 0.8), (1.0, 0.5)],
        };
        let s = svg(
            "a <row>",
            &[line("frame order", false), line("global", true)],
        );
        assert!(s.starts_with("<svg") && s.ends_with("</svg>\n"));
        assert_eq!(s.matches("<polyline").count(), 2);
        assert_eq!(s.matches("stroke-dasharray").count(), 2);
        assert!(s.contains("a &lt;row&gt;") && s.contains(">global</text>"));
        // Recall 0.5, precision 0.8 lands at x 50 + 0.5 x 420, y 70 + 0.2 x 300.
        assert!(s.contains("260.0,130.0"), "{s}");
    }
}
