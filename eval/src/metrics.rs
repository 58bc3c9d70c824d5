//! Metrics of `docs/method.md` §6 (the paper's §4.3), sans-IO.
//!
//! Predictions are matched to ground truth by object id: for each ground-truth object the
//! closest prediction carrying its id (2D centre distance) is a true positive, any other one
//! carrying it a false positive; an object with no prediction is a false negative, and a
//! prediction whose id is not in the frame's ground truth (or that has none) is a false positive
//! with no error to measure. Errors are false-positive-penalised: every prediction with a
//! ground-truth id, TP or FP, contributes its error against that object, averaged per class
//! (the ground truth's class) and then over the classes that have any ("m" = class mean). The
//! TP-only variant (nuScenes style) averages over true positives alone.
//! ATE: 2D centre distance (m); ASE: Euclidean distance of (l, w, h) (m); AOE: |yaw difference|
//! in degrees, with period pi for barriers and 2 pi otherwise.

use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use v2x_protocol::{wrap_angle, Class, Detection};
use v2x_truth::dataset::GtObject;

/// The errors of one prediction against its ground truth.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Errors {
    /// 2D centre distance (m).
    pub ate: f64,
    /// Euclidean distance of (l, w, h) (m).
    pub ase: f64,
    /// |yaw difference| (degrees; period pi for barriers).
    pub aoe: f64,
    /// 2D velocity error (m/s), when both have a velocity and the class moves (not for barriers
    /// and traffic cones, as in nuScenes).
    pub ave: Option<f64>,
}

/// Class-wise means of the errors: (ATE, ASE, AOE, AVE).
type Means = (f64, f64, f64, Option<f64>);

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sums {
    ate: f64,
    ase: f64,
    aoe: f64,
    n: usize,
    ave: f64,
    n_ave: usize,
}

