//! Regional fusers over two meshed Zenoh routers: agents publish per tile, each tile's fuser is a
//! client of its own router, and together the regions publish every object once per window,
//! the one crossing the border included, as one fuser fuses them; their tracks hand over at the
//! border, so every object keeps one tracking id.

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;
use v2x_agent::{now_us, Agent, Link};
use v2x_fuser::intake::region::Region;
use v2x_fuser::node::{self, Fused, NodeConfig};
use v2x_protocol::keys::FuserKeys;
use v2x_protocol::net::{open_session, ZenohArgs};
use v2x_protocol::tiles::{Tile, Tiling};
use v2x_protocol::{AgentKind, Detection, Frame};
use v2x_sim::run::free_port;
use v2x_tests::fuser::{det, endpoint, spawn_fuser_with};
use v2x_tests::within;

const NS: &str = "regions";

fn router(listen: u16, connect: Option<u16>) -> ZenohArgs {
    ZenohArgs {
        mode: Some("router".into()),
        listen: vec![endpoint(listen)],
        connect: connect.map(endpoint).into_iter().collect(),
        no_multicast_scouting: true,
        zenoh_config: None,
    }
}

fn client(port: u16) -> ZenohArgs {
    ZenohArgs {
        mode: Some("client".into()),
        connect: vec![endpoint(port)],
        ..Default::default()
    }
}

fn at(x: f64, y: f64) -> Detection {
    let mut d = det(x, 0);
    d.center[1] = y;
    d
}

/// The scene at step k, as one agent sees it (`off` shifts its copies): a car driving across
/// the border x = 100 at y = 50, parked cars on both sides and one on each side of the border.
fn scene(k: usize, off: f64) -> Vec<Detection> {
    vec![
        at(80.0 + 2.0 * k as f64 + off, 50.0 - off),
        at(50.0 + off, 20.0),
        at(150.0 - off, 20.0 + off),
        at(99.0 + off, 80.0),
        at(101.5 - off, 80.0 + off),
    ]
}

