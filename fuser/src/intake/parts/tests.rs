use super::*;
use v2x_protocol::{AgentKind, Uncertainty};

fn t(x: i32, y: i32) -> Tile {
    Tile { x, y }
}

fn det(x: f64) -> Detection {
    Detection {
        center: [x, 0.0, 0.5],
        std: Uncertainty::uniform(0.3, 0.1, 0.05),
        id: 0,
        ..v2x_protocol::fixtures::car(x, 0.0, 0.3)
    }
}

fn part(agent: &str, seq: u32, xs: &[f64]) -> Frame {
    Frame {
        agent: agent.into(),
        kind: AgentKind::Vehicle,
        seq,
        capture_us: 1_000_000 + seq as u64 * 100_000,
        origin: [0.0; 3],
        detections: xs.iter().map(|&x| det(x)).collect(),
    }
}

fn xs(a: &Assembled) -> Vec<f64> {
    a.frame.detections.iter().map(|d| d.center[0]).collect()
}

#[test]
fn a_capture_goes_on_when_every_subscribed_part_came() {
    // Subscribed to (0,0) and (1,0); the capture spans (0,0), (1,0) and (2,0): two parts due.
    let mut p = Parts::new(&[t(0, 0), t(1, 0)], 50_000, 8);
    let listed = [t(0, 0), t(1, 0), t(2, 0)];
    assert!(p
        .offer(t(1, 0), &listed, part("veh", 7, &[250.0]), 10)
        .unwrap()
        .is_empty());
    assert_eq!(p.waiting(), 1);
    assert_eq!(p.next_deadline(), Some(50_010));
    let out = p
        .offer(t(0, 0), &listed, part("veh", 7, &[10.0, 20.0]), 20)
        .unwrap();
    assert_eq!(out.len(), 1);
    assert!(out[0].complete);
    assert_eq!(xs(&out[0]), vec![10.0, 20.0, 250.0], "tile order");
    assert_eq!(out[0].frame.seq, 7);
    assert_eq!(p.waiting(), 0);
    // A repeat of a handed-on capture is late, never fused twice.
    assert_eq!(
        p.offer(t(0, 0), &listed, part("veh", 7, &[10.0]), 30),
        Err(PartError::Late)
    );
}

#[test]
fn a_single_part_capture_goes_on_at_once() {
    let mut p = Parts::new(&[t(0, 0)], 50_000, 8);
    let out = p
        .offer(t(0, 0), &[t(0, 0)], part("rsu", 1, &[5.0]), 0)
        .unwrap();
    assert_eq!(out.len(), 1);
    assert!(out[0].complete);
}

#[test]
fn a_missing_part_is_waited_for_max_wait_then_the_rest_goes_on() {
    let mut p = Parts::new(&[t(0, 0), t(1, 0)], 50_000, 8);
    let listed = [t(0, 0), t(1, 0)];
    p.offer(t(0, 0), &listed, part("veh", 1, &[10.0]), 1_000)
        .unwrap();
    assert!(p.expire(50_999).is_empty());
    let out = p.expire(51_000);
    assert_eq!(out.len(), 1);
    assert!(!out[0].complete);
    assert_eq!(xs(&out[0]), vec![10.0]);
    assert_eq!(
        p.offer(t(1, 0), &listed, part("veh", 1, &[210.0]), 52_000),
        Err(PartError::Late)
    );
    assert_eq!(p.next_deadline(), None);
}

#[test]
fn parts_that_do_not_fit_their_capture_are_rejected() {
    let mut p = Parts::new(&[t(0, 0), t(1, 0)], 50_000, 8);
    let listed = [t(0, 0), t(1, 0)];
    // A tile the list does not name, or one this fuser does not subscribe to.
    assert_eq!(
        p.offer(t(1, 0), &[t(0, 0)], part("veh", 1, &[]), 0),
        Err(PartError::TileNotListed(t(1, 0)))
    );
    assert_eq!(
        p.offer(t(5, 0), &[t(5, 0)], part("veh", 1, &[]), 0),
        Err(PartError::TileNotListed(t(5, 0)))
    );
    p.offer(t(0, 0), &listed, part("veh", 1, &[1.0]), 0)
        .unwrap();
    assert_eq!(
        p.offer(t(0, 0), &listed, part("veh", 1, &[2.0]), 0),
        Err(PartError::Repeated(t(0, 0)))
    );
    let mut other_time = part("veh", 1, &[201.0]);
    other_time.capture_us += 1;
    assert_eq!(
        p.offer(t(1, 0), &listed, other_time, 0),
        Err(PartError::Disagrees)
    );
    assert_eq!(
        p.offer(
            t(1, 0),
            &[t(0, 0), t(1, 0), t(2, 0)],
            part("veh", 1, &[201.0]),
            0
        ),
        Err(PartError::Disagrees)
    );
    // The rightful part still completes it.
    let out = p
        .offer(t(1, 0), &listed, part("veh", 1, &[201.0]), 0)
        .unwrap();
    assert_eq!(xs(&out[0]), vec![1.0, 201.0]);
}

#[test]
fn at_most_max_pending_captures_wait() {
    let mut p = Parts::new(&[t(0, 0), t(1, 0)], 50_000, 2);
    let listed = [t(0, 0), t(1, 0)];
    assert!(p
        .offer(t(0, 0), &listed, part("a", 1, &[1.0]), 1)
        .unwrap()
        .is_empty());
    assert!(p
        .offer(t(0, 0), &listed, part("b", 1, &[2.0]), 2)
        .unwrap()
        .is_empty());
    let out = p.offer(t(0, 0), &listed, part("c", 1, &[3.0]), 3).unwrap();
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].frame.agent, "a");
    assert!(!out[0].complete);
    assert_eq!(p.waiting(), 2);
    p.forget_agent("b");
    assert_eq!(p.waiting(), 1);
}
