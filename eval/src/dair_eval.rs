//! The DAIR-V2X cooperative detection protocol, as its official evaluation computes it: 3D and
//! bird's-eye-view average precision per class at fixed IoU thresholds (car 0.3, 0.5 and 0.7),
//! in the vehicle's LiDAR frame, over the boxes with a corner inside the evaluation range.
//!
//! Each step mirrors the official `eval_utils.py`, quirks included, so that the figures can be
//! compared with published ones:
//! - IoU: the bottom faces are clipped (Sutherland-Hodgman, strict inside test), the BEV IoU is
//!   intersection over union of the bottom rectangles, and the 3D IoU multiplies the
//!   intersection by the overlap of the vertical extents (from a bottom and a top corner).
//! - Matching, per frame, class and threshold: ground-truth boxes in order each take, among the
//!   predictions not yet taken (by score, highest first), the last one with the highest IoU at
//!   or above the threshold.
//! - AP: the frames' predictions in the order they were added, sorted by score (stably): every
//!   prediction of the split ranked by its score, the ordering OpenCOOD calls a global sort;
//!   precision made non-increasing from the right; the sum over the steps where recall changes
//!   of the recall step times the precision after it. As in the official code, the first step
//!   (from recall 0 to the first prediction's) is not counted. Beside it, the same steps in
//!   frame order (each frame's predictions by score, the frames in the order added, as V2V4Real
//!   publishes its AP): [`DairMetrics::frame_order_ap_3d`].
//!
//! Classes: car is car, truck and bus (the official "car" merges Car, Van, Truck and Bus),
//! cyclist is bicycle, pedestrian is pedestrian; other classes are not scored.

use serde::Serialize;
use std::collections::BTreeMap;
use v2x_fuser::maths::geometry::{convex_hull, polygon_area, Pt};
use v2x_protocol::{Class, Detection};
use v2x_truth::dair::{corners, Corners, Pose};
use v2x_truth::dataset::GtObject;

/// The official evaluation range in the vehicle's LiDAR frame: x0, y0, z0, x1, y1, z1 (m).
pub const RANGE: [f64; 6] = [-10.0, -49.68, -3.0, 79.12, 49.68, 1.0];

/// A class the DAIR-V2X protocol scores.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum DairClass {
    /// Car, van, truck, bus.
    Car,
    /// Cyclist.
    Cyclist,
    /// Pedestrian.
    Pedestrian,
}

impl DairClass {
    /// All scored classes.
    pub const ALL: [DairClass; 3] = [DairClass::Car, DairClass::Cyclist, DairClass::Pedestrian];

    /// The official name.
    pub fn name(self) -> &'static str {
        match self {
            DairClass::Car => "car",
            DairClass::Cyclist => "cyclist",
            DairClass::Pedestrian => "pedestrian",
        }
    }

    /// The official IoU thresholds of the class.
    pub fn thresholds(self) -> &'static [f64] {
        match self {
            DairClass::Car => &[0.3, 0.5, 0.7],
            DairClass::Cyclist | DairClass::Pedestrian => &[0.25, 0.5],
        }
    }

    /// The scored class of a detection class, if any.
    pub fn of(class: Class) -> Option<DairClass> {
        match class {
            Class::Car | Class::Truck | Class::Bus => Some(DairClass::Car),
            Class::Bicycle => Some(DairClass::Cyclist),
            Class::Pedestrian => Some(DairClass::Pedestrian),
            _ => None,
        }
    }
}

/// A box as the protocol sees it: its corners in the vehicle's frame, class and score.
#[derive(Clone, Debug, PartialEq)]
pub struct DairBox {
    /// The scored class (`None`: never matched, never counted).
    pub class: Option<DairClass>,
    /// Corners in the order of [`corners`].
    pub corners: Corners,
    /// Confidence (1 for ground truth).
    pub score: f64,
}

/// Whether a point lies in the evaluation range, as the official `point_in_box` decides for an
/// axis-aligned range: x and y within the bounds, z from the floor up to (not at) the ceiling.
fn in_range(p: [f64; 3]) -> bool {
    let [x0, y0, z0, x1, y1, z1] = RANGE;
    (x0..=x1).contains(&p[0]) && (y0..=y1).contains(&p[1]) && p[2] >= z0 && p[2] < z1
}

