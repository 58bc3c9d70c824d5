//! Scripted events in a run over loopback Zenoh: an agent that leaves stops sending and the
//! windows complete without it, a link change shows in the latency, a clock jump is rejected as
//! the ingest's clock tolerance says.

use v2x_sim::run::run_local;
use v2x_sim::scenario::Scenario;
use v2x_tests::{scenario_toml, within};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scripted_run_shows_each_event() {
    let mut toml = scenario_toml("timeline-events", &["mild"], 3, 4.0, 1.0, "csba-wls+");
    toml.push_str(
        r#"
[[events]]
at_s = 1.0
target = "a1"
action = "leave"

[[events]]
at_s = 1.0
target = "a0"
action = "link"
latency_ms = 150.0

[[events]]
at_s = 3.5
target = "a2"
action = "clock_jump"
jump_ms = 5000.0
"#,
    );
    let scenario = Scenario::parse(&toml, "timeline-events", None).unwrap();
    let gt = scenario.dataset.data_args().load().unwrap();
    let (summary, _) = within(90, "the scripted run", run_local(&scenario, &gt))
        .await
        .unwrap();
    // a1 sent its first second only: 10 of 40 captures.
    assert_eq!(summary.counts["a1"].sent, 10, "{:?}", summary.counts["a1"]);
    assert_eq!(summary.counts["a0"].sent, 40);
    // Every frame a2 stamped 5 s ahead (3.5 s to 4 s) is rejected, none before.
    let rejected = summary.counts["a2"].clock_rejected;
    assert!(
        (4..=5).contains(&rejected),
        "a2: {rejected} frames rejected"
    );
    assert_eq!(summary.counts["a0"].clock_rejected, 0);
    // Windows after a1 left complete without waiting for it: only a2's last half second,
    // whose frames were rejected while it stayed live, closes by deadline.
    assert!(summary.windows >= 38, "{} windows", summary.windows);
    assert!(
        summary.windows_incomplete <= 6,
        "{} windows incomplete",
        summary.windows_incomplete
    );
    // From 1 s on, every window waits for a0's frames, 150 ms late.
    let p50 = summary.e2e_latency_ms.p50_ms.unwrap();
    assert!((140.0..400.0).contains(&p50), "end-to-end p50 {p50} ms");
}
