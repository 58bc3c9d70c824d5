//! `v2x-sim bench async`: what capture-time offsets between two agents cost, and how much of
//! it motion compensation wins back.
//!
//! Agent 1 (the vehicle) captures on the data's frames. In a "10+10 Hz" pair, agent 2 (the
//! infrastructure unit) captures at the same rate `offset` earlier: at each of agent 1's
//! captures the fuser holds agent 1's fresh frame and agent 2's latest, `offset` old. In the
//! "10+20 Hz" pair agent 2 runs at twice the data's rate in phase with agent 1, and every
//! capture of agent 2 is fused with agent 1's latest frame, fresh or half a period old. Each
//! fused output is scored against the ground truth at its reference time t_ref (the latest
//! capture), interpolated between annotations where it falls between frames.
//!
//! Both agents draw their noise from the reference frame's index, so every row sees the same
//! noise and differs only in timing; frames within the largest offset of a scene's start are
//! left out of every row, so that every row scores the same instants.

use crate::bench::fusers::Fusers;
use crate::bench::BenchConfig;
use crate::bench::{in_order, merge_slots};
use crate::dataset::GroundTruth;
use crate::metrics::{Accumulator, Metrics};
use crate::noise::{detect, place_agents, Capture, NoiseSetting};
use crate::table::{
    cell, markdown,
    Align::{Left, Right},
    Rows,
};
use rayon::prelude::*;
use serde::Serialize;
use v2x_fuser::pipeline::Steps;
use v2x_fuser::time::motion::MotionParams;
use v2x_fuser::Method;
use v2x_protocol::Detection;

/// Agent 2's offsets behind agent 1 in the 10+10 Hz pairs (ms).
pub const OFFSETS_MS: [f64; 4] = [0.0, 25.0, 50.0, 100.0];

/// How the two agents capture.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Timing {
    /// Both at the data's rate, agent 2 `offset` (us) behind agent 1.
    Offset(u64),
    /// Agent 2 at twice the data's rate, in phase with agent 1.
    Double,
}

/// One row of the comparison.
#[derive(Clone, Debug, Serialize)]
pub struct AsyncRow {
    /// The agents' rates: `10+10 Hz` or `10+20 Hz` (on 10 Hz data).
    pub rates: String,
    /// Age of agent 2's frame at agent 1's capture (ms); for the 10+20 Hz pair, the largest age
    /// of agent 1's frame at agent 2's captures.
    pub offset_ms: f64,
    /// Whether detections were predicted to t_ref before fusion.
    pub compensation: bool,
    /// The method.
    pub method: Method,
    /// The metrics.
    #[serde(flatten)]
    pub metrics: Metrics,
}

/// The capture pairs of a timing: (t_ref, [(draw, t_capture); 2]) with agent 1 first.
fn pairs(gt: &GroundTruth, timing: Timing, skip_us: u64) -> Vec<(usize, u64, [u64; 2])> {
    let starts: Vec<u64> = (0..gt.scenes.len().max(1))
        .map(|s| gt.scene_span(s).map_or(0, |(a, _)| a))
        .collect();
    let mut out = Vec::new();
    for (k, f) in gt.frames.iter().enumerate() {
        let t = f.timestamp_us;
        if t < starts.get(f.scene).copied().unwrap_or(0) + skip_us {
            continue;
        }
        match timing {
            Timing::Offset(d) => out.push((k, t, [t, t - d])),
            Timing::Double => {
                out.push((k, t, [t, t]));
                let next = gt.frames.get(k + 1).filter(|n| n.scene == f.scene);
                if let Some(n) = next {
                    let mid = t + (n.timestamp_us - t) / 2;
                    out.push((k, mid, [t, mid]));
                }
            }
        }
    }
    out
}

