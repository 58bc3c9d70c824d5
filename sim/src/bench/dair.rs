//! DAIR-V2X runs offline (`v2x-sim bench --dataset dair-v2x`, `v2x-sim eval --dataset
//! dair-v2x`): the vehicle alone, the roadside alone and every method fusing the two, each
//! scored by the nuScenes-style benchmark over the classes the ground truth holds and by the
//! DAIR-V2X protocol in the vehicle's frame, with the bytes each frame costs on the wire.

use crate::bench::{in_order, FRAMES_PER_TASK};
use crate::dair::{Dair, AGENTS};
use crate::dair_eval::{detection_boxes, gt_boxes, official_bytes, DairEval, DairMetrics};
use crate::detection_eval::{DetectionEval, DetectionMetrics};
use crate::noise::NoiseSetting;
use crate::table::{
    markdown,
    Align::{Left, Right},
    Rows,
};
use crate::wire_bytes::{frame_bytes, Bytes};
use rayon::prelude::*;
use serde::Serialize;
use v2x_fuser::Method;
use v2x_protocol::nuscenes_json::Results;
use v2x_protocol::{AgentKind, Detection};

/// One row of the DAIR-V2X table.
#[derive(Clone, Debug, Serialize)]
pub struct DairRow {
    /// `veh`, `inf` or the method's name.
    pub method: String,
    /// The nuScenes-style benchmark over the classes the ground truth holds.
    pub detection: DetectionMetrics,
    /// The DAIR-V2X protocol (AP-3D, AP-BEV).
    pub dair: DairMetrics,
    /// Mean bytes per frame on the wire: what the row's agents send (both for a fusion); none
    /// for a results file scored on its own.
    pub bytes_per_frame: Option<f64>,
    /// The same boxes as ETSI CPMs: mean bytes per frame.
    pub cpm_bytes_per_frame: Option<f64>,
    /// Mean bytes per frame as the official late-fusion evaluation counts the roadside's
    /// boxes in range (72 per box; 0 for the vehicle alone).
    pub official_ab: Option<f64>,
}

/// What one agent's frame costs on the air, as frames and as CPMs.
pub fn wire_bytes(agent: usize, capture_us: u64, dets: &[Detection]) -> Bytes {
    let kind = if agent == 0 {
        AgentKind::Vehicle
    } else {
        AgentKind::Infrastructure
    };
    frame_bytes(AGENTS[agent], kind, capture_us, dets)
}

#[derive(Clone, Default)]
struct Slots {
    det: Vec<DetectionEval>,
    dair: Vec<DairEval>,
    bytes: [Bytes; 2],
    official: usize,
    frames: usize,
}

impl Slots {
    fn new(n: usize) -> Self {
        Slots {
            det: vec![DetectionEval::new(); n],
            dair: vec![DairEval::new(); n],
            ..Default::default()
        }
    }

    fn merge(mut self, other: Slots) -> Slots {
        for (a, b) in self.det.iter_mut().zip(other.det) {
            a.merge(b);
        }
        for (a, b) in self.dair.iter_mut().zip(other.dair) {
            a.merge(b);
        }
        self.bytes[0] += other.bytes[0];
        self.bytes[1] += other.bytes[1];
        self.official += other.official;
        self.frames += other.frames;
        self
    }
}

/// Scores both agents alone and every method on every pair, the agents' detections being their
/// labels as `setting` sees them (`labels`: exactly).
pub fn run(
    d: &Dair,
    methods: &[Method],
    setting: &NoiseSetting,
    seed: u64,
    range: Option<f64>,
) -> Vec<DairRow> {
    let n = 2 + methods.len();
    let frames: Vec<usize> = (0..d.gt.frames.len()).collect();
    let slots = in_order(
        frames.par_chunks(FRAMES_PER_TASK),
        |chunk| {
            let mut s = Slots::new(n);
            let mut fusers = crate::bench::fusers::Fusers::new(methods, 2, None);
            for &i in chunk {
                let agents: Vec<Vec<Detection>> = (0..2)
                    .map(|a| d.detections(a, i, &setting.agents[a], seed, range))
                    .collect();
                let Some(to_vehicle) = d.rec.pairs[i].veh_to_world.inverse() else {
                    continue;
                };
                let objects = &d.gt.frames[i].objects;
                let truth = gt_boxes(objects, &to_vehicle);
                let mut score = |slot: usize, preds: &[Detection]| {
                    s.det[slot].add_frame(objects, preds);
                    s.dair[slot].add_frame(&truth, &detection_boxes(preds, &to_vehicle));
                };
                for (a, dets) in agents.iter().enumerate() {
                    score(a, dets);
                }
                for m in 0..methods.len() {
                    score(2 + m, &fusers.fuse(m, d.capture_us(0, i), &agents));
                }
                for (a, dets) in agents.iter().enumerate() {
                    s.bytes[a] += wire_bytes(a, d.capture_us(a, i), dets);
                }
                s.official += official_bytes(detection_boxes(&agents[1], &to_vehicle).len());
                s.frames += 1;
            }
            s
        },
        Slots::merge,
    )
    .unwrap_or_else(|| Slots::new(n));
    let per_frame = |b: usize| b as f64 / slots.frames.max(1) as f64;
    let both = |b: Bytes| (per_frame(b.frame), per_frame(b.cpm));
    let names = AGENTS
        .iter()
        .map(|a| a.to_string())
        .chain(methods.iter().map(Method::name));
    names
        .enumerate()
        .map(|(k, method)| {
            let classes = slots.det[k].ground_truth_classes();
            let mut pair = slots.bytes[0];
            pair += slots.bytes[1];
            let ((bytes, cpm), official) = match k {
                0 => (both(slots.bytes[0]), 0.0),
                1 => (both(slots.bytes[1]), per_frame(slots.official)),
                _ => (both(pair), per_frame(slots.official)),
            };
            DairRow {
                method,
                detection: slots.det[k].summary_over(&classes),
                dair: slots.dair[k].summary(),
                bytes_per_frame: Some(bytes),
                cpm_bytes_per_frame: Some(cpm),
                official_ab: Some(official),
            }
        })
        .collect()
}

