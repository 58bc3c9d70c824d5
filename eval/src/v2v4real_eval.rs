//! V2V4Real's detection protocol, as its OpenCOOD `eval_utils` computes it: average precision
//! of cars at IoU 0.3, 0.5 and 0.7 over every frame, in the ego car's LiDAR frame, bird's-eye
//! view (the official IoU) and 3D beside it; overall and by range (0-30, 30-50, 50-100 m).
//!
//! Each step mirrors `caluclate_tp_fp` and `calculate_ap`, so that the figures compare with
//! published ones:
//! - IoU: intersection over union of the boxes' footprints (the official code's polygons), or of
//!   the rotated boxes for the 3D view.
//! - Matching, per frame: the predictions by score, highest first (ties in their given order),
//!   each a true positive when its best IoU with the ground truth not yet taken reaches the
//!   threshold, taking that box; else a false positive.
//! - Range: a box (prediction or label) is in a range when its centre's distance from the ego
//!   car, in the ground plane, lies strictly between the range's bounds; predictions and labels
//!   outside it are left out before matching. The overall figure takes every box.
//! - AP, two orderings of the same true and false positives. [`Ordering::Frame`], V2V4Real's
//!   published figure: the frames' true and false positives concatenated *in frame order*, not
//!   re-sorted by score across frames (`calculate_ap` as V2V4Real ships it never sorts), which
//!   comes close to precision times recall and so rewards dropping low-score boxes.
//!   [`Ordering::Global`], OpenCOOD's `--global_sort_detections` ("the mainstream AP computing
//!   method"): every prediction of the split ranked by its score, highest first (ties in frame
//!   order). Either way recall and precision are cumulated along the order; VOC 2010
//!   interpolation: precision made non-increasing from the right over recall padded with 0 and
//!   1, summed over the steps where recall changes.

use crate::dair_eval::View;
use serde::Serialize;
use std::collections::BTreeMap;
use v2x_fuser::maths::geometry::{bev_iou, iou_3d};
use v2x_protocol::Detection;

/// The IoU thresholds scored.
pub const THRESHOLDS: [f64; 3] = [0.3, 0.5, 0.7];

/// The distance bands V2V4Real reports beside the overall figure (m from the ego car).
pub const RANGES: [(f64, f64); 3] = [(0.0, 30.0), (30.0, 50.0), (50.0, 100.0)];

/// How the split's true and false positives are ordered before precision and recall are
/// cumulated.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ordering {
    /// Frame by frame (each frame's predictions by score), as V2V4Real publishes its AP.
    Frame,
    /// Every prediction of the split by score, as OpenCOOD's `--global_sort_detections`.
    Global,
}

impl Ordering {
    /// Both, the published one first.
    pub const ALL: [Ordering; 2] = [Ordering::Frame, Ordering::Global];

    /// The name tables use.
    pub fn name(self) -> &'static str {
        match self {
            Ordering::Frame => "frame order",
            Ordering::Global => "global sort",
        }
    }
}

/// The predictions of one view, threshold and range, in frame order (each with its score and
/// whether it was a true positive), and the ground truth.
#[derive(Clone, Debug, Default, PartialEq)]
struct Tally {
    tp: Vec<(f64, bool)>,
    gt: usize,
}

impl Tally {
    /// Whether each prediction was a true positive, in `ordering`.
    fn hits(&self, ordering: Ordering) -> Vec<bool> {
        let mut tp = self.tp.clone();
        if ordering == Ordering::Global {
            tp.sort_by(|a, b| b.0.total_cmp(&a.0));
        }
        tp.into_iter().map(|t| t.1).collect()
    }

    fn ap(&self, ordering: Ordering) -> Option<f64> {
        voc_ap(self.hits(ordering), self.gt)
    }
}

/// Index of the overall band in the tallies; bands of [`RANGES`] follow.
const BANDS: usize = 1 + RANGES.len();

/// Accumulates frames for the protocol; [`V2v4realEval::summary`] gives the APs.
#[derive(Clone, Debug, PartialEq)]
pub struct V2v4realEval {
    /// Per band (overall, then [`RANGES`]), view (3D, BEV) and threshold.
    tallies: [[[Tally; 3]; 2]; BANDS],
    frames: usize,
}

