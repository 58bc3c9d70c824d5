//! `v2x-sim load`: the fuser under load. N agents each publish M objects at a fixed rate over
//! loopback Zenoh to one fuser, all in this process; the report gives the fusion latency (window
//! close to publish) and end-to-end latency percentiles, for the first and second half of the run
//! (a growing backlog shows as the second half being slower), open windows at the end, the
//! process's CPU use and its resident memory at the start and end.
//!
//! `--regions K` spreads the same total load over 1, 2, ... K regional fusers behind a router
//! ([`run_regions`]); `--max-load` finds the largest load one fuser holds ([`run_max_load`]).

use crate::run::free_port;
use crate::seed::mix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use std::time::{Duration, Instant};
use v2x_agent::{now_us, Agent, Link};
use v2x_fuser::intake::region::Region;
use v2x_fuser::node::{self, Latency, NodeConfig};
use v2x_protocol::net::{open_session, ZenohArgs};
use v2x_protocol::tiles::{Tile, Tiling};
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
    /// The fusion method.
    #[command(flatten)]
    pub method: crate::cli::MethodArg,
    /// The report's format (table or JSON).
    #[command(flatten)]
    pub format: crate::cli::FormatArg,
    /// Scale-out instead: the same total load (agents x objects x rate) on 1, 2 and 4 (up to K)
    /// regional fusers behind a Zenoh router, the agents spread over four sites along an
    /// 800 m x 200 m strip and publishing per tile; reports fusion p99 and boxes fused per second
    /// for each configuration.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4))]
    pub regions: Option<u32>,
    /// Instead: the largest load one fuser holds, doubling the agents from --agents (at
    /// --objects and --hz) until fusion p99 reaches 50 ms or windows are lost.
    #[arg(long, conflicts_with = "regions")]
    pub max_load: bool,
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
    /// Bytes per agent frame, in the project's encoding and as CPMs.
    pub bytes: FrameBytes,
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

/// Where the agents of a run sit and who fuses them.
struct Layout {
    /// The fusers (one, or one per region).
    fusers: Vec<NodeConfig>,
    /// With regions: the tile grid the agents publish on (through a router).
    tiling: Option<Tiling>,
    /// Site centres; agent i sees the scene around site i mod the number of sites.
    sites: Vec<[f64; 2]>,
}

/// What one run measured.
struct Driven {
    stats: Vec<node::NodeStats>,
    frames: usize,
    wall_s: f64,
    cpu_percent: f64,
    rss_start_mib: f64,
    rss_end_mib: f64,
    bytes: FrameBytes,
}

/// What an agent's frame costs: its payload over the run, and the same boxes as ETSI CPMs in
/// the first frames (every frame of the load has the same fields, so the same size; counting
/// every frame would put the CPM encoder's time into the measured run).
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct FrameBytes {
    /// Mean payload bytes per frame published.
    pub payload_bytes_per_frame: f64,
    /// Mean bytes of the first frames' boxes as ETSI CPMs (docs/cpm.md).
    pub cpm_bytes_per_frame: f64,
}

/// The fuser of a load run: a window per capture period, every agent's boxes fused however
/// many (the load is the point).
fn fuser_config(args: &LoadArgs, ns: &str) -> anyhow::Result<NodeConfig> {
    let mut s = v2x_fuser::settings::FuserSettings {
        max_wait_ms: 100.0,
        ..Default::default()
    };
    s.fusion.method = args.method.method;
    s.fusion.window_ms = 1000.0 / args.hz;
    s.admission.max_objects_per_agent = s.admission.max_objects_per_agent.max(args.objects);
    s.node_config(ns)
        .map_err(|e| anyhow::anyhow!(e.on_command_line()))
}

/// Runs the load test.
pub async fn run(args: &LoadArgs) -> anyhow::Result<LoadReport> {
    let ns = "load";
    let layout = Layout {
        fusers: vec![fuser_config(args, ns)?],
        tiling: None,
        sites: vec![[0.0, 0.0]],
    };
    let d = drive(args, ns, layout).await?;
    let stats = &d.stats[0];
    Ok(LoadReport {
        agents: args.agents,
        objects: args.objects,
        hz: args.hz,
        frames_per_agent: d.frames,
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
        cpu_percent: d.cpu_percent,
        rss_start_mib: d.rss_start_mib,
        rss_end_mib: d.rss_end_mib,
        bytes: d.bytes,
    })
}

