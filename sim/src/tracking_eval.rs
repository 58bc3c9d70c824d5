//! Tracking metrics (`docs/method.md` §6.2): CLEAR MOT as the nuScenes tracking benchmark's
//! matching defines it, a 2 m centre distance within a class, computed the way `motmetrics`
//! accumulates it.
//!
//! Per class and frame, in time order:
//! 1. a ground-truth object keeps last frame's track if that track is still within 2 m;
//! 2. the other objects and tracks are matched by the exact minimum-distance assignment over
//!    pairs within 2 m;
//! 3. a match whose track differs from the object's previous track is an identity switch (IDS);
//!    unmatched tracks are false positives, unmatched objects misses.
//!
//! Summed over classes: MOTA = 1 - (FN + FP + IDS) / GT, MOTP = the mean distance (m) of the
//! matches, FRAG = the number of times an object goes from tracked to untracked between its
//! first and last tracked frame. AMOTA (MOTA averaged over recall thresholds) is not computed.

use crate::dataset::GtObject;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use v2x_fuser::association::{assign, Edge};
use v2x_protocol::Class;

/// The matching distance (m).
pub const MATCH_DISTANCE: f64 = 2.0;

/// One tracked box as the metrics see it.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackBox {
    /// The track's id (a string in the nuScenes tracking format).
    pub track: String,
    /// The class (`tracking_name`).
    pub class: Class,
    /// Centre x, y (m).
    pub center: [f64; 2],
}

/// The figures of `v2x-sim eval --tracking`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TrackingMetrics {
    /// 1 - (FN + FP + IDS) / GT.
    #[serde(rename = "MOTA")]
    pub mota: f64,
    /// Mean centre distance of the matches (m).
    #[serde(rename = "MOTP")]
    pub motp: f64,
    /// Identity switches.
    #[serde(rename = "IDS")]
    pub ids: usize,
    /// Fragmentations.
    #[serde(rename = "FRAG")]
    pub frag: usize,
    /// Matches.
    pub tp: usize,
    /// Tracked boxes matching nothing.
    pub fp: usize,
    /// Ground-truth boxes not matched.
    #[serde(rename = "fn")]
    pub fn_: usize,
    /// Ground-truth boxes.
    pub gt: usize,
    /// Distinct ground-truth objects.
    pub gt_tracks: usize,
    /// Identity switches per 100 ground-truth objects.
    pub ids_per_100_tracks: f64,
}

/// Collects frames in time order, then scores them.
#[derive(Clone, Debug, Default)]
pub struct TrackingEval {
    frames: Vec<(Vec<GtObject>, Vec<TrackBox>)>,
}

impl TrackingEval {
    /// An empty evaluation.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the next frame: its ground truth and the tracked boxes for it.
    pub fn add_frame(&mut self, gt: &[GtObject], boxes: &[TrackBox]) {
        self.frames.push((gt.to_vec(), boxes.to_vec()));
    }

    /// Appends another evaluation's frames after this one's (its sequences follow this one's).
    pub fn merge(&mut self, other: TrackingEval) {
        self.frames.extend(other.frames);
    }