/// The DAIR-V2X protocol over a results file's samples that name a pair (by its vehicle frame
/// id); with `all_frames`, pairs the file lacks count as empty. Returns the figures and the
/// number of pairs scored.
pub fn score_results(d: &Dair, results: &Results, all_frames: bool) -> (DairMetrics, usize) {
    let mut eval = DairEval::new();
    let mut scored = 0;
    for (i, f) in d.gt.frames.iter().enumerate() {
        let preds = match results.samples.get(&f.sample_token) {
            Some(p) => p.as_slice(),
            None if all_frames => &[],
            None => continue,
        };
        let Some(to_vehicle) = d.rec.pairs[i].veh_to_world.inverse() else {
            continue;
        };
        eval.add_frame(
            &gt_boxes(&f.objects, &to_vehicle),
            &detection_boxes(preds, &to_vehicle),
        );
        scored += 1;
    }
    (eval.summary(), scored)
}

/// The AP columns of a set of figures, in order (3D then BEV, each class and threshold).
fn ap_keys(m: &DairMetrics) -> Vec<(bool, String)> {
    m.ap_3d
        .keys()
        .map(|k| (true, k.clone()))
        .chain(m.ap_bev.keys().map(|k| (false, k.clone())))
        .collect()
}

fn ap_cell(m: &DairMetrics, (three_d, key): &(bool, String)) -> String {
    let map = if *three_d { &m.ap_3d } else { &m.ap_bev };
    map.get(key)
        .map_or_else(|| "-".into(), |v| format!("{:.2}", 100.0 * v))
}

fn frame_order_cell(m: &DairMetrics, (three_d, key): &(bool, String)) -> String {
    let map = if *three_d {
        &m.frame_order_ap_3d
    } else {
        &m.frame_order_ap_bev
    };
    map.get(key)
        .map_or_else(|| "-".into(), |v| format!("{:.2}", 100.0 * v))
}

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3}"))
}

impl Rows for [DairRow] {
    /// The rows as a Markdown table (AP in percent, as DAIR-V2X reports it).
    fn table(&self) -> String {
        let rows = self;
        let keys = rows.first().map(|r| ap_keys(&r.dair)).unwrap_or_default();
        let aps: Vec<String> = keys
            .iter()
            .map(|(three_d, k)| format!("AP-{} {k}", if *three_d { "3D" } else { "BEV" }))
            .collect();
        let mut columns = vec![
            ("agents / method", Left),
            ("precision", Right),
            ("recall", Right),
            ("mAP", Right),
            ("mATE (m)", Right),
        ];
        columns.extend(aps.iter().map(|h| (h.as_str(), Right)));
        columns.extend([
            ("bytes/frame", Right),
            ("CPM bytes/frame", Right),
            ("AB (official)", Right),
        ]);
        let bytes = |v: Option<f64>| v.map_or_else(|| "-".into(), |v| format!("{v:.0}"));
        let mut frame_order = vec![("agents / method", Left)];
        frame_order.extend(aps.iter().map(|h| (h.as_str(), Right)));
        let frame_order = markdown(
            &frame_order,
            rows.iter().map(|r| {
                let mut cells = vec![r.method.clone()];
                cells.extend(keys.iter().map(|k| frame_order_cell(&r.dair, k)));
                cells
            }),
        );
        let official = markdown(
            &columns,
            rows.iter().map(|r| {
                let mut cells = vec![
                    r.method.clone(),
                    opt(r.detection.precision),
                    opt(r.detection.recall),
                    format!("{:.4}", r.detection.m_ap),
                    format!("{:.3}", r.detection.m_ate),
                ];
                cells.extend(keys.iter().map(|k| ap_cell(&r.dair, k)));
                cells.extend([
                    bytes(r.bytes_per_frame),
                    bytes(r.cpm_bytes_per_frame),
                    bytes(r.official_ab),
                ]);
                cells
            }),
        );
        format!(
            "{official}\nDAIR-V2X's AP ranks every prediction of the split by score (a global \
             sort); the same AP in frame order (each frame's predictions by score, frames in \
             order, as V2V4Real publishes its AP):\n\n{frame_order}"
        )
    }

