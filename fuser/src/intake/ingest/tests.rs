use super::*;
use crate::time::window::Verdict;
use v2x_protocol::{wire, AgentKind, Detection, Frame};

const S: u64 = 1_000_000;
const NOW: u64 = 1_700_000_000 * S;

fn payload(agent: &str, capture_us: u64) -> Vec<u8> {
    wire::encode(&Frame {
        agent: agent.into(),
        kind: AgentKind::Vehicle,
        seq: 0,
        capture_us,
        origin: [0.0; 3],
        detections: vec![Detection::default()],
    })
    .unwrap()
}

#[test]
fn frames_far_from_the_fuser_clock_are_rejected_and_counted() {
    let mut i = Ingest::new(IngestConfig::default());
    assert!(i.offer("a", &payload("a", NOW - 30_000), NOW).is_ok());
    assert_eq!(
        i.offer("a", &payload("a", NOW + 3600 * S), NOW),
        Err(Rejection::Future(3600 * S))
    );
    assert!(matches!(
        i.offer("a", &payload("a", u64::MAX), NOW),
        Err(Rejection::Future(_))
    ));
    assert!(matches!(
        i.offer("a", &payload("a", 0), NOW),
        Err(Rejection::Stale(_))
    ));
    // within the tolerance either way
    assert!(i.offer("a", &payload("a", NOW + S - 1), NOW).is_ok());
    assert!(i.offer("a", &payload("a", NOW - S + 1), NOW).is_ok());
    let st = &i.agent_stats()["a"];
    assert_eq!((st.frames_in, st.future, st.stale), (6, 2, 1));
    assert_eq!(i.rejected()["future"], 2);
    // no tolerance: a replay on its data's clock
    let mut i = Ingest::new(IngestConfig {
        max_clock_skew_us: None,
        ..Default::default()
    });
    assert!(i.offer("a", &payload("a", 0), NOW).is_ok());
}

#[test]
fn the_lag_median_reports_latency_plus_offset() {
    let mut i = Ingest::new(IngestConfig::default());
    for (k, lag_ms) in [20u64, 25, 30, 500, 22].iter().enumerate() {
        let now = NOW + k as u64 * 100_000;
        i.offer("a", &payload("a", now - lag_ms * 1000), now)
            .unwrap();
    }
    assert_eq!(i.agent_stats()["a"].clock_lag_ms, Some(25.0));
}

#[test]
fn wrong_names_and_bad_payloads() {
    let mut i = Ingest::new(IngestConfig::default());
    assert_eq!(
        i.offer("a", &payload("b", NOW), NOW),
        Err(Rejection::WrongAgent("b".into()))
    );
    assert!(matches!(
        i.offer("a", &[2, 0xff], NOW),
        Err(Rejection::Invalid(_))
    ));
    assert_eq!(
        i.offer("a*b", &payload("a", NOW), NOW),
        Err(Rejection::BadKey)
    );
    let st = &i.agent_stats()["a"];
    assert_eq!((st.wrong_agent, st.invalid), (1, 1));
    assert!(!i.tracks("a*b"));
}

#[test]
fn the_table_stays_bounded_and_keeps_token_holders() {
    let mut i = Ingest::new(IngestConfig {
        max_agents: 10,
        ..Default::default()
    });
    assert!(i.token("honest", true, NOW));
    for k in 0..1000u64 {
        let name = format!("x{k}");
        let _ = i.offer(&name, &payload(&name, NOW), NOW + k);
    }
    assert_eq!(i.tracked(), 10);
    assert!(i.tracks("honest"), "a token holder is never evicted");
    assert_eq!(i.forgotten(), 1000 - 9);
    assert_eq!(
        i.prune(NOW).len(),
        1000 - 9,
        "evicted names are handed out once"
    );
    assert!(i.prune(NOW).is_empty());
    // token holders fill the table: newcomers are refused
    let mut i = Ingest::new(IngestConfig {
        max_agents: 3,
        ..Default::default()
    });
    for k in 0..3 {
        assert!(i.token(&format!("t{k}"), true, NOW));
    }
    assert!(!i.token("t9", true, NOW));
    assert_eq!(
        i.offer("z", &payload("z", NOW), NOW),
        Err(Rejection::AgentCap)
    );
    assert_eq!(i.rejected()["agent_cap"], 2);
}

