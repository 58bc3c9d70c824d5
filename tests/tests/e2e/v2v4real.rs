//! V2V4Real over Zenoh: two real cars' detector boxes replayed by a scenario through a live
//! fuser that scores a detector's groups, as `v2x-fuser fuse --detector` does offline.

use v2x_sim::run::{run_local, Schedule};
use v2x_sim::scenario::Scenario;
use v2x_tests::within;

fn example() -> (std::path::PathBuf, Scenario) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/v2v4real.toml");
    let s = Scenario::load(&path).unwrap();
    (path, s)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn both_cars_replay_their_boxes_and_the_fuser_scores_them_as_a_detectors() {
    let (_, s) = example();
    let gt = s.dataset.data_args().load().unwrap();
    let schedule = Schedule::of(&gt, s.duration_s);
    // The fixture's first sequence: three frames, 100 ms apart.
    assert_eq!(schedule.frames.len(), 3);
    let (summary, outcome) = within(90, "the V2V4Real run", run_local(&s, &gt))
        .await
        .unwrap();
    assert_eq!(
        summary.windows, 3,
        "both cars' frames of each instant in one window"
    );
    assert_eq!(summary.windows_incomplete, 0);
    // Frame 0: the car both saw (0.9 and 0.6) and car 1's lone 0.7, each scored by its chance
    // of being real (above 0.99 and near 0.96); the ego car's 0.25 box 42 m out falls below
    // 0.2. Scores cross the wire in 1/255 steps.
    let first = outcome.fused.values().next().unwrap();
    let mut scores: Vec<f64> = first.iter().map(|d| d.score).collect();
    scores.sort_by(|a, b| b.total_cmp(a));
    assert_eq!(scores.len(), 2, "{scores:?}");
    assert!(scores[0] > 0.99 && scores[1] > 0.9, "{scores:?}");
    // Six labelled cars over the three frames: every fused box is one of them, frame 2's lone
    // 0.3 box of the sixth (20 m out) included.
    assert_eq!((summary.fused.tp, summary.fused.fp), (6, 0));
    assert_eq!(summary.fused.recall, Some(1.0));
}

#[test]
fn the_example_scenario_names_two_cars_at_their_own_times() {
    let (path, _) = example();
    let text = std::fs::read_to_string(&path).unwrap();
    let three = format!("{text}\n[[agents]]\nname = \"x\"\nnoise = \"mild\"\n");
    let e = Scenario::parse(&three, "three", path.parent())
        .unwrap_err()
        .to_string();
    assert!(e.contains("V2V4Real has two agents"), "{e}");
    let e = Scenario::parse(
        &text.replace("\"train\"", "\"dev\""),
        "split",
        path.parent(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("split 'dev'"), "{e}");
}
