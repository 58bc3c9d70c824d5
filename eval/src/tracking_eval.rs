//! Tracking metrics (`docs/method.md` §6.2) as the nuScenes tracking benchmark computes them
//! (`tracking_nips_2019`): a 2 m centre distance within a class, events accumulated the way
//! `motmetrics` does, AMOTA over recall thresholds.
//!
//! Preparation, per scene:
//! - each track's boxes get the track's mean score;
//! - a track (ground truth or predicted) missing from frames between its first and last gets
//!   boxes interpolated there, with the devkit's weights (a box at time t between boxes at
//!   l and r takes (1 - w) of the left centre and w of the right, w = (r - t) / (r - l)),
//!   appended after the frame's own boxes with the tracks in the order they first appear, as
//!   the devkit's `interpolate_tracks` appends them.
//!
//! Order matters: each frame's ground truth is walked in the order given (for nuScenes tables,
//! `sample_annotation.json` order, the devkit's), so when two objects last matched the same
//! track and both are near it, the first keeps it, as `motmetrics` decides.
//!
//! Events, per class and frame in time order (frames with neither objects nor boxes skipped):
//! 1. a ground-truth object keeps the track it last matched if that track is under 2 m away;
//! 2. the other objects and tracks are matched by the exact minimum-distance assignment (most
//!    pairs first) over pairs under 2 m;
//! 3. a match whose track differs from the object's last one is an identity switch (IDS);
//!    unmatched tracks are false positives (FP), unmatched objects misses (FN).
//!
//! Per class: the scores of the matches at no threshold give 40 score thresholds at recalls
//! 0.1 ... 1 (`np.interp`; a recall never reached counts as worst). At each threshold, boxes
//! below it are dropped and the events recounted: MOTAR = max(0, 1 - (FN + FP + IDS - (1 - r)
//! GT) / (r GT)) with r = matches / GT. AMOTA is MOTAR's mean (unreached: 0), AMOTP MOTP's
//! (unreached: 2 m). MOTA = max(0, 1 - (FN + FP + IDS) / GT), MOTP, IDS, FRAG, TP, FP, FN are
//! taken at the threshold of best MOTA. Over classes: rates are averaged over the classes with
//! ground truth, counts summed. Only the seven tracking classes count (no barrier, traffic cone
//! or construction vehicle); the devkit's range filter around the ego vehicle is not applied.

use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use v2x_fuser::maths::association::{assign, Edge};
use v2x_protocol::nuscenes_json::JsonError;
use v2x_protocol::{Class, UnknownName};
use v2x_truth::dataset::GtObject;

mod read;
pub use read::{parse_tracking, read_tracking};

mod scenes;
use scenes::{fragmentations, prepare};

/// The matching distance (m): pairs at this distance or more never match.
pub const MATCH_DISTANCE: f64 = 2.0;

/// Recall thresholds of AMOTA.
const NUM_THRESHOLDS: usize = 40;
/// The lowest recall threshold.
const MIN_RECALL: f64 = 0.1;
/// AMOTP's value at a recall never reached (m).
const WORST_MOTP: f64 = 2.0;

/// One tracked box as the metrics see it.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackBox {
    /// The track's id (a string in the nuScenes tracking format).
    pub track: String,
    /// The class (`tracking_name`).
    pub class: Class,
    /// Centre x, y (m).
    pub center: [f64; 2],
    /// Confidence (`tracking_score`).
    pub score: f64,
}

/// The figures of `v2x-sim eval --tracking`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TrackingMetrics {
    /// MOTAR averaged over recall thresholds, then over classes.
    #[serde(rename = "AMOTA")]
    pub amota: f64,
    /// MOTP averaged over recall thresholds, then over classes (m).
    #[serde(rename = "AMOTP")]
    pub amotp: f64,
    /// max(0, 1 - (FN + FP + IDS) / GT) at the best threshold, averaged over classes.
    #[serde(rename = "MOTA")]
    pub mota: f64,
    /// Mean centre distance of the matches at the best threshold, averaged over classes (m).
    #[serde(rename = "MOTP")]
    pub motp: f64,
    /// Identity switches.
    #[serde(rename = "IDS")]
    pub ids: usize,
    /// Fragmentations.
    #[serde(rename = "FRAG")]
    pub frag: usize,
    /// Matches (switches not counted).
    pub tp: usize,
    /// Tracked boxes matching nothing.
    pub fp: usize,
    /// Ground-truth boxes not matched.
    #[serde(rename = "fn")]
    pub fn_: usize,
    /// Ground-truth boxes of the tracking classes.
    pub gt: usize,
    /// Distinct ground-truth objects of the tracking classes.
    pub gt_tracks: usize,
    /// Identity switches per 100 ground-truth objects.
    pub ids_per_100_tracks: f64,
    /// Per class (`tracking_name`): AMOTA, AMOTP, MOTA, MOTP, IDS and FRAG.
    pub classes: BTreeMap<String, ClassTracking>,
}