    /// The rows as CSV.
    fn csv(&self) -> Option<String> {
        let rows = self;
        let keys = rows.first().map(|r| ap_keys(&r.dair)).unwrap_or_default();
        let mut s = String::from("method,precision,recall,mAP,mATE");
        for (three_d, k) in &keys {
            s.push_str(&format!(",AP_{}_{k}", if *three_d { "3d" } else { "bev" }));
        }
        s.push_str(",bytes_per_frame,cpm_bytes_per_frame,official_ab\n");
        for r in rows {
            s.push_str(&format!(
                "{},{},{},{},{}",
                r.method,
                r.detection
                    .precision
                    .map_or(String::new(), |v| v.to_string()),
                r.detection.recall.map_or(String::new(), |v| v.to_string()),
                r.detection.m_ap,
                r.detection.m_ate
            ));
            for (three_d, k) in &keys {
                let map = if *three_d {
                    &r.dair.ap_3d
                } else {
                    &r.dair.ap_bev
                };
                s.push_str(&format!(
                    ",{}",
                    map.get(k).map_or(String::new(), |v| v.to_string())
                ));
            }
            let bytes = |v: Option<f64>| v.map_or(String::new(), |v| v.to_string());
            s.push_str(&format!(
                ",{},{},{}\n",
                bytes(r.bytes_per_frame),
                bytes(r.cpm_bytes_per_frame),
                bytes(r.official_ab)
            ));
        }
        Some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn fixture(name: &str) -> Dair {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../truth/fixtures/dair")
            .join(name);
        crate::dair::load_dair(&root, true).unwrap()
    }

    #[test]
    fn fusion_finds_what_either_side_alone_misses() {
        let d = fixture("dair-v2x-c");
        let methods: Vec<Method> = ["csba-wls+", "dair-v2x-late"]
            .iter()
            .map(|m| m.parse().unwrap())
            .collect();
        let labels = NoiseSetting::parse("labels", 2).unwrap();
        let rows = run(&d, &methods, &labels, 1, None);
        let names: Vec<&str> = rows.iter().map(|r| r.method.as_str()).collect();
        assert_eq!(names, ["veh", "inf", "csba-wls+", "dair-v2x-late"]);
        // Ground truth: car A (both), truck B (roadside only), van C (vehicle only), 3 frames.
        assert_eq!(rows[0].detection.classes, ["car", "truck"]);
        let recall = |r: &DairRow| r.detection.recall.unwrap();
        assert!((recall(&rows[0]) - 6.0 / 9.0).abs() < 1e-12);
        assert!((recall(&rows[1]) - 6.0 / 9.0).abs() < 1e-12);
        for r in &rows[2..] {
            assert_eq!(recall(r), 1.0, "{}", r.method);
            assert!(
                r.detection.m_ate < 1e-6,
                "{}: the labels coincide",
                r.method
            );
        }
        // With the offset on, every side's boxes are exact. The protocol's car is car, van and
        // truck: 9 in range, all hit by the fusion; its AP counts every recall step but the
        // first (the official quirk): (1 - 1/9) x 1.
        let ap = |r: &DairRow, k: &str| r.dair.ap_3d[k];
        assert!(
            (ap(&rows[2], "car@0.7") - 8.0 / 9.0).abs() < 1e-9,
            "{:?}",
            rows[2].dair
        );
        // The vehicle alone: 6 hits over 9, the first step skipped: 5/9 at precision 1.
        assert!(
            (ap(&rows[0], "car@0.7") - 5.0 / 9.0).abs() < 1e-9,
            "{:?}",
            rows[0].dair
        );
        // Bytes: the roadside sends its three boxes, and the official count 72 per box in
        // range (car, truck and pedestrian all within 80 m ahead of the vehicle).
        assert_eq!(rows[1].official_ab, Some(216.0));
        assert_eq!(rows[0].official_ab, Some(0.0));
        assert!(rows[2].bytes_per_frame > rows[1].bytes_per_frame);
        let cpm = |k: usize| rows[k].cpm_bytes_per_frame.unwrap();
        assert!((cpm(2) - cpm(0) - cpm(1)).abs() < 1e-9 && cpm(1) > 0.0);
    }
}
