//! Motion compensation over loopback Zenoh: two agents capture a fast car 50 ms apart; the fuser
//! predicts both boxes to the window's latest capture, and the fused centre lands where the car
//! is then, as when both captured at once. Without compensation it lands halfway between.

use v2x_fuser::node::NodeConfig;
use v2x_fuser::time::motion::MotionParams;
use v2x_protocol::{AgentKind, Frame, Velocity};
use v2x_sim::run::free_port;
use v2x_tests::fuser::{
    connect, det, frame, joined, listen, next_fused, next_t, spawn_fuser_with, wait_live,
};
use v2x_tests::within;

/// The car: 20 m/s along x, at x = 10 m at `t0_us`.
fn car_x(t0_us: u64, t_us: u64) -> f64 {
    10.0 + 20.0 * (t_us as f64 - t0_us as f64) / 1e6
}

/// Runs 5 rounds in which agent `a` captures at t and agent `b` at t + `offset_us`; returns the
/// fused centre's x error against the car at each window's reference time.
async fn fused_errors(ns: &'static str, motion: Option<MotionParams>, offset_us: u64) -> Vec<f64> {
    let port = free_port().unwrap();
    let fs = listen(port).await;
    let mut cfg = NodeConfig::new(ns, "csba-wls+".parse().unwrap());
    cfg.window_ms = 150.0;
    cfg.steps.motion = motion;
    let mut fuser = spawn_fuser_with(fs, cfg);
    let mut agents = Vec::new();
    let mut sessions = Vec::new();
    for (i, name) in ["a", "b"].into_iter().enumerate() {
        let s = connect(port).await;
        let agent = joined(&s, ns, name, AgentKind::Vehicle, i as u64).await;
        agents.push(agent);
        sessions.push(s);
    }
    wait_live(&sessions[0], ns, &["a", "b"]).await;
    let mut last = 0;
    let t0 = next_t(&mut last);
    let mut errors = Vec::new();
    for _ in 0..5 {
        let t = next_t(&mut last);
        for (agent, (capture, dy)) in agents.iter_mut().zip([(t, 0.2), (t + offset_us, -0.2)]) {
            let mut d = det(car_x(t0, capture), 1);
            d.center[1] = dy;
            d.velocity = Some(Velocity {
                v: [20.0, 0.0],
                std: [0.5, 0.5],
            });
            agent
                .send(Frame {
                    detections: vec![d],
                    ..frame(capture)
                })
                .unwrap();
        }
        let f = next_fused(&mut fuser.1).await;
        assert_eq!(
            f.provenance.agents,
            vec!["a", "b"],
            "both captures in one window"
        );
        assert_eq!(
            f.frame.capture_us,
            t + offset_us,
            "t_ref is the latest capture"
        );
        let d = &f.frame.detections;
        assert_eq!(d.len(), 1, "associated: {d:?}");
        assert!(d[0].center[1].abs() < 0.02, "{:?}", d[0].center);
        if motion.is_some() {
            let v = d[0].velocity.as_ref().expect("a fused velocity");
            assert!((v.v[0] - 20.0).abs() < 0.05 && v.std[0] < 0.5, "{v:?}");
        }
        errors.push(d[0].center[0] - car_x(t0, t + offset_us));
    }
    fuser.0.send(()).unwrap();
    within(30, "fuser shutdown", fuser.2).await.unwrap();
    errors
}

#[tokio::test(flavor = "multi_thread")]
async fn a_fast_car_seen_50_ms_apart_is_fused_where_it_is() {
    let on = Some(MotionParams::default());
    let sync = fused_errors("motion-sync", on, 0).await;
    let compensated = fused_errors("motion-comp", on, 50_000).await;
    let raw = fused_errors("motion-raw", None, 50_000).await;
    // Synchronous and compensated: on the car, within the wire's centimetre quantization.
    for e in sync.iter().chain(&compensated) {
        assert!(e.abs() < 0.02, "sync {sync:?} compensated {compensated:?}");
    }
    // Uncompensated: the mean of where the car was 50 ms ago (1 m behind) and where it is.
    for e in &raw {
        assert!((e + 0.5).abs() < 0.02, "{raw:?}");
    }
}