/// One class's headline figures.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ClassTracking {
    /// AMOTA of the class.
    #[serde(rename = "AMOTA")]
    pub amota: f64,
    /// MOTA at the class's best threshold.
    #[serde(rename = "MOTA")]
    pub mota: f64,
    /// Identity switches at the class's best threshold.
    #[serde(rename = "IDS")]
    pub ids: usize,
    /// MOTP averaged over recall thresholds (m).
    #[serde(rename = "AMOTP")]
    pub amotp: f64,
    /// MOTP at the class's best threshold (m).
    #[serde(rename = "MOTP")]
    pub motp: f64,
    /// Fragmentations at the class's best threshold.
    #[serde(rename = "FRAG")]
    pub frag: usize,
}

/// A ground-truth box, reduced.
#[derive(Clone, Debug)]
struct Obj {
    id: u32,
    class: Class,
    xy: [f64; 2],
}

/// A tracked box, its id interned within its scene.
#[derive(Clone, Debug)]
struct Hyp {
    track: usize,
    class: Class,
    xy: [f64; 2],
    score: f64,
}

#[derive(Clone, Debug, Default)]
struct Frame {
    t_us: u64,
    gt: Vec<Obj>,
    hyps: Vec<Hyp>,
}

#[derive(Clone, Debug, Default)]
struct Scene {
    key: usize,
    tracks: HashMap<String, usize>,
    frames: Vec<Frame>,
}

/// Collects each scene's frames in time order, then scores them.
#[derive(Clone, Debug, Default)]
pub struct TrackingEval {
    scenes: Vec<Scene>,
}

/// Event counts of one class at one threshold.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Counts {
    objects: usize,
    matches: usize,
    switches: usize,
    misses: usize,
    fps: usize,
    dist_sum: f64,
    frag: usize,
}

impl Counts {
    fn mota(&self) -> f64 {
        (1.0 - (self.misses + self.switches + self.fps) as f64 / self.objects as f64).max(0.0)
    }

    fn motar(&self) -> f64 {
        let gt = self.objects as f64;
        let recall = self.matches as f64 / gt;
        let den = recall * gt;
        if den == 0.0 {
            return f64::NAN;
        }
        let nom = (self.misses + self.switches + self.fps) as f64 - (1.0 - recall) * gt;
        (1.0 - nom / den).max(0.0)
    }

    fn motp(&self) -> f64 {
        let detections = self.matches + self.switches;
        if detections == 0 {
            return f64::NAN;
        }
        self.dist_sum / detections as f64
    }
}

impl TrackingEval {
    /// An empty evaluation.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the next frame of a scene (frames of one scene in time order, scenes one after the
    /// other): its ground truth and the tracked boxes for it.
    pub fn add_frame(&mut self, scene: usize, t_us: u64, gt: &[GtObject], boxes: &[TrackBox]) {
        if self.scenes.last().is_none_or(|s| s.key != scene) {
            self.scenes.push(Scene {
                key: scene,
                ..Scene::default()
            });
        }
        let s = self.scenes.last_mut().expect("pushed above");
        // Only the tracking classes exist for the benchmark: a track's boxes of other classes
        // neither count towards its mean score nor stand in its gaps (the devkit never loads
        // them).
        let gt = gt
            .iter()
            .filter(|o| o.class.is_tracking())
            .map(|o| Obj {
                id: o.id,
                class: o.class,
                xy: [o.center[0], o.center[1]],
            })
            .collect();
        let hyps = boxes
            .iter()
            .filter(|b| b.class.is_tracking())
            .map(|b| {
                let n = s.tracks.len();
                Hyp {
                    track: *s.tracks.entry(b.track.clone()).or_insert(n),
                    class: b.class,
                    xy: b.center,
                    score: b.score,
                }
            })
            .collect();
        s.frames.push(Frame { t_us, gt, hyps });
    }