/// Runs every method with and without compensation for one timing; rows in method order, the
/// uncompensated first.
pub fn run_timing(
    gt: &GroundTruth,
    cfg: &BenchConfig,
    setting: &NoiseSetting,
    timing: Timing,
    skip_us: u64,
) -> Vec<(bool, Method, Metrics)> {
    let n = cfg.methods.len();
    // The same pipelines without and with motion compensation; no step carries history.
    let raw = Fusers::new(&cfg.methods, 2, None);
    let compensated = Fusers::with_steps(&cfg.methods, 2, |method| Steps {
        motion: Some(MotionParams::default()),
        ..Steps::method(method)
    });
    let accs = in_order(
        pairs(gt, timing, skip_us).into_par_iter(),
        |(k, t_ref, caps)| {
            let mut accs = vec![Accumulator::new(); 2 * n];
            let frame = &gt.frames[k];
            let places = place_agents(frame, 2, cfg.seed);
            // Agent 2's draw at a half-period capture is its own.
            let draw2 = if caps[1] == frame.timestamp_us {
                k as u64
            } else {
                k as u64 | 1 << 40
            };
            let lists: Vec<Vec<Detection>> = (0..2)
                .map(|a| {
                    let objects = gt.in_draw_order(gt.objects_at(frame.scene, caps[a]));
                    let draw = if a == 0 { k as u64 } else { draw2 };
                    let noise = &setting.agents[a];
                    let capture = Capture {
                        draw,
                        scene: frame.scene,
                        t_us: caps[a],
                    };
                    detect(
                        &objects,
                        capture,
                        a,
                        noise,
                        places[a].position,
                        cfg.range,
                        cfg.seed,
                    )
                })
                .collect();
            let (mut raw, mut compensated) = (raw.clone(), compensated.clone());
            let truth = gt.objects_at(frame.scene, t_ref);
            for m in 0..n {
                accs[m].add_frame(&truth, &raw.fuse_window(m, &caps, &lists));
                accs[n + m].add_frame(&truth, &compensated.fuse_window(m, &caps, &lists));
            }
            accs
        },
        merge_slots,
    )
    .unwrap_or_else(|| vec![Accumulator::new(); 2 * n]);
    let mut order: Vec<usize> = (0..2 * n).collect();
    order.sort_by_key(|&i| (i % n, i >= n));
    order
        .into_iter()
        .map(|i| (i >= n, cfg.methods[i % n], accs[i].summary()))
        .collect()
}

/// The whole comparison: the 10+10 Hz pairs at [`OFFSETS_MS`], then the 10+20 Hz pair.
pub fn run(gt: &GroundTruth, cfg: &BenchConfig, setting: &NoiseSetting) -> Vec<AsyncRow> {
    let period_us = (1e6 / gt.hz()).round() as u64;
    let skip_us = (OFFSETS_MS[OFFSETS_MS.len() - 1] * 1000.0) as u64;
    let mut timings: Vec<(String, f64, Timing)> = OFFSETS_MS
        .iter()
        .map(|&o| {
            (
                format!("{0}+{0} Hz", fmt_hz(gt.hz())),
                o,
                Timing::Offset((o * 1000.0) as u64),
            )
        })
        .collect();
    timings.push((
        format!("{}+{} Hz", fmt_hz(gt.hz()), fmt_hz(2.0 * gt.hz())),
        (period_us as f64 / 2000.0).round(),
        Timing::Double,
    ));
    let mut out = Vec::new();
    for (rates, offset_ms, timing) in timings {
        for (compensation, method, metrics) in run_timing(gt, cfg, setting, timing, skip_us) {
            out.push(AsyncRow {
                rates: rates.clone(),
                offset_ms,
                compensation,
                method,
                metrics,
            });
        }
    }
    out
}

fn fmt_hz(hz: f64) -> String {
    format!("{}", (hz * 10.0).round() / 10.0)
}

/// Whether a row's agents run at one rate.
fn same_rate(r: &AsyncRow) -> bool {
    let mut hz = r.rates.trim_end_matches(" Hz").split('+');
    hz.next() == hz.next()
}

