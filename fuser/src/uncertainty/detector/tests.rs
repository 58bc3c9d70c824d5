use super::*;

/// The detector's parameters with groups scored by noisy-OR (no existence model).
fn noisy_or() -> DetectorParams {
    DetectorParams {
        existence: None,
        ..DetectorParams::default()
    }
}

fn car(x: f64, score: f64) -> Detection {
    Detection {
        score,
        ..v2x_protocol::fixtures::car(x, 0.0, 0.5)
    }
}

#[test]
fn stds_follow_the_score_and_the_pose() {
    let p = DetectorParams::default();
    assert!((stds(&p, &car(0.0, 1.0), true).pos[0] - 0.15).abs() < 1e-12);
    // 0.15 + 1.2 x 0.5^2
    assert!((stds(&p, &car(0.0, 0.5), true).pos[2] - 0.45).abs() < 1e-12);
    // Another agent's box: sqrt(0.15^2 + 0.5^2).
    let other = stds(&p, &car(0.0, 1.0), false);
    assert!((other.pos[1] - 0.15f64.hypot(0.5)).abs() < 1e-12);
    // Its height less certain: sqrt(0.15^2 + 1^2).
    assert!((other.pos[2] - 0.15f64.hypot(1.0)).abs() < 1e-12);
    assert_eq!((other.size, other.yaw), ([0.2; 3], 0.15));
}

#[test]
fn a_group_scores_the_noisy_or_of_its_members() {
    assert!((group_score([0.5, 0.5]) - 0.75).abs() < 1e-12);
    assert!((group_score([0.6, 0.5]) - 0.8).abs() < 1e-12);
    assert_eq!(group_score([]), 0.0);
    assert_eq!(group_score([0.3]), 0.3);
}

#[test]
fn seen_twice_is_kept_and_the_lone_tail_is_dropped() {
    let p = DetectorParams {
        min_score: 0.4,
        ..noisy_or()
    };
    let mut ego = vec![car(10.0, 0.6), car(40.0, 0.3), car(-30.0, 0.45)];
    let mut other = vec![car(10.3, 0.5), car(70.0, 0.35)];
    ready(&p, &mut ego, true);
    ready(&p, &mut other, false);
    let fused = fuse_scored(&p, &CsbaParams::PLUS, &[ego, other], Some(0));
    let mut got: Vec<(f64, f64)> = fused.iter().map(|d| (d.center[0], d.score)).collect();
    got.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert_eq!(got.len(), 2, "{got:?}");
    // The lone 0.45 box stays; the pair scores 1 - 0.4 x 0.5 and lies nearer the ego car's box,
    // whose std is the smaller: (10 / 0.342^2 + 10.3 / (0.45^2 + 0.5^2)) / (its weights' sum).
    assert_eq!(got[0], (-30.0, 0.45));
    assert!((got[1].1 - 0.8).abs() < 1e-12);
    let (w0, w1) = (
        1.0 / (0.15 + 1.2 * 0.16f64).powi(2),
        1.0 / (0.45f64.powi(2) + 0.25),
    );
    let want = (10.0 * w0 + 10.3 * w1) / (w0 + w1);
    assert!(
        (got[1].0 - want).abs() < 1e-9,
        "{} against {want}",
        got[1].0
    );
}

#[test]
fn a_tracker_gets_the_tail_too() {
    let p = DetectorParams::default().for_tracking();
    assert_eq!(p.min_score, 0.0);
    assert_eq!(p.pose_std, DetectorParams::default().pose_std);
}

#[test]
fn a_group_whose_heights_disagree_is_one_box_at_the_receivers_height() {
    // One car seen by both agents, the other agent's box 1.5 m higher: one box, its height
    // nearer the receiver's (the other agent's height std is sqrt(sigma^2 + 1)).
    let mut ego = vec![car(10.0, 0.6)];
    let mut other = vec![Detection {
        center: [10.2, 0.0, 1.5],
        ..car(10.2, 0.5)
    }];
    let p = noisy_or();
    ready(&p, &mut ego, true);
    ready(&p, &mut other, false);
    let fused = fuse_scored_sourced(&p, &CsbaParams::PLUS, &[ego, other], Some(0));
    assert_eq!(fused.len(), 1);
    assert!(fused[0].det.center[2] > 0.0 && fused[0].det.center[2] < 0.75);
    assert_eq!(fused[0].sources.len(), 2);
    lists_fused_once(&p.for_tracking(), 0.9);
}

/// Two agents' boxes of one car `dz` apart in height fuse to one box.
fn lists_fused_once(p: &DetectorParams, dz: f64) {
    let mut ego = vec![car(10.0, 0.6)];
    let mut other = vec![Detection {
        center: [10.2, 0.0, dz],
        ..car(10.2, 0.5)
    }];
    ready(p, &mut ego, true);
    ready(p, &mut other, false);
    let fused = fuse_scored_sourced(p, &CsbaParams::PLUS, &[ego, other], Some(0));
    assert_eq!(fused.len(), 1, "{dz} m apart");
    assert!((fused[0].det.score - 0.8).abs() < 1e-12);
}

#[test]
fn by_default_a_group_scores_its_chance_of_being_real() {
    // A car both agents see near the receiver, and a far 0.25 box only the other agent has.
    let p = DetectorParams::default();
    let mut ego = vec![car(10.0, 0.6)];
    let mut other = vec![car(10.3, 0.5), car(70.0, 0.25)];
    ready(&p, &mut ego, true);
    ready(&p, &mut other, false);
    let lists = [ego, other];
    let described = fuse_described(&p, &CsbaParams::PLUS, &lists, Some(0));
    assert_eq!(described.len(), 2);
    for (s, x) in &described {
        assert_eq!(s.det.score, existence::DETECTOR_DEFAULT.probability(x));
    }
    let score = |x0: f64| {
        described
            .iter()
            .find(|(s, _)| (s.det.center[0] - x0).abs() < 1.0)
            .map(|(s, _)| s.det.score)
            .unwrap()
    };
    // Seen by both: above either member's score; seen once, far, weakly: below the cut.
    assert!(score(10.0) > 0.95, "{}", score(10.0));
    assert!(score(70.0) < p.min_score, "{}", score(70.0));
    let kept = fuse_scored(&p, &CsbaParams::PLUS, &lists, Some(0));
    assert_eq!(kept.len(), 1);
    // Without the receiver among the members the same pair loses the receiver's term.
    let as_other = fuse_described(&p, &CsbaParams::PLUS, &lists, None);
    assert_eq!(as_other[0].1[3], 0.0);
    assert_eq!(described[0].1[3], 1.0);
}