    /// CLEAR MOT over every frame added.
    pub fn summary(&self) -> TrackingMetrics {
        let mut m = TrackingMetrics::default();
        let mut dist_sum = 0.0;
        // per object: the frames (indices) it appears in and whether it was tracked there
        let mut history: BTreeMap<u32, Vec<bool>> = BTreeMap::new();
        for class in Class::ALL {
            let mut last: HashMap<u32, &str> = HashMap::new();
            for (gt, boxes) in &self.frames {
                let objs: Vec<&GtObject> = gt.iter().filter(|o| o.class == class).collect();
                let hyps: Vec<&TrackBox> = boxes.iter().filter(|b| b.class == class).collect();
                let dist = |o: &GtObject, h: &TrackBox| {
                    (o.center[0] - h.center[0]).hypot(o.center[1] - h.center[1])
                };
                let mut obj_to: Vec<Option<usize>> = vec![None; objs.len()];
                let mut hyp_taken = vec![false; hyps.len()];
                // 1. keep last frame's correspondences still within the distance
                for (i, o) in objs.iter().enumerate() {
                    let Some(&track) = last.get(&o.id) else {
                        continue;
                    };
                    let keep = hyps.iter().enumerate().find(|(j, h)| {
                        !hyp_taken[*j] && h.track == track && dist(o, h) <= MATCH_DISTANCE
                    });
                    if let Some((j, _)) = keep {
                        obj_to[i] = Some(j);
                        hyp_taken[j] = true;
                    }
                }
                // 2. the rest by minimum total distance
                let free_o: Vec<usize> = (0..objs.len()).filter(|i| obj_to[*i].is_none()).collect();
                let free_h: Vec<usize> = (0..hyps.len()).filter(|j| !hyp_taken[*j]).collect();
                let mut edges = Vec::new();
                for (a, &i) in free_o.iter().enumerate() {
                    for (b, &j) in free_h.iter().enumerate() {
                        let d = dist(objs[i], hyps[j]);
                        if d <= MATCH_DISTANCE {
                            edges.push(Edge { a, b, cost: d });
                        }
                    }
                }
                for (a, b) in assign(free_o.len(), free_h.len(), &edges) {
                    let (i, j) = (free_o[a], free_h[b]);
                    obj_to[i] = Some(j);
                    hyp_taken[j] = true;
                    // 3. a new match with another track than before: a switch
                    if last.get(&objs[i].id).is_some_and(|t| *t != hyps[j].track) {
                        m.ids += 1;
                    }
                }
                for (i, o) in objs.iter().enumerate() {
                    history.entry(o.id).or_default().push(obj_to[i].is_some());
                    match obj_to[i] {
                        Some(j) => {
                            m.tp += 1;
                            dist_sum += dist(o, hyps[j]);
                            last.insert(o.id, hyps[j].track.as_str());
                        }
                        None => m.fn_ += 1,
                    }
                }
                m.fp += hyp_taken.iter().filter(|t| !**t).count();
                m.gt += objs.len();
            }
        }
        m.frag = history.values().map(|h| fragmentations(h)).sum();
        m.gt_tracks = history.len();
        m.mota = if m.gt > 0 {
            1.0 - (m.fn_ + m.fp + m.ids) as f64 / m.gt as f64
        } else {
            0.0
        };
        m.motp = if m.tp > 0 {
            dist_sum / m.tp as f64
        } else {
            0.0
        };
        m.ids_per_100_tracks = if m.gt_tracks > 0 {
            100.0 * m.ids as f64 / m.gt_tracks as f64
        } else {
            0.0
        };
        m
    }
}

/// Times an object goes from tracked to untracked between its first and last tracked frame.
fn fragmentations(tracked: &[bool]) -> usize {
    let (Some(first), Some(last)) = (
        tracked.iter().position(|t| *t),
        tracked.iter().rposition(|t| *t),
    ) else {
        return 0;
    };
    tracked[first..=last]
        .windows(2)
        .filter(|w| w[0] && !w[1])
        .count()
}

