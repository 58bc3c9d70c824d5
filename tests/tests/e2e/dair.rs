//! DAIR-V2X over Zenoh: the data's vehicle and roadside unit replayed at their recorded capture
//! times (the roadside 20 ms before the vehicle) through a live fuser, scored against the
//! cooperative labels.

use v2x_sim::run::{agent_captures, run_local, Schedule};
use v2x_sim::scenario::Scenario;
use v2x_tests::within;

fn scenario(ns: &str, offset: bool) -> Scenario {
    let root =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../truth/fixtures/dair/dair-v2x-c");
    let toml = format!(
        r#"namespace = "{ns}"
duration_s = 0.3
[dataset]
kind = "dair-v2x"
dataroot = "{}"
calibration_offset = {offset}
[fuser]
method = "csba-wls+"
max_wait_ms = 400.0
[[agents]]
name = "veh"
kind = "vehicle"
noise = "labels"
[[agents]]
name = "inf"
kind = "infrastructure"
noise = "labels"
"#,
        root.display()
    );
    Scenario::parse(&toml, ns, None).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn the_vehicle_and_the_roadside_fuse_live_at_their_own_capture_times() {
    let s = scenario("dair-live", true);
    let gt = s.dataset.data_args().load().unwrap();
    let schedule = Schedule::of(&gt, s.duration_s);
    assert_eq!(schedule.frames.len(), 3);
    let veh = agent_captures(&s, &gt, &schedule, 0);
    let inf = agent_captures(&s, &gt, &schedule, 1);
    assert_eq!(veh.len(), 3);
    assert!(
        veh.iter().zip(&inf).all(|(v, i)| v - i == 20_000),
        "{veh:?} {inf:?}"
    );

    let (summary, outcome) = within(90, "the DAIR-V2X run", run_local(&s, &gt))
        .await
        .unwrap();
    assert_eq!(summary.windows, 3, "both agents of each pair in one window");
    assert_eq!(summary.windows_incomplete, 0);
    assert_eq!(outcome.fused.len(), 3);
    // Car A (both sides), truck B (roadside only), van C (vehicle only) per frame: the fusion
    // finds all nine; the roadside's pedestrian is no cooperative class, its one false
    // positive a frame.
    assert_eq!(summary.fused.recall, Some(1.0));
    assert_eq!((summary.fused.tp, summary.fused.fp), (9, 3));
    assert!(
        summary.fused.all.m_ate.unwrap() < 0.01,
        "{:?}",
        summary.fused.all.m_ate
    );
    for name in ["veh", "inf"] {
        let a = &summary.agents[name];
        assert_eq!(a.tp, 6, "{name}: two of the three objects a frame");
    }
}

#[test]
fn the_example_scenario_reads_the_fixture() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/dair-v2x.toml");
    let s = Scenario::load(&path).unwrap();
    let d = s.dataset.data_args().load_dair().unwrap();
    assert_eq!(d.gt.frames.len(), 3);
    // Two agents, the vehicle first, and nothing else is a DAIR-V2X scenario.
    let text = std::fs::read_to_string(&path).unwrap();
    let three = format!("{text}\n[[agents]]\nname = \"x\"\nnoise = \"mild\"\n");
    let e = Scenario::parse(&three, "three", path.parent())
        .unwrap_err()
        .to_string();
    assert!(e.contains("DAIR-V2X has two agents"), "{e}");
    let timed = text.replace("name = \"inf\"", "name = \"inf\"\nhz = 20.0");
    let e = Scenario::parse(&timed, "timed", path.parent())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("inf: DAIR-V2X agents capture at their recorded times"),
        "{e}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn without_the_calibration_offset_the_shared_car_lands_apart() {
    let s = scenario("dair-nooffset", false);
    let gt = s.dataset.data_args().load().unwrap();
    let (summary, _) = within(90, "the DAIR-V2X run without offset", run_local(&s, &gt))
        .await
        .unwrap();
    // The roadside's boxes lie 0.58 m off: still matched within 2 m, with a translation error.
    assert_eq!(summary.fused.recall, Some(1.0));
    let m_ate = summary.fused.all.m_ate.unwrap();
    assert!(m_ate > 0.05, "{m_ate}");
}
