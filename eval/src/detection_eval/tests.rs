use super::*;
use v2x_protocol::{Uncertainty, Velocity};

fn gt(class: Class, x: f64) -> GtObject {
    GtObject {
        id: 0,
        class,
        center: [x, 0.0, 1.0],
        size: [4.0, 2.0, 1.5],
        yaw: 0.2,
        velocity: Some([10.0, 0.0]),
    }
}

fn pred(class: Class, x: f64, score: f64) -> Detection {
    Detection {
        class,
        center: [x, 0.0, 1.0],
        size: [4.0, 2.0, 1.5],
        yaw: 0.2,
        score,
        std: Uncertainty::uniform(0.5, 0.1, 0.1),
        pos_cov: None,
        velocity: Some(Velocity {
            v: [10.0, 0.0],
            std: [0.5, 0.5],
        }),
        // Ids play no part in distance matching.
        id: 77,
    }
}

/// Two cars at x = 0 and 10; predictions at 0.3 (score 0.9), 30 (0.8, false) and 10.8 (0.7).
fn hand_scene() -> DetectionEval {
    let mut e = DetectionEval::new();
    e.add_frame(
        &[gt(Class::Car, 0.0), gt(Class::Car, 10.0)],
        &[
            pred(Class::Car, 0.3, 0.9),
            pred(Class::Car, 30.0, 0.8),
            pred(Class::Car, 10.8, 0.7),
        ],
    );
    e
}

#[test]
fn a_hand_made_scene_scores_as_computed_by_hand() {
    let m = hand_scene().summary();
    let car = &m.per_class["car"];
    // 0.5 m: only the first prediction matches. Precision is 1 below 50% recall, 1/3 at it, 0
    // beyond: AP = (39 x 0.9 + (1/3 - 0.1)) / 90 / 0.9.
    let ap_half = (39.0 * 0.9 + (1.0 / 3.0 - 0.1)) / 81.0;
    assert!((car.ap["0.5"] - ap_half).abs() < 1e-12, "{}", car.ap["0.5"]);
    // 1, 2 and 4 m: both match; precision 1 below 50% recall, 1/2 at it, then rising linearly to
    // 2/3 at full recall: AP = (39 x 0.9 + 0.4 + sum_k (0.4 + k / 300)) / 81.
    let ap = (39.0 * 0.9 + 0.4 + 50.0 * 0.4 + 1275.0 / 300.0) / 81.0;
    for th in ["1", "2", "4"] {
        assert!((car.ap[th] - ap).abs() < 1e-12, "{th}: {}", car.ap[th]);
    }
    // ATE at 2 m: the running mean of (0.3, 0.8) read at each recall point's confidence:
    // 0.3 below 50% recall, 0.425 at it, then 0.425 + 0.25 (r - 0.5): mean 36.5625 / 90.
    assert!(
        (car.errors.ate.unwrap() - 0.40625).abs() < 1e-12,
        "{:?}",
        car.errors.ate
    );
    assert_eq!(
        (car.errors.ase, car.errors.aoe, car.errors.ave, car.aae),
        (Some(0.0), Some(0.0), Some(0.0), Some(1.0))
    );
    assert_eq!((car.gt, car.tp, car.fp), (2, 2, 1));
    // The nine classes without ground truth score AP 0 and errors 1 where defined.
    let car_map = (ap_half + 3.0 * ap) / 4.0;
    assert!((m.m_ap - car_map / 10.0).abs() < 1e-12);
    assert!((m.m_ate - (0.40625 + 9.0) / 10.0).abs() < 1e-12);
    assert!((m.m_ase - 0.9).abs() < 1e-12);
    assert!(
        (m.m_aoe - 8.0 / 9.0).abs() < 1e-12,
        "cones have no orientation error"
    );
    assert!(
        (m.m_ave - 7.0 / 8.0).abs() < 1e-12,
        "nor barriers a velocity error"
    );
    assert_eq!(m.m_aae, 1.0);
    let scores = (1.0 - m.m_ate) + 0.1 + 1.0 / 9.0 + 0.125 + 0.0;
    assert!((m.nds - (5.0 * m.m_ap + scores) / 10.0).abs() < 1e-12);
    assert!((m.nds - 0.072_663_3).abs() < 1e-6, "{}", m.nds);
    assert_eq!((m.tp, m.fp, m.fn_), (2, 1, 0));
    assert_eq!(m.precision, Some(2.0 / 3.0));
    assert_eq!(m.recall, Some(1.0));
}

#[test]
fn a_box_far_off_is_not_a_true_positive_whatever_its_id() {
    let mut e = DetectionEval::new();
    let mut p = pred(Class::Car, 50.0, 0.9);
    p.id = 0; // the ground truth's id
    e.add_frame(&[gt(Class::Car, 0.0)], &[p]);
    let m = e.summary();
    assert_eq!((m.tp, m.fp, m.fn_), (0, 1, 1));
    assert_eq!(m.m_ap, 0.0);
    assert_eq!(m.per_class["car"].errors.ate, Some(1.0));
}

#[test]
fn perfect_detections_score_ap_one_and_classes_match_separately() {
    let mut e = DetectionEval::new();
    for f in 0..5 {
        let x = f as f64;
        e.add_frame(
            &[gt(Class::Car, x), gt(Class::Pedestrian, x + 20.0)],
            &[
                pred(Class::Car, x, 0.9),
                pred(Class::Pedestrian, x + 20.0, 0.6),
            ],
        );
    }
    let m = e.summary();
    for c in ["car", "pedestrian"] {
        assert!(
            m.per_class[c].ap.values().all(|&a| (a - 1.0).abs() < 1e-12),
            "{c}"
        );
        assert_eq!(m.per_class[c].errors.ate, Some(0.0));
    }
    assert!((m.m_ap - 0.2).abs() < 1e-12);
    // A pedestrian predicted where a car is matches nothing.
    let mut e = DetectionEval::new();
    e.add_frame(&[gt(Class::Car, 0.0)], &[pred(Class::Pedestrian, 0.0, 0.9)]);
    assert_eq!(e.summary().tp, 0);
}

#[test]
fn interp_and_cummean_follow_numpy() {
    let xp = [0.5, 0.5, 1.0];
    let fp = [1.0, 0.5, 2.0 / 3.0];
    assert_eq!(interp(0.2, &xp, &fp, 0.0), 1.0);
    assert_eq!(interp(0.5, &xp, &fp, 0.0), 0.5);
    assert!((interp(0.75, &xp, &fp, 0.0) - (0.5 + 1.0 / 12.0)).abs() < 1e-15);
    assert_eq!(interp(1.0, &xp, &fp, 0.0), 2.0 / 3.0);
    assert_eq!(interp(1.5, &xp, &fp, 9.0), 9.0);
    assert_eq!(cummean(&[f64::NAN, 2.0, 4.0]), vec![0.0, 2.0, 3.0]);
    assert_eq!(cummean(&[f64::NAN, f64::NAN]), vec![1.0, 1.0]);
    assert!(
        (yaw_diff(0.05, std::f64::consts::PI - 0.05, std::f64::consts::PI) - 0.1).abs() < 1e-12
    );
    assert!(
        (yaw_diff(3.0, -3.0, 2.0 * std::f64::consts::PI) - (2.0 * std::f64::consts::PI - 6.0))
            .abs()
            < 1e-12
    );
}