/// Reads a nuScenes tracking results file: per sample token, each box's `tracking_id` (a string
/// or an integer), `tracking_name` and `translation`. Errors name the file, sample, box and field.
pub fn read_tracking(path: &Path) -> Result<BTreeMap<String, Vec<TrackBox>>, String> {
    let file = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| format!("{file}: cannot read: {e}"))?;
    let doc: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{file}: not JSON: {e}"))?;
    let results = doc
        .get("results")
        .and_then(|r| r.as_object())
        .ok_or_else(|| format!("{file}: no \"results\" object"))?;
    let mut out = BTreeMap::new();
    for (sample, boxes) in results {
        let boxes = boxes
            .as_array()
            .ok_or_else(|| format!("{file}: sample {sample}: expected an array of boxes"))?;
        let mut list = Vec::with_capacity(boxes.len());
        for (k, b) in boxes.iter().enumerate() {
            let at = |field: &str, what: &str| {
                format!("{file}: sample {sample}, box {k}: {field}: {what}")
            };
            let track = match b.get("tracking_id") {
                Some(serde_json::Value::String(s)) => s.clone(),
                Some(serde_json::Value::Number(n)) => n.to_string(),
                Some(_) => return Err(at("tracking_id", "expected a string")),
                None => {
                    return Err(at(
                        "tracking_id",
                        "missing (is this a tracking results file?)",
                    ))
                }
            };
            let name = b
                .get("tracking_name")
                .and_then(|v| v.as_str())
                .ok_or_else(|| at("tracking_name", "missing or not a string"))?;
            let class: Class = name.parse().map_err(|e: String| at("tracking_name", &e))?;
            let t = b
                .get("translation")
                .and_then(|v| v.as_array())
                .filter(|a| a.len() == 3)
                .ok_or_else(|| at("translation", "expected 3 numbers"))?;
            let xy: Vec<f64> = t[..2]
                .iter()
                .filter_map(|v| v.as_f64())
                .filter(|v| v.is_finite())
                .collect();
            if xy.len() != 2 {
                return Err(at("translation", "expected finite numbers"));
            }
            list.push(TrackBox {
                track,
                class,
                center: [xy[0], xy[1]],
            });
        }
        out.insert(sample.clone(), list);
    }
    Ok(out)
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
        TrackBox {
            track: track.into(),
            class: Class::Car,
            center: [x, 0.0],
        }
    }

    #[test]
    fn a_hand_computed_sequence() {
        // Objects 1 (at x = 0) and 2 (at x = 20) over five frames.
        //   frame 0: tracks a on 1 (0.5 m), b on 2 (1.0 m)            TP 2
        //   frame 1: a on 1 (0.0 m); 2 missed; a ghost g far away      TP 1, FN 1, FP 1
        //   frame 2: a on 1 (1.5 m), c on 2 (0.0 m): 2 switches b -> c TP 2, IDS 1
        //   frame 3: a 3 m off 1 (no match, FP), c on 2 (0.5 m)        TP 1, FN 1, FP 1
        //   frame 4: a on 1 (0.0 m), c on 2 (0.0 m)                    TP 2
        let mut e = TrackingEval::new();
        let both = [obj(1, 0.0), obj(2, 20.0)];
        e.add_frame(&both, &[trk("a", 0.5), trk("b", 21.0)]);
        e.add_frame(&both, &[trk("a", 0.0), trk("g", 60.0)]);
        e.add_frame(&both, &[trk("a", 1.5), trk("c", 20.0)]);
        e.add_frame(&both, &[trk("a", 3.0), trk("c", 20.5)]);
        e.add_frame(&both, &[trk("a", 0.0), trk("c", 20.0)]);
        let m = e.summary();
        assert_eq!((m.tp, m.fp, m.fn_, m.ids, m.gt), (8, 2, 2, 1, 10));
        // MOTA = 1 - (2 + 2 + 1) / 10
        assert!((m.mota - 0.5).abs() < 1e-12);
        // MOTP = (0.5 + 1 + 0 + 1.5 + 0 + 0.5 + 0 + 0) / 8
        assert!((m.motp - 3.5 / 8.0).abs() < 1e-12);
        // object 1 untracked in frame 3, object 2 in frame 1: one fragmentation each
        assert_eq!(m.frag, 2);
        assert_eq!(m.gt_tracks, 2);
        assert!((m.ids_per_100_tracks - 50.0).abs() < 1e-12);
    }

    #[test]
    fn a_kept_track_wins_over_a_closer_newcomer() {
        // Track a followed object 1; now b is closer but a is still within 2 m: no switch.
        let mut e = TrackingEval::new();
        e.add_frame(&[obj(1, 0.0)], &[trk("a", 0.0)]);
        e.add_frame(&[obj(1, 0.0)], &[trk("a", 1.5), trk("b", 0.1)]);
        let m = e.summary();
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
            r#"{"results": {"s1": [{"tracking_id": "7", "tracking_name": "car", "translation": [1, 2, 0]}]}}"#,
        );
        let r = read_tracking(&p).unwrap();
        assert_eq!(
            r["s1"],
            vec![TrackBox {
                track: "7".into(),
                class: Class::Car,
                center: [1.0, 2.0]
            }]
        );
        write(r#"{"results": {"s1": [{"tracking_name": "car", "translation": [1, 2, 0]}]}}"#);
        assert!(read_tracking(&p)
            .unwrap_err()
            .contains("sample s1, box 0: tracking_id: missing"));
        write(
            r#"{"results": {"s1": [{"tracking_id": 3, "tracking_name": "lorry", "translation": [1, 2, 0]}]}}"#,
        );
        assert!(read_tracking(&p).unwrap_err().contains("tracking_name"));
        write(
            r#"{"results": {"s1": [{"tracking_id": 3, "tracking_name": "car", "translation": [1, 2]}]}}"#,
        );
        assert!(read_tracking(&p).unwrap_err().contains("translation"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
