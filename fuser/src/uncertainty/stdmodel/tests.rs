use super::*;
use v2x_protocol::{Uncertainty, NO_ID};

fn sample(class: Class, score: f64, x: f64) -> ErrorSample {
    ErrorSample {
        class,
        score,
        error: [x, -x, 0.5 * x, 0.1, 0.0, 0.0, 0.01 * x],
        velocity: Some([x, 0.0]),
    }
}

fn car(score: f64) -> Detection {
    Detection {
        class: Class::Car,
        center: [10.0, 20.0, 1.0],
        size: [4.6, 1.95, 1.75],
        yaw: 0.5,
        score,
        std: Uncertainty::uniform(0.5, 0.1, 0.1),
        pos_cov: None,
        velocity: Some(Velocity {
            v: [3.0, 0.0],
            std: [0.25; 2],
        }),
        id: NO_ID,
    }
}

#[test]
fn a_cell_by_hand() {
    // x errors 1 and 3: bias 2, std sqrt(2); y the opposite; size l biased 0.1 with no scatter.
    let s = [sample(Class::Car, 0.5, 1.0), sample(Class::Car, 0.5, 3.0)];
    let c = Cell::fit(&s.iter().collect::<Vec<_>>());
    assert_eq!(c.count, 2);
    assert_eq!(c.bias.center, [2.0, -2.0, 1.0]);
    assert!((c.std.center[0] - 2f64.sqrt()).abs() < 1e-12);
    assert!((c.std.center[2] - 0.5 * 2f64.sqrt()).abs() < 1e-12);
    assert!((c.bias.size[0] - 0.1).abs() < 1e-12 && c.std.size[0] < 1e-12);
    assert_eq!(c.bias.velocity, Some([2.0, 0.0]));
}

#[test]
fn the_std_interval_matches_chi_square_tables() {
    // 100 samples: k = 99, chi2 0.975 = 128.422, 0.025 = 73.361 (tables).
    let x: Vec<f64> = (0..100)
        .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let (mean, s, low, high) = moments(&x);
    assert_eq!(mean, 0.0);
    assert!((low / s - (99.0f64 / 128.422).sqrt()).abs() < 1e-5, "{low}");
    assert!(
        (high / s - (99.0f64 / 73.361).sqrt()).abs() < 1e-5,
        "{high}"
    );
    // Small counts, where approximations fail (tables: k = 1, 2, 5, 30).
    for (k, lo, hi) in [
        (1.0, 0.000982069, 5.023886),
        (2.0, 0.0506356, 7.377759),
        (5.0, 0.8312116, 12.832502),
        (30.0, 16.790772, 46.979242),
    ] {
        assert!((chi2_quantile(k, 0.025) / lo - 1.0).abs() < 1e-5, "{k}");
        assert!((chi2_quantile(k, 0.975) / hi - 1.0).abs() < 1e-6, "{k}");
    }
}

#[test]
fn score_bins_classes_and_fallbacks() {
    let mut samples = Vec::new();
    for i in 0..40 {
        // Cars below score 0.5 err by 2 m, above by 0.5 m; three pedestrians only.
        let score = if i < 20 { 0.3 } else { 0.8 };
        let x = if i < 20 { 2.0 } else { 0.5 } * if i % 2 == 0 { 1.0 } else { -1.0 };
        samples.push(sample(Class::Car, score, x));
    }
    for x in [1.0, -1.0, 0.0] {
        samples.push(sample(Class::Pedestrian, 0.6, x));
    }
    let m = ErrorModel::fit(&samples, 2, "id").unwrap();
    // The median of 20 x 0.3, 3 x 0.6 and 20 x 0.8.
    assert_eq!(m.score_edges, vec![0.6]);
    assert_eq!(bin_of(&m.score_edges, 0.59), 0);
    assert_eq!(bin_of(&m.score_edges, 0.6), 1);
    let low = m.cell(Class::Car, 0.3);
    let high = m.cell(Class::Car, 0.9);
    assert_eq!((low.count, high.count), (20, 20));
    assert!((low.std.center[0] - 2.0 * (20.0f64 / 19.0).sqrt()).abs() < 1e-9);
    assert!((high.std.center[0] - 0.5 * (20.0f64 / 19.0).sqrt()).abs() < 1e-9);
    // Three pedestrians are too few: the cell of all classes; an unseen class too.
    assert_eq!(m.cell(Class::Pedestrian, 0.6).count, 43);
    assert_eq!(m.cell(Class::Bus, 0.6).count, 43);
    assert!(ErrorModel::fit(&samples[..1], 3, "id").is_none());
}

