//! DAIR-V2X runs offline (`v2x-sim bench --dataset dair-v2x`, `v2x-sim eval --dataset
//! dair-v2x`): the vehicle alone, the roadside alone and every method fusing the two, each
//! scored by the nuScenes-style benchmark over the classes the ground truth holds and by the
//! DAIR-V2X protocol in the vehicle's frame, with the bytes each frame costs on the wire.

use crate::bench::frames::{self, BenchFrame, Frames, RowBoxes};
use crate::bench::fusers::Fusers;
use crate::dair::{Dair, AGENTS};
use crate::dair_eval::{detection_boxes, gt_boxes, official_bytes, DairEval, DairMetrics};
use crate::dataset::GtObject;
use crate::detection_eval::{DetectionEval, DetectionMetrics};
use crate::noise::NoiseSetting;
use crate::table::{
    markdown,
    Align::{Left, Right},
    Rows,
};
use crate::wire_bytes::{frame_bytes, Bytes};
use serde::Serialize;
use v2x_eval::protocol::{Merge, VehicleFrame};
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

/// What the two agents' frames cost on the air, and the roadside's boxes as the official
/// late-fusion evaluation counts them.
#[derive(Clone, Copy, Default)]
pub struct DairCost {
    bytes: [Bytes; 2],
    official: usize,
}

impl Merge for DairCost {
    fn absorb(&mut self, other: Self) {
        self.bytes[0] += other.bytes[0];
        self.bytes[1] += other.bytes[1];
        self.official += other.official;
    }
}

/// DAIR-V2X's pairs as the bench reads them: each side's labels as `setting` sees them, scored
/// devkit-style over the world's labels and by DAIR-V2X's protocol in the vehicle's frame.
pub struct DairFrames<'a> {
    d: &'a Dair,
    setting: &'a NoiseSetting,
    seed: u64,
    range: Option<f64>,
}

impl Frames for DairFrames<'_> {
    type Truth = (Vec<GtObject>, VehicleFrame);
    type Cost = DairCost;

    fn count(&self) -> usize {
        self.d.gt.frames.len()
    }

    /// Pair `i`, unless its vehicle pose cannot be inverted.
    fn frame(&self, i: usize) -> Option<BenchFrame<Self::Truth>> {
        let to_vehicle = self.d.rec.pairs[i].veh_to_world.inverse()?;
        let objects = self.d.gt.frames[i].objects.clone();
        let boxes = gt_boxes(&objects, &to_vehicle);
        Some(BenchFrame {
            index: i,
            agents: (0..2)
                .map(|a| {
                    let noise = &self.setting.agents[a];
                    self.d.detections(a, i, noise, self.seed, self.range)
                })
                .collect(),
            kinds: vec![AgentKind::Vehicle, AgentKind::Infrastructure],
            t_us: self.d.capture_us(0, i),
            truth: (objects, VehicleFrame { boxes, to_vehicle }),
        })
    }

    fn cost(&self, f: &BenchFrame<Self::Truth>) -> DairCost {
        let mut cost = DairCost::default();
        for (a, dets) in f.agents.iter().enumerate() {
            cost.bytes[a] += wire_bytes(a, self.d.capture_us(a, f.index), dets);
        }
        let roadside_in_range = detection_boxes(&f.agents[1], &f.truth.1.to_vehicle).len();
        cost.official = official_bytes(roadside_in_range);
        cost
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
    let source = DairFrames {
        d,
        setting,
        seed,
        range,
    };
    let row_boxes = RowBoxes::agents_then_methods(2, methods.len());
    let fusers = Fusers::new(methods, 2, None);
    let new = || (DetectionEval::new(), DairEval::new());
    let totals = frames::score(&source, &row_boxes, &fusers, new, &|| ());
    let per_frame = |b: usize| b as f64 / totals.frames.max(1) as f64;
    let both = |b: Bytes| (per_frame(b.frame), per_frame(b.cpm));
    let [veh, inf] = totals.cost.bytes;
    let mut pair = veh;
    pair += inf;
    let names = AGENTS
        .iter()
        .map(|a| a.to_string())
        .chain(methods.iter().map(Method::name));
    names
        .zip(&totals.rows)
        .enumerate()
        .map(|(k, (method, (det, dair)))| {
            let ((bytes, cpm), official) = match k {
                0 => (both(veh), 0.0),
                1 => (both(inf), per_frame(totals.cost.official)),
                _ => (both(pair), per_frame(totals.cost.official)),
            };
            DairRow {
                method,
                detection: det.summary_over(&det.ground_truth_classes()),
                dair: dair.summary(),
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