/// Side of one block of the scale-out strip (m): four blocks along x make the city.
pub const BLOCK_M: f64 = 200.0;

/// One configuration of the scale-out benchmark.
#[derive(Clone, Debug, Serialize)]
pub struct RegionRow {
    /// Regional fusers.
    pub fusers: usize,
    /// Their tile side (m).
    pub tile_m: f64,
    /// Boxes the agents sent per second (agents x objects x rate).
    pub input_boxes_per_s: f64,
    /// Fused boxes published per second, over every fuser.
    pub fused_boxes_per_s: f64,
    /// Windows fused, over every fuser.
    pub windows: u64,
    /// Of those, closed with an awaited agent missing.
    pub windows_incomplete: u64,
    /// Captures fused without every part.
    pub captures_incomplete: u64,
    /// Windows dropped or still open at the end, over every fuser.
    pub windows_lost: u64,
    /// Fusion latency over every fuser's windows.
    pub fusion_latency_ms: Latency,
    /// The worst fuser's end-to-end p99 (ms).
    pub e2e_p99_ms: Option<f64>,
    /// CPU of the whole process, in percent of one core.
    pub cpu_percent: f64,
}

/// The tiles of a configuration of `k` fusers over the 4-block strip: blocks of 4/k each.
fn strip_tiles(k: usize) -> anyhow::Result<(Tiling, Vec<Tile>)> {
    if !(k.is_power_of_two() && k <= 4) {
        anyhow::bail!("--regions: the strip splits into 1, 2 or 4 regions (got {k})");
    }
    let tiling = Tiling::new(4.0 * BLOCK_M / k as f64).map_err(anyhow::Error::msg)?;
    Ok((tiling, (0..k as i32).map(|x| Tile { x, y: 0 }).collect()))
}

/// Runs the scale-out benchmark: 1, 2, ... up to `args.regions` regional fusers (1, 2, 4).
pub async fn run_regions(args: &LoadArgs) -> anyhow::Result<Vec<RegionRow>> {
    let most = args.regions.unwrap_or(4) as usize;
    let mut rows = Vec::new();
    let mut k = 1;
    while k <= most {
        let (tiling, tiles) = strip_tiles(k)?;
        let ns = format!("load-regions-{k}");
        let fusers = tiles
            .iter()
            .map(|&tile| {
                let mut cfg = fuser_config(args, &ns)?;
                cfg.region = Some(Region {
                    tiling,
                    tile,
                    halo_m: v2x_fuser::intake::region::DEFAULT_HALO_M,
                });
                Ok(cfg)
            })
            .collect::<anyhow::Result<_>>()?;
        let sites = (0..4)
            .map(|b| [(b as f64 + 0.5) * BLOCK_M, 0.5 * BLOCK_M])
            .collect();
        let layout = Layout {
            fusers,
            tiling: Some(tiling),
            sites,
        };
        let d = drive(args, &ns, layout).await?;
        let samples: Vec<f64> = d
            .stats
            .iter()
            .flat_map(|s| s.fusion_samples.iter().copied())
            .collect();
        let sum = |f: fn(&node::NodeStats) -> u64| d.stats.iter().map(f).sum::<u64>();
        rows.push(RegionRow {
            fusers: k,
            tile_m: tiling.size_m(),
            input_boxes_per_s: (args.agents * args.objects) as f64 * args.hz,
            fused_boxes_per_s: sum(|s| s.fused_objects) as f64 / d.wall_s,
            windows: sum(|s| s.windows),
            windows_incomplete: sum(|s| s.windows_incomplete),
            captures_incomplete: sum(|s| s.captures_incomplete),
            windows_lost: sum(|s| s.windows_dropped + s.open_windows_at_stop as u64),
            fusion_latency_ms: Latency::of(&samples),
            e2e_p99_ms: d
                .stats
                .iter()
                .filter_map(|s| s.e2e_latency_ms.p99_ms)
                .max_by(f64::total_cmp),
            cpu_percent: d.cpu_percent,
        });
        k *= 2;
    }
    Ok(rows)
}

/// The p99 (ms) below which one fuser is said to hold a load.
pub const HOLD_P99_MS: f64 = 50.0;

