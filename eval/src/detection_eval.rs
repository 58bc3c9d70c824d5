//! The nuScenes detection benchmark, sans-IO: predictions matched to ground truth by centre
//! distance, not by id, so a detector's own output (which has no ground-truth ids) can be
//! scored. It follows the devkit's `accumulate`, `calc_ap` and `calc_tp` with the
//! `detection_cvpr_2019` configuration (`docs/method.md` §6.1):
//!
//! - per class, every prediction in descending score order is matched to the nearest unmatched
//!   ground-truth box of its class in its frame (2D centre distance); it is a true positive when
//!   that distance is below the threshold;
//! - precision is sampled at 101 recall points, linearly interpolated as `np.interp` does;
//!   AP is the mean of max(0, precision - 0.1) / 0.9 above 10% recall, at 0.5, 1, 2 and 4 m;
//! - the TP errors (ATE, ASE = 1 - aligned-box IoU, AOE in radians with period pi for barriers,
//!   AVE, AAE) are cumulative means over the matches at 2 m, read at the same recall points and
//!   averaged from 10% recall to the highest recall reached (1 when it is not reached);
//! - mAP and the mean TP errors are taken over the ten classes, a class without ground truth
//!   scoring AP 0 and errors 1 (as in the devkit); NDS = (5 mAP + sum of max(0, 1 - error)) / 10.
//!   [`DetectionEval::summary_over`] takes them over a subset instead (`v2x-sim eval` by default
//!   over the classes the ground truth holds), the ten-class mAP and NDS still reported;
//! - equal scores are broken as the devkit breaks them: the prediction added later first, frames
//!   in the order added (`v2x-sim eval` adds a file's samples in the order the file lists them,
//!   as the devkit reads them), and among equally near ground-truth boxes the first listed.
//!
//! Not applied: the devkit's per-class range filter around the ego vehicle and its removal of
//! boxes without lidar points (the evaluation has no ego pose; the simulated agents' own range
//! plays that part). Predictions carry no attribute, so AAE is 1 wherever it is defined.

use crate::metrics::ClassErrors;
use serde::Serialize;
use std::collections::BTreeMap;
use v2x_protocol::{Class, Detection};
use v2x_truth::dataset::GtObject;

/// Centre-distance thresholds of the AP (m).
pub const DIST_THS: [f64; 4] = [0.5, 1.0, 2.0, 4.0];
/// The threshold at which TP errors are measured (m).
pub const DIST_TH_TP: f64 = 2.0;
const MIN_RECALL: f64 = 0.1;
const MIN_PRECISION: f64 = 0.1;
const MEAN_AP_WEIGHT: f64 = 5.0;
/// Recall sampling points.
const NELEM: usize = 101;

/// The TP error names, in the devkit's order.
pub const TP_METRICS: [&str; 5] = [
    "trans_err",
    "scale_err",
    "orient_err",
    "vel_err",
    "attr_err",
];

/// One prediction as the matcher sees it.
#[derive(Clone, Debug)]
struct Pred {
    frame: usize,
    score: f64,
    det: Detection,
}

/// Collects frames, then scores them all at once (AP needs every prediction of a class).
#[derive(Clone, Debug, Default)]
pub struct DetectionEval {
    gt: Vec<Vec<GtObject>>,
    preds: Vec<Pred>,
}

/// A class's curves at one threshold, sampled at the 101 recall points.
#[derive(Clone, Debug)]
struct Curves {
    precision: Vec<f64>,
    confidence: Vec<f64>,
    /// Per TP metric, the error curve.
    errors: [Vec<f64>; 5],
    /// True and false positives over all predictions (not interpolated).
    tp: usize,
    fp: usize,
}

impl Curves {
    fn no_predictions() -> Self {
        Curves {
            precision: vec![0.0; NELEM],
            confidence: vec![0.0; NELEM],
            errors: std::array::from_fn(|_| vec![1.0; NELEM]),
            tp: 0,
            fp: 0,
        }
    }
}

