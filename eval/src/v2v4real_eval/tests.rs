use super::*;
use v2x_protocol::Uncertainty;

/// A 4 m x 2 m x 1.6 m car at (x, y, z), heading along x.
fn car(x: f64, y: f64, z: f64, score: f64) -> Detection {
    Detection {
        center: [x, y, z],
        size: [4.0, 2.0, 1.6],
        score,
        std: Uncertainty::uniform(0.3, 0.1, 0.1),
        ..v2x_protocol::fixtures::car(x, y, 0.3)
    }
}

/// Two frames worked by hand. Frame 1: one car, found exactly (0.9) and a false box far away
/// (0.8). Frame 2: two cars; one found 1 m off along its length (0.95: BEV and 3D IoU 6/10),
/// the other found in place but 0.8 m too high (0.5: BEV IoU 1, 3D IoU 6.4/19.2).
fn worked() -> V2v4realEval {
    let mut e = V2v4realEval::new();
    e.add_frame(
        &[car(0.0, 0.0, 0.0, 1.0)],
        &[car(50.0, 50.0, 0.0, 0.8), car(0.0, 0.0, 0.0, 0.9)],
    );
    e.add_frame(
        &[car(10.0, 0.0, 0.0, 1.0), car(20.0, 5.0, 0.0, 1.0)],
        &[car(20.0, 5.0, 0.8, 0.5), car(11.0, 0.0, 0.0, 0.95)],
    );
    e
}

#[test]
fn the_worked_case_gives_the_hand_computed_aps() {
    let e = worked();
    let close = |got: Option<f64>, want: f64| {
        let got = got.unwrap();
        assert!((got - want).abs() < 1e-12, "{got} against {want}");
    };
    // BEV at 0.3 and 0.5: tp fp | tp tp, 3 cars: 1/3 x 1 + 1/3 x 3/4 + 1/3 x 3/4.
    close(e.ap(View::Bev, 0.3), 5.0 / 6.0);
    close(e.ap(View::Bev, 0.5), 5.0 / 6.0);
    // BEV at 0.7: tp fp | fp tp: 1/3 x 1 + 1/3 x 1/2.
    close(e.ap(View::Bev, 0.7), 0.5);
    // 3D at 0.5: tp fp | tp fp: 1/3 x 1 + 1/3 x 2/3.
    close(e.ap(View::ThreeD, 0.5), 5.0 / 9.0);
    // 3D at 0.3: the high box's IoU is exactly 1/3, so it counts.
    close(e.ap(View::ThreeD, 0.3), 5.0 / 6.0);
    // 3D at 0.7: tp fp | fp fp.
    close(e.ap(View::ThreeD, 0.7), 1.0 / 3.0);
    let s = e.summary();
    assert_eq!((s.frames, s.gt, s.predictions), (2, 3, 4));
    assert_eq!(s.ap_bev["0.70"], 0.5);
}

#[test]
fn frames_are_not_re_sorted_by_score() {
    // Frame 2's 0.95 box ranks above frame 1's boxes across frames; the protocol keeps frame
    // order, so at 0.7 BEV frame 1's hit still comes first. Re-sorted, the AP would be
    // 1/3 x 1/2 + 1/3 x 1/2 (fp tp fp tp) = 1/3.
    let e = worked();
    assert_eq!(e.ap(View::Bev, 0.7), Some(0.5));
    let mut swapped = V2v4realEval::new();
    swapped.add_frame(
        &[car(10.0, 0.0, 0.0, 1.0), car(20.0, 5.0, 0.0, 1.0)],
        &[car(20.0, 5.0, 0.8, 0.5), car(11.0, 0.0, 0.0, 0.95)],
    );
    swapped.add_frame(
        &[car(0.0, 0.0, 0.0, 1.0)],
        &[car(50.0, 50.0, 0.0, 0.8), car(0.0, 0.0, 0.0, 0.9)],
    );
    // fp tp | tp fp: 1/3 x 2/3 (at recall 2/3 the precision is 2/3) + 1/3 x 2/3.
    let ap = swapped.ap(View::Bev, 0.7).unwrap();
    assert!((ap - 4.0 / 9.0).abs() < 1e-12, "{ap}");
}

#[test]
fn a_merge_is_the_frames_in_order() {
    let mut a = V2v4realEval::new();
    a.add_frame(
        &[car(0.0, 0.0, 0.0, 1.0)],
        &[car(50.0, 50.0, 0.0, 0.8), car(0.0, 0.0, 0.0, 0.9)],
    );
    let mut b = V2v4realEval::new();
    b.add_frame(
        &[car(10.0, 0.0, 0.0, 1.0), car(20.0, 5.0, 0.0, 1.0)],
        &[car(20.0, 5.0, 0.8, 0.5), car(11.0, 0.0, 0.0, 0.95)],
    );
    a.merge(b);
    assert_eq!(a, worked());
}

