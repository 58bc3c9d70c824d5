//! The protocol against the official functions (`examples/python/dair_ap_case.py` wrote the
//! expected values by running them) and by hand.

use super::*;
use serde_json::Value;

const CASE: &str = include_str!("../../tests/data/dair_ap_case.json");

fn class(name: &str) -> Class {
    match name {
        "car" => Class::Car,
        "truck" => Class::Truck,
        "pedestrian" => Class::Pedestrian,
        "cyclist" => Class::Bicycle,
        other => panic!("class {other}"),
    }
}

fn dair_box(v: &Value) -> DairBox {
    let arr = |k: &str| -> [f64; 3] { std::array::from_fn(|i| v[k][i].as_f64().unwrap()) };
    let c = corners(arr("center"), arr("size"), v["yaw"].as_f64().unwrap());
    DairBox {
        class: DairClass::of(class(v["class"].as_str().unwrap())),
        corners: c,
        score: v.get("score").and_then(Value::as_f64).unwrap_or(1.0),
    }
}

#[test]
fn iou_equals_the_official_box3d_iou() {
    let case: Value = serde_json::from_str(CASE).unwrap();
    let ious = case["ious"].as_array().unwrap();
    assert!(ious.len() > 200);
    let mut overlapping = 0;
    for pair in ious {
        let (g, p) = (dair_box(&pair["gt"]), dair_box(&pair["pred"]));
        let (i3, i2) = box_iou(&g.corners, &p.corners);
        let (e3, e2) = (
            pair["iou_3d"].as_f64().unwrap(),
            pair["iou_bev"].as_f64().unwrap(),
        );
        assert!(
            (i3 - e3).abs() < 1e-9 && (i2 - e2).abs() < 1e-9,
            "{pair}: ours {i3} {i2}"
        );
        overlapping += usize::from(e3 > 0.0);
    }
    assert!(overlapping > 20);
}

#[test]
fn ap_equals_the_official_evaluator() {
    let case: Value = serde_json::from_str(CASE).unwrap();
    let mut eval = DairEval::new();
    for f in case["frames"].as_array().unwrap() {
        let gt: Vec<DairBox> = f["gt"].as_array().unwrap().iter().map(dair_box).collect();
        let preds: Vec<DairBox> = f["preds"]
            .as_array()
            .unwrap()
            .iter()
            .map(dair_box)
            .collect();
        eval.add_frame(&gt, &preds);
    }
    let mut checked = 0;
    for (key, expected) in case["ap"].as_object().unwrap() {
        let (view, rest) = key.split_once(' ').unwrap();
        let (name, t) = rest.split_once('@').unwrap();
        let cls = DairClass::ALL
            .into_iter()
            .find(|c| c.name() == name)
            .unwrap();
        let view = if view == "3d" {
            View::ThreeD
        } else {
            View::Bev
        };
        let ours = eval.ap(view, cls, t.parse().unwrap()).unwrap();
        let expected = expected.as_f64().unwrap();
        assert!(
            (ours - expected).abs() < 1e-12,
            "{key}: ours {ours}, official {expected}"
        );
        checked += usize::from(expected > 0.0);
    }
    assert!(checked >= 8, "the case must exercise non-zero APs");
}

#[test]
fn hand_computed_iou_and_ap() {
    let b = |x: f64, z: f64| corners([x, 0.0, z], [4.0, 2.0, 1.0], 0.0);
    // Identical: 1. Shifted by half a length: BEV 4/12 = 1/3. Lifted by half a height as well:
    // 3D 2/(8 + 8 - 2) = 1/7.
    assert!((box_iou(&b(0.0, 0.0), &b(0.0, 0.0)).0 - 1.0).abs() < 1e-12);
    let (i3, i2) = box_iou(&b(0.0, 0.0), &b(2.0, 0.5));
    assert!(
        (i2 - 1.0 / 3.0).abs() < 1e-12 && (i3 - 1.0 / 7.0).abs() < 1e-12,
        "{i3} {i2}"
    );
    assert_eq!(box_iou(&b(0.0, 0.0), &b(10.0, 0.0)), (0.0, 0.0));
    // Three ground truths, predictions hit, miss, hit by score: tp fp tp. Precision 1, 1/2,
    // 2/3 -> 1, 2/3, 2/3; recall 1/3, 1/3, 2/3. The official sum skips the first step: only
    // (2/3 - 1/3) x 2/3 = 2/9 is counted.
    assert!(
        (compute_ap(&[(0.9, true), (0.8, false), (0.7, true)], 3).unwrap() - 2.0 / 9.0).abs()
            < 1e-12
    );
    assert_eq!(compute_ap(&[], 2), Some(0.0));
    assert_eq!(compute_ap(&[(0.5, false)], 0), None);
    assert_eq!(official_bytes(0), 72);
    assert_eq!(official_bytes(3), 216);
}

#[test]
fn range_keeps_a_box_with_a_corner_inside() {
    let pose = Pose::IDENTITY;
    let at = |x: f64| to_vehicle(Class::Car, [x, 0.0, -1.0], [4.0, 2.0, 1.5], 0.0, 1.0, &pose);
    assert!(at(80.0).is_some(), "its back corners lie at 78 m");
    assert!(at(81.2).is_none());
    assert!(at(-11.0).is_some());
    assert!(at(-12.1).is_none());
    // The ceiling is open: a box wholly above 1 m is out.
    assert!(to_vehicle(
        Class::Car,
        [10.0, 0.0, 2.0],
        [4.0, 2.0, 1.5],
        0.0,
        1.0,
        &pose
    )
    .is_none());
    assert_eq!(at(10.0).unwrap().class, Some(DairClass::Car));
    assert_eq!(
        to_vehicle(Class::Barrier, [10.0, 0.0, -1.0], [1.0; 3], 0.0, 1.0, &pose)
            .unwrap()
            .class,
        None
    );
}

#[test]
fn frame_order_reads_the_predictions_as_gathered() {
    // Frame 1 finds its car at 0.5; frame 2 holds a false box at 0.9. Ranked by score: a false
    // box first, the car second (precision 1/2 at recall 1). As gathered: the car first, then
    // the false box; the official steps skip the first one, so nothing is counted.
    let preds: Vec<Scored> = vec![(0.5, true), (0.9, false)];
    assert_eq!(compute_ap(&preds, 1), Some(0.5));
    assert_eq!(ap_in_order(&preds, 1), Some(0.0));
    assert_eq!(ap_in_order(&preds, 0), None);
}