async fn live(session: &zenoh::Session, tile: Tile, want: &[&str]) {
    let key = FuserKeys::of(NS, Some(tile)).stats;
    within(20, &format!("fuser {tile} sees {want:?}"), async {
        loop {
            if let Ok(v) = node::query_stats_at(session, &key, Duration::from_secs(2)).await {
                let live: Vec<&str> = v["live"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_str().unwrap())
                    .collect();
                if live == want {
                    return;
                }
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn two_regions_over_two_routers_fuse_every_object_once() {
    let (pa, pb) = (free_port().unwrap(), free_port().unwrap());
    let ra = open_session(&router(pa, None)).await.unwrap();
    let rb = open_session(&router(pb, Some(pa))).await.unwrap();
    let tiling = Tiling::new(100.0).unwrap();
    let method: v2x_fuser::Method = "csba-wls+".parse().unwrap();
    let tiles = [Tile { x: 0, y: 0 }, Tile { x: 1, y: 0 }];
    let mut fusers = Vec::new();
    for (tile, port) in tiles.iter().zip([pa, pb]) {
        let mut cfg = NodeConfig::new(NS, method);
        cfg.steps.motion = None;
        cfg.max_wait_ms = 300.0;
        cfg.track = Some(Default::default());
        cfg.region = Some(Region {
            tiling,
            tile: *tile,
            halo_m: 30.0,
        });
        let s = open_session(&client(port)).await.unwrap();
        fusers.push(spawn_fuser_with(s, cfg));
    }
    // The vehicle is a client of router A, the roadside unit of router B.
    let (sv, sr) = (
        open_session(&client(pa)).await.unwrap(),
        open_session(&client(pb)).await.unwrap(),
    );
    let mut veh = Agent::start(&sv, NS, "veh", AgentKind::Vehicle, Link::default(), 1)
        .await
        .unwrap()
        .with_tiling(tiling);
    let mut rsu = Agent::start(
        &sr,
        NS,
        "rsu",
        AgentKind::Infrastructure,
        Link::default(),
        2,
    )
    .await
    .unwrap()
    .with_tiling(tiling);
    for a in [&veh, &rsu] {
        for t in tiles {
            a.wait_for_subscriber_in(t, Duration::from_secs(20))
                .await
                .unwrap();
        }
    }
    for t in tiles {
        live(&sv, t, &["rsu", "veh"]).await;
    }
    // A warm-up capture: an agent's first frame in a region may come after its window closed
    // (a regional fuser awaits an agent once it has heard from it).
    let mut last = now_us();
    for a in [&mut veh, &mut rsu] {
        a.send(Frame {
            agent: String::new(),
            kind: AgentKind::Vehicle,
            seq: 0,
            capture_us: last,
            origin: [0.0; 3],
            detections: scene(0, 0.0),
        })
        .unwrap();
    }
    let warm_up = last;
    tokio::time::sleep(Duration::from_millis(100)).await;
    let steps = 20;
    let mut sent = Vec::new();
    for k in 0..steps {
        last = now_us().max(last + 100_000);
        let frame = |dets| Frame {
            agent: String::new(),
            kind: AgentKind::Vehicle,
            seq: 0,
            capture_us: last,
            origin: [0.0; 3],
            detections: dets,
        };
        let (a, b) = (scene(k, 0.3), scene(k, -0.3));
        sent.push((last, vec![a.clone(), b.clone()]));
        veh.send(frame(a)).unwrap();
        rsu.send(frame(b)).unwrap();
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    tokio::time::sleep(Duration::from_millis(400)).await;
    let mut by_time: BTreeMap<u64, Vec<Detection>> = BTreeMap::new();
    let mut tracks: BTreeMap<u64, Vec<Detection>> = BTreeMap::new();
    let mut stats = Vec::new();
    for (stop, mut rx, task) in fusers {
        stop.send(()).unwrap();
        let s = within(20, "fuser stops", task).await.unwrap();
        while let Ok(f) = rx.try_recv() {
            let f: Fused = f;
            if f.frame.capture_us == warm_up {
                continue;
            }
            assert!(f.provenance.complete, "window at {}", f.frame.capture_us);
            tracks
                .entry(f.frame.capture_us)
                .or_default()
                .extend(f.tracks.unwrap_or_default());
            by_time
                .entry(f.frame.capture_us)
                .or_default()
                .extend(f.frame.detections);
        }
        stats.push(s);
    }
    for (s, t) in stats.iter().zip(tiles) {
        assert_eq!(s.region.as_deref(), Some(t.to_string().as_str()));
        assert_eq!(s.captures_incomplete, 0);
        assert_eq!(s.inbox_overflow, 0);
        // At most the warm-up's second frame came after its window.
        let late = s.rejected.get("late").copied().unwrap_or(0);
        assert!(
            late <= 1 && s.rejected.len() <= late as usize,
            "{:?} {:#?}",
            s.rejected,
            s.agents
        );
        // Every capture reached both fusers (both tiles are in each one's halo).
        assert!(s.agents["veh"].accepted >= steps as u64);
        assert!(s.agents["rsu"].accepted >= steps as u64);
    }
    assert_eq!(by_time.len(), steps, "one window per capture");
    for (k, (t, agents)) in sent.iter().enumerate() {
        let got = &by_time[t];
        let car_x = 80.0 + 2.0 * k as f64;
        let near =
            |d: &&Detection| (d.center[0] - car_x).abs() < 1.0 && (d.center[1] - 50.0).abs() < 1.0;
        assert_eq!(
            got.iter().filter(near).count(),
            1,
            "step {k}: the moving car once"
        );
        // What one fuser makes of the same boxes, to the wire's precision.
        let mut single: Vec<[f64; 2]> = method
            .fuse(agents)
            .iter()
            .map(|d| [d.center[0], d.center[1]])
            .collect();
        let mut split: Vec<[f64; 2]> = got.iter().map(|d| [d.center[0], d.center[1]]).collect();
        single.sort_by(|a, b| a.partial_cmp(b).unwrap());
        split.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(split.len(), single.len(), "step {k}");
        for (a, b) in split.iter().zip(&single) {
            assert!(
                (a[0] - b[0]).abs() < 0.05 && (a[1] - b[1]).abs() < 0.05,
                "step {k}: {a:?} vs {b:?}"
            );
        }
    }
    // Tracks: each object under one id in both regions, the car crossing the border included,
    // and published by one region per window.
    let parked = [[50.0, 20.0], [150.0, 20.0], [99.0, 80.0], [101.5, 80.0]];
    let mut ids: BTreeMap<usize, BTreeSet<u32>> = BTreeMap::new();
    let mut sides = BTreeSet::new();
    for (t, list) in &tracks {
        let k = sent.iter().position(|(s, _)| s == t).unwrap();
        let car_x = 80.0 + 2.0 * k as f64;
        let mut once = BTreeSet::new();
        for d in list {
            let near =
                |[x, y]: [f64; 2]| (d.center[0] - x).abs() < 1.0 && (d.center[1] - y).abs() < 1.0;
            let place = if near([car_x, 50.0]) {
                sides.insert(d.center[0] >= 100.0);
                parked.len()
            } else {
                parked
                    .iter()
                    .position(|&p| near(p))
                    .unwrap_or_else(|| panic!("step {k}: a track at {:?}", d.center))
            };
            assert!(once.insert(place), "step {k}: {place:?} published twice");
            ids.entry(place).or_default().insert(d.id);
        }
    }
    assert_eq!(
        sides.len(),
        2,
        "the car is tracked on both sides of the border"
    );
    assert_eq!(ids.len(), 5, "{ids:?}");
    for (place, set) in &ids {
        assert_eq!(set.len(), 1, "{place:?} changed its tracking id: {set:?}");
    }
    let all: BTreeSet<u32> = ids.values().flatten().copied().collect();
    assert_eq!(all.len(), 5, "one id per object: {ids:?}");
    drop((veh, rsu));
    for s in [sv, sr, rb, ra] {
        s.close().await.unwrap();
    }
}
