//! Robust ingest over loopback Zenoh: every fault an outside client or a broken agent can
//! produce is counted under its reason while the honest agents' fusion goes on.

use std::time::Duration;
use v2x_agent::{now_us, Agent};
use v2x_fuser::node::{self, NodeConfig};
use v2x_protocol::{keys, limits, wire, AgentKind, Detection, Frame, Uncertainty};
use v2x_sim::run::free_port;
use v2x_tests::fuser::{
    connect, det, frame, joined, listen, next_fused, next_t, spawn_fuser_with, stats, wait_live,
};
use v2x_tests::within;
use zenoh::qos::CongestionControl;

/// A fuser listening on a fresh port, and two agents `a` and `b` connected to it and seen live.
struct Setup {
    port: u16,
    a: Agent,
    b: Agent,
    sa: zenoh::Session,
    _sb: zenoh::Session,
    fuser: v2x_tests::fuser::FuserHandle,
}

async fn setup(ns: &'static str, cfg: NodeConfig) -> Setup {
    let port = free_port().unwrap();
    let fs = listen(port).await;
    let fuser = spawn_fuser_with(fs, cfg);
    let sa = connect(port).await;
    let sb = connect(port).await;
    let a = joined(&sa, ns, "a", AgentKind::Vehicle, 1).await;
    let b = joined(&sb, ns, "b", AgentKind::Infrastructure, 2).await;
    wait_live(&sa, ns, &["a", "b"]).await;
    Setup {
        port,
        a,
        b,
        sa,
        _sb: sb,
        fuser,
    }
}

fn cfg(ns: &str, max_wait_ms: f64) -> NodeConfig {
    let mut c = NodeConfig::new(ns, "csba-wls+".parse().unwrap());
    c.max_wait_ms = max_wait_ms;
    c
}

