//! The tracking metrics against the nuScenes devkit: a random case (three scenes, four classes,
//! misses, unannotated frames, ghosts, new ids for old objects, each frame's objects in shuffled
//! order), a crafted scene where two objects compete for one track (as annotated and as filled
//! in), and the figures the devkit's tracking evaluation gives for it, every column and class,
//! made by `examples/python/devkit_tracking_case.py`.

use v2x_protocol::Class;
use v2x_sim::dataset::GtObject;
use v2x_sim::tracking_eval::{TrackBox, TrackingEval};

fn xy(v: &serde_json::Value) -> [f64; 2] {
    [v[0].as_f64().unwrap(), v[1].as_f64().unwrap()]
}

fn class(v: &serde_json::Value) -> Class {
    v.as_str().unwrap().parse().unwrap()
}

#[test]
fn the_metrics_equal_the_devkits() {
    let text = include_str!("../data/tracking_devkit_case.json");
    let case: serde_json::Value = serde_json::from_str(text).unwrap();
    let mut eval = TrackingEval::new();
    for (s, frames) in case["scenes"].as_array().unwrap().iter().enumerate() {
        for f in frames.as_array().unwrap() {
            let gt: Vec<GtObject> = f["gt"]
                .as_array()
                .unwrap()
                .iter()
                .map(|o| {
                    let [x, y] = xy(&o["xy"]);
                    GtObject {
                        id: o["id"].as_u64().unwrap() as u32,
                        class: class(&o["class"]),
                        center: [x, y, 0.0],
                        size: [1.0; 3],
                        yaw: 0.0,
                        velocity: None,
                    }
                })
                .collect();
            let boxes: Vec<TrackBox> = f["boxes"]
                .as_array()
                .unwrap()
                .iter()
                .map(|b| TrackBox {
                    track: b["track"].as_str().unwrap().into(),
                    class: class(&b["class"]),
                    center: xy(&b["xy"]),
                    score: b["score"].as_f64().unwrap(),
                })
                .collect();
            eval.add_frame(s, f["t_us"].as_u64().unwrap(), &gt, &boxes);
        }
    }
    let m = eval.summary();
    let want = &case["devkit"];
    close(
        "overall",
        want,
        &[
            ("amota", m.amota),
            ("amotp", m.amotp),
            ("mota", m.mota),
            ("motp", m.motp),
            ("ids", m.ids as f64),
            ("frag", m.frag as f64),
            ("tp", m.tp as f64),
            ("fp", m.fp as f64),
            ("fn", m.fn_ as f64),
        ],
    );
    let classes = want["classes"].as_object().unwrap();
    assert_eq!(m.classes.len(), classes.len());
    for (name, w) in classes {
        let got = &m.classes[name];
        close(
            name,
            w,
            &[
                ("amota", got.amota),
                ("amotp", got.amotp),
                ("mota", got.mota),
                ("motp", got.motp),
                ("ids", got.ids as f64),
                ("frag", got.frag as f64),
            ],
        );
    }
}

/// Each figure equals the devkit's to 1e-9.
fn close(what: &str, want: &serde_json::Value, got: &[(&str, f64)]) {
    for (key, got) in got {
        let w = want[key].as_f64().unwrap();
        assert!(
            (got - w).abs() < 1e-9,
            "{what} {key}: {got} here, {w} in the devkit"
        );
    }
}