    /// Appends another evaluation's scenes after this one's.
    pub fn merge(&mut self, other: TrackingEval) {
        self.scenes.extend(other.scenes);
    }

    /// The tracking benchmark's figures over every frame added.
    pub fn summary(&self) -> TrackingMetrics {
        self.score(None)
    }

    /// [`TrackingEval::summary`], and where each identity switch it counts happened: the
    /// object's centre (x, y) in the frame it changed track, at its class's threshold of best
    /// MOTA.
    pub fn summary_with_switches(&self) -> (TrackingMetrics, Vec<[f64; 2]>) {
        let mut at = Vec::new();
        let m = self.score(Some(&mut at));
        (m, at)
    }

    /// The figures; the switches' places into `switches_at` when given.
    fn score(&self, mut switches_at: Option<&mut Vec<[f64; 2]>>) -> TrackingMetrics {
        let scenes: Vec<Scene> = self.scenes.iter().map(prepare).collect();
        let mut m = TrackingMetrics::default();
        let (mut amota, mut amotp, mut mota, mut motp) = (vec![], vec![], vec![], vec![]);
        let mut objects = std::collections::HashSet::new();
        for class in Class::TRACKING {
            let gt_count: usize = frames(&scenes)
                .map(|f| f.gt.iter().filter(|o| o.class == class).count())
                .sum();
            if gt_count == 0 {
                continue;
            }
            for f in frames(&scenes) {
                objects.extend(f.gt.iter().filter(|o| o.class == class).map(|o| o.id));
            }
            let c = evaluate_class(&scenes, class, gt_count);
            amota.push(c.amota);
            amotp.push(c.amotp);
            if !c.mota.is_nan() {
                mota.push(c.mota);
            }
            if !c.motp.is_nan() {
                motp.push(c.motp);
            }
            if let (Some(at), Some(_)) = (switches_at.as_deref_mut(), c.best) {
                accumulate(&scenes, class, c.best_threshold, Some(at));
            }
            if let Some(best) = c.best {
                m.ids += best.switches;
                m.frag += best.frag;
                m.tp += best.matches;
                m.fp += best.fps;
            }
            m.fn_ += c.best.map_or(gt_count, |b| b.misses);
            m.gt += gt_count;
            m.classes.insert(
                class.name().to_string(),
                ClassTracking {
                    amota: c.amota,
                    mota: c.mota,
                    ids: c.best.map_or(0, |b| b.switches),
                    amotp: c.amotp,
                    motp: c.motp,
                    frag: c.best.map_or(0, |b| b.frag),
                },
            );
        }
        let mean = |v: &[f64]| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        m.amota = mean(&amota);
        m.amotp = mean(&amotp);
        m.mota = mean(&mota);
        m.motp = mean(&motp);
        m.gt_tracks = objects.len();
        m.ids_per_100_tracks = if m.gt_tracks > 0 {
            100.0 * m.ids as f64 / m.gt_tracks as f64
        } else {
            0.0
        };
        m
    }
}

fn frames(scenes: &[Scene]) -> impl Iterator<Item = &Frame> {
    scenes.iter().flat_map(|s| &s.frames)
}

/// One class's figures: AMOTA, AMOTP, and the counts at the threshold of best MOTA.
struct ClassFigures {
    amota: f64,
    amotp: f64,
    mota: f64,
    motp: f64,
    best: Option<Counts>,
    /// The score threshold of `best` (`None`: every box).
    best_threshold: Option<f64>,
}

