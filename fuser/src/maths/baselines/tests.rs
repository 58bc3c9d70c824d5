use super::*;
use crate::maths::method::Method;
use v2x_protocol::Class;

/// The boxes of a method's output, without their sources.
fn dets(out: Vec<Sourced>) -> Vec<Detection> {
    out.into_iter().map(|s| s.det).collect()
}

fn bx(class: Class, x: f64, y: f64, score: f64, id: u32) -> Detection {
    Detection {
        class,
        center: [x, y, 0.8],
        size: [4.0, 2.0, 1.6],
        yaw: 0.0,
        score,
        std: Uncertainty::uniform(0.5, 0.1, 0.1),
        pos_cov: None,
        velocity: None,
        id,
    }
}

#[test]
fn nms_keeps_the_higher_score_and_suppresses_the_overlap() {
    // 0.5 m apart: IoU = 3.5/4.5 > 0.15; the far box survives.
    let a = vec![
        bx(Class::Car, 0.0, 0.0, 0.6, 1),
        bx(Class::Car, 30.0, 0.0, 0.6, 3),
    ];
    let b = vec![bx(Class::Car, 0.5, 0.0, 0.9, 2)];
    for m in [Method::Nms3d, Method::NmsGiou3d] {
        let out = m.fuse(&[a.clone(), b.clone()]);
        assert_eq!(out.len(), 2, "{m}");
        assert_eq!(out[0].id, 2);
        assert_eq!(out[0].center[0], 0.5, "the top box is kept as is");
        assert_eq!(out[1].id, 3);
    }
    // other classes never suppress each other
    let c = vec![bx(Class::Truck, 0.5, 0.0, 0.9, 2)];
    assert_eq!(nms_3d(&[a.clone(), c]).len(), 3);
}

#[test]
fn nms_giou_suppresses_what_iou_does_not() {
    // 3.6 m apart along x: IoU = 0.4 / 7.6 = 0.053 < 0.15 keeps both under nms-3d;
    // GIoU = IoU - (C - U)/C with C = 7.6 * 2 * 1.6 = U, so GIoU = IoU: equal here.
    // 1 m apart in y instead: IoU = 4*1/(8+8-4) = 0.333 suppresses under both.
    let a = vec![bx(Class::Car, 0.0, 0.0, 0.6, 1)];
    let b = vec![bx(Class::Car, 3.6, 0.0, 0.9, 2)];
    assert_eq!(nms_3d(&[a.clone(), b.clone()]).len(), 2);
    assert_eq!(nms_giou_3d(&[a.clone(), b.clone()]).len(), 2);
    let c = vec![bx(Class::Car, 0.0, 1.0, 0.9, 2)];
    assert_eq!(nms_3d(&[a.clone(), c.clone()]).len(), 1);
}

#[test]
fn wbf_averages_a_cluster() {
    // scores 0.6 and 0.2, 0.4 m apart (IoU = 3.6/4.4 > 0.55): centre = (0*0.6 + 0.4*0.2)/0.8
    let a = vec![bx(Class::Car, 0.0, 0.0, 0.6, 1)];
    let b = vec![bx(Class::Car, 0.4, 0.0, 0.2, 2)];
    let out = dets(wbf_3d(&[a, b]));
    assert_eq!(out.len(), 1);
    assert!((out[0].center[0] - 0.1).abs() < 1e-12);
    // score: mean 0.4 x min(2, 2)/2
    assert!((out[0].score - 0.4).abs() < 1e-12);
    assert_eq!(out[0].id, 1);
    // a lone box is down-weighted by min(W, n)/W = 1/2
    let out = dets(wbf_3d(&[vec![bx(Class::Car, 0.0, 0.0, 0.6, 1)], vec![]]));
    assert!((out[0].score - 0.3).abs() < 1e-12);
}

