//! Security over loopback: a Zenoh router with mutual TLS and the access-control policy that
//! `v2x-sim certs` writes, the fuser, agents and an observer as its clients. Every forbidden
//! action is tried, and each is shown to reach nobody by a permitted action sent after it on the
//! same session (Zenoh delivers a session's messages in order), never by waiting.

use std::path::{Path, PathBuf};
use std::time::Duration;
use v2x_agent::{now_us, Agent, Link};
use v2x_fuser::node::{self, NodeConfig};
use v2x_protocol::net::{open_session, ZenohArgs};
use v2x_protocol::{keys, wire, AgentKind, Frame};
use v2x_sim::certs::{client_config, issue, leaf, new_ca, CertsConfig, Issued};
use v2x_sim::run::free_port;
use v2x_tests::fuser::{det, frame, joined, next_fused, next_t, spawn_fuser_with, wait_live};
use v2x_tests::{tempdir, within};

fn certs(name: &str, ns: &str, port: u16) -> Issued {
    let endpoint = format!("tls/127.0.0.1:{port}");
    issue(&CertsConfig {
        out: tempdir(name),
        ns: ns.into(),
        agents: vec!["a".into(), "b".into()],
        listen: vec![endpoint.clone()],
        connect: vec![endpoint],
        days: 1,
    })
    .unwrap()
}

async fn open(config: &Path) -> zenoh::Session {
    open_session(&ZenohArgs {
        zenoh_config: Some(config.to_path_buf()),
        ..Default::default()
    })
    .await
    .unwrap()
}

async fn router(issued: &Issued) -> zenoh::Session {
    open(&issued.router).await
}

/// Opening a session with this client configuration fails within a few seconds.
async fn refused(config: serde_json::Value, dir: &Path, name: &str) {
    let mut config = config;
    config["connect"]["timeout_ms"] = serde_json::json!({ "client": 2000 });
    let path = dir.join(format!("{name}.json5"));
    std::fs::write(&path, config.to_string()).unwrap();
    let r = within(
        30,
        name,
        open_session(&ZenohArgs {
            zenoh_config: Some(path),
            ..Default::default()
        }),
    )
    .await;
    assert!(r.is_err(), "{name}: the router accepted the session");
}

#[tokio::test(flavor = "multi_thread")]
async fn clients_without_a_valid_certificate_cannot_connect() {
    let ns = "sec-refuse";
    let port = free_port().unwrap();
    let issued = certs(ns, ns, port);
    let _router = router(&issued).await;
    let endpoint = vec![format!("tls/127.0.0.1:{port}")];
    let dir = &issued.dir;
    // The observer's own configuration connects: the setup works.
    let observer = open(&issued.observer).await;
    drop(observer);
    // No client certificate at all.
    let mut none = client_config(&issued.ca, Path::new("x"), Path::new("x"), &endpoint);
    let tls = none["transport"]["link"]["tls"].as_object_mut().unwrap();
    tls.remove("connect_certificate");
    tls.remove("connect_private_key");
    refused(none, dir, "no-certificate").await;
    // Plain TCP on the TLS port.
    refused(
        serde_json::json!({
            "mode": "client",
            "connect": { "endpoints": [format!("tcp/127.0.0.1:{port}")] },
            "scouting": { "multicast": { "enabled": false } },
        }),
        dir,
        "plain-tcp",
    )
    .await;
    // An expired certificate from the right CA.
    let issuer = v2x_sim::certs::load_ca(dir, ns).unwrap();
    let day = time::Duration::days(1);
    let long_ago = time::OffsetDateTime::now_utc() - 10 * day;
    let write_pair = |stem: &str, (cert, key): (String, String)| -> (PathBuf, PathBuf) {
        let (c, k) = (
            dir.join(format!("{stem}.pem")),
            dir.join(format!("{stem}-key.pem")),
        );
        std::fs::write(&c, cert).unwrap();
        std::fs::write(&k, key).unwrap();
        (c, k)
    };
    let (c, k) = write_pair(
        "expired",
        leaf(&issuer, "a", &[], long_ago, long_ago + day).unwrap(),
    );
    refused(client_config(&issued.ca, &c, &k, &endpoint), dir, "expired").await;
    // A certificate signed by another CA, with a name the policy knows.
    let (_, other) = new_ca(ns, 1).unwrap();
    let now = time::OffsetDateTime::now_utc();
    let (c, k) = write_pair(
        "other-ca",
        leaf(&other, "a", &[], now - day, now + day).unwrap(),
    );
    refused(
        client_config(&issued.ca, &c, &k, &endpoint),
        dir,
        "other-ca",
    )
    .await;
}

