//! AB3DMOT's KITTI tracking evaluation (its `scripts/KITTI/evaluate.py`, 3D IoU at 0.25), as
//! DMSTrack and V2V4Real's tracking results report it: sAMOTA, AMOTA, AMOTP, and MOTA, MOTP,
//! MT, ML, IDS and FRAG at the threshold of best MOTA.
//!
//! Each step follows the script, so the figures equal its own:
//! - A track's score is the mean of its boxes' scores over the sequence, recomputed (from the
//!   scores the last pass left) at every pass, as the script does.
//! - Per frame, labels and tracked boxes are matched by a minimum-cost assignment of
//!   1 - IoU-3D among the pairs with IoU >= 0.25, the most pairs first (its Munkres with 1e9 for
//!   the others). IoU-3D is the script's own computation, repeated step for step: footprints in
//!   the camera's x-z plane clipped by Sutherland-Hodgman, the box spanning [y - h, y] in height.
//!   It is not a true IoU everywhere (two equal rotated boxes can score above 1), so no
//!   geometry of the project's stands in for it.
//! - A tracked box left unmatched is ignored, not a false positive: the script ignores a box whose
//!   2D box is at most 25 px tall, and the layout's rows carry no 2D box (zeros). Unless an
//!   earlier pass matched it: the script's `valid` mark outlives the pass, and such a box counts
//!   as a false positive. So FP is small but not always 0, and the figures measure recall and
//!   identities. [`FalsePositives::Counted`] scores the same rows as the script does when their
//!   2D box is tall enough to pass its test: every unmatched tracked box is a false positive.
//! - Identity switches and fragmentations are counted along each label track
//!   (`compute3rdPartyMetrics`'s second pass); MT above 80% of its frames tracked, ML below 20%.
//! - MOTA = 1 - (FN + FP + IDS) / GT; sMOTA at recall r = clip(1 - (FN + FP + IDS - (1 - r) GT)
//!   / (r GT), 0, 1).
//! - The recall points: the matched boxes' track scores, highest first, thinned to steps of
//!   1/40 of recall (`getThresholds`, first point dropped); at each, tracks below the threshold
//!   are dropped and MOTA, MOTP and sMOTA computed; AMOTA, AMOTP and sAMOTA are their sums over
//!   40 (a recall the tracks never reach counts 0).

use serde::Serialize;
use std::collections::BTreeMap;
use v2x_fuser::maths::association::{assign, Edge};
use v2x_protocol::Detection;

/// Whether unmatched tracked boxes count.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum FalsePositives {
    /// As the script scores this layout (rows without a 2D box): an unmatched box is ignored
    /// unless an earlier pass matched it. DMSTrack's published figures.
    #[default]
    AsScript,
    /// Every unmatched tracked box is a false positive (the script on rows whose 2D box is
    /// taller than 25 px).
    Counted,
}

/// The IoU-3D a label and a tracked box need to match.
pub const MIN_OVERLAP: f64 = 0.25;
/// The script's number of recall sample points (the recall steps are 1/40).
const SAMPLE_POINTS: f64 = 41.0;

/// One sequence: per frame, the labels (`id` the object's) and the tracked boxes (`id` the
/// track's, `score` the box's).
#[derive(Clone, Debug, Default)]
pub struct Sequence {
    /// Labels per frame.
    pub gt: Vec<Vec<Detection>>,
    /// Tracked boxes per frame, as many frames as `gt`.
    pub tracks: Vec<Vec<Detection>>,
}

/// The evaluation's figures (fractions, not percent).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Ab3dmotMetrics {
    /// Mean scaled MOTA over the 40 recall points.
    pub samota: f64,
    /// Mean MOTA over the 40 recall points.
    pub amota: f64,
    /// Mean MOTP over the 40 recall points.
    pub amotp: f64,
    /// MOTA at the threshold of best MOTA.
    pub mota: f64,
    /// MOTP (mean IoU-3D of the matches) there.
    pub motp: f64,
    /// Mostly tracked label tracks (share).
    pub mt: f64,
    /// Mostly lost label tracks (share).
    pub ml: f64,
    /// Identity switches.
    pub ids: usize,
    /// Fragmentations.
    pub frag: usize,
    /// Matches, false positives and misses.
    pub tp: usize,
    /// False positives (few for this layout: see the module's notes).
    pub fp: usize,
    /// Missed labels.
    pub fn_: usize,
    /// Recall.
    pub recall: f64,
    /// The track-score threshold of best MOTA (-10000: none).
    pub threshold: f64,
}

