//! Agents that send ETSI CPMs (docs/cpm.md) beside agents that send frames, over loopback
//! Zenoh: the fuser reads both through the same checks.

use v2x_agent::now_us;
use v2x_cpm::Geo;
use v2x_fuser::node::NodeConfig;
use v2x_protocol::net::cpm_encoding;
use v2x_protocol::{keys, AgentKind};
use v2x_sim::run::free_port;
use v2x_tests::fuser::{
    connect, frame, joined, listen, next_fused, next_t, spawn_fuser_with, stats, wait_live,
    wait_matching,
};
use v2x_tests::within;

/// Munich: far from the map origin's default, so a fuser reading with another origin would not
/// find the boxes where they are.
const MUNICH: Geo = Geo {
    lat_deg: 48.1374,
    lon_deg: 11.5755,
};

#[tokio::test(flavor = "multi_thread")]
async fn a_cpm_agent_and_a_frame_agent_fuse_together() {
    let ns = "cpm";
    let port = free_port().unwrap();
    let mut cfg = NodeConfig::new(ns, "csba-wls+".parse().unwrap());
    cfg.max_wait_ms = 2000.0;
    cfg.map_origin = MUNICH;
    let (stop, mut fused, task) = spawn_fuser_with(listen(port).await, cfg);
    let (sa, sb) = (connect(port).await, connect(port).await);
    let mut a = joined(&sa, ns, "a", AgentKind::Vehicle, 1)
        .await
        .sending_cpm(MUNICH);
    let mut b = joined(&sb, ns, "b", AgentKind::Infrastructure, 2).await;
    wait_live(&sa, ns, &["a", "b"]).await;
    let mut last = 0;
    for _ in 0..2 {
        let t = next_t(&mut last);
        a.send(frame(t)).unwrap();
        b.send(frame(t)).unwrap();
        let f = next_fused(&mut fused).await;
        assert_eq!(f.provenance.agents, vec!["a", "b"]);
        assert!(f.provenance.complete);
        // Two cars at x = 10 and 30 m, each seen by both agents, one of them through a CPM.
        let mut xs: Vec<f64> = f.frame.detections.iter().map(|d| d.center[0]).collect();
        xs.sort_by(f64::total_cmp);
        assert_eq!(xs.len(), 2, "{xs:?}");
        assert!(
            (xs[0] - 10.0).abs() < 0.01 && (xs[1] - 30.0).abs() < 0.01,
            "{xs:?}"
        );
    }
    stop.send(()).unwrap();
    let stats = within(10, "fuser shutdown", task).await.unwrap();
    let (sa_, sb_) = (&stats.agents["a"], &stats.agents["b"]);
    assert_eq!((sa_.invalid, sa_.fused, sb_.fused), (0, 2, 2));
    assert_eq!(
        (sa_.unnamed, sa_.objects),
        (0, 4),
        "every car of the CPMs has its class"
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn a_cpm_is_checked_as_a_frame_is() {
    let ns = "cpmbad";
    let port = free_port().unwrap();
    let mut cfg = NodeConfig::new(ns, "csba-wls+".parse().unwrap());
    cfg.max_wait_ms = 300.0;
    cfg.map_origin = MUNICH;
    let (stop, mut fused, task) = spawn_fuser_with(listen(port).await, cfg);
    let s = connect(port).await;
    let publisher = s
        .declare_publisher(keys::detections(ns, "x"))
        .encoding(cpm_encoding())
        .await
        .unwrap();
    wait_matching(&publisher).await;
    let cpm = |agent: &str, t: u64| {
        let mut f = frame(t);
        f.agent = agent.into();
        v2x_cpm::encode(&f, &MUNICH).unwrap()
    };
    let t = now_us();
    publisher.put(vec![0xde, 0xad, 0xbe, 0xef]).await.unwrap(); // not a CPM
    publisher.put(cpm("mallory", t)).await.unwrap(); // another station's
    publisher.put(cpm("x", t)).await.unwrap();
    publisher.put(cpm("x", t)).await.unwrap(); // the same message again
    let f = next_fused(&mut fused).await;
    assert_eq!(f.provenance.agents, vec!["x"]);
    assert_eq!(f.frame.detections.len(), 2);
    let v = stats(&s, ns).await;
    let x = &v["agents"]["x"];
    assert_eq!(
        (
            &x["frames_in"],
            &x["invalid"],
            &x["wrong_agent"],
            &x["duplicate"],
            &x["fused"]
        ),
        (&4.into(), &1.into(), &1.into(), &1.into(), &1.into()),
        "{x}"
    );
    stop.send(()).unwrap();
    within(10, "fuser shutdown", task).await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scenario_agent_sends_cpms_and_its_payload_is_their_size() {
    // The default scenario, 6 s at twice real time, its vehicle sending CPMs.
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/default.toml");
    let toml = std::fs::read_to_string(path)
        .unwrap()
        .replace(
            "duration_s = 20.0",
            "duration_s = 6.0\nmap_origin = [48.1374, 11.5755]",
        )
        .replace("speed = 1.0", "speed = 2.0")
        .replace("namespace = \"default\"", "namespace = \"cpmrun\"")
        .replace("noise = \"mild\"", "noise = \"mild\"\ncpm = true");
    let s = v2x_sim::scenario::Scenario::parse(&toml, "cpmrun", None).unwrap();
    assert!(s.agents[0].cpm && !s.agents[1].cpm);
    let gt = s.dataset.data_args().load().unwrap();
    let (summary, _) = within(90, "the run", v2x_sim::run::run_local(&s, &gt))
        .await
        .unwrap();
    assert_eq!(summary.windows_incomplete, 0);
    let veh = &summary.bandwidth["veh"];
    let rsu = &summary.bandwidth["rsu"];
    // What the vehicle put on the air is the CPMs the agent counts; the roadside's frames are
    // smaller than their CPMs.
    assert_eq!(Some(veh.payload_bytes_per_frame), veh.cpm_bytes_per_frame);
    assert!(rsu.payload_bytes_per_frame < rsu.cpm_bytes_per_frame.unwrap());
    assert!(summary.fused.recall.unwrap() > 0.9, "{:?}", summary.fused);
}
