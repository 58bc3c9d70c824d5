use super::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use v2x_protocol::{wrap_angle, Velocity};

const HZ10: u64 = 100_000;

/// A car at (x, y) heading `yaw`, with 0.5 m position std and no velocity.
pub(super) fn car(x: f64, y: f64, yaw: f64) -> Detection {
    Detection {
        center: [x, y, 1.0],
        yaw,
        ..v2x_protocol::fixtures::car(x, y, 0.5)
    }
}

#[test]
fn a_constant_velocity_track_converges() {
    // True motion (5, 2) m/s from (0, 0); boxes with 0.5 m noise and no velocity, at 10 Hz.
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut g = move || -> f64 { StandardNormal.sample(&mut rng) };
    let mut err_late = Vec::new();
    for run in 0..50 {
        let mut tr = Tracker::new(TrackerParams::default());
        let mut last = None;
        for k in 0..40u64 {
            let t = k as f64 * 0.1;
            let b = car(5.0 * t + 0.5 * g(), 2.0 * t + 0.5 * g(), 0.38);
            let out = tr.step(k * HZ10, &[b]);
            if k == 0 {
                assert!(out.is_empty(), "tentative at its first box");
            } else {
                assert_eq!(out.len(), 1, "run {run} step {k}");
                if let Some(id) = last {
                    assert_eq!(out[0].tracking_id, id, "one id throughout");
                }
                last = Some(out[0].tracking_id);
            }
            if k >= 30 {
                let v = out[0].det.velocity.unwrap();
                err_late.push((v.v[0] - 5.0).hypot(v.v[1] - 2.0));
                // the claimed std is honest: within 4 stds on each axis
                assert!((v.v[0] - 5.0).abs() < 4.0 * v.std[0] + 0.05, "{v:?}");
            }
        }
        assert_eq!(tr.stats().births, 1);
    }
    // After 3 s of 0.5 m boxes the velocity is known to a few tenths of a m/s.
    let mean = err_late.iter().sum::<f64>() / err_late.len() as f64;
    assert!(mean < 0.5, "mean velocity error {mean}");
}

#[test]
fn a_crossing_pair_keeps_its_ids() {
    // Two cars crossing at the origin at right angles, 10 m/s each, exact boxes with their
    // velocities: at the crossing they are 0 m apart, but their velocities tell them apart.
    let mut tr = Tracker::new(TrackerParams::default());
    let mut ids: Option<(u32, u32)> = None;
    for k in 0..41u64 {
        let t = (k as f64 - 20.0) * 0.1;
        let mut a = car(10.0 * t, 0.0, 0.0);
        a.velocity = Some(Velocity {
            v: [10.0, 0.0],
            std: [0.5, 0.5],
        });
        let mut b = car(0.0, 10.0 * t, std::f64::consts::FRAC_PI_2);
        b.velocity = Some(Velocity {
            v: [0.0, 10.0],
            std: [0.5, 0.5],
        });
        let out = tr.step(k * HZ10, &[a, b]);
        if k == 0 {
            continue;
        }
        assert_eq!(out.len(), 2, "step {k}");
        let id_of = |moving_x: bool| {
            out.iter()
                .find(|o| (o.det.velocity.unwrap().v[0] > 5.0) == moving_x)
                .unwrap()
                .tracking_id
        };
        let now = (id_of(true), id_of(false));
        assert_ne!(now.0, now.1);
        if let Some(before) = ids {
            assert_eq!(now, before, "ids swapped at step {k}");
        }
        ids = Some(now);
    }
}

#[test]
fn a_missed_window_does_not_end_a_track_but_four_do() {
    let mut tr = Tracker::new(TrackerParams::default());
    let mut k = 0u64;
    let mut step = |tr: &mut Tracker, seen: bool| {
        let t = k as f64 * 0.1;
        let boxes = if seen {
            vec![car(3.0 * t, 0.0, 0.0)]
        } else {
            vec![]
        };
        k += 1;
        tr.step((k - 1) * HZ10, &boxes)
    };
    for _ in 0..5 {
        step(&mut tr, true);
    }
    let seen = step(&mut tr, true);
    let id = seen[0].tracking_id;
    // a coasting track is shown where it predicts, at half the score
    let coast = step(&mut tr, false);
    assert_eq!(coast.len(), 1);
    assert_eq!(coast[0].tracking_id, id);
    assert!((coast[0].det.score - seen[0].det.score / 2.0).abs() < 0.1);
    assert!(
        (coast[0].det.center[0] - 3.0 * 0.6).abs() < 0.5,
        "{:?}",
        coast[0].det.center
    );
    let back = step(&mut tr, true);
    assert_eq!(back.len(), 1);
    assert_eq!(back[0].tracking_id, id, "one missed window: the same track");
    assert_eq!(tr.stats().live, 1);
    for k in 0..4 {
        let out = step(&mut tr, false);
        assert_eq!(out.len(), usize::from(k < 3), "miss {}", k + 1);
    }
    assert_eq!(
        tr.stats(),
        TrackStats {
            live: 0,
            births: 1,
            deaths: 1
        }
    );
}

