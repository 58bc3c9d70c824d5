//! Two and four agents and the fuser in one process over loopback Zenoh: the fused output scores
//! exactly as the offline fusion of the same (wire-quantized) detections, directly and through a
//! recorded results file read back by `eval`.

use v2x_protocol::{wire, Frame};
use v2x_sim::cli::{evaluate_file, EvalOptions, Evaluation, Match};
use v2x_sim::metrics::Accumulator;
use v2x_sim::run::{agent_view, recorded, run_local, Schedule};
use v2x_sim::scenario::Scenario;
use v2x_tests::{scenario_toml, tempdir, within};

async fn network_equals_offline(ns: &str, agents: usize, noises: &[&str]) {
    let scenario = Scenario::parse(
        &scenario_toml(ns, noises, agents, 3.0, 2.0, "csba-wls+"),
        ns,
        None,
    )
    .unwrap();
    let gt = scenario.dataset.data_args().load().unwrap();
    let (summary, outcome) = within(90, "the loopback run", run_local(&scenario, &gt))
        .await
        .unwrap();
    let schedule = Schedule::of(&gt, scenario.duration_s);
    assert_eq!(summary.frames_scheduled, 30);
    assert_eq!(summary.windows, 30, "one fused window per frame");
    assert_eq!(summary.windows_incomplete, 0);
    assert_eq!(
        outcome.fused.len(),
        30,
        "every window maps back to its frame"
    );

    // Offline: the same detections, quantized as the wire does, fused in the fuser's agent order.
    let mut order: Vec<usize> = (0..agents).collect();
    order.sort_by_key(|&i| scenario.agents[i].name.clone());
    let method = scenario.method();
    let mut acc = Accumulator::new();
    for (k, &gi) in schedule.frames.iter().enumerate() {
        let t = gt.frames[gi].timestamp_us;
        let lists: Vec<_> = order
            .iter()
            .map(|&idx| {
                let noise = scenario.agents[idx].agent_noise();
                let (detections, origin) = agent_view(&scenario, &gt, &schedule, idx, k, t, &noise);
                let f = Frame {
                    agent: "x".into(),
                    kind: Default::default(),
                    seq: 0,
                    capture_us: 0,
                    origin,
                    detections,
                };
                wire::decode(&wire::encode(&f).unwrap()).unwrap().detections
            })
            .collect();
        acc.add_frame(&gt.frames[gi].objects, &method.fuse(&lists));
    }
    let offline = acc.summary();
    assert_eq!(summary.fused, offline, "network and offline fusion differ");
    assert!(offline.precision.unwrap() > 0.99 && offline.recall.unwrap() > 0.99);

    // Through a recorded file, as `v2x-sim run --record` + `v2x-sim eval` do.
    let dir = tempdir(ns);
    let path = dir.join("fused.json");
    v2x_protocol::nuscenes_json::write_results(
        &path,
        &recorded(&gt, &schedule, &outcome),
        &gt.tokens,
    )
    .unwrap();
    let opts = EvalOptions {
        how: Match::Id,
        ..Default::default()
    };
    let (m, _) = evaluate_file(&gt, &path, &opts).unwrap();
    let Evaluation::Id(m) = m else {
        panic!("matched by id")
    };
    assert_eq!((m.tp, m.fp, m.fn_), (offline.tp, offline.fp, offline.fn_));
    for (a, b) in [
        (m.all.m_ate, offline.all.m_ate),
        (m.all.m_ase, offline.all.m_ase),
        (m.all.m_aoe, offline.all.m_aoe),
    ] {
        assert!((a.unwrap() - b.unwrap()).abs() < 1e-9, "{a:?} vs {b:?}");
    }
    // Bandwidth was measured on the wire, and is more than the payload.
    for b in summary.bandwidth.values() {
        assert_eq!(b.frames, 30);
        let wire = b.wire_bytes_per_frame.unwrap();
        assert!(
            wire > b.payload_bytes_per_frame,
            "{wire} vs {}",
            b.payload_bytes_per_frame
        );
        // About 13 bytes a box, plus a 4-byte ground-truth id and a velocity (about 2.5).
        assert!(b.payload_bytes_per_object < 24.0, "{b:?}");
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn two_agents_over_loopback_score_as_offline() {
    network_equals_offline("e2e-two", 2, &["mild", "large"]).await;
}

#[tokio::test(flavor = "multi_thread")]
async fn four_agents_over_loopback_score_as_offline() {
    network_equals_offline("e2e-four", 4, &["mild", "moderate", "large", "moderate"]).await;
}

#[tokio::test(flavor = "multi_thread")]
async fn a_secure_run_scores_as_the_plain_one() {
    let plain = scenario_toml("e2e-plain", &["mild", "large"], 2, 3.0, 2.0, "csba-wls+");
    let secure = format!(
        "{}\n[security]\nmode = \"mtls\"\n",
        plain.replace("e2e-plain", "e2e-secure")
    );
    let mut summaries = Vec::new();
    for (name, text) in [("plain", plain), ("secure", secure)] {
        let scenario = Scenario::parse(&text, name, None).unwrap();
        let gt = scenario.dataset.data_args().load().unwrap();
        let (summary, _) = within(90, "the loopback run", run_local(&scenario, &gt))
            .await
            .unwrap();
        assert_eq!(summary.windows, 30, "{name}");
        summaries.push(summary);
    }
    assert_eq!(summaries[0].security.mode, "plain");
    assert_eq!(summaries[1].security.mode, "mtls");
    assert_eq!(
        summaries[0].fused, summaries[1].fused,
        "the same fused output"
    );
    for (agent, b) in &summaries[1].bandwidth {
        let p = &summaries[0].bandwidth[agent];
        assert_eq!(b.payload_bytes_per_frame, p.payload_bytes_per_frame);
        // TLS records cost bytes on the wire: the relay sees them, Zenoh's counters do not.
        let tls = b.socket_bytes_per_frame.unwrap() - b.wire_bytes_per_frame.unwrap();
        let plain = p.socket_bytes_per_frame.unwrap() - p.wire_bytes_per_frame.unwrap();
        assert!(
            tls > plain + 10.0,
            "{agent}: TLS adds {tls} B/frame, plain {plain}"
        );
    }
}
