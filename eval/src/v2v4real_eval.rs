//! V2V4Real's detection protocol, as its OpenCOOD `eval_utils` computes it: average precision
//! of cars at IoU 0.3, 0.5 and 0.7 over every frame, in the ego car's LiDAR frame, bird's-eye
//! view (the official IoU) and 3D beside it.
//!
//! Each step mirrors `caluclate_tp_fp` and `calculate_ap`, so that the figures compare with
//! published ones:
//! - IoU: intersection over union of the boxes' footprints (the official code's polygons), or of
//!   the rotated boxes for the 3D view.
//! - Matching, per frame: the predictions by score, highest first (ties in their given order),
//!   each a true positive when its best IoU with the ground truth not yet taken reaches the
//!   threshold, taking that box; else a false positive.
//! - AP: the frames' true and false positives concatenated *in frame order*, not re-sorted by
//!   score across frames (the official `calculate_ap` never sorts); recall and precision
//!   cumulated along that order; VOC 2010 interpolation: precision made non-increasing from the
//!   right over recall padded with 0 and 1, summed over the steps where recall changes.
//! - No range filter beyond the data's own (the official call passes none for the overall AP).

use crate::dair_eval::View;
use serde::Serialize;
use std::collections::BTreeMap;
use v2x_fuser::maths::geometry::{bev_iou, iou_3d};
use v2x_protocol::Detection;

/// The IoU thresholds scored.
pub const THRESHOLDS: [f64; 3] = [0.3, 0.5, 0.7];

/// The true and false positives of one view and threshold, in frame order, and the ground truth.
#[derive(Clone, Debug, Default, PartialEq)]
struct Tally {
    tp: Vec<bool>,
    gt: usize,
}

/// Accumulates frames for the protocol; [`V2v4realEval::summary`] gives the APs.
#[derive(Clone, Debug, PartialEq)]
pub struct V2v4realEval {
    /// Per view (3D, BEV) and threshold.
    tallies: [[Tally; 3]; 2],
    frames: usize,
}

impl Default for V2v4realEval {
    fn default() -> Self {
        Self::new()
    }
}

/// The protocol's figures: AP per threshold (`"0.50"`), BEV and 3D.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct V2v4realMetrics {
    /// Bird's-eye-view AP by threshold, the official figure.
    pub ap_bev: BTreeMap<String, f64>,
    /// 3D AP by threshold.
    pub ap_3d: BTreeMap<String, f64>,
    /// Frames scored.
    pub frames: usize,
    /// Ground-truth boxes.
    pub gt: usize,
    /// Predictions.
    pub predictions: usize,
}

fn slot(view: View) -> usize {
    match view {
        View::ThreeD => 0,
        View::Bev => 1,
    }
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
            for (t, &thr) in self.tallies[slot(view)].iter_mut().zip(&THRESHOLDS) {
                let mut left: Vec<&Detection> = gt.iter().collect();
                for p in &order {
                    let best = left.iter().enumerate().map(|(k, g)| (k, iou(p, g))).fold(
                        None,
                        |m: Option<(usize, f64)>, (k, v)| match m {
                            Some((_, b)) if b >= v => m,
                            _ => Some((k, v)),
                        },
                    );
                    match best {
                        Some((k, v)) if v >= thr => {
                            left.remove(k);
                            t.tp.push(true);
                        }
                        _ => t.tp.push(false),
                    }
                }
                t.gt += gt.len();
            }
        }
        self.frames += 1;
    }

    /// Appends another accumulation's frames after this one's.
    pub fn merge(&mut self, other: V2v4realEval) {
        for (mine, theirs) in self.tallies.iter_mut().zip(other.tallies) {
            for (a, b) in mine.iter_mut().zip(theirs) {
                a.tp.extend(b.tp);
                a.gt += b.gt;
            }
        }
        self.frames += other.frames;
    }

    /// AP of one view at one of [`THRESHOLDS`] (`None`: no ground truth, or not a threshold).
    pub fn ap(&self, view: View, threshold: f64) -> Option<f64> {
        let k = THRESHOLDS.iter().position(|&t| t == threshold)?;
        let t = &self.tallies[slot(view)][k];
        voc_ap(&t.tp, t.gt)
    }

    /// Every AP, with the counts.
    pub fn summary(&self) -> V2v4realMetrics {
        let per = |view| {
            THRESHOLDS
                .iter()
                .filter_map(|&t| Some((format!("{t:.2}"), self.ap(view, t)?)))
                .collect()
        };
        let t = &self.tallies[1][0];
        V2v4realMetrics {
            ap_bev: per(View::Bev),
            ap_3d: per(View::ThreeD),
            frames: self.frames,
            gt: t.gt,
            predictions: t.tp.len(),
        }
    }
}

/// VOC 2010 AP of true positives in the order given, against `gt` boxes (`None` without any).
pub fn voc_ap(tp: &[bool], gt: usize) -> Option<f64> {
    if gt == 0 {
        return None;
    }
    let mut rec = vec![0.0];
    let mut prec = vec![0.0];
    let (mut hits, mut seen) = (0usize, 0usize);
    for &t in tp {
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