impl Default for V2v4realEval {
    fn default() -> Self {
        Self::new()
    }
}

/// AP per threshold (`"0.50"`) of one ordering, BEV and 3D.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Aps {
    /// Bird's-eye-view AP by threshold, the official IoU.
    pub bev: BTreeMap<String, f64>,
    /// 3D AP by threshold.
    pub three_d: BTreeMap<String, f64>,
}

impl Aps {
    /// The AP of a view at a threshold (`None`: no ground truth).
    pub fn get(&self, view: View, threshold: f64) -> Option<f64> {
        let map = match view {
            View::Bev => &self.bev,
            View::ThreeD => &self.three_d,
        };
        map.get(&format!("{threshold:.2}")).copied()
    }
}

/// One distance band's figures.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct BandMetrics {
    /// `"0-30"`, `"30-50"` or `"50-100"` (m).
    pub range: String,
    /// In frame order.
    pub frame: Aps,
    /// Globally sorted.
    pub global: Aps,
    /// Labels in the band.
    pub gt: usize,
    /// Predictions in the band.
    pub predictions: usize,
}

/// The protocol's figures: AP per threshold, BEV and 3D, in both orderings, overall and by
/// range.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct V2v4realMetrics {
    /// Bird's-eye-view AP by threshold in frame order: the official figure.
    pub ap_bev: BTreeMap<String, f64>,
    /// 3D AP by threshold in frame order.
    pub ap_3d: BTreeMap<String, f64>,
    /// Both views globally sorted (OpenCOOD's `--global_sort_detections`).
    pub global: Aps,
    /// By distance from the ego car ([`RANGES`]).
    pub ranges: Vec<BandMetrics>,
    /// Frames scored.
    pub frames: usize,
    /// Ground-truth boxes.
    pub gt: usize,
    /// Predictions.
    pub predictions: usize,
}

impl V2v4realMetrics {
    /// The overall APs in one ordering.
    pub fn aps(&self, ordering: Ordering) -> Aps {
        match ordering {
            Ordering::Frame => Aps {
                bev: self.ap_bev.clone(),
                three_d: self.ap_3d.clone(),
            },
            Ordering::Global => self.global.clone(),
        }
    }
}

fn slot(view: View) -> usize {
    match view {
        View::ThreeD => 0,
        View::Bev => 1,
    }
}

/// Whether a box lies in band `b` (0: overall).
fn in_band(b: usize, d: &Detection) -> bool {
    if b == 0 {
        return true;
    }
    let (lo, hi) = RANGES[b - 1];
    let r = d.center[0].hypot(d.center[1]);
    lo < r && r < hi
}

impl V2v4realEval {
    /// No frame yet.
    pub fn new() -> Self {
        V2v4realEval {
            tallies: Default::default(),
            frames: 0,
        }
    }

    /// Scores one frame: its ground truth and predictions (every box a car, as in V2V4Real).
    pub fn add_frame(&mut self, gt: &[Detection], preds: &[Detection]) {
        let mut order: Vec<&Detection> = preds.iter().collect();
        order.sort_by(|a, b| b.score.total_cmp(&a.score));
        for view in [View::ThreeD, View::Bev] {
            let iou = match view {
                View::ThreeD => iou_3d,
                View::Bev => bev_iou,
            };
            let ious: Vec<Vec<f64>> = order
                .iter()
                .map(|p| gt.iter().map(|g| iou(p, g)).collect())
                .collect();
            for (band, tallies) in self.tallies.iter_mut().enumerate() {
                let gts: Vec<usize> = (0..gt.len()).filter(|&k| in_band(band, &gt[k])).collect();
                for (t, &thr) in tallies[slot(view)].iter_mut().zip(&THRESHOLDS) {
                    let mut left = gts.clone();
                    for (p, row) in order.iter().zip(&ious) {
                        if !in_band(band, p) {
                            continue;
                        }
                        let best = left.iter().enumerate().map(|(k, &g)| (k, row[g])).fold(
                            None,
                            |m: Option<(usize, f64)>, (k, v)| match m {
                                Some((_, b)) if b >= v => m,
                                _ => Some((k, v)),
                            },
                        );
                        match best {
                            Some((k, v)) if v >= thr => {
                                left.remove(k);
                                t.tp.push((p.score, true));
                            }
                            _ => t.tp.push((p.score, false)),
                        }
                    }
                    t.gt += gts.len();
                }
            }
        }
        self.frames += 1;
    }