fn evaluate_class(scenes: &[Scene], class: Class, gt_count: usize) -> ClassFigures {
    let (_, scores) = accumulate(scenes, class, None, None);
    let thresholds = thresholds(scores, gt_count);
    // per threshold (ascending, the unreached ones first): the counts, computed once per value
    let mut counts: Vec<Option<Counts>> = Vec::with_capacity(NUM_THRESHOLDS);
    for (t, th) in thresholds.iter().enumerate() {
        let c = match th {
            None => None,
            Some(th) => match thresholds[..t].iter().position(|x| *x == Some(*th)) {
                Some(k) => counts[k],
                None => Some(accumulate(scenes, class, Some(*th), None).0),
            },
        };
        counts.push(c);
    }
    if counts.iter().all(Option::is_none) {
        // no recall reached: every figure at its worst
        return ClassFigures {
            amota: 0.0,
            amotp: WORST_MOTP,
            mota: 0.0,
            motp: WORST_MOTP,
            best: None,
            best_threshold: None,
        };
    }
    let over = |f: fn(&Counts) -> f64, worst: f64| {
        counts
            .iter()
            .map(|c| c.map(|c| f(&c)).filter(|v| !v.is_nan()).unwrap_or(worst))
            .sum::<f64>()
            / NUM_THRESHOLDS as f64
    };
    // np.nanargmax: the first of the largest
    let mut best: Option<(Counts, Option<f64>)> = None;
    for (c, th) in counts.iter().zip(&thresholds) {
        let Some(c) = c else { continue };
        if best.is_none_or(|(b, _)| c.mota() > b.mota()) {
            best = Some((*c, *th));
        }
    }
    let (best, best_threshold) = best.expect("some threshold reached");
    ClassFigures {
        amota: over(Counts::motar, 0.0),
        amotp: over(Counts::motp, WORST_MOTP),
        mota: best.mota(),
        motp: best.motp(),
        best: Some(best),
        best_threshold,
    }
}

/// The devkit's `compute_thresholds`, ascending: the score at each recall of
/// `linspace(0.1, 1, 40)`, `None` where that recall is never reached.
fn thresholds(mut scores: Vec<f64>, gt_count: usize) -> Vec<Option<f64>> {
    if scores.is_empty() {
        return vec![None; NUM_THRESHOLDS];
    }
    scores.sort_by(|a, b| b.total_cmp(a));
    let rec: Vec<f64> = (1..=scores.len())
        .map(|k| k as f64 / gt_count as f64)
        .collect();
    let max_rec = rec[rec.len() - 1];
    let step = (1.0 - MIN_RECALL) / (NUM_THRESHOLDS - 1) as f64;
    let mut out: Vec<Option<f64>> = (0..NUM_THRESHOLDS)
        .map(|k| {
            let r = if k == NUM_THRESHOLDS - 1 {
                1.0
            } else {
                MIN_RECALL + k as f64 * step
            };
            let r = (r * 1e12).round_ties_even() / 1e12;
            (r <= max_rec).then(|| crate::detection_eval::interp(r, &rec, &scores, 0.0))
        })
        .collect();
    out.reverse();
    out
}

/// Centre distance of an object and a hypothesis in the ground plane (m).
fn dist(o: &Obj, h: &Hyp) -> f64 {
    (o.xy[0] - h.xy[0]).hypot(o.xy[1] - h.xy[1])
}

/// Step 1 of a frame: each object keeps the track it last matched where that track's box is
/// still within the matching distance; the kept matches' scores.
fn keep_last(
    objs: &[&Obj],
    hyps: &[&Hyp],
    last: &HashMap<u32, usize>,
    obj_to: &mut [Option<usize>],
    hyp_taken: &mut [bool],
) -> Vec<f64> {
    let mut scores = Vec::new();
    for (i, o) in objs.iter().enumerate() {
        let Some(&track) = last.get(&o.id) else {
            continue;
        };
        let Some(j) = (0..hyps.len()).find(|j| !hyp_taken[*j] && hyps[*j].track == track) else {
            continue;
        };
        if dist(o, hyps[j]) < MATCH_DISTANCE {
            obj_to[i] = Some(j);
            hyp_taken[j] = true;
            scores.push(hyps[j].score);
        }
    }
    scores
}