#[tokio::test(flavor = "multi_thread")]
async fn each_identity_may_do_only_what_the_policy_allows() {
    let ns = "sec-acl";
    let port = free_port().unwrap();
    let issued = certs(ns, ns, port);
    let _router = router(&issued).await;
    let mut cfg = NodeConfig::new(ns, "csba-wls+".parse().unwrap());
    cfg.max_wait_ms = 300.0;
    let mut fuser = spawn_fuser_with(open(&issued.fuser).await, cfg);
    let observer = open(&issued.observer).await;
    let fused_seen = observer.declare_subscriber(keys::fused(ns)).await.unwrap();
    let raw_seen = observer
        .declare_subscriber(keys::all_detections(ns))
        .await
        .unwrap();

    // Mallory holds agent a's certificate and tries everything else first.
    let mallory = open(&issued.agents["a"]).await;
    let forged = |agent: &str, capture: u64| {
        let mut f = frame(capture);
        f.agent = agent.into();
        f.seq = 999;
        wire::encode(&f).unwrap()
    };
    mallory
        .put(keys::detections(ns, "b"), forged("b", now_us()))
        .await
        .unwrap();
    let mut fake_fused = frame(42);
    fake_fused.agent = "fuser".into();
    mallory
        .put(keys::fused(ns), wire::encode(&fake_fused).unwrap())
        .await
        .unwrap();
    let fake_stats = mallory.declare_queryable(keys::fuser_stats(ns)).await;
    let fake_token_b = mallory
        .liveliness()
        .declare_token(keys::alive(ns, "b"))
        .await;
    // ...then what its certificate allows: its own token, and later its own frames.
    let a_token = mallory
        .liveliness()
        .declare_token(keys::alive(ns, "a"))
        .await
        .unwrap();
    // The token as a arrives; the one as b, declared before it on the same session, never did.
    wait_live(&observer, ns, &["a"]).await;

    // Another observer's forbidden actions, before an honest frame is fused (a session's own
    // subscribers would see its puts locally, so this one has none).
    let nosy = open(&issued.observer).await;
    nosy.put(keys::detections(ns, "a"), forged("a", now_us()))
        .await
        .unwrap();
    nosy.put(keys::fused(ns), wire::encode(&fake_fused).unwrap())
        .await
        .unwrap();

    // Honest agents: b joins properly, and "a" (mallory) sends its own frames.
    let sb = open(&issued.agents["b"]).await;
    let mut b = joined(&sb, ns, "b", AgentKind::Infrastructure, 2).await;
    wait_live(&observer, ns, &["a", "b"]).await;
    let mut a = joined(&mallory, ns, "a", AgentKind::Vehicle, 1).await;
    let mut last = 0;
    let mut expected = Vec::new();
    for _ in 0..3 {
        let t = next_t(&mut last);
        let fa = Frame {
            detections: vec![det(10.0, 1), det(30.0, 2)],
            ..frame(t)
        };
        let fb = Frame {
            detections: vec![det(10.2, 1), det(29.9, 2)],
            ..frame(t)
        };
        a.send(fa.clone()).unwrap();
        b.send(fb.clone()).unwrap();
        let f = next_fused(&mut fuser.1).await;
        assert_eq!(
            f.provenance.agents,
            vec!["a", "b"],
            "exactly the two honest frames"
        );
        // Unchanged by everything above: the fusion of the two honest frames alone.
        let quantized = |f: &Frame| {
            let mut g = f.clone();
            g.agent = "x".into();
            wire::decode(&wire::encode(&g).unwrap()).unwrap().detections
        };
        let want = "csba-wls+"
            .parse::<v2x_fuser::Method>()
            .unwrap()
            .fuse(&[quantized(&fa), quantized(&fb)]);
        assert_eq!(f.frame.detections.len(), want.len());
        for (x, y) in f.frame.detections.iter().zip(&want) {
            assert!((x.center[0] - y.center[0]).abs() < 1e-9);
        }
        expected.push(t);
    }
    // The observer saw the three fused windows and nothing forged, and no raw detection.
    let mut seen = Vec::new();
    while seen.len() < 3 {
        let s = within(10, "fused output at the observer", fused_seen.recv_async())
            .await
            .unwrap();
        seen.push(wire::decode(&s.payload().to_bytes()).unwrap().capture_us);
    }
    assert_eq!(
        seen, expected,
        "no forged fused frame (capture 42) reached the observer"
    );
    assert!(
        raw_seen.try_recv().unwrap().is_none(),
        "the observer read detections"
    );
    // Only the real fuser answers the statistics query.
    let replies = observer
        .get(keys::fuser_stats(ns))
        .timeout(Duration::from_secs(3))
        .await
        .unwrap();
    let mut answers = Vec::new();
    while let Ok(r) = within(10, "stats replies", replies.recv_async()).await {
        answers.push(r.result().is_ok());
    }
    assert_eq!(answers, vec![true]);
    let stats = node::query_stats(&observer, ns, Duration::from_secs(5))
        .await
        .unwrap();
    assert!(stats["agents"]["b"]["wrong_agent"] == 0 && stats["agents"]["b"]["frames_in"] == 3);
    assert_eq!(
        stats["agents"]["a"]["frames_in"], 3,
        "the observer's put reached nobody"
    );
    drop((fake_stats, fake_token_b, a_token));
    fuser.0.send(()).unwrap();
    let st = within(30, "fuser shutdown", fuser.2).await.unwrap();
    assert_eq!(st.windows, 3);
}

