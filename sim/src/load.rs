//! `v2x-sim load`: the fuser under load. N agents each publish M objects at a fixed rate over
//! loopback Zenoh to one fuser, all in this process; the report gives the fusion latency (window
//! close to publish) and end-to-end latency percentiles, for the first and second half of the run
//! (a growing backlog shows as the second half being slower), open windows at the end, the
//! process's CPU use and its resident memory at the start and end.

use crate::noise::mix;
use crate::run::free_port;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use std::time::{Duration, Instant};
use v2x_agent::{now_us, Agent, Link};
use v2x_fuser::node::{self, Latency, NodeConfig};
use v2x_fuser::Method;
use v2x_protocol::net::{open_session, ZenohArgs};
use v2x_protocol::{wrap_angle, AgentKind, Class, Detection, Frame, NoiseProfile};

/// What to run.
#[derive(clap::Args, Clone, Debug)]
pub struct LoadArgs {
    /// Number of agents.
    #[arg(long, default_value_t = 16)]
    pub agents: usize,
    /// Objects each agent sees per frame.
    #[arg(long, default_value_t = 100)]
    pub objects: usize,
    /// Frames per second.
    #[arg(long, default_value_t = 10.0)]
    pub hz: f64,
    /// Length of the run (s).
    #[arg(long, default_value_t = 30.0)]
    pub seconds: f64,
    /// Fusion method.
    #[arg(long, default_value = "csba-wls+")]
    pub method: Method,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// The load report.
#[derive(Clone, Debug, Serialize)]
pub struct LoadReport {
    /// Agents.
    pub agents: usize,
    /// Objects per agent frame.
    pub objects: usize,
    /// Frames per second.
    pub hz: f64,
    /// Frames each agent sent.
    pub frames_per_agent: usize,
    /// Windows fused.
    pub windows: u64,
    /// Windows closed by deadline with an agent missing.
    pub windows_incomplete: u64,
    /// Fusion latency over the whole run.
    pub fusion_latency_ms: Latency,
    /// Fusion latency, first half of the windows.
    pub fusion_latency_first_half_ms: Latency,
    /// Fusion latency, second half of the windows.
    pub fusion_latency_second_half_ms: Latency,
    /// Capture to fused publish.
    pub e2e_latency_ms: Latency,
    /// Windows still open at the end.
    pub open_windows_at_end: usize,
    /// CPU time of the whole process (agents, Zenoh and fuser) over wall time, in percent of one core.
    pub cpu_percent: f64,
    /// Resident memory after start-up (MiB).
    pub rss_start_mib: f64,
    /// Resident memory at the end (MiB).
    pub rss_end_mib: f64,
}

fn cpu_seconds() -> f64 {
    // utime + stime of this process, from /proc/self/stat (fields 14 and 15, in clock ticks).
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let after = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

fn rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| {
            s.split_whitespace()
                .nth(1)
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(0.0, |pages| pages * 4096.0 / (1024.0 * 1024.0))
}

fn scene(objects: usize, t: f64, seed: u64) -> Vec<(Class, [f64; 3], [f64; 3], f64)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let classes = [
        Class::Car,
        Class::Car,
        Class::Car,
        Class::Pedestrian,
        Class::Barrier,
        Class::Truck,
    ];
    (0..objects)
        .map(|_| {
            let class = classes[rng.gen_range(0..classes.len())];
            let r = 60.0 * rng.gen::<f64>().sqrt();
            let a = rng.gen::<f64>() * std::f64::consts::TAU;
            let v = rng.gen_range(0.0..10.0);
            let yaw = rng.gen_range(-3.1..3.1);
            let (s, c) = f64::sin_cos(yaw);
            (
                class,
                [r * a.cos() + v * c * t, r * a.sin() + v * s * t, 1.0],
                class.typical_size(),
                yaw,
            )
        })
        .collect()
}

/// Runs the load test.
pub async fn run(args: &LoadArgs) -> anyhow::Result<LoadReport> {
    let port = free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let fuser_session =
        open_session(&ZenohArgs::loopback(std::slice::from_ref(&endpoint), &[])).await?;
    let ns = "load";
    let mut cfg = NodeConfig::new(ns, args.method);
    cfg.window_ms = 1000.0 / args.hz;
    cfg.max_wait_ms = 100.0;
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let fuser = tokio::spawn(async move {
        let r = node::run(&fuser_session, cfg, |_| {}, async {
            let _ = stop_rx.await;
        })
        .await;
        let _ = fuser_session.close().await;
        r
    });
    let mut sessions = Vec::new();
    let mut agents = Vec::new();
    for i in 0..args.agents {
        let s = open_session(&ZenohArgs::loopback(&[], std::slice::from_ref(&endpoint))).await?;
        let kind = if i % 4 == 1 {
            AgentKind::Infrastructure
        } else {
            AgentKind::Vehicle
        };
        agents.push(
            Agent::start(&s, ns, &format!("a{i:02}"), kind, Link::default(), i as u64).await?,
        );
        sessions.push(s);
    }
    for a in &agents {
        a.wait_for_subscriber(Duration::from_secs(30)).await?;
    }
    // Let liveliness settle so that windows close on completion.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let frames = (args.seconds * args.hz).round() as usize;
    let period = Duration::from_secs_f64(1.0 / args.hz);
    let noise = NoiseProfile::Mild.std();
    let rss_start = rss_mib();
    let cpu0 = cpu_seconds();
    let wall0 = Instant::now();
    let start = tokio::time::Instant::now();
    for k in 0..frames {
        tokio::time::sleep_until(start + period * k as u32).await;
        let t = k as f64 / args.hz;
        let truth = scene(args.objects, t, 11);
        let capture = now_us();
        for (i, agent) in agents.iter_mut().enumerate() {
            let mut rng = ChaCha8Rng::seed_from_u64(mix(5, i as u64, k as u64));
            let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
            let detections = truth
                .iter()
                .enumerate()
                .map(|(j, (class, c, s, yaw))| Detection {
                    class: *class,
                    center: std::array::from_fn(|d| c[d] + noise.pos[d] * g()),
                    size: std::array::from_fn(|d| (s[d] + noise.size[d] * g()).max(0.05)),
                    yaw: wrap_angle(yaw + noise.yaw * g()),
                    score: 0.9,
                    std: noise,
                    pos_cov: None,
                    velocity: None,
                    id: j as u32,
                })
                .collect();
            agent.send(Frame {
                agent: String::new(),
                kind: AgentKind::Vehicle,
                seq: 0,
                capture_us: capture,
                origin: [0.0; 3],
                detections,
            })?;
        }
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    let wall = wall0.elapsed().as_secs_f64();
    let cpu = cpu_seconds() - cpu0;
    let _ = stop_tx.send(());
    let stats = fuser.await??;
    let rss_end = rss_mib();
    drop(agents);
    for s in sessions {
        let _ = s.close().await;
    }
    Ok(LoadReport {
        agents: args.agents,
        objects: args.objects,
        hz: args.hz,
        frames_per_agent: frames,
        windows: stats.windows,
        windows_incomplete: stats.windows_incomplete,
        fusion_latency_ms: stats.fusion_latency_ms.clone(),
        fusion_latency_first_half_ms: Latency::of(
            &stats.fusion_samples[..stats.fusion_samples.len() / 2],
        ),
        fusion_latency_second_half_ms: Latency::of(
            &stats.fusion_samples[stats.fusion_samples.len() / 2..],
        ),
        e2e_latency_ms: stats.e2e_latency_ms.clone(),
        open_windows_at_end: stats.open_windows_at_stop,
        cpu_percent: 100.0 * cpu / wall,
        rss_start_mib: rss_start,
        rss_end_mib: rss_end,
    })
}
