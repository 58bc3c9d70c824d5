//! The run's time series as an SVG (`v2x-sim plot --timeline`): windows fused and incomplete,
//! end-to-end latency, each agent's frames and received kB and the fused mATE per second, one panel each, with
//! the scripted events as dashed lines across all panels.

use super::series::Timeline;
use std::fmt::Write;

const W: f64 = 960.0;
const LEFT: f64 = 70.0;
const RIGHT: f64 = 130.0;
const PANEL: f64 = 140.0;
const GAP: f64 = 40.0;
const TOP: f64 = 50.0;
const COLOURS: [&str; 8] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf",
];

/// One line of a panel: its label, colour and value per second.
struct Series<'a> {
    label: String,
    colour: &'a str,
    values: Vec<Option<f64>>,
}

/// Draws the timeline.
pub fn svg(tl: &Timeline) -> String {
    let n = tl.seconds.len().max(1) as f64;
    let x = |s: f64| LEFT + (W - LEFT - RIGHT) * s / n;
    let panels = panels(tl);
    let h = TOP + panels.len() as f64 * (PANEL + GAP);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{h}" font-family="sans-serif" font-size="11">"#
    );
    let _ = writeln!(
        s,
        r#"<rect width="100%" height="100%" fill="white"/><text x="{LEFT}" y="20" font-size="14">run {} · {} s</text>"#,
        tl.namespace,
        tl.seconds.len()
    );
    for (p, (title, lines)) in panels.iter().enumerate() {
        draw_panel(&mut s, p, title, lines, &x);
    }
    for (k, e) in tl.events.iter().enumerate() {
        let ex = x(e.at_s);
        let _ = writeln!(
            s,
            r##"<line x1="{ex:.1}" y1="{}" x2="{ex:.1}" y2="{}" stroke="#444" stroke-dasharray="4,3"/><text x="{:.1}" y="{}" font-size="10">{}</text>"##,
            TOP - 8.0,
            h - GAP + 4.0,
            ex + 2.0,
            32.0 + 10.0 * (k % 2) as f64,
            e.label
        );
    }
    for sec in (0..tl.seconds.len()).step_by(5.max(tl.seconds.len() / 10)) {
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{}" text-anchor="middle">{sec} s</text>"#,
            x(sec as f64),
            h - GAP + 18.0
        );
    }
    s.push_str("</svg>\n");
    s
}

/// The panels of a run's plot: windows, latency, each agent's frames and bytes, the fused error.
fn panels(tl: &Timeline) -> Vec<(&'static str, Vec<Series<'_>>)> {
    let col = |f: &dyn Fn(&super::series::Second) -> Option<f64>| -> Vec<Option<f64>> {
        tl.seconds.iter().map(f).collect()
    };
    // One line per agent, in the agents' colours.
    let per_agent = |f: &dyn Fn(&super::series::Second, &String) -> Option<f64>| -> Vec<Series> {
        tl.agents
            .iter()
            .enumerate()
            .map(|(k, a)| Series {
                label: a.clone(),
                colour: COLOURS[k % COLOURS.len()],
                values: col(&|r| f(r, a)),
            })
            .collect()
    };
    let panels: Vec<(&str, Vec<Series>)> = vec![
        (
            "windows / s",
            vec![
                Series {
                    label: "fused".into(),
                    colour: "#555555",
                    values: col(&|r| Some(r.windows as f64)),
                },
                Series {
                    label: "incomplete".into(),
                    colour: "#d62728",
                    values: col(&|r| Some(r.incomplete as f64)),
                },
            ],
        ),
        (
            "end to end (ms)",
            vec![
                Series {
                    label: "p50".into(),
                    colour: "#1f77b4",
                    values: col(&|r| r.e2e_p50_ms),
                },
                Series {
                    label: "p95".into(),
                    colour: "#ff7f0e",
                    values: col(&|r| r.e2e_p95_ms),
                },
            ],
        ),
        (
            "frames fused / s",
            per_agent(&|r, a| r.frames.get(a).map(|&v| v as f64)),
        ),
        (
            "kB/s received (wire, else payload)",
            per_agent(&|r, a| {
                r.wire_bytes
                    .get(a)
                    .or(r.payload_bytes.get(a))
                    .map(|&v| v as f64 / 1000.0)
            }),
        ),
        (
            "fused mATE (m)",
            vec![Series {
                label: "mATE".into(),
                colour: "#2ca02c",
                values: col(&|r| r.mate_m),
            }],
        ),
    ];
    panels
}

/// Draws panel `p`: its frame, title and scale, and each line with its label.
fn draw_panel(s: &mut String, p: usize, title: &str, lines: &[Series<'_>], x: &dyn Fn(f64) -> f64) {
    let y0 = TOP + p as f64 * (PANEL + GAP);
    let max = lines
        .iter()
        .flat_map(|l| l.values.iter().flatten())
        .fold(0.0f64, |a, &b| a.max(b))
        .max(1e-9)
        * 1.1;
    let y = |v: f64| y0 + PANEL - PANEL * v / max;
    // the axis top with as many decimals as its size needs
    let digits = if max >= 100.0 {
        0
    } else if max >= 10.0 {
        1
    } else {
        2
    };
    let _ = writeln!(
        s,
        r##"<rect x="{LEFT}" y="{y0}" width="{}" height="{PANEL}" fill="none" stroke="#999"/><text x="{LEFT}" y="{}">{title}</text><text x="{}" y="{}" text-anchor="end">{:.digits$}</text><text x="{}" y="{}" text-anchor="end">0</text>"##,
        W - LEFT - RIGHT,
        y0 - 4.0,
        LEFT - 4.0,
        y0 + 10.0,
        max,
        LEFT - 4.0,
        y0 + PANEL
    );
    for (k, line) in lines.iter().enumerate() {
        let mut d = String::new();
        let mut pen = false;
        for (i, v) in line.values.iter().enumerate() {
            match v {
                Some(v) => {
                    let _ = write!(
                        d,
                        "{}{:.1},{:.1} ",
                        if pen { "L" } else { "M" },
                        x(i as f64 + 0.5),
                        y(*v)
                    );
                    pen = true;
                }
                None => pen = false,
            }
        }
        let _ = writeln!(
            s,
            r#"<path d="{d}" fill="none" stroke="{}" stroke-width="1.6"/><text x="{}" y="{}" fill="{}">{}</text>"#,
            line.colour,
            W - RIGHT + 8.0,
            y0 + 14.0 + 14.0 * k as f64,
            line.colour,
            line.label
        );
    }
}