/// A box as the script sees it: KITTI's x, y (the bottom, pointing down), z, h, w, l, ry.
#[derive(Clone, Copy, Debug)]
struct ScriptBox {
    x: f64,
    y: f64,
    z: f64,
    h: f64,
    w: f64,
    l: f64,
    ry: f64,
}

impl ScriptBox {
    /// The columns of a box read by the KITTI readers (centre [x, z, y], size [l, w, h]).
    fn of(d: &Detection) -> ScriptBox {
        ScriptBox {
            x: d.center[0],
            y: d.center[2],
            z: d.center[1],
            h: d.size[2],
            w: d.size[1],
            l: d.size[0],
            ry: d.yaw,
        }
    }

    /// The bottom corners 3, 2, 1, 0 in the camera's x-z plane (`compute_bottom`).
    fn bottom(&self) -> [[f64; 2]; 4] {
        let (c, s) = (self.ry.cos(), self.ry.sin());
        let xc = [self.l / 2.0, self.l / 2.0, -self.l / 2.0, -self.l / 2.0];
        let zc = [self.w / 2.0, -self.w / 2.0, -self.w / 2.0, self.w / 2.0];
        let corner = |i: usize| {
            [
                c * xc[i] + 0.0 * 0.0 + s * zc[i] + self.x,
                -s * xc[i] + 0.0 * 0.0 + c * zc[i] + self.z,
            ]
        };
        [corner(3), corner(2), corner(1), corner(0)]
    }
}

/// The script's Sutherland-Hodgman clip of `subject` by `clip` (its `polygon_clip`, kept
/// as written: coincident edges can give far-off points, and the IoU of two equal rotated boxes
/// can exceed 1, which the script then counts).
fn polygon_clip(subject: &[[f64; 2]], clip: &[[f64; 2]]) -> Option<Vec<[f64; 2]>> {
    let inside = |p: [f64; 2], cp1: [f64; 2], cp2: [f64; 2]| {
        (cp2[0] - cp1[0]) * (p[1] - cp1[1]) > (cp2[1] - cp1[1]) * (p[0] - cp1[0])
    };
    let intersection = |cp1: [f64; 2], cp2: [f64; 2], s: [f64; 2], e: [f64; 2]| {
        let dc = [cp1[0] - cp2[0], cp1[1] - cp2[1]];
        let dp = [s[0] - e[0], s[1] - e[1]];
        let n1 = cp1[0] * cp2[1] - cp1[1] * cp2[0];
        let n2 = s[0] * e[1] - s[1] * e[0];
        let n3 = 1.0 / (dc[0] * dp[1] - dc[1] * dp[0]);
        [
            (n1 * dp[0] - n2 * dc[0]) * n3,
            (n1 * dp[1] - n2 * dc[1]) * n3,
        ]
    };
    let mut output = subject.to_vec();
    let mut cp1 = *clip.last()?;
    for &cp2 in clip {
        let input = std::mem::take(&mut output);
        let mut s = *input.last()?;
        for &e in &input {
            if inside(e, cp1, cp2) {
                if !inside(s, cp1, cp2) {
                    output.push(intersection(cp1, cp2, s, e));
                }
                output.push(e);
            } else if inside(s, cp1, cp2) {
                output.push(intersection(cp1, cp2, s, e));
            }
            s = e;
        }
        cp1 = cp2;
        if output.is_empty() {
            return None;
        }
    }
    Some(output)
}