#[test]
fn idle_agents_are_forgotten() {
    let mut i = Ingest::new(IngestConfig::default());
    i.offer("a", &payload("a", NOW), NOW).unwrap();
    i.token("b", true, NOW);
    assert!(i.prune(NOW + 59 * S).is_empty());
    assert_eq!(i.prune(NOW + 61 * S), vec!["a".to_string()]);
    assert!(i.tracks("b"), "a token keeps an agent");
    i.token("b", false, NOW + 62 * S);
    assert_eq!(i.prune(NOW + 123 * S), vec!["b".to_string()]);
    assert_eq!(i.forgotten(), 2);
}

fn send(i: &mut Ingest, agent: &str, t: u64) {
    i.offer(agent, &payload(agent, t), t).unwrap();
    i.record(agent, Verdict::Accepted, 1, t);
}

const H: u64 = 50_000; // half of a 100 ms window

#[test]
fn a_token_alone_is_awaited_for_three_windows_at_most() {
    let mut i = Ingest::new(IngestConfig::default());
    i.token("silent", true, NOW);
    i.token("a", true, NOW);
    send(&mut i, "raw", NOW); // frames, but no token: never awaited
    for k in 0..3 {
        let t = NOW + k * 100_000;
        send(&mut i, "a", t);
        let awaited = i.awaited(t, H);
        assert_eq!(awaited.into_iter().collect::<Vec<_>>(), vec!["a", "silent"]);
        let a = "a".to_string();
        i.window_closed(t, H, &[&a]);
    }
    assert_eq!(
        i.awaited(NOW + 300_000, H).into_iter().collect::<Vec<_>>(),
        vec!["a"]
    );
    // it sends: awaited again
    send(&mut i, "silent", NOW + 310_000);
    assert!(i.awaited(NOW + 400_000, H).contains("silent"));
}

#[test]
fn late_frames_teach_the_period_too() {
    let mut i = Ingest::new(IngestConfig::default());
    i.token("a", true, NOW);
    // Two captures 400 ms apart, then frames every 100 ms that all came too late.
    send(&mut i, "a", NOW);
    send(&mut i, "a", NOW + 400_000);
    for k in 1..=2 {
        let t = NOW + 400_000 + k * 100_000;
        i.offer("a", &payload("a", t), t + 20_000).unwrap();
        i.record("a", Verdict::Late, 1, t);
    }
    // Learnt from them: a 100 ms period, so expected 400 ms after the last (with a 400 ms
    // period it would be expected at 200 or 600 ms only).
    assert!(i.awaited(NOW + 1_000_000, H).contains("a"));
}

#[test]
fn a_late_frame_that_waiting_would_have_caught_makes_its_agent_awaited_again() {
    let mut i = Ingest::new(IngestConfig::default()); // waits 150 ms
    i.token("a", true, NOW);
    send(&mut i, "a", NOW);
    send(&mut i, "a", NOW + 100_000);
    for k in 2..5 {
        i.window_closed(NOW + k * 100_000, H, &[]);
    }
    assert!(!i.awaited(NOW + 500_000, H).contains("a"));
    // 400 ms late: waiting would not have caught it
    let t = NOW + 500_000;
    i.offer("a", &payload("a", t), t + 400_000).unwrap();
    i.record("a", Verdict::Late, 1, t);
    assert!(!i.awaited(NOW + 600_000, H).contains("a"));
    // 120 ms late: it would have made its window
    let t = NOW + 600_000;
    i.offer("a", &payload("a", t), t + 120_000).unwrap();
    i.record("a", Verdict::Late, 1, t);
    assert!(i.awaited(NOW + 700_000, H).contains("a"));
    assert_eq!(i.agent_stats()["a"].late, 2);
}