    /// Appends another accumulation's frames after this one's.
    pub fn merge(&mut self, other: V2v4realEval) {
        for (band, theirs) in self.tallies.iter_mut().zip(other.tallies) {
            for (mine, theirs) in band.iter_mut().zip(theirs) {
                for (a, b) in mine.iter_mut().zip(theirs) {
                    a.tp.extend(b.tp);
                    a.gt += b.gt;
                }
            }
        }
        self.frames += other.frames;
    }

    /// Overall AP of one view at one of [`THRESHOLDS`] in frame order (`None`: no ground
    /// truth, or not a threshold).
    pub fn ap(&self, view: View, threshold: f64) -> Option<f64> {
        self.ap_in(0, view, threshold, Ordering::Frame)
    }

    /// AP of band `band` (0: overall, then [`RANGES`]) in `ordering`.
    fn ap_in(&self, band: usize, view: View, threshold: f64, ordering: Ordering) -> Option<f64> {
        let k = THRESHOLDS.iter().position(|&t| t == threshold)?;
        self.tallies[band][slot(view)][k].ap(ordering)
    }

    /// The precision-recall curve of one view and threshold, overall, in `ordering`: (recall,
    /// precision) after each prediction.
    pub fn curve(&self, view: View, threshold: f64, ordering: Ordering) -> Vec<(f64, f64)> {
        let Some(k) = THRESHOLDS.iter().position(|&t| t == threshold) else {
            return Vec::new();
        };
        let t = &self.tallies[0][slot(view)][k];
        let gt = t.gt.max(1) as f64;
        let mut hits = 0usize;
        t.hits(ordering)
            .into_iter()
            .enumerate()
            .map(|(i, hit)| {
                hits += hit as usize;
                (hits as f64 / gt, hits as f64 / (i + 1) as f64)
            })
            .collect()
    }

    fn aps(&self, band: usize, ordering: Ordering) -> Aps {
        let per = |view| {
            THRESHOLDS
                .iter()
                .filter_map(|&t| Some((format!("{t:.2}"), self.ap_in(band, view, t, ordering)?)))
                .collect()
        };
        Aps {
            bev: per(View::Bev),
            three_d: per(View::ThreeD),
        }
    }

    /// Every AP, with the counts.
    pub fn summary(&self) -> V2v4realMetrics {
        let frame = self.aps(0, Ordering::Frame);
        let t = &self.tallies[0][1][0];
        V2v4realMetrics {
            ap_bev: frame.bev,
            ap_3d: frame.three_d,
            global: self.aps(0, Ordering::Global),
            ranges: RANGES
                .iter()
                .enumerate()
                .map(|(k, (lo, hi))| {
                    let t = &self.tallies[k + 1][1][0];
                    BandMetrics {
                        range: format!("{lo}-{hi}"),
                        frame: self.aps(k + 1, Ordering::Frame),
                        global: self.aps(k + 1, Ordering::Global),
                        gt: t.gt,
                        predictions: t.tp.len(),
                    }
                })
                .collect(),
            frames: self.frames,
            gt: t.gt,
            predictions: t.tp.len(),
        }
    }
}

/// VOC 2010 AP of true positives in the order given, against `gt` boxes (`None` without any).
pub fn voc_ap(tp: impl IntoIterator<Item = bool>, gt: usize) -> Option<f64> {
    if gt == 0 {
        return None;
    }
    let mut rec = vec![0.0];
    let mut prec = vec![0.0];
    let (mut hits, mut seen) = (0usize, 0usize);
    for t in tp {
        seen += 1;
        hits += t as usize;
        rec.push(hits as f64 / gt as f64);
        prec.push(hits as f64 / seen as f64);
    }
    rec.push(1.0);
    prec.push(0.0);
    for i in (0..prec.len() - 1).rev() {
        prec[i] = prec[i].max(prec[i + 1]);
    }
    Some(
        (1..rec.len())
            .filter(|&i| rec[i] != rec[i - 1])
            .map(|i| (rec[i] - rec[i - 1]) * prec[i])
            .sum(),
    )
}

#[cfg(test)]
mod tests;