impl Sums {
    fn add(&mut self, e: Errors) {
        self.ate += e.ate;
        self.ase += e.ase;
        self.aoe += e.aoe;
        self.n += 1;
        if let Some(v) = e.ave {
            self.ave += v;
            self.n_ave += 1;
        }
    }
    fn merge(&mut self, o: &Sums) {
        self.ate += o.ate;
        self.ase += o.ase;
        self.aoe += o.aoe;
        self.n += o.n;
        self.ave += o.ave;
        self.n_ave += o.n_ave;
    }
    fn means(&self) -> Option<Means> {
        (self.n > 0).then(|| {
            let n = self.n as f64;
            (
                self.ate / n,
                self.ase / n,
                self.aoe / n,
                (self.n_ave > 0).then(|| self.ave / self.n_ave as f64),
            )
        })
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct ClassSums {
    tp: usize,
    fp: usize,
    fn_: usize,
    all: Sums,
    tp_only: Sums,
}

/// Accumulates matches and errors over frames.
#[derive(Clone, Debug, Default)]
pub struct Accumulator {
    classes: BTreeMap<Class, ClassSums>,
}

/// The errors of a prediction against its ground truth.
pub fn errors(p: &Detection, g: &GtObject) -> Errors {
    let ate = (p.center[0] - g.center[0]).hypot(p.center[1] - g.center[1]);
    let ase = (0..3)
        .map(|k| (p.size[k] - g.size[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    let mut d = wrap_angle(p.yaw - g.yaw).abs();
    if g.class == Class::Barrier {
        d = d.min(std::f64::consts::PI - d);
    }
    let moves = !matches!(g.class, Class::Barrier | Class::TrafficCone);
    let ave = match (p.velocity, g.velocity) {
        (Some(pv), Some(gv)) if moves => Some((pv.v[0] - gv[0]).hypot(pv.v[1] - gv[1])),
        _ => None,
    };
    Errors {
        ate,
        ase,
        aoe: d.to_degrees(),
        ave,
    }
}

/// Predictions that carry no ground-truth id (a real detector's, a data set's own labels) given
/// the id of the object they match by centre distance, as the nuScenes benchmark matches at one
/// threshold: by score, highest first, each takes the nearest object of its class within `max_m`
/// that no earlier prediction took; the others keep no id. Predictions with ids keep them.
pub fn ids_by_distance(gt: &[GtObject], preds: &[Detection], max_m: f64) -> Vec<Detection> {
    let mut out = preds.to_vec();
    let mut order: Vec<usize> = (0..preds.len()).collect();
    order.sort_by(|&a, &b| preds[b].score.total_cmp(&preds[a].score).then(a.cmp(&b)));
    let mut taken = vec![false; gt.len()];
    for j in order {
        if out[j].id != v2x_protocol::NO_ID {
            continue;
        }
        let p = &preds[j];
        let best = gt
            .iter()
            .enumerate()
            .filter(|(i, g)| !taken[*i] && g.class == p.class)
            .map(|(i, g)| {
                (
                    i,
                    (p.center[0] - g.center[0]).hypot(p.center[1] - g.center[1]),
                )
            })
            .filter(|(_, d)| *d <= max_m)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, _)) = best {
            taken[i] = true;
            out[j].id = gt[i].id;
        }
    }
    out
}

impl Accumulator {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Scores one frame.
    pub fn add_frame(&mut self, gt: &[GtObject], preds: &[Detection]) {
        let index: HashMap<u32, usize> = gt.iter().enumerate().map(|(i, g)| (g.id, i)).collect();
        let mut claims: Vec<Vec<(usize, f64)>> = vec![Vec::new(); gt.len()];
        for (j, p) in preds.iter().enumerate() {
            match index.get(&p.id) {
                Some(&i) => {
                    let g = &gt[i];
                    claims[i].push((
                        j,
                        (p.center[0] - g.center[0]).hypot(p.center[1] - g.center[1]),
                    ));
                }
                None => self.classes.entry(p.class).or_default().fp += 1,
            }
        }
        for (i, g) in gt.iter().enumerate() {
            let c = self.classes.entry(g.class).or_default();
            let Some(&(best, _)) = claims[i]
                .iter()
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            else {
                c.fn_ += 1;
                continue;
            };
            for &(j, _) in &claims[i] {
                let e = errors(&preds[j], g);
                c.all.add(e);
                if j == best {
                    c.tp += 1;
                    c.tp_only.add(e);
                } else {
                    c.fp += 1;
                }
            }
        }
    }

    /// Adds another accumulator's counts.
    pub fn merge(&mut self, other: &Accumulator) {
        for (c, o) in &other.classes {
            let s = self.classes.entry(*c).or_default();
            s.tp += o.tp;
            s.fp += o.fp;
            s.fn_ += o.fn_;
            s.all.merge(&o.all);
            s.tp_only.merge(&o.tp_only);
        }
    }

    /// The metrics so far.
    pub fn summary(&self) -> Metrics {
        let mut per_class = BTreeMap::new();
        let (mut tp, mut fp, mut fn_) = (0, 0, 0);
        let mut all_means = Vec::new();
        let mut tp_means = Vec::new();
        for (c, s) in &self.classes {
            tp += s.tp;
            fp += s.fp;
            fn_ += s.fn_;
            let m = s.all.means();
            let t = s.tp_only.means();
            all_means.extend(m);
            tp_means.extend(t);
            per_class.insert(
                c.name().to_string(),
                ClassMetrics {
                    precision: ratio(s.tp, s.tp + s.fp),
                    recall: ratio(s.tp, s.tp + s.fn_),
                    errors: ClassErrors {
                        ate: m.map(|v| v.0),
                        ase: m.map(|v| v.1),
                        aoe: m.map(|v| v.2),
                        ave: m.and_then(|v| v.3),
                    },
                    tp: s.tp,
                    fp: s.fp,
                    fn_: s.fn_,
                    tp_only: ErrorMetrics::of(t.into_iter().collect::<Vec<_>>().as_slice()),
                },
            );
        }
        Metrics {
            precision: ratio(tp, tp + fp),
            recall: ratio(tp, tp + fn_),
            all: ErrorMetrics::of(&all_means),
            tp,
            fp,
            fn_,
            per_class,
            tp_only: ErrorMetrics::of(&tp_means),
        }
    }
}

fn ratio(a: usize, b: usize) -> Option<f64> {
    (b > 0).then(|| a as f64 / b as f64)
}

/// Class-mean errors.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ErrorMetrics {
    /// Mean ATE (m).
    #[serde(rename = "mATE")]
    pub m_ate: Option<f64>,
    /// Mean ASE (m).
    #[serde(rename = "mASE")]
    pub m_ase: Option<f64>,
    /// Mean AOE (degrees).
    #[serde(rename = "mAOE")]
    pub m_aoe: Option<f64>,
    /// Mean AVE (m/s), over the classes that have velocity errors.
    #[serde(rename = "mAVE")]
    pub m_ave: Option<f64>,
}

impl ErrorMetrics {
    fn of(means: &[Means]) -> Self {
        let mean = |v: Vec<f64>| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
        ErrorMetrics {
            m_ate: mean(means.iter().map(|m| m.0).collect()),
            m_ase: mean(means.iter().map(|m| m.1).collect()),
            m_aoe: mean(means.iter().map(|m| m.2).collect()),
            m_ave: mean(means.iter().filter_map(|m| m.3).collect()),
        }
    }
}

/// One class's mean errors (`ATE`, `ASE`, `AOE`, `AVE`), each as the figure holding them
/// defines it; none where the class has no such error.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ClassErrors {
    /// Translation error.
    #[serde(rename = "ATE")]
    pub ate: Option<f64>,
    /// Scale error.
    #[serde(rename = "ASE")]
    pub ase: Option<f64>,
    /// Orientation error.
    #[serde(rename = "AOE")]
    pub aoe: Option<f64>,
    /// Velocity error.
    #[serde(rename = "AVE")]
    pub ave: Option<f64>,
}

/// One class's figures.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ClassMetrics {
    /// TP / (TP + FP).
    pub precision: Option<f64>,
    /// TP / (TP + FN).
    pub recall: Option<f64>,
    /// Mean errors, false positives included: ATE and ASE (m), AOE (degrees), AVE (m/s).
    #[serde(flatten)]
    pub errors: ClassErrors,
    /// True positives.
    pub tp: usize,
    /// False positives.
    pub fp: usize,
    /// False negatives.
    #[serde(rename = "fn")]
    pub fn_: usize,
    /// TP-only errors.
    pub tp_only: ErrorMetrics,
}

