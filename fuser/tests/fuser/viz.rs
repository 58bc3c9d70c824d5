//! The MCAP a run writes for Foxglove, read back: its channels, schemas, message counts, and a
//! decoded box.

use foxglove::schemas::SceneUpdate;
use foxglove::Decode;
use std::collections::BTreeMap;
use v2x_fuser::time::align::Registration;
use v2x_fuser::viz::{agent_colour, Viz, FUSED};
use v2x_protocol::{AgentSet, Detection, Provenance, Velocity};

fn car(x: f64, id: u32) -> Detection {
    Detection {
        center: [x, 2.0, 0.9],
        yaw: 0.3,
        velocity: Some(Velocity {
            v: [10.0, 0.0],
            std: [0.3, 0.3],
        }),
        id,
        ..v2x_protocol::fixtures::car(x, 2.0, 0.5)
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn the_mcap_holds_every_source_as_scene_updates() {
    let dir = std::env::temp_dir().join(format!("v2x-viz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("run.mcap");
    let viz = Viz::open(Some(&path), None).await.unwrap();
    let t0 = 1_700_000_000_000_000u64;
    for k in 0..3u64 {
        let t = t0 + k * 100_000;
        viz.boxes(
            "/agents/veh",
            "veh",
            t,
            &[car(10.0, 1), car(30.0, 2)],
            agent_colour("veh"),
        );
        viz.boxes(
            "/agents/rsu",
            "rsu",
            t,
            &[car(10.2, 1)],
            agent_colour("rsu"),
        );
        let provenance = Provenance {
            agents: vec!["rsu".into(), "veh".into()],
            complete: true,
            sources: vec![[0, 1].into_iter().collect(), AgentSet::single(1)],
        };
        viz.fused(t, &[car(10.1, 1), car(30.0, 2)], &provenance);
        let registration = [(
            "veh".to_string(),
            Registration {
                pivot: [10.0, 2.0],
                shift_m: [0.66, -0.5],
                turn_rad: 0.01,
                std: [0.1, 0.1, 0.002],
                matches: 4,
                chi2: 40.0,
                turn_chi2: 2.0,
                applied: true,
                turn_applied: false,
            },
        )]
        .into();
        let mut learner = v2x_fuser::uncertainty::learn::Learner::new(Default::default());
        learner.observe("veh", t, &[]);
        viz.window(
            t,
            &["rsu".into(), "veh".into()],
            true,
            2,
            0.2,
            25.0,
            &registration,
            &learner.report(),
        );
    }
    viz.close().unwrap();

    let bytes = std::fs::read(&path).unwrap();
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut first_fused = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        match m.channel.topic.as_str() {
            "/stats" => {
                assert_eq!(
                    (schema.name.as_str(), m.channel.message_encoding.as_str()),
                    ("v2x.WindowStats", "json")
                );
                let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
                assert_eq!(v["members"], serde_json::json!(["rsu", "veh"]));
                assert_eq!(
                    v["registration"]["veh"]["shift_m"],
                    serde_json::json!([0.66, -0.5])
                );
                assert_eq!(v["registration"]["veh"]["applied"], true);
                assert_eq!(v["learned_std"]["veh"]["flagged"], false);
                assert!(
                    v["learned_std"]["veh"]["ratio_xy"].is_null(),
                    "nothing learned yet"
                );
            }
            _ => {
                assert_eq!(schema.name, "foxglove.SceneUpdate");
                assert_eq!(m.channel.message_encoding, "protobuf");
            }
        }
        if m.channel.topic == "/fused" && first_fused.is_none() {
            assert_eq!(m.log_time, t0 * 1000, "stamped with the capture time");
            first_fused = Some(SceneUpdate::decode(&m.data[..]).unwrap());
        }
        *counts.entry(m.channel.topic.clone()).or_default() += 1;
    }
    let want: BTreeMap<String, usize> = ["/agents/rsu", "/agents/veh", "/fused", "/stats"]
        .iter()
        .map(|t| (t.to_string(), 3))
        .collect();
    assert_eq!(counts, want);
    let scene = first_fused.unwrap();
    assert_eq!(scene.entities.len(), 2);
    let e = &scene.entities[0];
    let cube = &e.cubes[0];
    let p = cube.pose.as_ref().unwrap().position.as_ref().unwrap();
    assert_eq!((p.x, p.y, p.z), (10.1, 2.0, 0.9));
    let s = cube.size.as_ref().unwrap();
    assert_eq!((s.x, s.y, s.z), (4.5, 1.9, 1.6));
    let q = cube.pose.as_ref().unwrap().orientation.as_ref().unwrap();
    assert!(
        (2.0 * q.z.atan2(q.w) - 0.3).abs() < 1e-12,
        "yaw 0.3 about z"
    );
    assert_eq!(e.texts[0].text, "1 car from rsu+veh");
    assert_eq!(scene.entities[1].texts[0].text, "2 car from veh");
    assert_eq!(e.arrows[0].shaft_length, 10.0);
    std::fs::remove_dir_all(&dir).ok();
}

/// Reads one unmasked server frame's payload (text or binary) off a WebSocket stream.
async fn read_frame(s: &mut tokio::net::TcpStream) -> (u8, Vec<u8>) {
    use tokio::io::AsyncReadExt;
    let mut h = [0u8; 2];
    s.read_exact(&mut h).await.unwrap();
    let len = match h[1] & 0x7f {
        126 => {
            let mut b = [0u8; 2];
            s.read_exact(&mut b).await.unwrap();
            u16::from_be_bytes(b) as usize
        }
        127 => {
            let mut b = [0u8; 8];
            s.read_exact(&mut b).await.unwrap();
            u64::from_be_bytes(b) as usize
        }
        n => n as usize,
    };
    let mut payload = vec![0u8; len];
    s.read_exact(&mut payload).await.unwrap();
    (h[0] & 0x0f, payload)
}

#[tokio::test(flavor = "multi_thread")]
async fn the_live_server_speaks_the_foxglove_protocol_and_advertises_the_topics() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let viz = Viz::open(None, Some(("127.0.0.1".into(), 0)))
        .await
        .unwrap();
    viz.boxes(
        "/fused",
        "fused",
        1_700_000_000_000_000,
        &[car(1.0, 1)],
        FUSED,
    );
    let port = viz.port().unwrap();
    let wait = std::time::Duration::from_secs(10);
    let mut s = tokio::time::timeout(wait, tokio::net::TcpStream::connect(("127.0.0.1", port)))
        .await
        .unwrap()
        .unwrap();
    let req = format!(
        "GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\
         Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
    );
    s.write_all(req.as_bytes()).await.unwrap();
    // the handshake response, up to its blank line
    let mut head = Vec::new();
    while !head.ends_with(b"\r\n\r\n") {
        let mut b = [0u8; 1];
        tokio::time::timeout(wait, s.read_exact(&mut b))
            .await
            .unwrap()
            .unwrap();
        head.push(b[0]);
    }
    let head = String::from_utf8_lossy(&head).to_string();
    assert!(head.starts_with("HTTP/1.1 101"), "{head}");
    assert!(
        head.to_lowercase()
            .contains("sec-websocket-protocol: foxglove.sdk.v1"),
        "{head}"
    );
    // text frames: serverInfo, then the advertisement of the channels logged so far
    let mut topics = Vec::new();
    while !topics.contains(&"/fused".to_string()) {
        let (op, payload) = tokio::time::timeout(wait, read_frame(&mut s))
            .await
            .unwrap();
        if op != 1 {
            continue;
        }
        let v: serde_json::Value = serde_json::from_slice(&payload).unwrap();
        if v["op"] == "advertise" {
            for c in v["channels"].as_array().unwrap() {
                topics.push(c["topic"].as_str().unwrap().to_string());
            }
        }
    }
    assert!(topics.contains(&"/stats".to_string()), "{topics:?}");
    viz.close().unwrap();
}