#[test]
fn edge_cases() {
    assert_eq!(voc_ap(Vec::new(), 0), None);
    assert_eq!(voc_ap(Vec::new(), 3), Some(0.0));
    assert_eq!(voc_ap([true, true], 2), Some(1.0));
    // A taken box is not matched twice: the second exact duplicate is a false positive.
    let mut e = V2v4realEval::new();
    e.add_frame(
        &[car(0.0, 0.0, 0.0, 1.0)],
        &[car(0.0, 0.0, 0.0, 0.9), car(0.0, 0.0, 0.0, 0.8)],
    );
    assert_eq!(e.ap(View::Bev, 0.5), Some(1.0));
    assert_eq!(e.tallies[0][1][1].tp, [(0.9, true), (0.8, false)]);
    assert_eq!(e.ap(View::Bev, 0.4), None);
}

#[test]
fn a_global_sort_ranks_every_prediction_of_the_split_by_score() {
    // Ranked over both frames: 0.95 (frame 2, BEV IoU 0.6), 0.9 (tp), 0.8 (fp), 0.5.
    let s = worked().summary();
    let close = |got: f64, want: f64| assert!((got - want).abs() < 1e-12, "{got} against {want}");
    // BEV at 0.7: fp tp fp tp: 1/3 x 1/2 + 1/3 x 1/2.
    close(s.global.bev["0.70"], 1.0 / 3.0);
    // BEV at 0.5: tp tp fp tp: 2/3 x 1 + 1/3 x 3/4.
    close(s.global.bev["0.50"], 2.0 / 3.0 + 0.25);
    // 3D at 0.5: tp tp fp fp: 2/3.
    close(s.global.three_d["0.50"], 2.0 / 3.0);
    // In frame order the same boxes score 5/6 and 5/9 (above).
    close(s.ap_bev["0.50"], 5.0 / 6.0);
    assert_eq!(s.aps(Ordering::Global), s.global);
    assert_eq!(s.aps(Ordering::Frame).bev, s.ap_bev);
    // A box added below every other one cannot lower a globally sorted AP; in frame order a
    // false positive in the first frame can.
    let mut e = worked();
    e.add_frame(&[], &[car(70.0, 0.0, 0.0, 0.01)]);
    assert_eq!(e.summary().global.bev, s.global.bev);
    let mut early = V2v4realEval::new();
    early.add_frame(
        &[car(0.0, 0.0, 0.0, 1.0)],
        &[
            car(50.0, 50.0, 0.0, 0.8),
            car(0.0, 0.0, 0.0, 0.9),
            car(-40.0, 0.0, 0.0, 0.01),
        ],
    );
    early.merge({
        let mut b = V2v4realEval::new();
        b.add_frame(
            &[car(10.0, 0.0, 0.0, 1.0), car(20.0, 5.0, 0.0, 1.0)],
            &[car(20.0, 5.0, 0.8, 0.5), car(11.0, 0.0, 0.0, 0.95)],
        );
        b
    });
    assert!(early.summary().ap_bev["0.50"] < s.ap_bev["0.50"] - 0.05);
    assert_eq!(early.summary().global.bev["0.50"], s.global.bev["0.50"]);
}

#[test]
fn range_bands_keep_the_boxes_strictly_inside_them() {
    // Labels at 10 m, 40 m and 60 m; predictions exact at 10 m and 60 m, one at 29.9 m (a false
    // positive of the near band), one exactly at 30 m (in no band).
    let mut e = V2v4realEval::new();
    e.add_frame(
        &[
            car(10.0, 0.0, 0.0, 1.0),
            car(0.0, 40.0, 0.0, 1.0),
            car(60.0, 0.0, 0.0, 1.0),
        ],
        &[
            car(10.0, 0.0, 0.0, 0.9),
            car(60.0, 0.0, 0.0, 0.8),
            car(29.9, 0.0, 0.0, 0.95),
            car(30.0, 0.0, 0.0, 0.7),
        ],
    );
    let s = e.summary();
    let bands: Vec<(&str, usize, usize)> = s
        .ranges
        .iter()
        .map(|b| (b.range.as_str(), b.gt, b.predictions))
        .collect();
    assert_eq!(bands, [("0-30", 1, 2), ("30-50", 1, 0), ("50-100", 1, 1)]);
    // Near: fp tp against one label: 1 x 1/2. Middle: nothing found. Far: exact.
    assert_eq!(s.ranges[0].frame.bev["0.50"], 0.5);
    assert_eq!(s.ranges[1].frame.bev["0.50"], 0.0);
    assert_eq!(s.ranges[2].global.three_d["0.70"], 1.0);
    assert_eq!((s.gt, s.predictions), (3, 4));
}

#[test]
fn the_curve_follows_the_ordering() {
    let e = worked();
    let frame = e.curve(View::Bev, 0.7, Ordering::Frame);
    let global = e.curve(View::Bev, 0.7, Ordering::Global);
    let third = 1.0 / 3.0;
    assert_eq!(
        frame,
        [(third, 1.0), (third, 0.5), (third, third), (2.0 / 3.0, 0.5)]
    );
    assert_eq!(
        global,
        [(0.0, 0.0), (third, 0.5), (third, third), (2.0 / 3.0, 0.5)]
    );
    assert!(e.curve(View::Bev, 0.4, Ordering::Frame).is_empty());
}