/// `np.interp(x, xp, fp, right=right)` for non-decreasing `xp` (left: `fp[0]`).
pub(crate) fn interp(x: f64, xp: &[f64], fp: &[f64], right: f64) -> f64 {
    let last = xp.len() - 1;
    if x > xp[last] {
        return right;
    }
    if x == xp[last] {
        return fp[last];
    }
    let k = xp.partition_point(|&v| v <= x);
    if k == 0 {
        return fp[0];
    }
    let j = k - 1;
    if xp[j] == x {
        return fp[j];
    }
    let slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]);
    let y = slope * (x - xp[j]) + fp[j];
    if y.is_nan() {
        let y2 = slope * (x - xp[j + 1]) + fp[j + 1];
        if y2.is_nan() && fp[j] == fp[j + 1] {
            return fp[j];
        }
        return y2;
    }
    y
}

/// The devkit's `cummean`: running mean ignoring NaN (0 before the first value; all ones when
/// every value is NaN).
fn cummean(x: &[f64]) -> Vec<f64> {
    if x.iter().all(|v| v.is_nan()) {
        return vec![1.0; x.len()];
    }
    let (mut sum, mut n) = (0.0, 0usize);
    x.iter()
        .map(|&v| {
            if !v.is_nan() {
                sum += v;
                n += 1;
            }
            if n == 0 {
                0.0
            } else {
                sum / n as f64
            }
        })
        .collect()
}

/// The devkit's `angle_diff` made absolute: the smallest rotation between two yaws of `period`.
fn yaw_diff(gt: f64, pred: f64, period: f64) -> f64 {
    let mut d = (gt - pred + period / 2.0).rem_euclid(period) - period / 2.0;
    if d > std::f64::consts::PI {
        d -= 2.0 * std::f64::consts::PI;
    }
    d.abs()
}

/// IoU of two boxes aligned at the same centre and heading.
fn scale_iou(a: [f64; 3], b: [f64; 3]) -> f64 {
    let inter: f64 = (0..3).map(|k| a[k].min(b[k])).product();
    let (va, vb): (f64, f64) = (a.iter().product(), b.iter().product());
    inter / (va + vb - inter)
}

fn centre_distance(g: &GtObject, p: &Detection) -> f64 {
    (g.center[0] - p.center[0]).hypot(g.center[1] - p.center[1])
}

/// The five TP errors of a matched pair (NaN where undefined).
fn tp_errors(g: &GtObject, p: &Detection) -> [f64; 5] {
    let period = if g.class == Class::Barrier {
        std::f64::consts::PI
    } else {
        2.0 * std::f64::consts::PI
    };
    // A results file writes a box without velocity as (0, 0); the devkit reads it so.
    let pv = p.velocity.map_or([0.0, 0.0], |v| v.v);
    let vel = match g.velocity {
        Some(gv) => (pv[0] - gv[0]).hypot(pv[1] - gv[1]),
        None => f64::NAN,
    };
    [
        centre_distance(g, p),
        1.0 - scale_iou(g.size, p.size),
        yaw_diff(g.yaw, p.yaw, period),
        vel,
        // No predicted attributes: wrong (or undefined, which the devkit also scores 1).
        f64::NAN,
    ]
}

impl DetectionEval {
    /// An empty evaluation.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one frame: its ground truth and the predictions for it.
    pub fn add_frame(&mut self, gt: &[GtObject], preds: &[Detection]) {
        let frame = self.gt.len();
        self.gt.push(gt.to_vec());
        self.preds.extend(preds.iter().map(|d| Pred {
            frame,
            score: d.score,
            det: d.clone(),
        }));
    }

    /// Appends another evaluation's frames after this one's (in order, so that a parallel
    /// fold-and-reduce over frames gives the same result as one pass).
    pub fn merge(&mut self, other: DetectionEval) {
        let offset = self.gt.len();
        self.gt.extend(other.gt);
        self.preds.extend(other.preds.into_iter().map(|mut p| {
            p.frame += offset;
            p
        }));
    }

    /// Frames added so far.
    pub fn frames(&self) -> usize {
        self.gt.len()
    }

    /// Ground-truth boxes of a class over all frames.
    fn ground_truth(&self, class: Class) -> usize {
        self.gt
            .iter()
            .flatten()
            .filter(|g| g.class == class)
            .count()
    }