/// A world-frame box in the vehicle's frame (`world_to_vehicle`), if a corner lies in range.
pub fn to_vehicle(
    class: Class,
    center: [f64; 3],
    size: [f64; 3],
    yaw: f64,
    score: f64,
    world_to_vehicle: &Pose,
) -> Option<DairBox> {
    let c = corners(center, size, yaw).map(|p| world_to_vehicle.apply(p));
    c.iter().any(|p| in_range(*p)).then_some(DairBox {
        class: DairClass::of(class),
        corners: c,
        score,
    })
}

/// The ground-truth objects of a frame in the vehicle's frame, within range.
pub fn gt_boxes(objects: &[GtObject], world_to_vehicle: &Pose) -> Vec<DairBox> {
    objects
        .iter()
        .filter_map(|o| to_vehicle(o.class, o.center, o.size, o.yaw, 1.0, world_to_vehicle))
        .collect()
}

/// Detections in the vehicle's frame, within range.
pub fn detection_boxes(dets: &[Detection], world_to_vehicle: &Pose) -> Vec<DairBox> {
    dets.iter()
        .filter_map(|d| to_vehicle(d.class, d.center, d.size, d.yaw, d.score, world_to_vehicle))
        .collect()
}

/// The official corner permutation for boxes in [`corners`] order: bottom counter-clockwise,
/// then top.
const PERM: [usize; 8] = [3, 2, 1, 0, 7, 6, 5, 4];

/// The official Sutherland-Hodgman clip of `subject` by the convex, counter-clockwise `clip`,
/// except that an edge lying along a clip line yields its end rather than a point computed by
/// dividing by zero (which the official code can return far outside both boxes).
fn polygon_clip(subject: &[Pt], clip: &[Pt]) -> Vec<Pt> {
    let mut output: Vec<Pt> = subject.to_vec();
    let mut cp1 = clip[clip.len() - 1];
    for &cp2 in clip {
        let inside =
            |p: Pt| (cp2[0] - cp1[0]) * (p[1] - cp1[1]) > (cp2[1] - cp1[1]) * (p[0] - cp1[0]);
        let intersection = |s: Pt, e: Pt| -> Pt {
            let dc = [cp1[0] - cp2[0], cp1[1] - cp2[1]];
            let dp = [s[0] - e[0], s[1] - e[1]];
            let n1 = cp1[0] * cp2[1] - cp1[1] * cp2[0];
            let n2 = s[0] * e[1] - s[1] * e[0];
            let denom = dc[0] * dp[1] - dc[1] * dp[0];
            // An edge along the clip line, its ends told apart by rounding alone: both ends
            // lie on the line, and the official formula would divide by (nearly) zero.
            if denom.abs() <= 1e-9 * dc[0].hypot(dc[1]) * dp[0].hypot(dp[1]) {
                return e;
            }
            let n3 = 1.0 / denom;
            [
                (n1 * dp[0] - n2 * dc[0]) * n3,
                (n1 * dp[1] - n2 * dc[1]) * n3,
            ]
        };
        let input = std::mem::take(&mut output);
        let Some(&last) = input.last() else {
            return Vec::new();
        };
        let mut s = last;
        for &e in &input {
            if inside(e) {
                if !inside(s) {
                    output.push(intersection(s, e));
                }
                output.push(e);
            } else if inside(s) {
                output.push(intersection(s, e));
            }
            s = e;
        }
        cp1 = cp2;
        if output.is_empty() {
            return Vec::new();
        }
    }
    output
}

/// The area of the convex hull of `points` (the official code measures the clipped polygon by
/// its hull); 0 when the points span no area.
fn hull_area(points: &[Pt]) -> f64 {
    if points.len() < 3 || points.iter().flatten().any(|v| !v.is_finite()) {
        return 0.0;
    }
    let hull = convex_hull(points);
    if hull.len() < 3 {
        return 0.0;
    }
    polygon_area(&hull).abs()
}