#[tokio::test(flavor = "multi_thread")]
async fn the_statistics_admin_space_answers_its_own_session_only() {
    let ns = "sec-stats";
    let port = free_port().unwrap();
    let issued = certs(ns, ns, port);
    let _router = router(&issued).await;
    // An agent that counts its traffic (admin space on), as `v2x-sim run` opens every role.
    let key = keys::detections(ns, "a");
    let args = ZenohArgs {
        zenoh_config: Some(issued.agents["a"].clone()),
        ..Default::default()
    };
    let counted = v2x_protocol::net::open_counted_session(&args, std::slice::from_ref(&key))
        .await
        .unwrap();
    let fuser = open(&issued.fuser).await;
    let seen = fuser
        .declare_subscriber(keys::all_detections(ns))
        .await
        .unwrap();
    let publisher = counted.declare_publisher(&key).await.unwrap();
    within(10, "the fuser's subscription", async {
        while !publisher.matching_status().await.unwrap().matching() {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await;
    publisher.put(vec![7u8; 300]).await.unwrap();
    within(10, "the put at the fuser", seen.recv_async())
        .await
        .unwrap();
    // Its own statistics, through the router's access control: the put and its payload.
    let t = v2x_protocol::traffic::traffic(&counted, Duration::from_secs(5))
        .await
        .unwrap();
    assert_eq!(t.key(&key).tx.put_msgs, 1);
    assert_eq!(t.key(&key).tx.put_payload_bytes, 300);
    assert!(t.sent_with(&key).bytes > 300);
    // Nobody else may read its admin space (nor anyone's): the policy denies the query.
    let observer = open(&issued.observer).await;
    let replies = observer
        .get(format!("@/{}/**", counted.zid()))
        .timeout(Duration::from_secs(2))
        .await
        .unwrap();
    let mut answers = 0;
    while within(10, "admin replies", replies.recv_async())
        .await
        .is_ok()
    {
        answers += 1;
    }
    assert_eq!(answers, 0, "another session read the agent's admin space");
}

#[tokio::test(flavor = "multi_thread")]
async fn a_regional_fuser_is_held_to_the_same_policy() {
    use v2x_protocol::keys::FuserKeys;
    use v2x_protocol::tiles::{encode_tiles, Tile, Tiling};
    let ns = "sec-region";
    let port = free_port().unwrap();
    let issued = certs(ns, ns, port);
    let _router = router(&issued).await;
    let tile = Tile { x: 0, y: 0 };
    let tiling = Tiling::new(200.0).unwrap();
    let mut cfg = NodeConfig::new(ns, "csba-wls+".parse().unwrap());
    cfg.max_wait_ms = 300.0;
    cfg.region = Some(v2x_fuser::intake::region::Region {
        tiling,
        tile,
        halo_m: 30.0,
    });
    let mut fuser = spawn_fuser_with(open(&issued.fuser).await, cfg);
    let keys_of = FuserKeys::of(ns, Some(tile));
    let observer = open(&issued.observer).await;
    let fused_seen = observer
        .declare_subscriber(keys_of.fused.clone())
        .await
        .unwrap();
    // Agent a's certificate tries to publish as b in the tile, and as the regional fuser, once
    // the fuser's subscription has reached it (so only the policy can stop the forgery).
    let mallory = open(&issued.agents["a"]).await;
    let mut a = Agent::start(&mallory, ns, "a", AgentKind::Vehicle, Link::default(), 1)
        .await
        .unwrap()
        .with_tiling(tiling);
    a.wait_for_subscriber_in(tile, Duration::from_secs(10))
        .await
        .unwrap();
    let mut forged = frame(now_us());
    forged.agent = "b".into();
    forged.seq = 0;
    mallory
        .put(
            keys::detections_in(ns, tile, "b"),
            wire::encode(&forged).unwrap(),
        )
        .attachment(encode_tiles(&[tile]).unwrap())
        .await
        .unwrap();
    let mut fake = frame(42);
    fake.agent = "fuser".into();
    mallory
        .put(keys_of.fused.clone(), wire::encode(&fake).unwrap())
        .await
        .unwrap();
    let sb = open(&issued.agents["b"]).await;
    let mut b = Agent::start(&sb, ns, "b", AgentKind::Infrastructure, Link::default(), 2)
        .await
        .unwrap()
        .with_tiling(tiling);
    b.wait_for_subscriber_in(tile, Duration::from_secs(10))
        .await
        .unwrap();
    // A warm-up capture: a regional fuser awaits an agent once it has heard from it, so the
    // first window may close without the slower of the two.
    let mut last = 0;
    let t0 = next_t(&mut last);
    a.send(frame(t0)).unwrap();
    b.send(frame(t0)).unwrap();
    let mut expected = vec![next_fused(&mut fuser.1).await.frame.capture_us];
    for _ in 0..3 {
        let t = next_t(&mut last);
        a.send(frame(t)).unwrap();
        b.send(Frame {
            detections: vec![det(10.2, 1), det(29.9, 2)],
            ..frame(t)
        })
        .unwrap();
        let f = next_fused(&mut fuser.1).await;
        assert_eq!(f.provenance.agents, vec!["a", "b"]);
        assert_eq!(f.frame.detections.len(), 2);
        expected.push(t);
    }
    let mut seen = Vec::new();
    while seen.len() < 4 {
        let s = within(
            10,
            "regional output at the observer",
            fused_seen.recv_async(),
        )
        .await
        .unwrap();
        seen.push(wire::decode(&s.payload().to_bytes()).unwrap().capture_us);
    }
    assert_eq!(seen, expected, "no forged fused frame reached the observer");
    let stats = node::query_stats_at(&observer, &keys_of.stats, Duration::from_secs(5))
        .await
        .unwrap();
    assert_eq!(stats["region"], "0_0");
    assert_eq!(
        stats["agents"]["b"]["frames_in"], 4,
        "the forged part as b reached nobody"
    );
    fuser.0.send(()).unwrap();
    let st = within(30, "fuser shutdown", fuser.2).await.unwrap();
    assert_eq!(st.windows, 4);
}

#[tokio::test(flavor = "multi_thread")]
async fn an_authenticated_agent_on_its_own_key_cannot_take_the_others_output() {
    let ns = "sec-isolation";
    let port = free_port().unwrap();
    let endpoint = format!("tls/127.0.0.1:{port}");
    let issued = issue(&CertsConfig {
        out: tempdir(ns),
        ns: ns.into(),
        agents: vec!["a".into(), "b".into(), "c".into()],
        listen: vec![endpoint.clone()],
        connect: vec![endpoint],
        days: 1,
    })
    .unwrap();
    let _router = router(&issued).await;
    let mut cfg = NodeConfig::new(ns, "csba-wls+".parse().unwrap());
    cfg.max_wait_ms = 1000.0;
    let mut fuser = spawn_fuser_with(open(&issued.fuser).await, cfg);
    let mut honest = Vec::new();
    for (name, kind, seed) in [
        ("a", AgentKind::Vehicle, 1),
        ("b", AgentKind::Infrastructure, 2),
    ] {
        let s = open(&issued.agents[name]).await;
        let agent = joined(&s, ns, name, kind, seed).await;
        honest.push((s, agent));
    }
    // c holds its own certificate and writes only on its own key, with a token.
    let c = open(&issued.agents["c"]).await;
    let _token = c
        .liveliness()
        .declare_token(keys::alive(ns, "c"))
        .await
        .unwrap();
    let observer = open(&issued.observer).await;
    wait_live(&observer, ns, &["a", "b", "c"]).await;
    let put = |capture: u64, detections: Vec<v2x_protocol::Detection>| {
        let f = Frame {
            agent: "c".into(),
            origin: detections.first().map_or([0.0; 3], |d| d.center),
            detections,
            ..frame(capture)
        };
        c.put(keys::detections(ns, "c"), wire::encode(&f).unwrap())
    };
    let pile: Vec<_> = (0..v2x_protocol::limits::MAX_OBJECTS)
        .map(|i| {
            let mut d = det(1000.0 + 0.5 * (i % 64) as f64, i as u32);
            d.center[1] = 0.5 * (i / 64) as f64;
            d.score = 1.0;
            d
        })
        .collect();
    let far: Vec<_> = (0..25).map(|i| det(1e9 - i as f64, i)).collect();
    let mut last = 0;
    for round in 0..6 {
        let t = next_t(&mut last);
        match round % 3 {
            0 => put(t, pile.clone()).await.unwrap(),
            1 => put(t, far.clone()).await.unwrap(),
            // stamped half a second ahead, off the grid
            _ => put(now_us() + 513_000, vec![det(70.0, 1)]).await.unwrap(),
        }
        for (_, agent) in &mut honest {
            agent.send(frame(t)).unwrap();
        }
        let f = next_fused(&mut fuser.1).await;
        assert!(f.provenance.complete, "round {round}");
        let both: Vec<f64> = f
            .frame
            .detections
            .iter()
            .zip(&f.provenance.sources)
            .filter(|(_, s)| f.provenance.names(s).collect::<Vec<_>>() == ["a", "b"])
            .map(|(d, _)| d.center[0].round())
            .collect();
        assert_eq!(both, [10.0, 30.0], "round {round}");
    }
    fuser.0.send(()).unwrap();
    let st = within(30, "fuser shutdown", fuser.2).await.unwrap();
    assert_eq!(st.agents["c"].over_budget, 2 * (4096 - 500));
    assert_eq!(st.agents["c"].outside, 2 * 25);
    assert!(
        st.agents["c"].ahead >= 2,
        "the frames stamped half a second ahead"
    );
    assert_eq!((st.fit.objects_invalid, st.fit.objects_capped), (0, 0));
}
