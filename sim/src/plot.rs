//! A bird's-eye-view picture of one frame as SVG: ground truth, each agent's boxes and the fused
//! boxes in distinct colours, agents marked where they stand (like the paper's qualitative figure).

use crate::dataset::GtFrame;
use crate::noise::Placement;
use std::fmt::Write;
use v2x_protocol::{AgentKind, Detection};

const AGENT_COLOURS: [&str; 6] = [
    "#1f77b4", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
];

fn polygon(
    out: &mut String,
    corners: [[f64; 2]; 4],
    tf: &dyn Fn([f64; 2]) -> (f64, f64),
    stroke: &str,
    width: f64,
    dash: &str,
) {
    let pts: Vec<String> = corners
        .iter()
        .map(|&c| {
            let (x, y) = tf(c);
            format!("{x:.1},{y:.1}")
        })
        .collect();
    let _ = writeln!(
        out,
        r#"<polygon points="{}" fill="none" stroke="{stroke}" stroke-width="{width}" {dash}/>"#,
        pts.join(" ")
    );
}

/// The SVG text of one frame.
pub fn frame_svg(
    frame: &GtFrame,
    agents: &[Vec<Detection>],
    fused: &[Detection],
    places: &[Placement],
    title: &str,
) -> String {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for o in &frame.objects {
        x0 = x0.min(o.center[0]);
        x1 = x1.max(o.center[0]);
        y0 = y0.min(o.center[1]);
        y1 = y1.max(o.center[1]);
    }
    if x0 > x1 {
        (x0, y0, x1, y1) = (-50.0, -50.0, 50.0, 50.0);
    }
    let margin = 8.0;
    let (x0, y0, x1, y1) = (x0 - margin, y0 - margin, x1 + margin, y1 + margin);
    let scale = (1000.0 / (x1 - x0).max(y1 - y0)).min(20.0);
    let (w, h) = ((x1 - x0) * scale, (y1 - y0) * scale + 60.0);
    let tf = move |p: [f64; 2]| ((p[0] - x0) * scale, 60.0 + (y1 - p[1]) * scale);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}" font-family="sans-serif" font-size="14">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(s, r#"<text x="10" y="20">{title}</text>"#);
    legend(&mut s, agents.len());
    for o in &frame.objects {
        polygon(
            &mut s,
            o.as_detection().bev_corners(),
            &tf,
            "#000000",
            2.0,
            "",
        );
    }
    for (i, dets) in agents.iter().enumerate() {
        for d in dets {
            polygon(
                &mut s,
                d.bev_corners(),
                &tf,
                AGENT_COLOURS[i % AGENT_COLOURS.len()],
                1.0,
                r#"stroke-dasharray="4 3""#,
            );
        }
    }
    for d in fused {
        polygon(&mut s, d.bev_corners(), &tf, "#2ca02c", 2.0, "");
    }
    for (i, p) in places.iter().enumerate() {
        let (x, y) = tf([p.position[0], p.position[1]]);
        let colour = AGENT_COLOURS[i % AGENT_COLOURS.len()];
        let shape = match p.kind {
            AgentKind::Vehicle => {
                format!(r#"<circle cx="{x:.1}" cy="{y:.1}" r="7" fill="{colour}"/>"#)
            }
            AgentKind::Infrastructure => format!(
                r#"<rect x="{:.1}" y="{:.1}" width="14" height="14" fill="{colour}"/>"#,
                x - 7.0,
                y - 7.0
            ),
        };
        let _ = writeln!(s, "{shape}");
    }
    s.push_str("</svg>\n");
    s
}

/// The legend: the ground truth, the fused boxes and each of `agents` agents in its colour.
fn legend(s: &mut String, agents: usize) {
    let mut legend = vec![("ground truth", "#000000"), ("fused", "#2ca02c")];
    for i in 0..agents {
        legend.push((
            [
                "agent 1", "agent 2", "agent 3", "agent 4", "agent 5", "agent 6",
            ][i.min(5)],
            AGENT_COLOURS[i % AGENT_COLOURS.len()],
        ));
    }
    for (k, (name, colour)) in legend.iter().enumerate() {
        let x = 10.0 + 130.0 * k as f64;
        let _ = writeln!(
            s,
            r#"<rect x="{x}" y="32" width="14" height="14" fill="{colour}"/><text x="{}" y="44">{name}</text>"#,
            x + 18.0
        );
    }
}