    /// The devkit's `accumulate` for one class and threshold.
    fn accumulate(&self, class: Class, th: f64) -> Curves {
        let npos = self.ground_truth(class);
        let preds: Vec<&Pred> = self.preds.iter().filter(|p| p.det.class == class).collect();
        if npos == 0 {
            // the devkit's AP of a class without ground truth is 0; its boxes are all false
            return Curves {
                fp: preds.len(),
                ..Curves::no_predictions()
            };
        }
        // Descending score; among equal scores the later prediction first (the devkit reverses
        // an ascending sort of (score, index)).
        let mut order: Vec<usize> = (0..preds.len()).collect();
        order.sort_by(|&a, &b| preds[b].score.total_cmp(&preds[a].score).then(b.cmp(&a)));
        let mut taken: Vec<Vec<bool>> = self.gt.iter().map(|g| vec![false; g.len()]).collect();
        let (mut tp, mut fp, mut conf) = (Vec::new(), Vec::new(), Vec::new());
        let mut match_errors: [Vec<f64>; 5] = Default::default();
        let mut match_conf = Vec::new();
        let (mut ntp, mut nfp) = (0usize, 0usize);
        for &i in &order {
            let p = preds[i];
            match self.closest(p, class, &taken[p.frame]) {
                Some((gi, d)) if d < th => {
                    taken[p.frame][gi] = true;
                    ntp += 1;
                    let e = tp_errors(&self.gt[p.frame][gi], &p.det);
                    for (k, v) in e.into_iter().enumerate() {
                        match_errors[k].push(v);
                    }
                    match_conf.push(p.score);
                }
                _ => nfp += 1,
            }
            tp.push(ntp as f64);
            fp.push(nfp as f64);
            conf.push(p.score);
        }
        if match_conf.is_empty() {
            return Curves {
                tp: 0,
                fp: nfp,
                ..Curves::no_predictions()
            };
        }
        let prec: Vec<f64> = tp.iter().zip(&fp).map(|(t, f)| t / (t + f)).collect();
        let rec: Vec<f64> = tp.iter().map(|t| t / npos as f64).collect();
        // np.linspace(0, 1, 101): i x 0.01, the last point exactly 1.
        let mut points: Vec<f64> = (0..NELEM).map(|i| i as f64 * 0.01).collect();
        points[NELEM - 1] = 1.0;
        let precision: Vec<f64> = points
            .iter()
            .map(|&r| interp(r, &rec, &prec, 0.0))
            .collect();
        let confidence: Vec<f64> = points
            .iter()
            .map(|&r| interp(r, &rec, &conf, 0.0))
            .collect();
        // Errors at each recall point: the cumulative mean at that confidence.
        let conf_asc: Vec<f64> = match_conf.iter().rev().copied().collect();
        let errors = match_errors.map(|e| {
            let mean_asc: Vec<f64> = cummean(&e).into_iter().rev().collect();
            let mut out: Vec<f64> = confidence
                .iter()
                .rev()
                .map(|&c| interp(c, &conf_asc, &mean_asc, *mean_asc.last().expect("matches")))
                .collect();
            out.reverse();
            out
        });
        Curves {
            precision,
            confidence,
            errors,
            tp: ntp,
            fp: nfp,
        }
    }