/// Runs single-fuser loads with agents doubling from `args.agents` until one is not held (fusion
/// p99 at least [`HOLD_P99_MS`], or fewer than 95 % of the windows fused) or cannot run (this
/// machine's limits); returns every load run and whether it held, and why the search stopped
/// early, if it did.
pub async fn run_max_load(
    args: &LoadArgs,
) -> anyhow::Result<(Vec<(LoadReport, bool)>, Option<String>)> {
    let mut out = Vec::new();
    let mut agents = args.agents.max(1);
    loop {
        let a = LoadArgs {
            agents,
            ..args.clone()
        };
        let r = match run(&a).await {
            Ok(r) => r,
            Err(e) if !out.is_empty() => {
                return Ok((out, Some(format!("{agents} agents could not run: {e:#}"))))
            }
            Err(e) => return Err(e),
        };
        let held = r.fusion_latency_ms.p99_ms.is_some_and(|p| p < HOLD_P99_MS)
            && r.windows as f64 >= 0.95 * r.frames_per_agent as f64;
        out.push((r, held));
        if !held || agents >= v2x_protocol::limits::MAX_WINDOW_AGENTS {
            return Ok((out, None));
        }
        agents = (agents * 2).min(v2x_protocol::limits::MAX_WINDOW_AGENTS);
    }
}

/// Drives one run: starts the fusers (and, with regions, a router), the agents, sends the
/// frames, and stops everything.
async fn drive(args: &LoadArgs, ns: &str, layout: Layout) -> anyhow::Result<Driven> {
    let port = free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let (router, fuser_args, agent_args) = sessions_of(&endpoint, layout.tiling.is_some()).await?;
    let mut fusers = Vec::new();
    for cfg in layout.fusers.iter().cloned() {
        let session = open_session(&fuser_args).await?;
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let r = node::run(&session, cfg, |_| {}, async {
                let _ = stop_rx.await;
            })
            .await;
            let _ = session.close().await;
            r
        });
        fusers.push((stop_tx, task));
    }
    let (mut agents, sessions) = start_agents(args, ns, &layout, &agent_args).await?;
    // Let liveliness settle so that windows close on completion.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let frames = (args.seconds * args.hz).round() as usize;
    let period = Duration::from_secs_f64(1.0 / args.hz);
    let rss_start = rss_mib();
    let cpu0 = cpu_seconds();
    let wall0 = Instant::now();
    let start = tokio::time::Instant::now();
    let mut cpm_first = 0.0;
    for k in 0..frames {
        tokio::time::sleep_until(start + period * k as u32).await;
        let drawn = draw(args, &layout, agents.len(), k);
        if k == 0 {
            cpm_first = drawn
                .iter()
                .map(|d| {
                    let f = frame(now_us(), d.clone()).with_centroid_origin();
                    v2x_cpm::message_bytes(&f) as f64
                })
                .sum::<f64>()
                / drawn.len().max(1) as f64;
        }
        let capture = now_us();
        for (agent, detections) in agents.iter_mut().zip(drawn) {
            agent.send(frame(capture, detections))?;
        }
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    let wall = wall0.elapsed().as_secs_f64();
    let cpu = cpu_seconds() - cpu0;
    let stats = stop_fusers(fusers).await?;
    let rss_end = rss_mib();
    let totals = agents.iter().map(|a| a.counters().totals());
    let (payload, published) =
        totals.fold((0, 0), |(b, n), t| (b + t.payload_bytes, n + t.published));
    drop(agents);
    for s in sessions {
        let _ = s.close().await;
    }
    if let Some(r) = router {
        let _ = r.close().await;
    }
    Ok(Driven {
        stats,
        frames,
        wall_s: wall,
        cpu_percent: 100.0 * cpu / wall,
        rss_start_mib: rss_start,
        rss_end_mib: rss_end,
        bytes: FrameBytes {
            payload_bytes_per_frame: payload as f64 / published.max(1) as f64,
            cpm_bytes_per_frame: cpm_first,
        },
    })
}

/// Stops the fusers and waits for each one's statistics.
async fn stop_fusers(
    fusers: Vec<(
        tokio::sync::oneshot::Sender<()>,
        tokio::task::JoinHandle<anyhow::Result<node::NodeStats>>,
    )>,
) -> anyhow::Result<Vec<node::NodeStats>> {
    let (stops, tasks): (Vec<_>, Vec<_>) = fusers.into_iter().unzip();
    for stop in stops {
        let _ = stop.send(());
    }
    let mut stats = Vec::new();
    for task in tasks {
        stats.push(task.await??);
    }
    Ok(stats)
}

