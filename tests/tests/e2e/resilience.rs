//! The fuser under stress, over loopback Zenoh: an agent that leaves and rejoins, a fuser
//! restarted mid-run, and late, duplicate, out-of-order and malformed frames.

use std::time::Duration;
use v2x_agent::{now_us, Agent, Link};
use v2x_protocol::net::{open_session, ZenohArgs};
use v2x_protocol::{keys, wire, AgentKind};
use v2x_sim::run::free_port;
use v2x_tests::fuser::{
    connect, endpoint, frame, joined, listen, next_fused, next_t, spawn_fuser, stats, wait_live,
    wait_matching,
};
use v2x_tests::within;

#[tokio::test(flavor = "multi_thread")]
async fn an_agent_that_leaves_is_not_waited_for_and_can_rejoin() {
    let ns = "leave";
    let port = free_port().unwrap();
    let fuser_session = listen(port).await;
    // A long wait: windows can only close early because every *live* agent contributed.
    let (stop, mut fused, task) = spawn_fuser(fuser_session, ns, 5000.0);
    let sa = connect(port).await;
    let sb = connect(port).await;
    let mut a = joined(&sa, ns, "a", AgentKind::Vehicle, 1).await;
    let mut b = joined(&sb, ns, "b", AgentKind::Infrastructure, 2).await;
    wait_live(&sa, ns, &["a", "b"]).await;

    let mut last = 0;
    let t = next_t(&mut last);
    a.send(frame(t)).unwrap();
    b.send(frame(t)).unwrap();
    let f = next_fused(&mut fused).await;
    assert_eq!(f.provenance.agents, vec!["a", "b"]);
    assert!(f.provenance.complete);
    assert_eq!(
        f.frame.detections.len(),
        2,
        "the two agents' boxes fused pairwise"
    );

    // b stops: its token goes, and a alone completes windows at once.
    drop(b);
    wait_live(&sa, ns, &["a"]).await;
    let t0 = std::time::Instant::now();
    a.send(frame(next_t(&mut last))).unwrap();
    let f = next_fused(&mut fused).await;
    assert_eq!(f.provenance.agents, vec!["a"]);
    assert!(
        f.provenance.complete,
        "b is gone, so a alone completes the window"
    );
    assert!(
        t0.elapsed() < Duration::from_secs(4),
        "the fuser did not wait out the 5 s deadline"
    );

    // b rejoins with a fresh sequence; windows are joint again.
    let mut b = Agent::start(&sb, ns, "b", AgentKind::Infrastructure, Link::default(), 3)
        .await
        .unwrap();
    wait_live(&sa, ns, &["a", "b"]).await;
    let t = next_t(&mut last);
    a.send(frame(t)).unwrap();
    b.send(frame(t)).unwrap();
    let f = next_fused(&mut fused).await;
    assert_eq!(f.provenance.agents, vec!["a", "b"]);

    stop.send(()).unwrap();
    let stats = within(10, "fuser shutdown", task).await.unwrap();
    assert_eq!(stats.windows, 3);
    assert_eq!(stats.windows_incomplete, 0);
    assert_eq!(
        stats.agents["b"].duplicate, 0,
        "the rejoined agent's seq 0 is not a duplicate"
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn fusion_resumes_after_the_fuser_restarts() {
    let ns = "restart";
    // Agents listen; the fuser connects to them, so a restarted fuser simply connects again.
    let (pa, pb) = (free_port().unwrap(), free_port().unwrap());
    let sa = listen(pa).await;
    let sb = open_session(&ZenohArgs::loopback(&[endpoint(pb)], &[endpoint(pa)]))
        .await
        .unwrap();
    let mut a = Agent::start(&sa, ns, "a", AgentKind::Vehicle, Link::default(), 1)
        .await
        .unwrap();
    let mut b = Agent::start(&sb, ns, "b", AgentKind::Infrastructure, Link::default(), 2)
        .await
        .unwrap();
    let observer = sa.declare_subscriber(keys::fused(ns)).await.unwrap();
    let fuser_args = ZenohArgs::loopback(&[], &[endpoint(pa), endpoint(pb)]);

    let mut last = 0;
    for round in 0..2 {
        let (stop, mut fused, task) =
            spawn_fuser(open_session(&fuser_args).await.unwrap(), ns, 300.0);
        a.wait_for_subscriber(Duration::from_secs(10))
            .await
            .unwrap();
        b.wait_for_subscriber(Duration::from_secs(10))
            .await
            .unwrap();
        wait_live(&sa, ns, &["a", "b"]).await;
        // The agents keep publishing as they would; the fuser fuses again.
        for _ in 0..3 {
            let t = next_t(&mut last);
            a.send(frame(t)).unwrap();
            // b also sees a third object, far from the others.
            let mut fb = frame(t);
            fb.detections.push(v2x_tests::fuser::det(90.0, 3));
            b.send(fb).unwrap();
            let f = next_fused(&mut fused).await;
            assert_eq!(f.frame.capture_us, t, "round {round}");
            assert_eq!(f.provenance.agents, vec!["a", "b"]);
            let on_wire = within(10, "fused frame on the network", observer.recv_async())
                .await
                .unwrap();
            let (decoded, provenance) = wire::decode_with(&on_wire.payload().to_bytes()).unwrap();
            assert_eq!(decoded.capture_us, t);
            // The frame on the network says where each box came from: the two shared objects
            // from both agents, the third from b alone.
            let provenance = provenance.expect("fused frames carry their provenance");
            assert_eq!(provenance, f.provenance);
            assert!(provenance.complete);
            let sources: Vec<(f64, Vec<&str>)> = decoded
                .detections
                .iter()
                .zip(&provenance.sources)
                .map(|(d, s)| (d.center[0], provenance.names(s).collect()))
                .collect();
            assert_eq!(
                sources,
                vec![
                    (10.0, vec!["a", "b"]),
                    (30.0, vec!["a", "b"]),
                    (90.0, vec!["b"])
                ]
            );
        }
        stop.send(()).unwrap();
        within(10, "fuser shutdown", task).await.unwrap();
        // While no fuser runs, the agents keep sending into the void.
        a.send(frame(next_t(&mut last))).unwrap();
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn late_duplicate_out_of_order_and_malformed_frames() {
    let ns = "faults";
    let port = free_port().unwrap();
    let fuser_session = listen(port).await;
    let (stop, mut fused, task) = spawn_fuser(fuser_session, ns, 300.0);
    let s = connect(port).await;
    // A raw publisher with no liveliness token: windows close by deadline only.
    let publisher = s
        .declare_publisher(keys::detections(ns, "x"))
        .await
        .unwrap();
    wait_matching(&publisher).await;
    let base = now_us();
    let enc = |seq: u32, t_ms: u64, agent: &str| {
        let mut f = frame(base + t_ms * 1000);
        f.agent = agent.into();
        f.seq = seq;
        wire::encode(&f).unwrap()
    };
    publisher.put(vec![0xde, 0xad, 0xbe, 0xef]).await.unwrap(); // malformed
    publisher.put(enc(9, 0, "mallory")).await.unwrap(); // claims another agent's name
    let mut truncated = enc(0, 0, "x");
    truncated.truncate(truncated.len() - 3);
    publisher.put(truncated).await.unwrap(); // truncated
    publisher.put(enc(2, 200, "x")).await.unwrap(); // out of order: 200 before 100
    publisher.put(enc(1, 100, "x")).await.unwrap();
    publisher.put(enc(1, 100, "x")).await.unwrap(); // duplicate
    let mut anchors = Vec::new();
    for _ in 0..2 {
        anchors.push(next_fused(&mut fused).await.frame.capture_us);
    }
    assert_eq!(
        anchors,
        vec![base + 100_000, base + 200_000],
        "both windows fused once, in capture order"
    );
    publisher.put(enc(3, 100, "x")).await.unwrap(); // late: its window is closed
    publisher.put(enc(4, 300, "x")).await.unwrap(); // and the fuser keeps going
    assert_eq!(
        next_fused(&mut fused).await.frame.capture_us,
        base + 300_000
    );

    let v = stats(&s, ns).await;
    let x = &v["agents"]["x"];
    assert_eq!(x["frames_in"], 8);
    assert_eq!(x["invalid"], 2);
    assert_eq!(x["wrong_agent"], 1);
    assert_eq!(x["duplicate"], 1);
    assert_eq!(x["late"], 1);
    assert_eq!(x["accepted"], 3);
    assert_eq!(x["fused"], 3);
    stop.send(()).unwrap();
    let stats = within(10, "fuser shutdown", task).await.unwrap();
    assert_eq!(stats.windows, 3, "nothing fused twice");
    assert!(fused.try_recv().is_err());
}