/// Polls the stats until `cond` holds (10 s at most).
async fn stats_until(
    s: &zenoh::Session,
    ns: &str,
    what: &str,
    cond: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    within(10, what, async {
        loop {
            if let Ok(v) = node::query_stats(s, ns, Duration::from_secs(2)).await {
                if cond(&v) {
                    return v;
                }
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
}

/// One round of both honest agents; returns the fused window.
async fn honest_round(s: &mut Setup, last: &mut u64) -> node::Fused {
    let t = next_t(last);
    s.a.send(frame(t)).unwrap();
    s.b.send(frame(t)).unwrap();
    next_fused(&mut s.fuser.1).await
}

async fn finish(s: Setup) -> node::NodeStats {
    s.fuser.0.send(()).unwrap();
    within(30, "fuser shutdown", s.fuser.2).await.unwrap()
}

#[tokio::test(flavor = "multi_thread")]
async fn frames_stamped_far_ahead_are_rejected_and_fusion_goes_on() {
    let ns = "future";
    let mut s = setup(ns, cfg(ns, 300.0)).await;
    // Agent a's clock goes wrong for two frames: an hour ahead, then the largest stamp there is.
    let raw =
        s.sa.declare_publisher(keys::detections(ns, "a"))
            .await
            .unwrap();
    for capture in [now_us() + 3_600_000_000, u64::MAX] {
        let mut f = frame(capture);
        f.agent = "a".into();
        f.seq = 1000;
        raw.put(wire::encode(&f).unwrap()).await.unwrap();
    }
    let v = stats_until(&s.sa, ns, "two future frames counted", |v| {
        v["agents"]["a"]["future"] == 2
    })
    .await;
    assert_eq!(v["rejected"]["future"], 2);
    let mut last = 0;
    for _ in 0..3 {
        let f = honest_round(&mut s, &mut last).await;
        assert_eq!(f.provenance.agents, vec!["a", "b"]);
        assert!(f.provenance.complete);
    }
    let st = finish(s).await;
    assert_eq!(st.windows, 3);
    assert_eq!(st.agents["a"].fused, 3);
    assert_eq!(
        st.agents["a"].late, 0,
        "no honest frame was pushed out as late"
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn two_agents_at_the_minimum_std_are_fused_and_published() {
    let ns = "minstd";
    let mut s = setup(ns, cfg(ns, 300.0)).await;
    let observer = s.sa.declare_subscriber(keys::fused(ns)).await.unwrap();
    let mut d = det(10.0, 7);
    d.std = Uncertainty::uniform(limits::STD_MIN, limits::STD_MIN, limits::STD_MIN);
    let t = now_us();
    for agent in [&mut s.a, &mut s.b] {
        agent
            .send(Frame {
                detections: vec![d.clone()],
                ..frame(t)
            })
            .unwrap();
    }
    let f = next_fused(&mut s.fuser.1).await;
    assert_eq!(f.frame.detections.len(), 1);
    // WLS halves the variance, below the format's floor: the published std is the floor.
    assert_eq!(f.frame.detections[0].std.pos[0], limits::STD_MIN);
    let on_wire = within(10, "the fused frame", observer.recv_async())
        .await
        .unwrap();
    let decoded = wire::decode(&on_wire.payload().to_bytes()).unwrap();
    assert_eq!(decoded.detections[0].std.pos[0], limits::STD_MIN);
    let st = finish(s).await;
    assert_eq!((st.windows, st.windows_unpublished), (1, 0));
    assert_eq!(st.fit.stds_clamped, 7, "x, y, z, l, w, h and yaw");
}

fn rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<f64>().ok())
        .map_or(0.0, |pages| pages * 4096.0 / (1024.0 * 1024.0))
}

#[tokio::test(flavor = "multi_thread")]
async fn ten_thousand_agent_names_leave_the_fuser_bounded() {
    let ns = "names";
    let mut s = setup(ns, cfg(ns, 300.0)).await;
    let rss_before = rss_mib();
    let spam = connect(s.port).await;
    let t = now_us();
    for k in 0..10_000 {
        let name = format!("spam{k}");
        let mut f = frame(t);
        f.agent = name.clone();
        spam.put(keys::detections(ns, &name), wire::encode(&f).unwrap())
            .congestion_control(CongestionControl::Block)
            .await
            .unwrap();
    }
    let v = stats_until(&s.sa, ns, "the flood of names processed and fused", |v| {
        v["agents_forgotten"].as_u64().unwrap_or(0) >= 10_000 - 256
            && v["open_windows"] == 0
            && v["fusion_queue"] == 0
    })
    .await;
    while s.fuser.1.try_recv().is_ok() {} // the spam's own windows
    let reply = serde_json::to_vec(&v).unwrap().len();
    eprintln!(
        "10,000 agent names: {} tracked, {} forgotten, stats reply {reply} bytes, RSS {rss_before:.1} MiB before, {:.1} MiB after",
        v["agents_tracked"],
        v["agents_forgotten"],
        rss_mib()
    );
    assert!(v["agents_tracked"].as_u64().unwrap() <= 256);
    assert!(reply < 256 * 1024, "stats reply of {reply} bytes");
    assert!(v["agents"]["a"]["token"] == true && v["agents"]["b"]["token"] == true);
    // The honest agents are still fused together.
    let mut last = now_us();
    for _ in 0..3 {
        let f = honest_round(&mut s, &mut last).await;
        assert!(
            f.provenance.agents.contains(&"a".to_string())
                && f.provenance.agents.contains(&"b".to_string())
        );
    }
    let st = finish(s).await;
    assert!(st.agents_tracked <= 256);
    assert_eq!(st.agents["a"].fused, 3);
}

#[tokio::test(flavor = "multi_thread")]
async fn a_token_without_frames_costs_three_windows_at_most() {
    let ns = "ghost";
    let mut s = setup(ns, cfg(ns, 300.0)).await;
    let ghost =
        s.sa.liveliness()
            .declare_token(keys::alive(ns, "ghost"))
            .await
            .unwrap();
    wait_live(&s.sa, ns, &["a", "b", "ghost"]).await;
    let mut last = 0;
    let mut complete = Vec::new();
    for _ in 0..6 {
        complete.push(honest_round(&mut s, &mut last).await.provenance.complete);
    }
    assert_eq!(complete, [false, false, false, true, true, true]);
    drop(ghost);
    let st = finish(s).await;
    assert_eq!((st.windows, st.windows_incomplete), (6, 3));
}

#[tokio::test(flavor = "multi_thread")]
async fn of_a_fast_agents_frames_the_closest_to_the_anchor_is_fused() {
    let ns = "mixed";
    let mut s = setup(ns, cfg(ns, 2000.0)).await;
    // One session sends for three agents in a known order: slow (10 Hz) opens the window, fast
    // (20 Hz, with jitter) puts two frames in it, and a third agent completes it.
    let raw = connect(s.port).await;
    let mut tokens = Vec::new();
    for name in ["slow", "fast", "third"] {
        tokens.push(
            raw.liveliness()
                .declare_token(keys::alive(ns, name))
                .await
                .unwrap(),
        );
    }
    wait_live(&s.sa, ns, &["a", "b", "slow", "fast", "third"]).await;
    drop(s.a);
    drop(s.b);
    wait_live(&s.sa, ns, &["slow", "fast", "third"]).await;
    let t = now_us();
    let put = |name: &str, seq: u32, capture: u64, x: f64| {
        let f = Frame {
            agent: name.into(),
            seq,
            detections: vec![det(x, seq)],
            ..frame(capture)
        };
        raw.put(keys::detections(ns, name), wire::encode(&f).unwrap())
    };
    put("slow", 0, t, 10.0).await.unwrap();
    put("fast", 0, t - 45_000, 10.0).await.unwrap();
    put("fast", 1, t + 5_000, 10.0).await.unwrap();
    put("third", 0, t, 10.0).await.unwrap();
    let f = next_fused(&mut s.fuser.1).await;
    assert_eq!(f.provenance.agents, vec!["fast", "slow", "third"]);
    let st = stats(&s.sa, ns).await;
    assert_eq!(st["agents"]["fast"]["replaced"], 1);
    assert_eq!(st["agents"]["fast"]["duplicate"], 0);
    assert_eq!(st["agents"]["fast"]["accepted"], 2);
    s.fuser.0.send(()).unwrap();
    let stats = within(30, "fuser shutdown", s.fuser.2).await.unwrap();
    assert_eq!(stats.windows, 1);
    drop(tokens);
}

/// An agent of its own session, token and key, sending whatever it likes.
struct Attacker {
    name: &'static str,
    session: zenoh::Session,
    _token: zenoh::liveliness::LivelinessToken,
}

impl Attacker {
    async fn join(s: &Setup, ns: &'static str, name: &'static str, also_live: &[&str]) -> Self {
        let session = connect(s.port).await;
        let token = session
            .liveliness()
            .declare_token(keys::alive(ns, name))
            .await
            .unwrap();
        let mut live = vec!["a", "b", name];
        live.extend(also_live);
        wait_live(&s.sa, ns, &live).await;
        Attacker {
            name,
            session,
            _token: token,
        }
    }

    async fn send(&self, ns: &str, capture_us: u64, detections: Vec<Detection>) {
        let f = Frame {
            agent: self.name.into(),
            origin: detections.first().map_or([0.0; 3], |d| d.center),
            detections,
            ..frame(capture_us)
        };
        self.session
            .put(keys::detections(ns, self.name), wire::encode(&f).unwrap())
            .congestion_control(CongestionControl::Block)
            .await
            .unwrap();
    }
}

/// The honest boxes of a fused window: those a and b both contributed (at x = 10 and 30).
fn honest_boxes(f: &node::Fused) -> Vec<f64> {
    let mut xs: Vec<f64> = f
        .frame
        .detections
        .iter()
        .zip(&f.provenance.sources)
        .filter(|(_, s)| {
            let names: Vec<&str> = f.provenance.names(s).collect();
            names == ["a", "b"]
        })
        .map(|(d, _)| d.center[0].round())
        .collect();
    xs.sort_by(f64::total_cmp);
    xs
}

#[tokio::test(flavor = "multi_thread")]
async fn one_agent_cannot_evict_the_others_boxes_by_score_or_by_origin() {
    let ns = "evict";
    let mut s = setup(ns, cfg(ns, 300.0)).await;
    let mal = Attacker::join(&s, ns, "mal", &[]).await;
    let mut last = 0;
    let mut admitted = 0;
    // By score: 4,096 boxes of score 1.0 a kilometre away, each window.
    let piles: Vec<Detection> = (0..limits::MAX_OBJECTS)
        .map(|i| {
            let mut d = det(1000.0 + 0.5 * (i % 64) as f64, i as u32);
            d.center[1] = 0.5 * (i / 64) as f64;
            d.score = 1.0;
            d
        })
        .collect();
    // By origin: 25 valid boxes at 10^9 m, more than the honest agents have together.
    let far: Vec<Detection> = (0..25)
        .map(|i| {
            let mut d = det(1e9 - i as f64, i);
            d.score = 1.0;
            d
        })
        .collect();
    for (round, attack) in [&piles, &piles, &piles, &far, &far, &far]
        .iter()
        .enumerate()
    {
        let t = next_t(&mut last);
        mal.send(ns, t, attack.to_vec()).await;
        s.a.send(frame(t)).unwrap();
        s.b.send(frame(t)).unwrap();
        let f = next_fused(&mut s.fuser.1).await;
        assert_eq!(honest_boxes(&f), [10.0, 30.0], "round {round}");
        if round < 3 {
            admitted += f.frame.detections.len() - 2;
        }
    }
    // Of each pile, the budget of 500 boxes was fused; no fused box was dropped to fit the wire.
    assert_eq!(
        admitted,
        3 * v2x_fuser::intake::ingest::MAX_OBJECTS_PER_AGENT
    );
    let st = finish(s).await;
    assert_eq!(st.windows, 6);
    assert_eq!((st.fit.objects_invalid, st.fit.objects_capped), (0, 0));
    let budget = v2x_fuser::intake::ingest::MAX_OBJECTS_PER_AGENT as u64;
    assert_eq!(
        st.agents["mal"].over_budget,
        3 * (limits::MAX_OBJECTS as u64 - budget)
    );
    assert_eq!(st.agents["mal"].outside, 3 * 25);
    assert_eq!(st.dropped["outside"], 75);
    let area = st.area.expect("learned");
    assert!(area.learned && area.center[0] < 1000.0, "{area:?}");
}

#[tokio::test(flavor = "multi_thread")]
async fn piles_of_boxes_cannot_stall_the_honest_windows() {
    let ns = "stall";
    let mut s = setup(ns, cfg(ns, 300.0)).await;
    let m1 = Attacker::join(&s, ns, "pile1", &[]).await;
    let m2 = Attacker::join(&s, ns, "pile2", &["pile1"]).await;
    // Two agents with 4,096 cars each on one spot: every pair is a candidate.
    let pile: Vec<Detection> = (0..limits::MAX_OBJECTS)
        .map(|i| det(50.0 + 0.001 * i as f64, i as u32))
        .collect();
    let mut last = 0;
    for round in 0..8 {
        let t = next_t(&mut last);
        m1.send(ns, t, pile.clone()).await;
        m2.send(ns, t, pile.clone()).await;
        s.a.send(frame(t)).unwrap();
        s.b.send(frame(t)).unwrap();
        let f = next_fused(&mut s.fuser.1).await;
        assert!(f.provenance.complete, "round {round}");
        assert_eq!(honest_boxes(&f), [10.0, 30.0], "round {round}");
        // Each pile brought its budget of boxes (all on one spot, fused at most pairwise).
        assert!(
            f.frame.detections.len() <= 2 + 2 * v2x_fuser::intake::ingest::MAX_OBJECTS_PER_AGENT
        );
    }
    let st = finish(s).await;
    assert_eq!(
        (st.windows, st.windows_dropped, st.windows_incomplete),
        (8, 0, 0)
    );
    eprintln!(
        "two piles of 4,096 boxes: fusion p50 {:?} ms, max {:?} ms a window",
        st.fusion_latency_ms.p50_ms, st.fusion_latency_ms.max_ms
    );
    let over = 8 * (limits::MAX_OBJECTS - v2x_fuser::intake::ingest::MAX_OBJECTS_PER_AGENT) as u64;
    assert_eq!(st.dropped["over_budget"], 2 * over);
}

#[tokio::test(flavor = "multi_thread")]
async fn frames_stamped_ahead_hold_only_their_own_window() {
    let ns = "ahead";
    // A long wait: an honest window that waited for the early agent would close incomplete.
    let mut s = setup(ns, cfg(ns, 2000.0)).await;
    let mal = Attacker::join(&s, ns, "early", &[]).await;
    let mut last = 0;
    let mut spread = [200_000u64, 900_000, 550_000, 370_000, 730_000]
        .iter()
        .cycle();
    for round in 0..6 {
        let t = next_t(&mut last);
        // Off the time grid, 0.2-0.9 s ahead, before each honest round.
        mal.send(
            ns,
            now_us() + spread.next().unwrap() + 13_000,
            vec![det(70.0, 9)],
        )
        .await;
        s.a.send(frame(t)).unwrap();
        s.b.send(frame(t)).unwrap();
        let f = next_fused(&mut s.fuser.1).await;
        assert!(
            f.provenance.complete,
            "round {round}: {:?}",
            f.provenance.agents
        );
        assert_eq!(honest_boxes(&f), [10.0, 30.0], "round {round}");
    }
    let v = stats(&s.sa, ns).await;
    assert_eq!(v["agents"]["early"]["ahead"], 6);
    // (the honest rounds run ahead of the clock too, by up to half a second: counted as well)
    assert!(v["dropped"]["ahead"].as_u64().unwrap() >= 6);
    finish(s).await;
}

#[tokio::test(flavor = "multi_thread")]
async fn a_flapping_token_and_a_reserved_name_cost_nothing() {
    let ns = "flap";
    let mut s = setup(ns, cfg(ns, 300.0)).await;
    let other = connect(s.port).await;
    // An agent that calls itself the fuser is refused, frames and token.
    let fake = other
        .liveliness()
        .declare_token(keys::alive(ns, "fuser"))
        .await
        .unwrap();
    let mut f = frame(now_us());
    f.agent = "fuser".into();
    other
        .put(keys::detections(ns, "fuser"), wire::encode(&f).unwrap())
        .await
        .unwrap();
    stats_until(&s.sa, ns, "the fuser's name refused", |v| {
        v["rejected"]["reserved_name"] == 2
    })
    .await;
    drop(fake);
    // A token re-declared every window without a frame.
    let mut last = 0;
    let mut incomplete = 0;
    for _ in 0..12 {
        let token = other
            .liveliness()
            .declare_token(keys::alive(ns, "flap"))
            .await
            .unwrap();
        wait_live(&s.sa, ns, &["a", "b", "flap"]).await;
        incomplete += !honest_round(&mut s, &mut last).await.provenance.complete as u32;
        drop(token);
        wait_live(&s.sa, ns, &["a", "b"]).await;
    }
    assert_eq!(incomplete, v2x_fuser::intake::ingest::MAX_MISSES);
    let st = finish(s).await;
    assert!(!st.agents.contains_key("fuser"));
}

#[tokio::test(flavor = "multi_thread")]
async fn tracks_follow_the_fused_windows_on_their_key() {
    tracks_on_their_key("tracks", false).await;
}

#[tokio::test(flavor = "multi_thread")]
async fn tracks_through_the_tracks_on_their_key() {
    tracks_on_their_key("tracks-guided", true).await;
}

/// Two agents' honest rounds to a fuser that tracks (fed the fused boxes, or with `guided` each
/// agent's boxes through the tracks): tracks frames on their key, two tracks with stable ids.
async fn tracks_on_their_key(ns: &'static str, guided: bool) {
    let mut c = cfg(ns, 300.0);
    c.track = Some(v2x_fuser::tracker::TrackerParams::default().with_guided(guided));
    let mut s = setup(ns, c).await;
    let sub = s.sa.declare_subscriber(keys::tracks(ns)).await.unwrap();
    let mut last = 0;
    // The subscription reaches the fuser while the first windows fuse; tracks are confirmed
    // from a box's second window on (the first window's tracks frame is empty), so within a
    // few rounds every window brings both.
    let mut frames: Vec<Frame> = Vec::new();
    for _ in 0..8 {
        honest_round(&mut s, &mut last).await;
    }
    within(10, "tracks", async {
        while frames.len() < 3 {
            let sample = sub.recv_async().await.unwrap();
            let f = wire::decode(&sample.payload().to_bytes()).unwrap();
            if !f.detections.is_empty() {
                frames.push(f);
            }
        }
    })
    .await;
    let last_frame = frames.last().unwrap();
    assert_eq!(last_frame.agent, "fuser");
    assert_eq!(last_frame.detections.len(), 2, "{last_frame:?}");
    // each box carries its track's id, the same in every frame
    let ids = |f: &Frame| {
        let mut v: Vec<u32> = f.detections.iter().map(|d| d.id).collect();
        v.sort();
        v
    };
    let first = ids(&frames[frames.len() - 3]);
    assert_eq!(first.len(), 2);
    assert_ne!(first[0], first[1]);
    assert_eq!(ids(last_frame), first);
    let v = stats_until(&s.sa, ns, "track stats", |v| v["tracks"]["live"] == 2).await;
    assert_eq!(v["tracks"]["births"], 2);
    let st = finish(s).await;
    assert_eq!(st.tracks.unwrap().live, 2);
}

#[tokio::test(flavor = "multi_thread")]
async fn registration_is_reported_in_the_stats() {
    // Vehicle a reports six cars 0.66 m east and north of where roadside unit b does (a
    // calibration error): within a few windows the fuser applies the shift, and says so.
    let ns = "registration";
    let mut c = cfg(ns, 300.0);
    c.steps.align = Some(Default::default());
    let mut s = setup(ns, c).await;
    let cars = |dx: f64, dy: f64| -> Vec<Detection> {
        (0..6)
            .map(|i| {
                let mut d = det(12.0 * i as f64 + dx, i);
                d.center[1] = 5.0 * (i % 2) as f64 + dy;
                d.std = Uncertainty::uniform(0.1, 0.1, 0.1);
                d
            })
            .collect()
    };
    let mut last = 0;
    let mut fused = None;
    // (rounds run ahead of the clock by a window each: eight stay within what the fuser admits)
    for _ in 0..8 {
        let t = next_t(&mut last);
        s.a.send(Frame {
            detections: cars(-0.66, -0.66),
            ..frame(t)
        })
        .unwrap();
        s.b.send(Frame {
            detections: cars(0.0, 0.0),
            ..frame(t)
        })
        .unwrap();
        fused = Some(next_fused(&mut s.fuser.1).await);
    }
    let fused = fused.unwrap();
    let r = fused.registration["a"];
    assert!(r.applied && r.matches == 6, "{r:?}");
    // registered, each pair fuses into one box
    assert_eq!(fused.frame.detections.len(), 6);
    let v = stats_until(&s.sa, ns, "registration stats", |v| {
        v["registration"]["a"]["applied"] == true
    })
    .await;
    let shift = &v["registration"]["a"]["shift_m"];
    for k in 0..2 {
        let x = shift[k].as_f64().unwrap();
        assert!((x - 0.66).abs() < 0.05, "{shift}");
    }
    assert!(
        v["registration"].get("b").is_none(),
        "the reference is not registered"
    );
    finish(s).await;
}
