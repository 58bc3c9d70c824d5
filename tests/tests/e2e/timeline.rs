//! Scripted events in a run over loopback Zenoh: an agent that leaves stops sending and the
//! windows complete without it, a link change shows in the latency, a clock jump is rejected as
//! the ingest's clock tolerance says.

use v2x_sim::run::{run_local, series, Schedule};
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
    let (summary, outcome) = within(90, "the scripted run", run_local(&scenario, &gt))
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

    // The per-second series shows the same, second by second.
    let schedule = Schedule::of(&gt, scenario.duration_s);
    let tl = series::timeline(&scenario, &gt, &schedule, &outcome);
    assert_eq!(tl.seconds.len(), 4);
    let s = &tl.seconds;
    assert!(s[0].frames["a1"] >= 9, "{:?}", s[0]);
    assert_eq!((s[2].frames["a1"], s[3].frames["a1"]), (0, 0));
    assert!(s[0].e2e_p50_ms.unwrap() < 100.0, "{:?}", s[0]);
    assert!(s[2].e2e_p50_ms.unwrap() >= 140.0, "{:?}", s[2]);
    // a2's frames from 3.5 s on are rejected: half its frames of the last second are missing
    assert!(s[2].frames["a2"] >= 9, "{:?}", s[2]);
    assert!(s[3].frames["a2"] <= 5, "{:?}", s[3]);
    assert_eq!(tl.events.len(), 3);
    assert_eq!(tl.events[0].label, "a1 leave");
    let svg = v2x_sim::run::series_plot::svg(&tl);
    assert!(svg.contains("a1 leave") && svg.contains("a0 link") && svg.contains("a2 clock_jump"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fuser_restart_loses_its_downtime_and_fuses_again() {
    let mut toml = scenario_toml("timeline-restart", &["mild"], 2, 3.0, 1.0, "csba-wls+");
    toml.push_str(
        r#"
[[events]]
at_s = 1.0
target = "fuser"
action = "restart"
duration_s = 0.5
"#,
    );
    let scenario = Scenario::parse(&toml, "timeline-restart", None).unwrap();
    let gt = scenario.dataset.data_args().load().unwrap();
    let (summary, outcome) = within(90, "the run with a restart", run_local(&scenario, &gt))
        .await
        .unwrap();
    assert_eq!(outcome.restarts_us.len(), 1);
    // Down from 1.0 s to 1.5 s: about five windows lost, every other one fused.
    assert!(
        (22..=26).contains(&summary.windows),
        "{} windows",
        summary.windows
    );
    let schedule = Schedule::of(&gt, scenario.duration_s);
    let down = |t: &u64| {
        let s = (t - schedule.t0_us) as f64 / 1e6;
        (1.05..1.45).contains(&s)
    };
    assert!(
        !outcome.fused.keys().any(down),
        "no window fused while the fuser was down: {:?}",
        outcome.fused.keys().filter(|t| down(t)).collect::<Vec<_>>()
    );
    let after = outcome
        .fused
        .keys()
        .filter(|t| (**t - schedule.t0_us) as f64 / 1e6 >= 1.6)
        .count();
    assert!(after >= 13, "{after} windows after the restart");
    // The counters of both runs of the node add up.
    assert!(
        summary.counts["a0"].fused >= 22,
        "{:?}",
        summary.counts["a0"]
    );
    assert!(summary.e2e_latency_ms.p50_ms.is_some());
    let tl = series::timeline(&scenario, &gt, &schedule, &outcome);
    assert_eq!(tl.events[0].label, "fuser restart");
    assert!(tl.seconds[1].windows <= 6, "{:?}", tl.seconds[1]);
}
