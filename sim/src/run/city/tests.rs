use super::*;
use crate::run::roles::WindowRecord;
use v2x_protocol::Detection;

fn window(agents: &[&str], objects: &[u64], complete: bool, e2e_ms: f64) -> WindowRecord {
    WindowRecord {
        agents: agents.iter().map(|s| s.to_string()).collect(),
        objects: objects.to_vec(),
        complete,
        e2e_ms,
        flagged: Vec::new(),
    }
}

fn boxes(xs: &[f64]) -> Vec<Detection> {
    xs.iter()
        .map(|&x| Detection {
            center: [x, 0.0, 0.0],
            ..Default::default()
        })
        .collect()
}

#[test]
fn regions_join_by_reference_time() {
    let mut a = FuserOutcome {
        reached_us: 900,
        ..Default::default()
    };
    a.fused.insert(100, boxes(&[1.0, 2.0]));
    a.windows
        .insert(100, window(&["veh", "rsu"], &[2, 1], true, 10.0));
    a.stats.windows = 1;
    a.stats.fused_objects = 2;
    a.stats.fusion_samples = vec![1.0];
    let mut b = FuserOutcome {
        reached_us: 800,
        ..Default::default()
    };
    b.fused.insert(100, boxes(&[150.0]));
    b.fused.insert(200, boxes(&[160.0]));
    b.windows.insert(100, window(&["rsu"], &[1], true, 30.0));
    b.windows.insert(200, window(&["rsu"], &[1], false, 20.0));
    b.stats.windows = 2;
    b.stats.fused_objects = 2;
    b.stats.captures_incomplete = 1;
    b.stats.fusion_samples = vec![3.0, 5.0];
    let all = join(vec![a, b]);
    let xs = |t: u64| {
        all.fused[&t]
            .iter()
            .map(|d| d.center[0])
            .collect::<Vec<_>>()
    };
    assert_eq!(xs(100), vec![1.0, 2.0, 150.0]);
    assert_eq!(xs(200), vec![160.0]);
    assert_eq!(
        all.windows[&100],
        window(&["veh", "rsu"], &[2, 2], true, 30.0)
    );
    assert_eq!(all.stats.windows, 2, "one window per reference time");
    assert_eq!(all.stats.windows_incomplete, 1);
    assert_eq!(all.stats.fused_objects, 4);
    assert_eq!(all.stats.captures_incomplete, 1);
    assert_eq!(all.reached_us, 800);
    assert_eq!(all.stats.fusion_latency_ms.max_ms, Some(5.0));
    assert_eq!(all.stats.e2e_latency_ms.max_ms, Some(30.0));
}
