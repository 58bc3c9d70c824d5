//! Bandwidth from Zenoh's own statistics in a run over loopback: what each agent's session wrote
//! agrees with the payload it published plus a per-message overhead, with what the fuser received,
//! and with the bytes the TCP relay saw; the per-second series adds up to the run's total.

use v2x_sim::run::{run_local, series, Schedule};
use v2x_sim::scenario::Scenario;
use v2x_tests::{scenario_toml, within};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn zenoh_counts_the_payload_and_its_framing() {
    let toml = scenario_toml(
        "traffic-stats",
        &["mild", "large"],
        2,
        3.0,
        1.0,
        "csba-wls+",
    );
    let scenario = Scenario::parse(&toml, "traffic-stats", None).unwrap();
    let gt = scenario.dataset.data_args().load().unwrap();
    let (summary, outcome) = within(60, "the run", run_local(&scenario, &gt))
        .await
        .unwrap();
    for (name, b) in &summary.bandwidth {
        let c = &summary.counts[name];
        assert_eq!(c.sent, 30, "{name}: {c:?}");
        assert_eq!(b.frames, 30, "{name}");
        assert_eq!(b.zenoh_frames, Some(30), "{name}");
        // Zenoh counts exactly the payload the agent published, and the fuser received it all.
        assert_eq!(
            b.zenoh_payload_bytes_per_frame,
            Some(b.payload_bytes_per_frame),
            "{name}: {b:?}"
        );
        assert_eq!(
            b.received_payload_bytes_per_frame,
            Some(b.payload_bytes_per_frame),
            "{name}: {b:?}"
        );
        // The wire carries the payload plus Zenoh's framing and session traffic: a few tens of
        // bytes per message.
        let wire = b.wire_bytes_per_frame.unwrap();
        let overhead = b.overhead_bytes_per_message.unwrap();
        assert!(
            (8.0..120.0).contains(&overhead),
            "{name}: overhead {overhead} B/message"
        );
        assert!(
            (wire - b.payload_bytes_per_frame - overhead).abs() < 1e-9,
            "{name}: one put per frame, so wire = payload + overhead: {b:?}"
        );
        // What the agent wrote is what the fuser read from its transport (peer mode: one each).
        let received = b.received_wire_bytes_per_frame.unwrap();
        assert!(
            (received - wire).abs() <= 0.02 * wire,
            "{name}: sent {wire} B/frame, received {received}"
        );
        // The relay sees Zenoh's bytes plus the session's opening handshake: at most a few
        // hundred bytes in all.
        let socket = b.socket_bytes_per_frame.unwrap();
        let extra = (socket - wire) * 30.0;
        assert!(
            (0.0..3000.0).contains(&extra),
            "{name}: relay {socket} B/frame, Zenoh {wire}"
        );
    }
    // Per key at the fuser: each agent's detections in; the fused output went nowhere, since
    // nobody subscribed to it in this run (Zenoh sends, and counts, only what a subscriber gets).
    let fused = &summary.fuser_keys[&v2x_protocol::keys::fused("traffic-stats")];
    assert_eq!(fused.tx.put_msgs, 0, "{fused:?}");
    for name in summary.bandwidth.keys() {
        let k = &summary.fuser_keys[&v2x_protocol::keys::detections("traffic-stats", name)];
        assert_eq!(k.rx.put_msgs, 30, "{name}: {k:?}");
    }
    // The fuser sampled its traffic each second; the series adds up to what it received.
    let schedule = Schedule::of(&gt, scenario.duration_s);
    let tl = series::timeline(&scenario, &gt, &schedule, &outcome);
    for (name, b) in &summary.bandwidth {
        let total = b.received_payload_bytes_per_frame.unwrap() * 30.0;
        let by_second: u64 = tl.seconds.iter().map(|s| s.payload_bytes[name]).sum();
        assert!(
            by_second as f64 >= 0.9 * total && by_second as f64 <= total + 1e-9,
            "{name}: {by_second} of {total} payload bytes in the series"
        );
        let wire: u64 = tl
            .seconds
            .iter()
            .filter_map(|s| s.wire_bytes.get(name))
            .sum();
        assert!(
            wire >= by_second,
            "{name}: wire {wire} < payload {by_second}"
        );
        assert!(
            tl.seconds.iter().all(|s| s.objects[name] > 0),
            "{name}: {:?}",
            tl.seconds
        );
    }
}