/// The devkit's `accumulate_threshold` for one class: the event counts with the boxes scoring
/// at least `threshold` (all of them with `None`), and the scores of the matches; where each
/// switch's object stood, into `switches_at` when given.
fn accumulate(
    scenes: &[Scene],
    class: Class,
    threshold: Option<f64>,
    mut switches_at: Option<&mut Vec<[f64; 2]>>,
) -> (Counts, Vec<f64>) {
    let mut c = Counts::default();
    let mut scores = Vec::new();
    for scene in scenes {
        // per object: the track it last matched, and tracked-or-not in each frame it is in
        let mut last: HashMap<u32, usize> = HashMap::new();
        let mut history: HashMap<u32, Vec<bool>> = HashMap::new();
        for f in &scene.frames {
            let objs: Vec<&Obj> = f.gt.iter().filter(|o| o.class == class).collect();
            let hyps: Vec<&Hyp> = f
                .hyps
                .iter()
                .filter(|h| h.class == class && threshold.is_none_or(|t| h.score >= t))
                .collect();
            if objs.is_empty() && hyps.is_empty() {
                continue;
            }
            let mut obj_to: Vec<Option<usize>> = vec![None; objs.len()];
            let mut hyp_taken = vec![false; hyps.len()];
            // 1. keep last correspondences still under the distance
            let kept = keep_last(&objs, &hyps, &last, &mut obj_to, &mut hyp_taken);
            c.matches += kept.len();
            scores.extend(kept);
            // 2. the rest by minimum total distance, most pairs first
            let free_o: Vec<usize> = (0..objs.len()).filter(|i| obj_to[*i].is_none()).collect();
            let free_h: Vec<usize> = (0..hyps.len()).filter(|j| !hyp_taken[*j]).collect();
            let mut edges = Vec::new();
            for (a, &i) in free_o.iter().enumerate() {
                for (b, &j) in free_h.iter().enumerate() {
                    let d = dist(objs[i], hyps[j]);
                    if d < MATCH_DISTANCE {
                        edges.push(Edge::new(a, b, d));
                    }
                }
            }
            for (a, b) in assign(free_o.len(), free_h.len(), &edges) {
                let (i, j) = (free_o[a], free_h[b]);
                obj_to[i] = Some(j);
                hyp_taken[j] = true;
                // 3. a new match with another track than before: a switch
                if last.get(&objs[i].id).is_some_and(|t| *t != hyps[j].track) {
                    c.switches += 1;
                    if let Some(at) = switches_at.as_deref_mut() {
                        at.push(objs[i].xy);
                    }
                } else {
                    c.matches += 1;
                    scores.push(hyps[j].score);
                }
            }
            for (i, o) in objs.iter().enumerate() {
                history.entry(o.id).or_default().push(obj_to[i].is_some());
                match obj_to[i] {
                    Some(j) => {
                        c.dist_sum += dist(o, hyps[j]);
                        last.insert(o.id, hyps[j].track);
                    }
                    None => c.misses += 1,
                }
            }
            c.fps += hyp_taken.iter().filter(|t| !**t).count();
            c.objects += objs.len();
        }
        c.frag += history.values().map(|h| fragmentations(h)).sum::<usize>();
    }
    (c, scores)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(id: u32, x: f64) -> GtObject {
        GtObject {
            id,
            class: Class::Car,
            center: [x, 0.0, 0.0],
            size: [4.5, 1.9, 1.6],
            yaw: 0.0,
            velocity: None,
        }
    }

    fn trk(track: &str, x: f64) -> TrackBox {
        scored(track, x, 1.0)
    }

    fn scored(track: &str, x: f64, score: f64) -> TrackBox {
        TrackBox {
            track: track.into(),
            class: Class::Car,
            center: [x, 0.0],
            score,
        }
    }

    #[test]
    fn each_switch_is_placed_where_its_object_stood() {
        // Object 2 changes track twice (b -> c at x = 20, c -> d at x = 25); object 1 never.
        let mut e = TrackingEval::new();
        let frames: [(&[GtObject], &[TrackBox]); 3] = [
            (
                &[obj(1, 0.0), obj(2, 20.0)],
                &[trk("a", 0.0), trk("b", 20.0)],
            ),
            (
                &[obj(1, 0.0), obj(2, 20.0)],
                &[trk("a", 0.0), trk("c", 20.5)],
            ),
            (
                &[obj(1, 0.0), obj(2, 25.0)],
                &[trk("a", 0.0), trk("d", 25.0)],
            ),
        ];
        for (k, (gt, boxes)) in frames.iter().enumerate() {
            e.add_frame(0, 500_000 * k as u64, gt, boxes);
        }
        let (m, at) = e.summary_with_switches();
        assert_eq!(m, e.summary());
        assert_eq!(m.ids, 2);
        assert_eq!(at, vec![[20.0, 0.0], [25.0, 0.0]]);
        assert!(TrackingEval::new().summary_with_switches().1.is_empty());
    }

    /// Frames of one scene, 0.5 s apart.
    fn run(frames: &[(&[GtObject], &[TrackBox])]) -> TrackingMetrics {
        let mut e = TrackingEval::new();
        for (k, (gt, boxes)) in frames.iter().enumerate() {
            e.add_frame(0, 500_000 * k as u64, gt, boxes);
        }
        e.summary()
    }

    #[test]
    fn a_hand_computed_sequence() {
        // Objects 1 (at x = 0) and 2 (at x = 20) over five frames, every score 1.
        //   frame 0: tracks a on 1 (0.5 m), b on 2 (1.0 m)            TP 2
        //   frame 1: a on 1 (0.0 m); 2 missed; a ghost g far away      TP 1, FN 1, FP 1
        //   frame 2: a on 1 (1.5 m), c on 2 (0.0 m): 2 switches b -> c TP 1, IDS 1
        //   frame 3: a 3 m off 1 (no match, FP), c on 2 (0.5 m)        TP 1, FN 1, FP 1
        //   frame 4: a on 1 (0.0 m), c on 2 (0.0 m)                    TP 2
        let both = [obj(1, 0.0), obj(2, 20.0)];
        let m = run(&[
            (&both, &[trk("a", 0.5), trk("b", 21.0)]),
            (&both, &[trk("a", 0.0), trk("g", 60.0)]),
            (&both, &[trk("a", 1.5), trk("c", 20.0)]),
            (&both, &[trk("a", 3.0), trk("c", 20.5)]),
            (&both, &[trk("a", 0.0), trk("c", 20.0)]),
        ]);
        assert_eq!((m.tp, m.fp, m.fn_, m.ids, m.gt), (7, 2, 2, 1, 10));
        // MOTA = 1 - (2 + 2 + 1) / 10
        assert!((m.mota - 0.5).abs() < 1e-12);
        // MOTP = (0.5 + 1 + 0 + 1.5 + 0 + 0.5 + 0 + 0) / 8 (the switch's distance counts)
        let motp = 3.5 / 8.0;
        assert!((m.motp - motp).abs() < 1e-12);
        // One threshold (1.0) reaches recall 7/10: the 27 recalls 0.1 + k 0.9/39 <= 0.7.
        // MOTAR = 1 - (5 - 0.3 x 10) / 7 = 5/7 there, 0 at the other 13.
        assert!(
            (m.amota - 27.0 / 40.0 * 5.0 / 7.0).abs() < 1e-12,
            "{}",
            m.amota
        );
        assert!((m.amotp - (27.0 * motp + 13.0 * 2.0) / 40.0).abs() < 1e-12);
        // object 1 untracked in frame 3, object 2 in frame 1: one fragmentation each
        assert_eq!(m.frag, 2);
        assert_eq!(m.gt_tracks, 2);
        assert!((m.ids_per_100_tracks - 50.0).abs() < 1e-12);
    }

    #[test]
    fn amota_sweeps_the_score_thresholds() {
        // Object 1 tracked by a (score 0.9, 0.5 m off), object 2 by b (score 0.5, 1 m off),
        // a ghost g (score 0.6), four frames. Matched scores 0.9 x 4, 0.5 x 4 of 8 objects:
        // the threshold is 0.9 up to recall 0.5, falls linearly to 0.5 at 0.625, then stays.
        //   recall < 0.59375 (k = 0..21):   only a   MOTAR 1,   MOTA 0.5, MOTP 0.5
        //   k = 22 (threshold in (.5, .6]):  a and g  MOTAR 0,   MOTA 0,   MOTP 0.5
        //   k = 23..39 (threshold 0.5):      all      MOTAR 0.5, MOTA 0.5, MOTP 0.75
        let both = [obj(1, 0.0), obj(2, 20.0)];
        let boxes = [
            scored("a", 0.5, 0.9),
            scored("b", 21.0, 0.5),
            scored("g", 60.0, 0.6),
        ];
        let frame: (&[GtObject], &[TrackBox]) = (&both, &boxes);
        let m = run(&[frame; 4]);
        assert!(
            (m.amota - (22.0 + 0.5 * 17.0) / 40.0).abs() < 1e-12,
            "{}",
            m.amota
        );
        assert!((m.amotp - (23.0 * 0.5 + 17.0 * 0.75) / 40.0).abs() < 1e-12);
        // best MOTA: 0.5, first reached at the lowest threshold (every box)
        assert!((m.mota - 0.5).abs() < 1e-12);
        assert_eq!((m.tp, m.fp, m.fn_, m.ids), (8, 4, 0, 0));
        assert!((m.motp - 0.75).abs() < 1e-12);
    }

    #[test]
    fn a_track_score_is_its_mean_and_gaps_are_filled() {
        // Track a scores 1.0 and 0.2 (mean 0.6) and skips frame 1, where the devkit fills it
        // in from its neighbours: all three frames match, none is missed.
        let one = [obj(1, 0.0)];
        let m = run(&[
            (&one, &[scored("a", 0.2, 1.0)]),
            (&one, &[]),
            (&one, &[scored("a", 0.4, 0.2)]),
        ]);
        assert_eq!((m.tp, m.fp, m.fn_), (3, 0, 0));
        // w = (t2 - t1) / (t2 - t0) = 0.5: the filled centre is 0.3, so MOTP = 0.9 / 3
        assert!((m.motp - 0.3).abs() < 1e-12);
        assert!((m.amota - 1.0).abs() < 1e-12);
    }

    #[test]
    fn classes_outside_the_tracking_benchmark_do_not_count() {
        let mut cone = obj(1, 0.0);
        cone.class = Class::TrafficCone;
        let m = run(&[(&[cone], &[])]);
        assert_eq!(m.gt, 0);
        assert!(m.amota.is_nan());
    }

    #[test]
    fn a_kept_track_wins_over_a_closer_newcomer() {
        // Track a followed object 1; now b is closer but a is still within 2 m: no switch.
        let one = [obj(1, 0.0)];
        let m = run(&[
            (&one, &[trk("a", 0.0)]),
            (&one, &[trk("a", 1.5), trk("b", 0.1)]),
        ]);
        assert_eq!((m.tp, m.fp, m.ids), (2, 1, 0));
    }

    #[test]
    fn fragmentations_count_drops_inside_the_tracked_span() {
        assert_eq!(fragmentations(&[false, true, false, true, true, false]), 1);
        assert_eq!(fragmentations(&[true, false, false, true, false, true]), 2);
        assert_eq!(fragmentations(&[false, false]), 0);
    }

    #[test]
    fn reading_names_what_is_wrong() {
        let dir = std::env::temp_dir().join(format!("v2x-trk-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("t.json");
        let write = |s: &str| std::fs::write(&p, s).unwrap();
        write(
            r#"{"results": {"s1": [{"tracking_id": "7", "tracking_name": "car", "translation": [1, 2, 0], "tracking_score": 0.5}]}}"#,
        );
        let r = read_tracking(&p).unwrap();
        assert_eq!(
            r["s1"],
            vec![TrackBox {
                track: "7".into(),
                class: Class::Car,
                center: [1.0, 2.0],
                score: 0.5,
            }]
        );
        write(r#"{"results": {"s1": [{"tracking_name": "car", "translation": [1, 2, 0]}]}}"#);
        let e = read_tracking(&p).unwrap_err();
        assert_eq!(
            (e.sample.as_deref(), e.index, e.field.as_deref()),
            (Some("s1"), Some(0), Some("tracking_id"))
        );
        assert!(e.to_string().ends_with(
            "sample 's1', box 0, field 'tracking_id': missing (is this a tracking results file?)"
        ));
        write(
            r#"{"results": {"s1": [{"tracking_id": 3, "tracking_name": "lorry", "translation": [1, 2, 0]}]}}"#,
        );
        assert_eq!(
            read_tracking(&p).unwrap_err().field.as_deref(),
            Some("tracking_name")
        );
        write(
            r#"{"results": {"s1": [{"tracking_id": 3, "tracking_name": "car", "translation": [1, 2]}]}}"#,
        );
        assert_eq!(
            read_tracking(&p).unwrap_err().field.as_deref(),
            Some("translation")
        );
        write(
            r#"{"results": {"s1": [{"tracking_id": 3, "tracking_name": "car", "translation": [1, 2, 0]}]}}"#,
        );
        assert_eq!(
            read_tracking(&p).unwrap_err().field.as_deref(),
            Some("tracking_score")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