/// The official 3D and BEV IoU of two boxes given in [`corners`] order.
pub fn box_iou(a: &Corners, b: &Corners) -> (f64, f64) {
    let a: Corners = PERM.map(|i| a[i]);
    let b: Corners = PERM.map(|i| b[i]);
    let rect = |c: &Corners| -> [Pt; 4] { std::array::from_fn(|i| [c[i][0], c[i][1]]) };
    let (ra, rb) = (rect(&a), rect(&b));
    let (area_a, area_b) = (polygon_area(&ra).abs(), polygon_area(&rb).abs());
    let inter = hull_area(&polygon_clip(&ra, &rb));
    let iou_2d = inter / (area_a + area_b - inter);
    let zmax = a[4][2].min(b[4][2]);
    let zmin = a[0][2].max(b[0][2]);
    let inter_vol = inter * (zmax - zmin).max(0.0);
    let dist = |p: [f64; 3], q: [f64; 3]| {
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
    };
    let vol = |c: &Corners| dist(c[0], c[1]) * dist(c[1], c[2]) * dist(c[0], c[4]);
    let iou = inter_vol / (vol(&a) + vol(&b) - inter_vol);
    if !iou.is_finite() || !iou_2d.is_finite() {
        return (0.0, 0.0);
    }
    (iou, iou_2d)
}

/// Which IoU a figure uses.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum View {
    /// 3D IoU.
    ThreeD,
    /// Bird's-eye-view IoU.
    Bev,
}

/// One scored prediction: score and whether it matched.
type Scored = (f64, bool);