#[test]
fn a_slow_agent_is_awaited_only_where_its_frames_fall() {
    let mut i = Ingest::new(IngestConfig::default());
    i.token("slow", true, NOW);
    for k in 0..3 {
        send(&mut i, "slow", NOW + k * S); // 1 Hz
    }
    let last = NOW + 2 * S;
    assert!(!i.awaited(last + 300_000, H).contains("slow"));
    assert!(!i.awaited(last + 700_000, H).contains("slow"));
    assert!(i.awaited(last + S, H).contains("slow"));
    assert!(i.awaited(last + S + 40_000, H).contains("slow"), "jitter");
    assert!(
        i.awaited(last + 2 * S, H).contains("slow"),
        "one frame lost"
    );
    // it stops sending: three missed windows where it was expected, then no more waiting
    for k in 1..=3 {
        let anchor = last + k * S;
        assert!(i.awaited(anchor, H).contains("slow"));
        i.window_closed(anchor, H, &[]);
    }
    assert!(!i.awaited(last + 4 * S, H).contains("slow"));
}

/// A frame of `agent` with boxes at the given (x, score).
fn boxes(agent: &str, capture_us: u64, at: &[(f64, f64)]) -> Vec<u8> {
    let detections = at
        .iter()
        .enumerate()
        .map(|(k, &(x, score))| Detection {
            center: [x, 5.0, 0.0],
            score,
            id: k as u32,
            ..Detection::default()
        })
        .collect();
    wire::encode(&Frame {
        agent: agent.into(),
        kind: AgentKind::Vehicle,
        seq: 0,
        capture_us,
        origin: [at.first().map_or(0.0, |b| b.0), 0.0, 0.0],
        detections,
    })
    .unwrap()
}

#[test]
fn an_agent_brings_at_most_its_budget_of_boxes_the_highest_scoring() {
    let mut i = Ingest::new(IngestConfig {
        max_objects: 3,
        ..IngestConfig::default()
    });
    let at = [(1.0, 0.2), (2.0, 0.9), (3.0, 0.5), (4.0, 0.9), (5.0, 0.1)];
    let f = i.offer("a", &boxes("a", NOW, &at), NOW).unwrap();
    // The three best, in their order (of two equal scores, the first).
    let xs: Vec<f64> = f.detections.iter().map(|d| d.center[0]).collect();
    assert_eq!(xs, [2.0, 3.0, 4.0]);
    assert_eq!(i.agent_stats()["a"].over_budget, 2);
    assert_eq!(i.noted()["over_budget"], 2);
    assert_eq!(
        i.take_notes(),
        vec![Note::OverBudget {
            agent: "a".into(),
            dropped: 2
        }]
    );
    // Within the budget nothing changes.
    let f = i.offer("b", &boxes("b", NOW, &at[..3]), NOW).unwrap();
    assert_eq!(f.detections.len(), 3);
    assert!(i.take_notes().is_empty());
}

#[test]
fn far_agents_cannot_move_the_learned_area() {
    let mut i = Ingest::new(IngestConfig {
        area: Area::Learned { radius_m: 1000.0 },
        ..IngestConfig::default()
    });
    // The far agent comes first: the area is its own until others come.
    let far = [(1e9 - 1.0, 1.0), (1e9, 1.0)];
    assert_eq!(
        i.offer("far", &boxes("far", NOW, &far), NOW)
            .unwrap()
            .detections
            .len(),
        2
    );
    assert_eq!(i.area_center(), Some([1e9, 5.0]));
    let honest = [(10.0, 0.5), (30.0, 0.5), (20.0, 0.5)];
    // One honest agent ties with it: the earliest stays.
    assert!(i
        .offer("a", &boxes("a", NOW, &honest), NOW + 1)
        .unwrap()
        .detections
        .is_empty());
    // Two honest agents outnumber it: the area moves to them, centred on their median.
    let f = i
        .offer("b", &boxes("b", NOW, &[(40.0, 0.5)]), NOW + 2)
        .unwrap();
    assert_eq!(f.detections.len(), 1);
    assert_eq!(i.area_center(), Some([20.0, 5.0]));
    assert_eq!(
        i.offer("a", &boxes("a", NOW, &honest), NOW + 3)
            .unwrap()
            .detections
            .len(),
        3
    );
    // The far agent's boxes are now dropped, and the honest ones kept.
    assert!(i
        .offer("far", &boxes("far", NOW, &far), NOW + 4)
        .unwrap()
        .detections
        .is_empty());
    assert_eq!(i.agent_stats()["far"].outside, 2);
    assert_eq!(i.agent_stats()["a"].outside, 3);
    assert_eq!(i.noted()["outside"], 5);
    // A box at the area's edge stays, one just beyond goes.
    let edge = [(1020.0, 0.5), (1020.1, 0.5)];
    let f = i.offer("b", &boxes("b", NOW, &edge), NOW + 5).unwrap();
    assert_eq!(f.detections.len(), 1);
}