#[test]
fn a_false_positive_does_not_become_a_track() {
    let mut tr = Tracker::new(TrackerParams::default());
    for k in 0..20u64 {
        let mut boxes = vec![car(1.0 * k as f64, 0.0, 0.0)];
        // a ghost in every fifth window, each time somewhere else
        if k % 5 == 2 {
            boxes.push(car(40.0 + 7.0 * k as f64, 30.0, 1.0));
        }
        let out = tr.step(k * HZ10, &boxes);
        assert!(out.len() <= 1, "step {k}: {out:?}");
    }
    assert_eq!(tr.stats().births, 1);
}

#[test]
fn a_flipped_heading_keeps_the_tracks_yaw_and_a_new_scene_starts_afresh() {
    let mut tr = Tracker::new(TrackerParams::default());
    for k in 0..10u64 {
        // every third box has its heading turned by pi
        let yaw = if k % 3 == 2 {
            0.3 + std::f64::consts::PI
        } else {
            0.3
        };
        let out = tr.step(k * HZ10, &[car(0.0, 0.0, yaw)]);
        for o in out {
            assert!(wrap_angle(o.det.yaw - 0.3).abs() < 0.05, "{}", o.det.yaw);
        }
    }
    // 10 s later (a gap beyond max_gap_s): the old track ends, a new one starts tentative.
    let out = tr.step(10 * HZ10 + 10_000_000, &[car(0.0, 0.0, 0.3)]);
    assert!(out.is_empty());
    assert_eq!(tr.stats().deaths, 1);
}

#[test]
fn classes_do_not_mix() {
    let mut tr = Tracker::new(TrackerParams::default());
    let mut truck = car(0.0, 0.0, 0.0);
    truck.class = Class::Truck;
    tr.step(0, &[car(0.0, 0.0, 0.0)]);
    let out = tr.step(HZ10, &[truck.clone()]);
    assert!(out.is_empty(), "a truck does not confirm a car's track");
    let out = tr.step(2 * HZ10, &[truck]);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].det.class, Class::Truck);
}

#[test]
fn a_faster_replay_is_tracked_in_data_time() {
    // The same motion, (5, 2) m/s, replayed 4x faster: windows 25 ms apart on the wall clock.
    let mut params = TrackerParams::default();
    params.motion.time_scale = 4.0;
    let mut tr = Tracker::new(params);
    let mut out = Vec::new();
    for k in 0..40u64 {
        let t = k as f64 * 0.1; // data time
        out = tr.step(k * HZ10 / 4, &[car(5.0 * t, 2.0 * t, 0.38)]);
    }
    let v = out[0].det.velocity.unwrap();
    assert!(
        (v.v[0] - 5.0).abs() < 0.05 && (v.v[1] - 2.0).abs() < 0.05,
        "velocity in m per data second: {v:?}"
    );
    // Without the scale the same windows read as 4x the speed.
    let mut tr = Tracker::new(TrackerParams::default());
    for k in 0..40u64 {
        let t = k as f64 * 0.1;
        out = tr.step(k * HZ10 / 4, &[car(5.0 * t, 2.0 * t, 0.38)]);
    }
    assert!((out[0].det.velocity.unwrap().v[0] - 20.0).abs() < 0.2);
}