/// The official matching of one frame, one class, one threshold: the predictions with their
/// outcome (matches in ground-truth order, then the rest by score) and the ground-truth count.
fn compute_type(
    gt: &[&DairBox],
    preds: &[&DairBox],
    threshold: f64,
    view: View,
) -> (Vec<Scored>, usize) {
    let mut left: Vec<&DairBox> = preds.to_vec();
    // Stable: equal scores keep their order.
    left.sort_by(|a, b| {
        b.score
            .partial_cmp(&a.score)
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut out = Vec::with_capacity(left.len());
    for g in gt {
        let mut best = threshold;
        let mut pick = None;
        for (i, p) in left.iter().enumerate() {
            let (iou3, iou2) = box_iou(&g.corners, &p.corners);
            let iou = if view == View::Bev { iou2 } else { iou3 };
            if iou >= best {
                best = iou;
                pick = Some(i);
            }
        }
        if let Some(i) = pick {
            out.push((left.remove(i).score, true));
        }
    }
    out.extend(left.iter().map(|p| (p.score, false)));
    (out, gt.len())
}

/// The official AP of predictions in the order they were gathered; `None` without ground truth.
pub fn compute_ap(preds: &[Scored], num_gt: usize) -> Option<f64> {
    let mut sorted = preds.to_vec();
    sorted.sort_by(|a, b| b.0.partial_cmp(&a.0).unwrap_or(std::cmp::Ordering::Equal));
    ap_in_order(&sorted, num_gt)
}

/// The official AP's steps over predictions in the order given; `None` without ground truth.
pub fn ap_in_order(sorted: &[Scored], num_gt: usize) -> Option<f64> {
    if num_gt == 0 {
        return None;
    }
    let n = sorted.len();
    let mut tp = 0.0;
    let mut precision = Vec::with_capacity(n);
    let mut recall = Vec::with_capacity(n);
    for (i, (_, hit)) in sorted.iter().enumerate() {
        if *hit {
            tp += 1.0;
        }
        precision.push(tp / (i + 1) as f64);
        recall.push(tp / num_gt as f64);
    }
    for i in (1..n).rev() {
        precision[i - 1] = precision[i].max(precision[i - 1]);
    }
    Some(
        (0..n.saturating_sub(1))
            .filter(|&i| recall[i + 1] != recall[i])
            .map(|i| (recall[i + 1] - recall[i]) * precision[i + 1])
            .sum(),
    )
}

/// The protocol's accumulator over frames.
#[derive(Clone, Debug, Default)]
pub struct DairEval {
    preds: BTreeMap<(View, DairClass, u64), Vec<Scored>>,
    gt: BTreeMap<DairClass, usize>,
}

/// The protocol's figures: AP per view, class and threshold (in [0, 1]).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DairMetrics {
    /// 3D AP, keyed `class@threshold` (e.g. `car@0.5`), for the classes with ground truth.
    pub ap_3d: BTreeMap<String, f64>,
    /// BEV AP, keyed likewise.
    pub ap_bev: BTreeMap<String, f64>,
    /// 3D AP in frame order (not the official figure), keyed likewise.
    pub frame_order_ap_3d: BTreeMap<String, f64>,
    /// BEV AP in frame order, keyed likewise.
    pub frame_order_ap_bev: BTreeMap<String, f64>,
    /// Ground-truth boxes in range per class.
    pub gt: BTreeMap<String, usize>,
}

impl DairEval {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one frame: its ground truth and predictions, both in the vehicle's frame.
    pub fn add_frame(&mut self, gt: &[DairBox], preds: &[DairBox]) {
        for class in DairClass::ALL {
            let g: Vec<&DairBox> = gt.iter().filter(|b| b.class == Some(class)).collect();
            let p: Vec<&DairBox> = preds.iter().filter(|b| b.class == Some(class)).collect();
            *self.gt.entry(class).or_default() += g.len();
            for &t in class.thresholds() {
                for view in [View::ThreeD, View::Bev] {
                    let (mut scored, _) = compute_type(&g, &p, t, view);
                    // Each frame's by score (stably): the global sort is unchanged by it, and
                    // frame order reads it as gathered.
                    scored
                        .sort_by(|a, b| b.0.partial_cmp(&a.0).unwrap_or(std::cmp::Ordering::Equal));
                    self.preds
                        .entry((view, class, t.to_bits()))
                        .or_default()
                        .extend(scored);
                }
            }
        }
    }

    /// Adds another accumulator's frames after this one's.
    pub fn merge(&mut self, other: DairEval) {
        for (k, v) in other.preds {
            self.preds.entry(k).or_default().extend(v);
        }
        for (k, n) in other.gt {
            *self.gt.entry(k).or_default() += n;
        }
    }

    /// The AP of one view, class and threshold; `None` without ground truth.
    pub fn ap(&self, view: View, class: DairClass, threshold: f64) -> Option<f64> {
        compute_ap(self.gathered(view, class, threshold), self.gt_of(class))
    }

    /// [`DairEval::ap`] in frame order.
    pub fn frame_order_ap(&self, view: View, class: DairClass, threshold: f64) -> Option<f64> {
        ap_in_order(self.gathered(view, class, threshold), self.gt_of(class))
    }

    fn gt_of(&self, class: DairClass) -> usize {
        self.gt.get(&class).copied().unwrap_or(0)
    }

    fn gathered(&self, view: View, class: DairClass, threshold: f64) -> &[Scored] {
        self.preds
            .get(&(view, class, threshold.to_bits()))
            .map(Vec::as_slice)
            .unwrap_or(&[])
    }

    /// Every AP of the classes with ground truth.
    pub fn summary(&self) -> DairMetrics {
        let mut m = DairMetrics::default();
        for class in DairClass::ALL {
            let n = self.gt.get(&class).copied().unwrap_or(0);
            if n == 0 {
                continue;
            }
            m.gt.insert(class.name().into(), n);
            for &t in class.thresholds() {
                let key = format!("{}@{t}", class.name());
                if let Some(ap) = self.ap(View::ThreeD, class, t) {
                    m.ap_3d.insert(key.clone(), ap);
                }
                if let Some(ap) = self.ap(View::Bev, class, t) {
                    m.ap_bev.insert(key.clone(), ap);
                }
                if let Some(ap) = self.frame_order_ap(View::ThreeD, class, t) {
                    m.frame_order_ap_3d.insert(key.clone(), ap);
                }
                if let Some(ap) = self.frame_order_ap(View::Bev, class, t) {
                    m.frame_order_ap_bev.insert(key, ap);
                }
            }
        }
        m
    }
}

/// The communication cost the official late-fusion evaluation counts for one roadside frame:
/// 8 bytes per value, 7 values of box, a score and a label per box, and one empty box when
/// there is none.
pub fn official_bytes(boxes: usize) -> usize {
    72 * boxes.max(1)
}

#[cfg(test)]
mod tests;