#[test]
fn a_given_area_holds_from_the_first_frame() {
    let area = Area::parse("100,-50,10").unwrap();
    assert_eq!(
        area,
        Area::Given {
            center: [100.0, -50.0],
            radius_m: 10.0
        }
    );
    for bad in ["1,2", "1,2,0", "a,b,c", "1,2,inf", "1e10,0,5"] {
        assert!(Area::parse(bad).is_err(), "{bad}");
    }
    let mut i = Ingest::new(IngestConfig {
        area,
        ..IngestConfig::default()
    });
    let f = i
        .offer("a", &boxes("a", NOW, &[(95.0, 0.5), (120.0, 0.5)]), NOW)
        .unwrap();
    // (95, 5) is 55 m from (100, -50): outside; the frame is admitted empty.
    assert!(f.detections.is_empty());
    assert_eq!(i.area_center(), Some([100.0, -50.0]));
}

#[test]
fn frames_stamped_ahead_hold_only_their_own_window() {
    let mut i = Ingest::new(IngestConfig::default());
    i.token("a", true, NOW);
    i.token("early", true, NOW);
    send(&mut i, "a", NOW);
    // "early" stamps its frames 0.2-0.9 s ahead, off any grid.
    for (k, ahead) in [200_000u64, 900_000, 450_000].into_iter().enumerate() {
        let now = NOW + k as u64 * 100_000;
        i.offer("early", &payload("early", now + ahead), now)
            .unwrap();
        i.record("early", Verdict::Accepted, 1, now + ahead);
    }
    assert_eq!(i.agent_stats()["early"].ahead, 3);
    assert_eq!(i.noted()["ahead"], 3);
    // Honest windows before its latest stamp (1.0 s ahead) do not wait for it; its own does.
    for k in 0..10 {
        let anchor = NOW + k * 100_000;
        assert!(!i.awaited(anchor, H).contains("early"), "window {k}");
    }
    assert!(i.awaited(NOW + 1_000_000, H).contains("early"));
    // 30 ms ahead is within the tolerance: not counted.
    i.offer("a", &payload("a", NOW + 130_000), NOW + 100_000)
        .unwrap();
    assert_eq!(i.agent_stats()["a"].ahead, 0);
}

#[test]
fn a_token_declared_again_and_again_costs_its_three_windows_once() {
    let mut i = Ingest::new(IngestConfig::default());
    i.token("a", true, NOW);
    i.token("flap", true, NOW);
    let a = "a".to_string();
    let mut missing = 0;
    for k in 0..20 {
        let t = NOW + k * 100_000;
        if k % 5 == 0 {
            i.token("flap", false, t);
            i.token("flap", true, t);
        }
        send(&mut i, "a", t);
        missing += i.awaited(t, H).contains("flap") as u32;
        i.window_closed(t, H, &[&a]);
    }
    assert_eq!(missing, MAX_MISSES);
    // Once it sends, it is awaited again.
    send(&mut i, "flap", NOW + 2_000_000);
    assert!(i.awaited(NOW + 2_100_000, H).contains("flap"));
}

#[test]
fn the_names_of_other_roles_are_refused() {
    let mut i = Ingest::new(IngestConfig::default());
    for name in ["fuser", "observer", "router"] {
        assert_eq!(
            i.offer(name, &payload(name, NOW), NOW),
            Err(Rejection::ReservedName)
        );
        assert!(!i.token(name, true, NOW));
    }
    assert_eq!(i.rejected()["reserved_name"], 6);
    assert_eq!(i.tracked(), 0);
}

#[test]
fn boxes_a_cpm_carried_without_a_class_here_are_counted_for_their_agent() {
    let mut i = Ingest::new(IngestConfig::default());
    i.offer("a", &payload("a", NOW), NOW).unwrap();
    i.unnamed("a", 2);
    i.unnamed("a", 1);
    i.unnamed("nobody", 5);
    let stats = i.agent_stats();
    assert_eq!(stats["a"].unnamed, 3);
    assert!(!stats.contains_key("nobody"));
}