/// How much compensation wins back, per method: mATE at 50 ms compensated over the synchronous one,
/// and the share of the 100 ms loss that compensation recovers,
/// (uncompensated - compensated) / (uncompensated - synchronous).
pub fn recovery(rows: &[AsyncRow], method: Method) -> Option<(f64, f64)> {
    let ate = |offset: f64, comp: bool| {
        rows.iter()
            .find(|r| {
                r.method == method
                    && r.offset_ms == offset
                    && r.compensation == comp
                    && same_rate(r)
            })
            .and_then(|r| r.metrics.all.m_ate)
    };
    let sync = ate(0.0, false)?;
    let at50 = ate(50.0, true)? / sync;
    let (raw, comp) = (ate(100.0, false)?, ate(100.0, true)?);
    Some((at50, (raw - comp) / (raw - sync)))
}

impl Rows for [AsyncRow] {
    /// The rows as a Markdown table, with each method's recovery ([`recovery`]) under it.
    fn table(&self) -> String {
        let rows = self;
        let mut s = markdown(
            &[
                ("rates", Left),
                ("offset (ms)", Right),
                ("compensation", Left),
                ("method", Left),
                ("precision", Right),
                ("recall", Right),
                ("mATE (m)", Right),
                ("mAVE (m/s)", Right),
                ("TP-only mATE", Right),
            ],
            rows.iter().map(|r| {
                let m = &r.metrics;
                vec![
                    r.rates.clone(),
                    r.offset_ms.to_string(),
                    (if r.compensation { "yes" } else { "no" }).to_string(),
                    r.method.to_string(),
                    cell(m.precision, 4),
                    cell(m.recall, 4),
                    cell(m.all.m_ate, 3),
                    cell(m.all.m_ave, 3),
                    cell(m.tp_only.m_ate, 3),
                ]
            }),
        );
        let mut methods: Vec<Method> = Vec::new();
        for r in rows {
            if !methods.contains(&r.method) {
                methods.push(r.method);
            }
        }
        for method in methods {
            if let Some((at50, recovered)) = recovery(rows, method) {
                s.push_str(&format!(
                    "\n{method}: compensated mATE at 50 ms = {:.1}% of the synchronous; {:.0}% of the 100 ms loss recovered",
                    100.0 * at50,
                    100.0 * recovered
                ));
            }
        }
        s.push('\n');
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::town::{generate, TownConfig};

    #[test]
    fn compensation_wins_back_what_the_offset_costs() {
        let gt = generate(&TownConfig {
            scenes: 2,
            seconds: 6.0,
            hz: 10.0,
            seed: 3,
        });
        let cfg = BenchConfig {
            methods: vec!["csba-wls+".parse().unwrap(), "gt-wls".parse().unwrap()],
            settings: vec![],
            seed: 1,
            range: None,
        };
        let setting = NoiseSetting::parse("mild", 2).unwrap();
        let rows = run(&gt, &cfg, &setting);
        assert_eq!(rows.len(), 5 * 2 * 2);
        let ate = |offset: f64, comp: bool| {
            rows.iter()
                .find(|r| {
                    r.method == Method::GtWls && r.offset_ms == offset && r.compensation == comp
                })
                .unwrap()
                .metrics
                .all
                .m_ate
                .unwrap()
        };
        // At no offset there is nothing to compensate.
        assert_eq!(ate(0.0, false), ate(0.0, true));
        // The loss grows with the offset, and compensation takes most of it back.
        assert!(ate(25.0, false) < ate(50.0, false) && ate(50.0, false) < ate(100.0, false));
        assert!(
            ate(100.0, false) > 1.05 * ate(0.0, false),
            "{}",
            ate(100.0, false)
        );
        let (at50, recovered) = recovery(&rows, Method::GtWls).unwrap();
        assert!(at50 < 1.05, "{at50}");
        assert!(recovered > 0.6, "{recovered}");
        assert!(rows.iter().all(|r| r.metrics.all.m_ave.is_some()));
        // The 10+20 Hz pair scores twice the instants.
        let double = rows.iter().find(|r| r.rates == "10+20 Hz").unwrap();
        let single = rows.iter().find(|r| r.offset_ms == 0.0).unwrap();
        let n = |m: &Metrics| m.tp + m.fn_;
        assert!(n(&double.metrics) > 19 * n(&single.metrics) / 10);
    }
}