/// The metrics of a whole prediction set (`eval --format json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Metrics {
    /// TP / (TP + FP).
    pub precision: Option<f64>,
    /// TP / (TP + FN).
    pub recall: Option<f64>,
    /// Class-mean errors, false positives included (`mATE` ... `mAVE` beside the counts).
    #[serde(flatten)]
    pub all: ErrorMetrics,
    /// True positives.
    pub tp: usize,
    /// False positives.
    pub fp: usize,
    /// False negatives.
    #[serde(rename = "fn")]
    pub fn_: usize,
    /// Per-class figures by class name.
    pub per_class: BTreeMap<String, ClassMetrics>,
    /// TP-only class-mean errors.
    pub tp_only: ErrorMetrics,
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::Uncertainty;

    fn gt(id: u32, class: Class, x: f64, yaw: f64) -> GtObject {
        GtObject {
            id,
            class,
            center: [x, 0.0, 1.0],
            size: [4.0, 2.0, 1.5],
            yaw,
            velocity: Some([10.0, 0.0]),
        }
    }

    fn pred(id: u32, class: Class, x: f64, y: f64, yaw: f64, size: [f64; 3]) -> Detection {
        Detection {
            class,
            center: [x, y, 1.0],
            size,
            yaw,
            score: 0.5,
            std: Uncertainty::uniform(1.0, 1.0, 1.0),
            pos_cov: None,
            velocity: None,
            id,
        }
    }

    #[test]
    fn one_tp_and_one_fp_of_the_same_id() {
        let g = [gt(1, Class::Car, 0.0, 0.0)];
        // TP 3-4-5 away (ATE 5), FP 10 m away; sizes off by (0, 0, 1) -> ASE 1; yaw 10 deg
        let p = [
            pred(1, Class::Car, 10.0, 0.0, 0.0, [4.0, 2.0, 1.5]),
            pred(1, Class::Car, 3.0, 4.0, 10f64.to_radians(), [4.0, 2.0, 2.5]),
        ];
        let mut acc = Accumulator::new();
        acc.add_frame(&g, &p);
        let m = acc.summary();
        assert_eq!((m.tp, m.fp, m.fn_), (1, 1, 0));
        assert_eq!(m.precision, Some(0.5));
        assert_eq!(m.recall, Some(1.0));
        assert!((m.all.m_ate.unwrap() - 7.5).abs() < 1e-12);
        assert!((m.all.m_ase.unwrap() - 0.5).abs() < 1e-12);
        assert!((m.all.m_aoe.unwrap() - 5.0).abs() < 1e-9);
        assert!((m.tp_only.m_ate.unwrap() - 5.0).abs() < 1e-12);
        assert!((m.tp_only.m_aoe.unwrap() - 10.0).abs() < 1e-9);
    }

    #[test]
    fn a_missed_object_and_an_unknown_id() {
        let g = [
            gt(1, Class::Car, 0.0, 0.0),
            gt(2, Class::Pedestrian, 5.0, 0.0),
        ];
        let p = [
            pred(1, Class::Car, 1.0, 0.0, 0.0, [4.0, 2.0, 1.5]),
            pred(99, Class::Car, 50.0, 0.0, 0.0, [4.0, 2.0, 1.5]),
        ];
        let mut acc = Accumulator::new();
        acc.add_frame(&g, &p);
        let m = acc.summary();
        assert_eq!((m.tp, m.fp, m.fn_), (1, 1, 1));
        assert_eq!(m.recall, Some(0.5));
        // only the car has errors: the class mean is the car's
        assert!((m.all.m_ate.unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(m.per_class["pedestrian"].fn_, 1);
        assert_eq!(m.per_class["pedestrian"].errors.ate, None);
    }

    #[test]
    fn a_barrier_yawed_by_pi_has_no_orientation_error() {
        let g = [
            gt(1, Class::Barrier, 0.0, 0.2),
            gt(2, Class::Car, 10.0, 0.2),
        ];
        let p = [
            pred(
                1,
                Class::Barrier,
                0.0,
                0.0,
                wrap_angle(0.2 + std::f64::consts::PI),
                [4.0, 2.0, 1.5],
            ),
            pred(
                2,
                Class::Car,
                10.0,
                0.0,
                wrap_angle(0.2 + std::f64::consts::PI),
                [4.0, 2.0, 1.5],
            ),
        ];
        let mut acc = Accumulator::new();
        acc.add_frame(&g, &p);
        let m = acc.summary();
        assert!(m.per_class["barrier"].errors.aoe.unwrap() < 1e-9);
        assert!((m.per_class["car"].errors.aoe.unwrap() - 180.0).abs() < 1e-9);
        // class mean of 0 and 180
        assert!((m.all.m_aoe.unwrap() - 90.0).abs() < 1e-9);
    }

    #[test]
    fn velocity_errors_where_both_have_one_and_the_class_moves() {
        let g = [gt(1, Class::Car, 0.0, 0.0), gt(2, Class::Barrier, 9.0, 0.0)];
        let mut p = pred(1, Class::Car, 0.0, 0.0, 0.0, [4.0, 2.0, 1.5]);
        p.velocity = Some(v2x_protocol::Velocity {
            v: [13.0, 4.0],
            std: [1.0, 1.0],
        });
        let mut b = pred(2, Class::Barrier, 9.0, 0.0, 0.0, [4.0, 2.0, 1.5]);
        b.velocity = p.velocity;
        let mut acc = Accumulator::new();
        acc.add_frame(&g, &[p.clone(), b]);
        let m = acc.summary();
        assert!(
            (m.all.m_ave.unwrap() - 5.0).abs() < 1e-12,
            "3-4-5, barrier excluded"
        );
        assert_eq!(m.per_class["barrier"].errors.ave, None);
        // no velocity, no error to average
        let mut acc = Accumulator::new();
        p.velocity = None;
        acc.add_frame(&g[..1], &[p]);
        assert_eq!(acc.summary().all.m_ave, None);
    }

    #[test]
    fn merge_equals_one_pass() {
        let g = [gt(1, Class::Car, 0.0, 0.0)];
        let p = [pred(1, Class::Car, 1.0, 0.0, 0.0, [4.0, 2.0, 1.5])];
        let mut a = Accumulator::new();
        a.add_frame(&g, &p);
        a.add_frame(&g, &[]);
        let mut b = Accumulator::new();
        b.add_frame(&g, &p);
        let mut c = Accumulator::new();
        c.add_frame(&g, &[]);
        b.merge(&c);
        assert_eq!(a.summary(), b.summary());
    }
}