    /// The closest ground-truth box of `class` in `p`'s frame not yet `taken`, and its distance.
    fn closest(&self, p: &Pred, class: Class, taken: &[bool]) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        for (gi, g) in self.gt[p.frame].iter().enumerate() {
            if g.class == class && !taken[gi] {
                let d = centre_distance(g, &p.det);
                if best.is_none_or(|(_, m)| d < m) {
                    best = Some((gi, d));
                }
            }
        }
        best
    }

    /// Every figure of the benchmark, the headline averaged over the ten classes as the devkit
    /// averages it.
    pub fn summary(&self) -> DetectionMetrics {
        self.summary_over(&Class::ALL)
    }

    /// The classes that have ground truth in the frames added, in [`Class::ALL`] order.
    pub fn ground_truth_classes(&self) -> Vec<Class> {
        Class::ALL
            .into_iter()
            .filter(|c| self.ground_truth(*c) > 0)
            .collect()
    }

    /// Every figure of the benchmark, the headline (mAP, NDS, the mean TP errors, precision and
    /// recall) taken over `classes` only; the ten-class mAP and NDS beside it. With no class
    /// given, over the ten.
    pub fn summary_over(&self, classes: &[Class]) -> DetectionMetrics {
        let classes: Vec<Class> = if classes.is_empty() {
            Class::ALL.to_vec()
        } else {
            Class::ALL
                .into_iter()
                .filter(|c| classes.contains(c))
                .collect()
        };
        let mut per_class = BTreeMap::new();
        // per class: its mean AP and TP errors, in Class::ALL order
        let mut scored: Vec<(Class, f64, [Option<f64>; 5])> = Vec::new();
        let (mut tp2, mut fp2, mut npos) = (0, 0, 0);
        for class in Class::ALL {
            let mut ap = BTreeMap::new();
            let mut class_aps = Vec::new();
            let mut at_tp = None;
            for th in DIST_THS {
                let c = self.accumulate(class, th);
                let a = calc_ap(&c);
                ap.insert(format!("{th}"), a);
                class_aps.push(a);
                if th == DIST_TH_TP {
                    at_tp = Some(c);
                }
            }
            let c = at_tp.expect("the TP threshold is one of the thresholds");
            let errs = calc_tp(&c, class);
            let n_gt = self.ground_truth(class);
            if classes.contains(&class) {
                tp2 += c.tp;
                fp2 += c.fp;
                npos += n_gt;
            }
            let mean_ap = class_aps.iter().sum::<f64>() / class_aps.len() as f64;
            scored.push((class, mean_ap, errs));
            per_class.insert(
                class.name().to_string(),
                ClassDetection {
                    ap,
                    mean_ap,
                    errors: ClassErrors {
                        ate: errs[0],
                        ase: errs[1],
                        aoe: errs[2],
                        ave: errs[3],
                    },
                    aae: errs[4],
                    gt: n_gt,
                    tp: c.tp,
                    fp: c.fp,
                },
            );
        }
        let (m_ap, nds, tp_err) = headline(&scored, &classes);
        let (m_ap_all, nds_all, _) = headline(&scored, &Class::ALL);
        DetectionMetrics {
            m_ap,
            nds,
            m_ate: tp_err[0],
            m_ase: tp_err[1],
            m_aoe: tp_err[2],
            m_ave: tp_err[3],
            m_aae: tp_err[4],
            classes: classes.iter().map(|c| c.name().to_string()).collect(),
            m_ap_all,
            nds_all,
            precision: (tp2 + fp2 > 0).then(|| tp2 as f64 / (tp2 + fp2) as f64),
            recall: (npos > 0).then(|| tp2 as f64 / npos as f64),
            tp: tp2,
            fp: fp2,
            fn_: npos - tp2,
            frames: self.gt.len(),
            per_class,
        }
    }
}

/// The first recall step the benchmark counts (recall above `MIN_RECALL`).
fn first_step() -> usize {
    (100.0 * MIN_RECALL).round() as usize + 1
}

/// The devkit's `calc_ap`: the mean of the precision above `MIN_PRECISION` over the recall
/// steps above `MIN_RECALL`, normalised.
fn calc_ap(c: &Curves) -> f64 {
    let first = first_step();
    c.precision[first..]
        .iter()
        .map(|p| (p - MIN_PRECISION).max(0.0))
        .sum::<f64>()
        / (NELEM - first) as f64
        / (1.0 - MIN_PRECISION)
}

/// The devkit's `calc_tp`: each TP error's mean over the recall steps above `MIN_RECALL` up to
/// the last with a prediction (1 when there is none); `None` for errors the class does not
/// define (a cone's orientation, velocity and attribute, a barrier's velocity and attribute).
fn calc_tp(c: &Curves, class: Class) -> [Option<f64>; 5] {
    let first = first_step();
    let last = c.confidence.iter().rposition(|&v| v != 0.0).unwrap_or(0);
    std::array::from_fn(|k| {
        let undefined = match class {
            Class::TrafficCone => k >= 2,
            Class::Barrier => k >= 3,
            _ => false,
        };
        if undefined {
            None
        } else if last < first {
            Some(1.0)
        } else {
            let v = &c.errors[k][first..=last];
            Some(v.iter().sum::<f64>() / v.len() as f64)
        }
    })
}