#[test]
fn psa_keeps_the_argmax() {
    // three overlapping boxes; the middle one overlaps both others and wins v.
    let a = vec![
        bx(Class::Car, 0.0, 0.0, 0.5, 1),
        bx(Class::Car, 2.0, 0.0, 0.5, 3),
    ];
    let b = vec![bx(Class::Car, 1.0, 0.0, 0.4, 2)];
    let out = dets(psa(&[a, b]));
    // v(middle) = 0.4 + 2 * 0.6 * 0.5 = 1.0; v(sides) = 0.5 + 0.6*0.4 + (1/3... no overlap at 2 m? IoU(0, 2) = 2*2/12 = 1/3)
    // v(side) = 0.5 + 0.6 * 0.4 + (1/3) * 0.5 = 0.9067 < 1.0
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].id, 2);
}

#[test]
fn distance_methods_do_not_match_beyond_three_metres() {
    let a = vec![bx(Class::Car, 0.0, 0.0, 0.5, 1)];
    let near = vec![bx(Class::Car, 2.0, 0.0, 0.5, 2)];
    let far = vec![bx(Class::Car, 3.5, 0.0, 0.5, 2)];
    for m in [Method::InfraDet3dLate, Method::DairV2xLate] {
        let out = m.fuse(&[a.clone(), near.clone()]);
        assert_eq!(out.len(), 1, "{m}");
        assert!((out[0].center[0] - 1.0).abs() < 1e-12);
        assert_eq!(m.fuse(&[a.clone(), far.clone()]).len(), 2, "{m}");
    }
}

#[test]
fn infradet_takes_the_first_agents_yaw_and_ignores_class() {
    let mut a = bx(Class::Car, 0.0, 0.0, 0.5, 1);
    a.yaw = 0.1;
    let mut b = bx(Class::Truck, 1.0, 0.0, 0.7, 2);
    b.yaw = 0.5;
    b.size = [6.0, 2.0, 1.6];
    let out = dets(infradet3d_late(&[vec![a.clone()], vec![b.clone()]]));
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].yaw, 0.1);
    assert_eq!(out[0].class, Class::Car);
    assert!((out[0].size[0] - 5.0).abs() < 1e-12);
    // DAIR-V2X-Late does not match different classes
    assert_eq!(dair_v2x_late(&[vec![a.clone()], vec![b.clone()]]).len(), 2);
    b.class = Class::Car;
    let out = dets(dair_v2x_late(&[vec![a], vec![b]]));
    assert_eq!(out.len(), 1);
    assert!((out[0].yaw - 0.3).abs() < 1e-12, "mean yaw");
    assert!((out[0].score - 0.6).abs() < 1e-12, "mean score");
}

#[test]
fn hungarian_is_global_not_greedy() {
    // a0 at 0, a1 at 2.5; b0 at 1.4, b1 at -1.2: greedy would pair a0-b1? no: global optimum pairs
    // a0-b1 (1.2) and a1-b0 (1.1) rather than a0-b0 (1.4) + a1-b1 (3.7, beyond the gate).
    let a = vec![
        bx(Class::Car, 0.0, 0.0, 0.5, 1),
        bx(Class::Car, 2.5, 0.0, 0.5, 2),
    ];
    let b = vec![
        bx(Class::Car, 1.4, 0.0, 0.5, 3),
        bx(Class::Car, -1.2, 0.0, 0.5, 4),
    ];
    let out = dets(dair_v2x_late(&[a, b]));
    assert_eq!(out.len(), 2);
    assert!((out[0].center[0] + 0.6).abs() < 1e-12);
    assert!((out[1].center[0] - 1.95).abs() < 1e-12);
}

#[test]
fn gt_wls_groups_by_id() {
    let a = vec![
        bx(Class::Car, 0.0, 0.0, 0.5, 7),
        bx(Class::Car, 10.0, 0.0, 0.5, v2x_protocol::NO_ID),
    ];
    let b = vec![
        bx(Class::Car, 5.0, 0.0, 0.5, 7),
        bx(Class::Car, 10.0, 0.0, 0.5, v2x_protocol::NO_ID),
    ];
    let out = dets(gt_wls(&[a, b]));
    assert_eq!(out.len(), 3);
    let g = out.iter().find(|d| d.id == 7).unwrap();
    assert!((g.center[0] - 2.5).abs() < 1e-12, "grouped even 5 m apart");
}
