//! `v2x-sim eval` on data shaped like a real vehicle-infrastructure data set converted to
//! nuScenes tables: every annotation its own instance (nothing tracked across frames), capture
//! times that differ from the frames' by a few tens of milliseconds, a ground truth of cars
//! only, and detections with equal scores.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use v2x_protocol::Class;
use v2x_sim::cli::{evaluate_file, EvalOptions, Evaluation, Match, Timing};
use v2x_sim::dataset::{GroundTruth, GtFrame, GtObject, Motion, TrackPoint};
use v2x_sim::detection_eval::DetectionMetrics;

const FRAME_US: u64 = 100_000;
const T0: u64 = 1_600_000_000_000_000;

fn car(id: u32, x: f64, y: f64) -> GtObject {
    GtObject {
        id,
        class: Class::Car,
        center: [x, y, 1.0],
        size: [4.5, 1.9, 1.6],
        yaw: 0.3,
        velocity: None,
    }
}

/// Ten frames at 10 Hz of five cars driving at 10 m/s, each annotation its own instance (as
/// most vehicle-infrastructure data sets are labelled).
fn untracked() -> GroundTruth {
    let mut frames = Vec::new();
    let mut tracks = BTreeMap::new();
    for k in 0..10u32 {
        let t = T0 + k as u64 * FRAME_US;
        let objects: Vec<GtObject> = (0..5u32)
            .map(|i| {
                car(
                    100 * k + i,
                    12.0 * i as f64 + k as f64,
                    3.0 * (i % 2) as f64,
                )
            })
            .collect();
        for o in &objects {
            tracks.insert(
                o.id,
                vec![TrackPoint {
                    t_us: t,
                    object: o.clone(),
                }],
            );
        }
        frames.push(GtFrame {
            sample_token: format!("s{k}"),
            scene: 0,
            timestamp_us: t,
            ego: None,
            objects,
        });
    }
    GroundTruth {
        scenes: vec!["scene-0".into()],
        frames,
        motion: Motion::Tracks(vec![tracks]),
        ..Default::default()
    }
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("v2x-eval-real-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join("results.json")
}

/// A box of a results file (no ground-truth id: matched by distance).
fn box_json(sample: &str, name: &str, x: f64, y: f64, score: f64) -> serde_json::Value {
    serde_json::json!({
        "sample_token": sample, "translation": [x, y, 1.0], "size": [1.9, 4.5, 1.6],
        "rotation": [0.9887710779360422, 0.0, 0.0, 0.14943813247359922], "velocity": [0, 0],
        "detection_name": name, "detection_score": score, "attribute_name": ""
    })
}

/// Writes a results file: `samples` in this order, with `meta`.
fn write(path: &Path, meta: serde_json::Value, samples: &[(String, Vec<serde_json::Value>)]) {
    let body: Vec<String> = samples
        .iter()
        .map(|(k, v)| format!("{}: {}", serde_json::json!(k), serde_json::json!(v)))
        .collect();
    let text = format!("{{\"meta\": {meta}, \"results\": {{{}}}}}", body.join(", "));
    std::fs::write(path, text).unwrap();
}

/// Every ground-truth car detected exactly, stamped `late_us` after its frame.
fn exact_detections(gt: &GroundTruth, path: &Path, late_us: u64) {
    let mut stamps = serde_json::Map::new();
    let samples: Vec<(String, Vec<serde_json::Value>)> = gt
        .frames
        .iter()
        .map(|f| {
            stamps.insert(f.sample_token.clone(), (f.timestamp_us + late_us).into());
            let boxes = f
                .objects
                .iter()
                .map(|o| box_json(&f.sample_token, "car", o.center[0], o.center[1], 0.8))
                .collect();
            (f.sample_token.clone(), boxes)
        })
        .collect();
    write(
        path,
        serde_json::json!({ "v2x_timestamps": stamps }),
        &samples,
    );
}

fn distance(e: Evaluation) -> DetectionMetrics {
    match e {
        Evaluation::Distance(m) => m,
        Evaluation::Id(_) => panic!("matched by distance"),
    }
}

#[test]
fn a_sample_is_scored_at_its_own_frame_whatever_its_capture_time() {
    // The roadside unit captured 28 ms after the vehicle's frames: scored at its sample's
    // frame, every box is right.
    let gt = untracked();
    let path = tmp("late");
    exact_detections(&gt, &path, 28_000);
    let (m, note) = evaluate_file(&gt, &path, &EvalOptions::default()).unwrap();
    let m = distance(m);
    assert_eq!((m.precision, m.recall), (Some(1.0), Some(1.0)), "{note}");
    assert!(
        !note.contains("warning") && !note.contains("interpolated"),
        "{note}"
    );
    // Asking for capture times on ground truth with nothing to interpolate is refused.
    let opts = EvalOptions {
        timing: Timing::Capture,
        ..Default::default()
    };
    let e = evaluate_file(&gt, &path, &opts).unwrap_err().to_string();
    assert!(
        e.contains("no object in it is annotated in more than one frame"),
        "{e}"
    );
}

#[test]
fn node_recordings_between_frames_take_the_nearest_frame_and_say_so() {
    // Keys t<us> (a fuser node's recording) 28 ms after each frame: the nearest frame.
    let gt = untracked();
    let path = tmp("node");
    let samples: Vec<(String, Vec<serde_json::Value>)> = gt
        .frames
        .iter()
        .map(|f| {
            let key = format!("t{}", f.timestamp_us + 28_000);
            let boxes = f
                .objects
                .iter()
                .map(|o| box_json(&key, "car", o.center[0], o.center[1], 0.8))
                .collect();
            (key, boxes)
        })
        .collect();
    write(&path, serde_json::json!({}), &samples);
    let (m, note) = evaluate_file(&gt, &path, &EvalOptions::default()).unwrap();
    assert_eq!(distance(m).precision, Some(1.0), "{note}");
    assert!(
        note.contains("10 sample(s) at a time between frames scored against the nearest frame"),
        "{note}"
    );
}

#[test]
fn predictions_where_the_ground_truth_is_empty_are_warned_about() {
    // Every box filed under the one frame with no object.
    let mut gt = untracked();
    gt.frames[9].objects.clear();
    let path = tmp("empty");
    let boxes: Vec<serde_json::Value> = (0..20)
        .map(|i| box_json("s9", "car", i as f64 * 5.0, 0.0, 0.8))
        .collect();
    write(&path, serde_json::json!({}), &[("s9".into(), boxes)]);
    let (_, note) = evaluate_file(&gt, &path, &EvalOptions::default()).unwrap();
    assert!(note.contains("warning: 20 of 20 predictions fall in samples whose ground truth holds fewer than a tenth as many objects"), "{note}");
}

#[test]
fn the_headline_averages_the_classes_the_ground_truth_holds() {
    // Cars only, detected exactly, and three barriers where there are none.
    let gt = untracked();
    let path = tmp("classes");
    let samples: Vec<(String, Vec<serde_json::Value>)> = gt
        .frames
        .iter()
        .map(|f| {
            let mut boxes: Vec<serde_json::Value> = f
                .objects
                .iter()
                .map(|o| box_json(&f.sample_token, "car", o.center[0], o.center[1], 0.8))
                .collect();
            if f.sample_token == "s0" {
                for i in 0..3 {
                    boxes.push(box_json("s0", "barrier", -30.0 - 5.0 * i as f64, 0.0, 0.5));
                }
            }
            (f.sample_token.clone(), boxes)
        })
        .collect();
    write(&path, serde_json::json!({}), &samples);
    let (m, note) = evaluate_file(&gt, &path, &EvalOptions::default()).unwrap();
    let m = distance(m);
    assert_eq!(m.classes, ["car"]);
    assert!((m.m_ap - 1.0).abs() < 1e-12, "{}", m.m_ap);
    // the devkit's ten-class average: car's 1 and nine zeros
    assert!((m.m_ap_all - 0.1).abs() < 1e-12, "{}", m.m_ap_all);
    assert_eq!((m.precision, m.recall), (Some(1.0), Some(1.0)));
    assert!(
        note.contains("predicted boxes of classes not scored: barrier 3"),
        "{note}"
    );
    // Chosen classes: the barriers count (AP 0), their boxes are false positives.
    let opts = EvalOptions {
        classes: Some(vec![Class::Car, Class::Barrier]),
        ..Default::default()
    };
    let m = distance(evaluate_file(&gt, &path, &opts).unwrap().0);
    assert_eq!(m.classes, ["car", "barrier"]);
    assert!((m.m_ap - 0.5).abs() < 1e-12, "{}", m.m_ap);
    assert_eq!((m.tp, m.fp), (50, 3));
    // A class neither holds: nothing is scored.
    let opts = EvalOptions {
        classes: Some(vec![Class::Truck]),
        how: Match::Distance,
        ..Default::default()
    };
    let m = distance(evaluate_file(&gt, &path, &opts).unwrap().0);
    assert_eq!((m.tp, m.fp, m.fn_), (0, 0, 0));
}

#[test]
fn equal_scores_are_ranked_as_the_devkit_ranks_them() {
    // Three samples with one car each; the file lists b (a box 3 m off), c and a (exact), all
    // at score 0.5. The devkit takes the later of equal scores first: a, c, then b. Its AP,
    // from nuscenes.eval.detection.algo.accumulate and calc_ap: 0.6222... below 4 m, 1 at 4 m
    // (ranked in token order, a, b, c, it would be 0.4525).
    let mut gt = untracked();
    gt.frames.truncate(3);
    for (f, name) in gt.frames.iter_mut().zip(["a", "b", "c"]) {
        f.sample_token = name.into();
        f.objects = vec![car(f.timestamp_us as u32, 0.0, 0.0)];
    }
    let path = tmp("ties");
    write(
        &path,
        serde_json::json!({}),
        &[
            ("b".into(), vec![box_json("b", "car", 3.0, 0.0, 0.5)]),
            ("c".into(), vec![box_json("c", "car", 0.0, 0.0, 0.5)]),
            ("a".into(), vec![box_json("a", "car", 0.0, 0.0, 0.5)]),
        ],
    );
    let m = distance(
        evaluate_file(&gt, &path, &EvalOptions::default())
            .unwrap()
            .0,
    );
    let ap = &m.per_class["car"].ap;
    for th in ["0.5", "1", "2"] {
        assert!(
            (ap[th] - 0.6222222222222222).abs() < 1e-12,
            "{th}: {}",
            ap[th]
        );
    }
    assert!((ap["4"] - 1.0000000000000004).abs() < 1e-12, "{}", ap["4"]);
}