/// mAP, NDS and the class-mean TP errors over the classes `over` of the per-class rows
/// (class, mean AP, TP errors).
fn headline(scored: &[(Class, f64, [Option<f64>; 5])], over: &[Class]) -> (f64, f64, [f64; 5]) {
    let rows: Vec<&(Class, f64, [Option<f64>; 5])> =
        scored.iter().filter(|r| over.contains(&r.0)).collect();
    let m_ap = rows.iter().map(|r| r.1).sum::<f64>() / rows.len() as f64;
    let tp_err: [f64; 5] = std::array::from_fn(|k| {
        let v: Vec<f64> = rows.iter().filter_map(|r| r.2[k]).collect();
        // a metric no chosen class defines (cones alone: no AVE) counts as worst
        if v.is_empty() {
            1.0
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    });
    let tp_scores: f64 = tp_err.iter().map(|e| (1.0 - e).max(0.0)).sum();
    let nds = (MEAN_AP_WEIGHT * m_ap + tp_scores) / (MEAN_AP_WEIGHT + 5.0);
    (m_ap, nds, tp_err)
}

/// One class's benchmark figures.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ClassDetection {
    /// AP by centre-distance threshold (m).
    #[serde(rename = "AP")]
    pub ap: BTreeMap<String, f64>,
    /// Mean of the AP over the thresholds.
    #[serde(rename = "mean_AP")]
    pub mean_ap: f64,
    /// TP errors at 2 m: ATE (m), ASE (1 - aligned IoU), AOE (rad; none for traffic cones),
    /// AVE (m/s; none for barriers and cones).
    #[serde(flatten)]
    pub errors: ClassErrors,
    /// Attribute error; none for barriers and cones.
    #[serde(rename = "AAE")]
    pub aae: Option<f64>,
    /// Ground-truth boxes.
    pub gt: usize,
    /// True positives at 2 m (all predictions).
    pub tp: usize,
    /// False positives at 2 m (all predictions).
    pub fp: usize,
}

/// The nuScenes detection benchmark's figures (`eval --match distance --format json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct DetectionMetrics {
    /// Mean AP over the headline's classes and the four thresholds.
    #[serde(rename = "mAP")]
    pub m_ap: f64,
    /// nuScenes detection score over the headline's classes.
    #[serde(rename = "NDS")]
    pub nds: f64,
    /// Class-mean TP translation error (m).
    #[serde(rename = "mATE")]
    pub m_ate: f64,
    /// Class-mean TP scale error.
    #[serde(rename = "mASE")]
    pub m_ase: f64,
    /// Class-mean TP orientation error (rad).
    #[serde(rename = "mAOE")]
    pub m_aoe: f64,
    /// Class-mean TP velocity error (m/s).
    #[serde(rename = "mAVE")]
    pub m_ave: f64,
    /// Class-mean TP attribute error.
    #[serde(rename = "mAAE")]
    pub m_aae: f64,
    /// The classes the headline averages (all ten unless asked otherwise).
    pub classes: Vec<String>,
    /// Mean AP over all ten classes, as the devkit reports it (0 for a class without ground
    /// truth).
    #[serde(rename = "mAP_all10")]
    pub m_ap_all: f64,
    /// NDS over all ten classes, as the devkit reports it.
    #[serde(rename = "NDS_all10")]
    pub nds_all: f64,
    /// TP / (TP + FP) at 2 m over the headline classes' predictions.
    pub precision: Option<f64>,
    /// TP / ground truth at 2 m over all predictions.
    pub recall: Option<f64>,
    /// True positives at 2 m.
    pub tp: usize,
    /// False positives at 2 m.
    pub fp: usize,
    /// Ground truth not matched at 2 m.
    #[serde(rename = "fn")]
    pub fn_: usize,
    /// Frames scored.
    pub frames: usize,
    /// Per class.
    pub per_class: BTreeMap<String, ClassDetection>,
}

#[cfg(test)]
mod tests;