/// The sessions of a load: a single fuser listens on `endpoint` and the agents connect to it as
/// clients; with regions a router listens and every fuser and agent is its client. The router
/// (with regions), the fusers' and the agents' settings.
async fn sessions_of(
    endpoint: &str,
    regions: bool,
) -> anyhow::Result<(Option<zenoh::Session>, ZenohArgs, ZenohArgs)> {
    // Agents are clients: peers would also mesh with each other, a connection per pair.
    let client = ZenohArgs {
        mode: Some("client".into()),
        connect: vec![endpoint.to_string()],
        ..Default::default()
    };
    if !regions {
        let fuser = ZenohArgs::loopback(&[endpoint.to_string()], &[]);
        return Ok((None, fuser, client));
    }
    let router = open_session(&ZenohArgs {
        mode: Some("router".into()),
        listen: vec![endpoint.to_string()],
        no_multicast_scouting: true,
        ..Default::default()
    })
    .await?;
    Ok((Some(router), client.clone(), client))
}

/// Every agent's boxes at frame `k`, drawn before its capture time, so that end-to-end latency
/// is the system's alone, not the drawing's (about 6 ms at 64 agents of 200 boxes).
fn draw(args: &LoadArgs, layout: &Layout, agents: usize, k: usize) -> Vec<Vec<Detection>> {
    let noise = NoiseProfile::Mild.std();
    let t = k as f64 / args.hz;
    // With several sites, each site's objects come back every 6 s, so that they stay near it.
    let (t_scene, sites) = match layout.sites.len() {
        1 => (t, 1),
        n => (t % 6.0, n),
    };
    let truths: Vec<_> = (0..sites)
        .map(|b| scene(args.objects, t_scene, 11 + b as u64))
        .collect();
    (0..agents)
        .map(|i| {
            let (site, truth) = (layout.sites[i % sites], &truths[i % sites]);
            noisy_boxes(truth, site, &noise, mix(5, i as u64, k as u64))
        })
        .collect()
}

/// A vehicle's frame of `detections` captured at `capture_us` (the agent names and numbers it).
fn frame(capture_us: u64, detections: Vec<Detection>) -> Frame {
    Frame {
        agent: String::new(),
        kind: AgentKind::Vehicle,
        seq: 0,
        capture_us,
        origin: [0.0; 3],
        detections,
    }
}

/// Starts the load's agents (every fourth a roadside unit), each waiting for a fuser of its site:
/// the agents and their sessions.
async fn start_agents(
    args: &LoadArgs,
    ns: &str,
    layout: &Layout,
    agent_args: &ZenohArgs,
) -> anyhow::Result<(Vec<Agent>, Vec<zenoh::Session>)> {
    let mut sessions = Vec::new();
    let mut agents = Vec::new();
    for i in 0..args.agents {
        let s = open_session(agent_args).await?;
        let kind = if i % 4 == 1 {
            AgentKind::Infrastructure
        } else {
            AgentKind::Vehicle
        };
        let mut agent =
            Agent::start(&s, ns, &format!("a{i:02}"), kind, Link::default(), i as u64).await?;
        let site = layout.sites[i % layout.sites.len()];
        match layout.tiling {
            None => agent.wait_for_subscriber(Duration::from_secs(30)).await?,
            Some(t) => {
                agent = agent.with_tiling(t);
                agent
                    .wait_for_subscriber_in(
                        t.tile_of([site[0], site[1], 0.0]),
                        Duration::from_secs(30),
                    )
                    .await?;
            }
        }
        agents.push(agent);
        sessions.push(s);
    }
    Ok((agents, sessions))
}

/// One agent's boxes of `truth` around `site`: mild noise from the stream `seed`, stating it.
fn noisy_boxes(
    truth: &[(Class, [f64; 3], [f64; 3], f64)],
    site: [f64; 2],
    noise: &v2x_protocol::Uncertainty,
    seed: u64,
) -> Vec<Detection> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
    truth
        .iter()
        .enumerate()
        .map(|(j, (class, c, s, yaw))| Detection {
            class: *class,
            center: std::array::from_fn(|d| {
                c[d] + site.get(d).copied().unwrap_or(0.0) + noise.pos[d] * g()
            }),
            size: std::array::from_fn(|d| (s[d] + noise.size[d] * g()).max(0.05)),
            yaw: wrap_angle(yaw + noise.yaw * g()),
            score: 0.9,
            std: *noise,
            pos_cov: None,
            velocity: None,
            id: j as u32,
        })
        .collect()
}