#[test]
fn applying_takes_off_the_bias_and_states_the_stds() {
    let samples: Vec<ErrorSample> = (0..20)
        .map(|i| sample(Class::Car, 0.5, 1.0 + if i % 2 == 0 { 0.5 } else { -0.5 }))
        .collect();
    let m = ErrorModel::fit(&samples, 1, "id").unwrap();
    let mut d = car(0.5);
    d.pos_cov = Some(Box::new([
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ]));
    m.apply(&mut d);
    assert!((d.center[0] - 9.0).abs() < 1e-12 && (d.center[1] - 21.0).abs() < 1e-12);
    assert!((d.size[0] - 4.5).abs() < 1e-12);
    let s = 0.5 * (20.0f64 / 19.0).sqrt();
    assert!((d.std.pos[0] - s).abs() < 1e-12);
    assert!(
        d.pos_cov.is_none(),
        "the model's stds replace a stated covariance"
    );
    let v = d.velocity.unwrap();
    assert!((v.v[0] - 2.0).abs() < 1e-12 && (v.std[0] - s).abs() < 1e-12);
    let mut models = Models::default();
    models.0.insert("rsu".into(), m);
    let mut boxes = vec![car(0.5)];
    models.apply("veh", &mut boxes);
    assert_eq!(
        boxes[0],
        car(0.5),
        "an agent without a model keeps its stds"
    );
    models.apply("rsu", &mut boxes);
    assert_ne!(boxes[0], car(0.5));
}

#[test]
fn files_round_trip_and_bad_ones_are_named() {
    let samples: Vec<ErrorSample> = (0..30)
        .map(|i| sample(Class::Car, 0.3 + 0.02 * i as f64, (i % 5) as f64 - 2.0))
        .collect();
    let m = ErrorModel::fit(&samples, 3, "ground-truth id").unwrap();
    let text = serde_json::to_string_pretty(&m).unwrap();
    assert_eq!(ErrorModel::from_json(&text).unwrap(), m);
    let bad = |from: &str, to: &str| {
        let t = text.replacen(from, to, 1);
        assert_ne!(t, text, "{from}");
        ErrorModel::from_json(&t).unwrap_err()
    };
    let format = "v2x-std-model/9".to_string();
    assert_eq!(bad(FORMAT, "v2x-std-model/9"), ModelError::Format(format));
    let tank = ModelError::UnknownClass("tank".into());
    assert_eq!(bad("\"car\"", "\"tank\""), tank);
    let e = bad("\"count\": 30", "\"count\": 1");
    assert!(
        matches!(e, ModelError::Cell { field, value, .. } if field == "all.count" && value == 1.0)
    );
    let e = bad("\"matched_by\"", "\"colour\": 1, \"matched_by\"");
    assert!(matches!(e, ModelError::Json(m) if m.contains("colour")));
    let mut neg = m.clone();
    neg.classes.get_mut("car").unwrap().all.std.yaw = -1.0;
    let t = serde_json::to_string(&neg).unwrap();
    let e = ErrorModel::from_json(&t).unwrap_err();
    assert!(matches!(e, ModelError::Cell { field, .. } if field == "classes.car.all.std"));
    let mut edges = m.clone();
    edges.score_edges.reverse();
    let t = serde_json::to_string(&edges).unwrap();
    assert_eq!(ErrorModel::from_json(&t), Err(ModelError::ScoreEdges));
    let mut bins = m;
    bins.classes.get_mut("car").unwrap().by_score.pop();
    let t = serde_json::to_string(&bins).unwrap();
    let e = ModelError::Bins {
        class: "car".into(),
        bins: 2,
        edges: 2,
    };
    assert_eq!(ErrorModel::from_json(&t), Err(e));
}
