//! A run's summary as tables: the fused output, each agent, bandwidth, regions, and what
//! agent roles without the fuser print.

use super::summary::{Bandwidth, RegionReport, Summary, BORDER_M};
use crate::table::{
    cell, markdown,
    Align::{Left, Right},
};
use serde::Serialize;
use std::collections::BTreeMap;
use v2x_fuser::node::Latency;

/// What agent roles without the fuser print: each one's own side.
#[derive(Clone, Debug, Serialize)]
pub struct AgentReport {
    /// Namespace.
    pub namespace: String,
    /// Bandwidth per agent that ran here.
    pub bandwidth: BTreeMap<String, Bandwidth>,
    /// Frames each produced and its link dropped.
    pub sent: BTreeMap<String, (u64, u64)>,
}

/// Prints an agent report as a table.
pub fn print_agent_table(r: &AgentReport) {
    print!(
        "{}",
        markdown(
            &[
                ("agent", Left),
                ("frames", Right),
                ("payload B/frame", Right),
                ("CPM B/frame", Right),
                ("wire B/frame", Right),
                ("Zenoh overhead B/msg", Right),
                ("kbit/s", Right),
                ("dropped by link", Right),
            ],
            r.bandwidth.iter().map(|(n, b)| {
                vec![
                    n.clone(),
                    b.frames.to_string(),
                    format!("{:.0}", b.payload_bytes_per_frame),
                    cell(b.cpm_bytes_per_frame, 0),
                    cell(b.wire_bytes_per_frame, 0),
                    cell(b.overhead_bytes_per_message, 1),
                    format!("{:.1}", b.kbit_s),
                    r.sent.get(n).map_or(0, |s| s.1).to_string(),
                ]
            }),
        )
    );
}

/// Prints a city's regions, one row each.
pub fn print_regions(regions: &[RegionReport]) {
    print!(
        "{}",
        markdown(
            &[
                ("region", Left),
                ("router", Left),
                ("windows (incomplete)", Left),
                ("captures incomplete", Left),
                ("fused boxes", Left),
                ("agents heard", Left),
                ("fusion p50 / p99 (ms)", Left),
            ],
            regions.iter().map(|r| {
                let ms = |v: Option<f64>| v.unwrap_or(f64::NAN);
                vec![
                    r.tile.clone(),
                    r.router.clone(),
                    format!("{} ({})", r.windows, r.windows_incomplete),
                    r.captures_incomplete.to_string(),
                    r.fused_objects.to_string(),
                    r.agents_heard.join(", "),
                    format!(
                        "{:.2} / {:.2}",
                        ms(r.fusion_latency_ms.p50_ms),
                        ms(r.fusion_latency_ms.p99_ms)
                    ),
                ]
            }),
        )
    );
}

/// Prints a run's summary as tables.
pub fn print_table(s: &Summary) {
    let setup = s
        .security
        .session_setup_ms
        .map_or(String::new(), |ms| format!(", session set-up {ms:.1} ms"));
    println!("scenario {} · method {} · noise {} · {} frames scheduled · {} windows fused ({} incomplete) · {:.1} s · security {}{setup}", s.namespace, s.method, s.noise, s.frames_scheduled, s.windows, s.windows_incomplete, s.wall_s, s.security.mode);
    println!();
    let mut rows = vec![crate::bench::Row {
        noise: s.noise.clone(),
        method: format!("fused ({})", s.method),
        metrics: s.fused.clone(),
    }];
    for (n, m) in &s.agents {
        rows.push(crate::bench::Row {
            noise: s.noise.clone(),
            method: format!("{n} alone"),
            metrics: m.clone(),
        });
    }
    print!("{}", crate::table::Rows::table(&rows[..]));
    println!();
    if let Some(t) = &s.tracking {
        let border = s.border_switches.map_or(String::new(), |n| {
            format!(", {n} within {BORDER_M} m of a tile border")
        });
        println!(
            "tracks: AMOTA {:.4} · AMOTP {:.3} m · MOTA {:.4} · MOTP {:.3} m · IDS {} ({:.2} per 100 objects{border}) · FRAG {}",
            t.amota, t.amotp, t.mota, t.motp, t.ids, t.ids_per_100_tracks, t.frag
        );
        println!();
    }
    print!("{}", bandwidth_table(s));
    println!("(late-fusion reference in the paper: 2^9 = 512 bytes per frame)");
    println!();
    let l = |x: &Latency| {
        format!(
            "p50 {} · p95 {} · p99 {} ms",
            f(x.p50_ms),
            f(x.p95_ms),
            f(x.p99_ms)
        )
    };
    println!(
        "end-to-end latency (capture to fused publish): {}",
        l(&s.e2e_latency_ms)
    );
    println!(
        "fusion latency (window close to publish):      {}",
        l(&s.fusion_latency_ms)
    );
    if !s.regions.is_empty() {
        println!();
        print_regions(&s.regions);
    }
}

/// Each agent's bandwidth and frame counts, as a markdown table.
fn bandwidth_table(s: &Summary) -> String {
    markdown(
        &[
            ("agent", Left),
            ("frames", Right),
            ("objects/frame", Right),
            ("payload B/frame", Right),
            ("payload B/object", Right),
            ("CPM B/frame", Right),
            ("wire B/frame sent", Right),
            ("Zenoh overhead B/msg", Right),
            ("wire B/frame received", Right),
            ("kbit/s", Right),
            ("late", Right),
            ("duplicate", Right),
            ("invalid", Right),
            ("dropped by link", Right),
        ],
        s.bandwidth.iter().map(|(n, b)| {
            let c = &s.counts[n];
            vec![
                n.clone(),
                b.frames.to_string(),
                format!("{:.1}", b.objects_per_frame),
                format!("{:.0}", b.payload_bytes_per_frame),
                format!("{:.1}", b.payload_bytes_per_object),
                cell(b.cpm_bytes_per_frame, 0),
                cell(b.wire_bytes_per_frame, 0),
                cell(b.overhead_bytes_per_message, 1),
                cell(b.received_wire_bytes_per_frame, 0),
                format!("{:.1}", b.kbit_s),
                c.late.to_string(),
                c.duplicate.to_string(),
                c.invalid.to_string(),
                c.dropped_by_link.to_string(),
            ]
        }),
    )
}

fn f(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{x:.2}"))
}