#[test]
fn by_id_follows_the_true_ids_where_the_likelihood_follows_the_boxes() {
    // Two parked cars 2 m apart, ids 1 and 2; at window 5 their boxes trade places, and at
    // window 8 car 1's box lands 50 m away (far outside any gate).
    let boxes = |k: u64| {
        let (x1, x2) = match k {
            0..=4 => (0.0, 2.0),
            5..=7 => (2.0, 0.0),
            _ => (50.0, 0.0),
        };
        let mut a = car(x1, 0.0, 0.0);
        a.id = 1;
        let mut b = car(x2, 0.0, 0.0);
        b.id = 2;
        [a, b]
    };
    let run = |by_id: bool| {
        let mut tr = Tracker::new(TrackerParams::with_mode(if by_id {
            Association::ById
        } else {
            Association::Assignment
        }));
        (0..10u64)
            .map(|k| {
                let mut out = tr.step(k * HZ10, &boxes(k));
                out.sort_by_key(|t| t.det.id);
                out.iter()
                    .map(|t| (t.tracking_id, t.det.id))
                    .collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
    };
    let ids = run(true);
    // By id: one track per car from window 1 to the end, the jump included.
    for out in &ids[1..] {
        assert_eq!(out, &[(1, 1), (2, 2)]);
    }
    let near = run(false);
    assert_eq!(near[4], [(1, 1), (2, 2)]);
    // By likelihood the track at x = 0 takes car 2's box: the boxes' ids trade tracks.
    assert_eq!(near[5], [(2, 1), (1, 2)]);
    // and car 1's jump starts a new track (tentative, not shown) while track 2 coasts.
    assert!(
        near[8].iter().all(|&(track, _)| track <= 2),
        "{:?}",
        near[8]
    );
}

#[test]
fn by_id_never_matches_a_box_without_an_id() {
    let mut tr = Tracker::new(TrackerParams::with_mode(Association::ById));
    for k in 0..5u64 {
        assert!(tr.step(k * HZ10, &[car(0.0, 0.0, 0.0)]).is_empty());
    }
    assert_eq!(tr.stats().births, 0);
}

#[test]
fn only_the_tracking_classes_are_followed_unless_asked() {
    // a car, a barrier and a cone standing still for five windows
    let boxes = |_: u64| {
        let mut barrier = car(10.0, 0.0, 0.0);
        barrier.class = Class::Barrier;
        let mut cone = car(20.0, 0.0, 0.0);
        cone.class = Class::TrafficCone;
        vec![car(0.0, 0.0, 0.0), barrier, cone]
    };
    for (all_classes, want) in [
        (false, vec![Class::Car]),
        (true, vec![Class::Car, Class::TrafficCone, Class::Barrier]),
    ] {
        let mut params = TrackerParams::default();
        params.management.all_classes = all_classes;
        let mut tr = Tracker::new(params);
        let mut out = Vec::new();
        for k in 0..5 {
            out = tr.step(k * HZ10, &boxes(k));
        }
        let mut classes: Vec<Class> = out.iter().map(|t| t.det.class).collect();
        classes.sort();
        let mut want = want;
        want.sort();
        assert_eq!(classes, want, "all_classes {all_classes}");
        assert_eq!(tr.stats().births, want.len() as u64);
    }
}

#[test]
fn the_height_follows_its_boxes() {
    // Born at 1 m (box std 0.5 m: variance 0.25), then boxes at 2 m, 10 Hz. The first update
    // gains 1 m^2/s x 0.1 s: P = 0.35, K = 0.35 / 0.60, height 1 + K = 1.5833.
    let mut tr = Tracker::new(TrackerParams::default());
    tr.step(0, &[car(0.0, 0.0, 0.0)]);
    let at = |z: f64| Detection {
        center: [0.0, 0.0, z],
        ..car(0.0, 0.0, 0.0)
    };
    let out = tr.step(HZ10, &[at(2.0)]);
    assert!(
        (out[0].det.center[2] - (1.0 + 0.35 / 0.6)).abs() < 1e-12,
        "{out:?}"
    );
    // Ten boxes later it is there; an average of every box would still be 0.09 m short.
    let mut last = out;
    for k in 2..11 {
        last = tr.step(k * HZ10, &[at(2.0)]);
    }
    assert!(last[0].det.center[2] > 1.97, "{last:?}");
}

#[test]
fn with_one_acceleration_for_both_models_the_mixture_is_one_kalman_filter() {
    // A box at the origin (1 m std, no velocity) starts P = diag(1, 1, 100, 100); one second
    // of a car's 2 m/s^2 (q = 4) gives P_xx = 1 + 100 + q/4 = 102, P_xvx = 100 + q/2 = 102; a
    // box at (1, 0) then gains K_x = 102 / (102 + 1) and K_vx = 102 / 103.
    let mut params = TrackerParams::default();
    params.motion.quiet_accel_std = 2.0;
    params.management.confirm_hits = 1;
    let mut tr = Tracker::new(params);
    let one = |x: f64| Detection {
        center: [x, 0.0, 1.0],
        ..v2x_protocol::fixtures::car(x, 0.0, 1.0)
    };
    tr.step(0, &[one(0.0)]);
    let out = tr.step(1_000_000, &[one(1.0)]);
    let t = &tr.tracks[0];
    assert!((t.x[0] - 102.0 / 103.0).abs() < 1e-12, "{}", t.x[0]);
    assert!((out[0].det.velocity.unwrap().v[0] - 102.0 / 103.0).abs() < 1e-12);
    // Both models hold the same state, and their probabilities stay even.
    assert_eq!(t.modes[0], t.modes[1]);
    assert!((t.mu[0] - 0.5).abs() < 1e-12, "{:?}", t.mu);
}

#[test]
fn a_steady_object_weighs_the_quiet_model_and_a_turn_the_agile_one() {
    // Exact boxes of a car at 10 m/s along x for 3 s at 10 Hz, then turning: 5 m/s^2 across
    // for a second.
    let mut tr = Tracker::new(TrackerParams::default());
    let mut pos = [0.0, 0.0];
    for k in 0..30u64 {
        pos[0] = k as f64;
        tr.step(k * HZ10, &[car(pos[0], pos[1], 0.0)]);
    }
    let steady = tr.tracks[0].mu;
    assert!(steady[0] > 0.6, "steady: {steady:?}");
    for k in 30..40u64 {
        let t = (k - 29) as f64 * 0.1;
        pos = [k as f64, 0.5 * 5.0 * t * t];
        tr.step(k * HZ10, &[car(pos[0], pos[1], 0.0)]);
    }
    assert_eq!(tr.tracks.len(), 1, "one track through the turn");
    assert!(
        tr.tracks[0].mu[1] > 0.9,
        "turning: {:?} after {steady:?}",
        tr.tracks[0].mu
    );
}

#[test]
fn at_two_hertz_the_quiet_model_follows_a_steady_object_closer() {
    // A car at (5, 2) m/s seen at 2 Hz with 1.5 m of noise: the mixture with a quiet model
    // ends nearer the truth than the agile model alone (mean over the last 10 boxes of 40 runs).
    let err = |params: TrackerParams| {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut g = move || -> f64 { StandardNormal.sample(&mut rng) };
        let mut sum = 0.0;
        for _ in 0..40 {
            let mut tr = Tracker::new(params);
            for k in 0..30u64 {
                let t = k as f64 * 0.5;
                let b = Detection {
                    center: [5.0 * t + 1.5 * g(), 2.0 * t + 1.5 * g(), 1.0],
                    ..v2x_protocol::fixtures::car(0.0, 0.0, 1.5)
                };
                let out = tr.step(k * 500_000, &[b]);
                if k >= 20 {
                    let c = out[0].det.center;
                    sum += (c[0] - 5.0 * t).hypot(c[1] - 2.0 * t);
                }
            }
        }
        sum / 400.0
    };
    let mixed = err(TrackerParams::default());
    let mut agile = TrackerParams::default();
    agile.motion.quiet_accel_std = 2.0;
    let agile = err(agile);
    assert!(
        mixed < 0.93 * agile,
        "mixture {mixed} m, agile alone {agile} m"
    );
}

#[test]
fn boxes_below_the_operating_point_are_not_output_but_the_track_goes_on() {
    // A car whose boxes score 0.3 while the output's operating point is 0.2: shown; coasting at
    // half its score (0.15): not shown, yet the track lives and keeps its id when boxes return.
    let mut params = TrackerParams::default();
    params.management.min_score = 0.2;
    let mut tr = Tracker::new(params);
    let b = |x: f64| Detection {
        score: 0.3,
        ..car(x, 0.0, 0.0)
    };
    let mut id = None;
    for k in 0..4u64 {
        let out = tr.step(k * HZ10, &[b(k as f64)]);
        if k >= 1 {
            assert_eq!(out.len(), 1, "step {k}");
            id = Some(out[0].tracking_id);
        }
    }
    assert!(tr.step(4 * HZ10, &[]).is_empty());
    assert_eq!(tr.stats().live, 1);
    let back = tr.step(5 * HZ10, &[b(5.0)]);
    assert_eq!(
        back.iter().map(|t| t.tracking_id).collect::<Vec<_>>(),
        [id.unwrap()]
    );
    // Without an operating point the coasting box is shown.
    let mut all = Tracker::new(TrackerParams::default());
    for k in 0..4u64 {
        all.step(k * HZ10, &[b(k as f64)]);
    }
    assert_eq!(all.step(4 * HZ10, &[]).len(), 1);
}