/// The area of the convex hull of `points` (the script's `ConvexHull(...).volume`); 0 for
/// fewer than three points, collinear ones, or any not finite.
fn hull_area(points: &[[f64; 2]]) -> f64 {
    if points.len() < 3 || points.iter().flatten().any(|v| !v.is_finite()) {
        return 0.0;
    }
    let mut p = points.to_vec();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    let n = hull.len();
    if n < 3 {
        return 0.0;
    }
    (0..n)
        .map(|i| {
            let (a, b) = (hull[i], hull[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        .abs()
        / 2.0
}

/// The script's IoU-3D of two boxes (`iou(..., metric='iou_3d')`).
fn script_iou(a: &ScriptBox, b: &ScriptBox) -> f64 {
    let inter_2d = polygon_clip(&a.bottom(), &b.bottom()).map_or(0.0, |p| hull_area(&p));
    let height = (a.y.min(b.y) - (-a.h + a.y).max(-b.h + b.y)).max(0.0);
    let inter = inter_2d * height;
    inter / (a.w * a.l * a.h + b.w * b.l * b.h - inter)
}

/// One pass's counts.
#[derive(Default)]
struct Pass {
    tp: usize,
    fp: usize,
    fn_: usize,
    n_gt: usize,
    total_iou: f64,
    ids: usize,
    frag: usize,
    mt: usize,
    ml: usize,
    trajectories: usize,
    /// The track score of every match.
    scores: Vec<f64>,
}

/// One frame ready for the passes: each label's object id, each tracked box's track id and
/// mean track score, and the pairs within [`MIN_OVERLAP`] with their cost 1 - IoU-3D.
struct Frame {
    gt: Vec<u32>,
    tracks: Vec<(u32, f64)>,
    pairs: Vec<(usize, usize, f64)>,
    /// Whether each tracked box was matched in some pass so far: the script marks a matched
    /// box `valid` for good, and a valid box left unmatched in a later pass is not ignored but
    /// a false positive.
    valid: Vec<bool>,
}

/// Sets every tracked box's score to its track's mean score over the sequence, summed in
/// frame order as the script does. The script overwrites the scores at every pass, so from the
/// second pass on it averages averages, which can move a track's score by a rounding step (and
/// decide whether it stands at a threshold equal to its first mean): repeated here.
fn average_scores(frames: &mut [Frame]) {
    let mut sums: BTreeMap<u32, (f64, usize)> = BTreeMap::new();
    for (id, score) in frames.iter().flat_map(|f| &f.tracks) {
        let e = sums.entry(*id).or_default();
        e.0 += score;
        e.1 += 1;
    }
    for (id, score) in frames.iter_mut().flat_map(|f| &mut f.tracks) {
        let (sum, n) = sums[id];
        *score = sum / n as f64;
    }
}

/// Matches every frame with tracks of mean score below `threshold` dropped, then counts.
fn pass(seqs: &mut [Vec<Frame>], threshold: f64) -> Pass {
    let mut p = Pass::default();
    for frames in seqs.iter_mut() {
        average_scores(frames);
        // Per label id, the matched track id of each frame it appears in (-1: none).
        let mut traj: BTreeMap<u32, Vec<i64>> = BTreeMap::new();
        for fr in frames {
            let matched = p.frame(fr, threshold);
            for (&gid, m) in fr.gt.iter().zip(matched) {
                traj.entry(gid).or_default().push(m);
            }
        }
        p.trajectories += traj.len();
        for g in traj.values() {
            p.trajectory(g);
        }
    }
    p
}

impl Pass {
    /// Scores one frame's tracks of score at least `threshold`: per label, the matched track id
    /// (-1: none).
    fn frame(&mut self, fr: &mut Frame, threshold: f64) -> Vec<i64> {
        let p = self;
        p.n_gt += fr.gt.len();
        let kept: Vec<Option<usize>> = {
            let mut n = 0;
            fr.tracks
                .iter()
                .map(|&(_, s)| {
                    (s >= threshold).then(|| {
                        n += 1;
                        n - 1
                    })
                })
                .collect()
        };
        let mut back = Vec::new();
        let edges: Vec<Edge> = fr
            .pairs
            .iter()
            .filter_map(|&(i, j, c)| kept[j].map(|k| (i, j, k, c)))
            .map(|(i, j, k, c)| {
                back.push(j);
                Edge::new(i, k, c)
            })
            .collect();
        let kept_n = kept.iter().flatten().count();
        let mut matched = vec![-1i64; fr.gt.len()];
        let mut hit = vec![false; fr.tracks.len()];
        for (i, k) in assign(fr.gt.len(), kept_n, &edges) {
            let e = edges
                .iter()
                .position(|e| e.ia() == i && e.ib() == k)
                .expect("an assigned pair is an edge");
            let (id, score) = fr.tracks[back[e]];
            hit[back[e]] = true;
            fr.valid[back[e]] = true;
            matched[i] = id as i64;
            p.total_iou += 1.0 - edges[e].cost;
            p.tp += 1;
            p.scores.push(score);
        }
        p.fn_ += matched.iter().filter(|&&m| m < 0).count();
        p.fp += (0..fr.tracks.len())
            .filter(|&j| kept[j].is_some() && !hit[j] && fr.valid[j])
            .count();
        matched
    }

    /// Counts one label's trajectory (its matched track id per frame): switches,
    /// fragmentations, mostly tracked or mostly lost.
    fn trajectory(&mut self, g: &[i64]) {
        let p = self;
        if g.iter().all(|&m| m == -1) {
            p.ml += 1;
            return;
        }
        let mut last_id = g[0];
        let mut tracked = usize::from(g[0] >= 0);
        let mut f = 0;
        for k in 1..g.len() {
            f = k;
            if last_id != g[k] && last_id != -1 && g[k] != -1 && g[k - 1] != -1 {
                p.ids += 1;
            }
            if k < g.len() - 1 && g[k - 1] != g[k] && last_id != -1 && g[k] != -1 && g[k + 1] != -1
            {
                p.frag += 1;
            }
            if g[k] != -1 {
                tracked += 1;
                last_id = g[k];
            }
        }
        if g.len() > 1 && g[f - 1] != g[f] && last_id != -1 && g[f] != -1 {
            p.frag += 1;
        }
        let ratio = tracked as f64 / g.len() as f64;
        if ratio > 0.8 {
            p.mt += 1;
        } else if ratio < 0.2 {
            p.ml += 1;
        }
    }
}

impl Pass {
    fn mota(&self) -> f64 {
        1.0 - (self.fn_ + self.fp + self.ids) as f64 / self.n_gt as f64
    }

    fn motp(&self) -> f64 {
        if self.tp == 0 {
            0.0
        } else {
            self.total_iou / self.tp as f64
        }
    }

    fn smota(&self, r: f64) -> f64 {
        let n = self.n_gt as f64;
        (1.0 - ((self.fn_ + self.fp + self.ids) as f64 - (1.0 - r) * n) / (r * n)).clamp(0.0, 1.0)
    }
}

/// The script's `getThresholds`: thresholds at steps of 1/40 of recall, the first dropped.
fn thresholds(scores: &[f64], num_gt: usize) -> Vec<(f64, f64)> {
    let mut s = scores.to_vec();
    s.sort_by(|a, b| b.total_cmp(a));
    let mut current = 0.0;
    let mut out = Vec::new();
    for (i, &score) in s.iter().enumerate() {
        let l = (i + 1) as f64 / num_gt as f64;
        let last = i == s.len() - 1;
        let r = if last {
            l
        } else {
            (i + 2) as f64 / num_gt as f64
        };
        if (r - current) < (current - l) && !last {
            continue;
        }
        out.push((score, current));
        current += 1.0 / (SAMPLE_POINTS - 1.0);
    }
    out.into_iter().skip(1).collect()
}

/// Evaluates the sequences as the script does (see the module's notes); `None` without labels.
pub fn evaluate(sequences: &[Sequence]) -> Option<Ab3dmotMetrics> {
    evaluate_with(sequences, FalsePositives::AsScript)
}

/// [`evaluate`] with unmatched tracked boxes treated as `fp` says.
pub fn evaluate_with(sequences: &[Sequence], fp: FalsePositives) -> Option<Ab3dmotMetrics> {
    let mut seqs: Vec<Vec<Frame>> = sequences
        .iter()
        .map(|s| {
            s.gt.iter()
                .zip(&s.tracks)
                .map(|(g, t)| {
                    let tb: Vec<ScriptBox> = t.iter().map(ScriptBox::of).collect();
                    let mut pairs = Vec::new();
                    for (i, gg) in g.iter().enumerate() {
                        let gb = ScriptBox::of(gg);
                        for (j, tt) in tb.iter().enumerate() {
                            let c = 1.0 - script_iou(&gb, tt);
                            if c <= 1.0 - MIN_OVERLAP {
                                pairs.push((i, j, c));
                            }
                        }
                    }
                    Frame {
                        gt: g.iter().map(|d| d.id).collect(),
                        tracks: t.iter().map(|d| (d.id, d.score)).collect(),
                        valid: vec![fp == FalsePositives::Counted; t.len()],
                        pairs,
                    }
                })
                .collect()
        })
        .collect();
    let all = pass(&mut seqs, f64::NEG_INFINITY);
    if all.n_gt == 0 {
        return None;
    }
    let (mut smota, mut mota, mut motp) = (0.0, 0.0, 0.0);
    let (mut best_mota, mut best_threshold) = (0.0, -10000.0);
    for (threshold, recall) in thresholds(&all.scores, all.tp + all.fn_) {
        let p = pass(&mut seqs, threshold);
        smota += p.smota(recall);
        mota += p.mota();
        motp += p.motp();
        if p.mota() > best_mota {
            best_mota = p.mota();
            best_threshold = threshold;
        }
    }
    let best = pass(&mut seqs, best_threshold);
    let trajectories = best.trajectories.max(1) as f64;
    Some(Ab3dmotMetrics {
        samota: smota / (SAMPLE_POINTS - 1.0),
        amota: mota / (SAMPLE_POINTS - 1.0),
        amotp: motp / (SAMPLE_POINTS - 1.0),
        mota: best.mota(),
        motp: best.motp(),
        mt: best.mt as f64 / trajectories,
        ml: best.ml as f64 / trajectories,
        ids: best.ids,
        frag: best.frag,
        tp: best.tp,
        fp: best.fp,
        fn_: best.fn_,
        recall: best.tp as f64 / (best.tp + best.fn_).max(1) as f64,
        threshold: best_threshold,
    })
}

#[cfg(test)]
mod tests;
