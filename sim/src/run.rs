//! `v2x-sim run`: a scenario over Zenoh. With no `--role`, every role runs in this process on
//! loopback: the fuser listens on a free local port and each agent reaches it through a small
//! byte-counting TCP relay, which is how wire bytes (Zenoh framing, declarations and keep-alives
//! included) are measured. With `--role NAME` only those roles run, each with the endpoints its
//! scenario entry gives, so one file drives a multi-machine experiment (one role per host).
//!
//! Agents replay the ground truth's frames on a shared schedule: frame k is captured at
//! epoch + k x period / speed on each agent's (possibly offset) clock. The fuser role fixes the
//! epoch and answers it on `v2x/NS/sim/epoch`; agent roles ask for it, and an agent that joins
//! late starts at the current frame. At the end the fuser role maps each fused window back to its
//! ground-truth frame and prints the summary: metrics of the fused output and of each agent alone,
//! bandwidth, latency and frame counts.

use crate::dataset::{GroundTruth, GtFrame};
use crate::metrics::{Accumulator, Metrics};
use crate::noise::{detect, place_agents, AgentNoise};
use crate::scenario::Scenario;
use anyhow::{anyhow, bail, Context};
use clap::{Args, ValueEnum};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use v2x_agent::{now_us, open_session, Agent, AgentTotals};
use v2x_fuser::node::{self, Latency, NodeConfig, NodeStats};
use v2x_protocol::net::ZenohArgs;
use v2x_protocol::nuscenes_json::{write_results, Results};
use v2x_protocol::{Detection, Frame};

/// Output format of the summary.
#[derive(Copy, Clone, Debug, ValueEnum, PartialEq, Eq)]
pub enum RunFormat {
    /// Human-readable tables.
    Table,
    /// One JSON object (fields in the README).
    Json,
}

/// `v2x-sim run` arguments.
#[derive(Args, Clone, Debug)]
pub struct RunArgs {
    /// Scenario file (TOML); without it, the embedded default scenario.
    pub scenario: Option<PathBuf>,
    /// Run only these roles: `fuser` or an agent's name (repeatable). Default: every role, here.
    #[arg(long = "role")]
    pub roles: Vec<String>,
    /// Summary format.
    #[arg(long, value_enum, default_value = "table")]
    pub format: RunFormat,
    /// Record the fused output as a nuScenes results file (ground-truth sample tokens).
    #[arg(long)]
    pub record: Option<PathBuf>,
}

/// The `run` subcommand.
#[derive(clap::Subcommand, Clone, Debug)]
pub enum RunCommand {
    /// Run a scenario over Zenoh (whole, or only the named roles) and report metrics, bandwidth
    /// and latency.
    Run(RunArgs),
}

/// Bandwidth of one agent.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Bandwidth {
    /// Frames published.
    pub frames: u64,
    /// Mean objects per frame.
    pub objects_per_frame: f64,
    /// Mean payload bytes per frame.
    pub payload_bytes_per_frame: f64,
    /// Mean payload bytes per object.
    pub payload_bytes_per_object: f64,
    /// Mean bytes on the wire per frame (all of the agent's TCP bytes towards the fuser, Zenoh
    /// framing and session traffic included), when measured.
    pub wire_bytes_per_frame: Option<f64>,
    /// Wire (or, unmeasured, payload) rate in kbit/s over the run.
    pub kbit_s: f64,
}

/// Frame counts of one agent.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Counts {
    /// Frames the agent produced.
    pub sent: u64,
    /// Frames its link dropped.
    pub dropped_by_link: u64,
    /// Frames the fuser received.
    pub received: u64,
    /// Frames fused.
    pub fused: u64,
    /// Late frames (window already closed).
    pub late: u64,
    /// Duplicate frames.
    pub duplicate: u64,
    /// Invalid frames.
    pub invalid: u64,
}

/// The summary of a run (`--format json`).
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Namespace.
    pub namespace: String,
    /// Method.
    pub method: String,
    /// Agents' noise, in order.
    pub noise: String,
    /// Ground-truth frames scheduled.
    pub frames_scheduled: usize,
    /// Fused windows published.
    pub windows: u64,
    /// Windows closed by deadline with a live agent missing.
    pub windows_incomplete: u64,
    /// Wall-clock length of the run (s).
    pub wall_s: f64,
    /// Metrics of the fused output over the fused frames.
    pub fused: Metrics,
    /// Metrics of each agent alone over the same frames.
    pub agents: BTreeMap<String, Metrics>,
    /// Bandwidth per agent.
    pub bandwidth: BTreeMap<String, Bandwidth>,
    /// Frame counts per agent.
    pub counts: BTreeMap<String, Counts>,
    /// Capture to fused publish (ms).
    pub e2e_latency_ms: Latency,
    /// Window close to fused publish (ms).
    pub fusion_latency_ms: Latency,
}

/// The frames a scenario replays and their spacing.
pub struct Schedule {
    /// Indices into the ground truth's frames, in replay order.
    pub frames: Vec<usize>,
    /// Spacing of frames in data time (us).
    pub period_us: u64,
}

impl Schedule {
    /// The first `duration_s` of data.
    pub fn of(gt: &GroundTruth, duration_s: f64) -> Schedule {
        let hz = gt.hz();
        let n = ((duration_s * hz).round() as usize)
            .max(1)
            .min(gt.frames.len());
        Schedule {
            frames: (0..n).collect(),
            period_us: (1e6 / hz).round() as u64,
        }
    }

    /// Wall-clock capture time of the k-th frame.
    pub fn due_us(&self, epoch_us: u64, k: usize, speed: f64) -> u64 {
        epoch_us + (k as f64 * self.period_us as f64 / speed) as u64
    }

    /// The frame a capture time belongs to.
    pub fn frame_of(&self, epoch_us: u64, capture_us: u64, speed: f64) -> Option<usize> {
        let k = ((capture_us as f64 - epoch_us as f64) * speed / self.period_us as f64).round();
        (k >= 0.0 && (k as usize) < self.frames.len()).then_some(k as usize)
    }
}

/// A TCP relay that counts the bytes flowing from its clients to `target`.
pub async fn counting_relay(target_port: u16, upstream: Arc<AtomicU64>) -> anyhow::Result<u16> {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .context("relay: bind")?;
    let port = listener.local_addr()?.port();
    tokio::spawn(async move {
        while let Ok((client, _)) = listener.accept().await {
            let upstream = upstream.clone();
            tokio::spawn(async move {
                let Ok(server) = tokio::net::TcpStream::connect(("127.0.0.1", target_port)).await
                else {
                    return;
                };
                let _ = client.set_nodelay(true);
                let _ = server.set_nodelay(true);
                let (mut cr, mut cw) = client.into_split();
                let (mut sr, mut sw) = server.into_split();
                let up = async move {
                    let mut buf = vec![0u8; 64 * 1024];
                    while let Ok(n) = cr.read(&mut buf).await {
                        if n == 0 || sw.write_all(&buf[..n]).await.is_err() {
                            break;
                        }
                        upstream.fetch_add(n as u64, Ordering::Relaxed);
                    }
                    let _ = sw.shutdown().await;
                };
                let down = async move {
                    let _ = tokio::io::copy(&mut sr, &mut cw).await;
                    let _ = cw.shutdown().await;
                };
                tokio::join!(up, down);
            });
        }
    });
    Ok(port)
}

/// A free TCP port on loopback (bound, then released).
pub fn free_port() -> anyhow::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// The detections agent `idx` of a scenario makes of ground-truth frame `gi`.
pub fn agent_view(
    scenario: &Scenario,
    gt: &GroundTruth,
    gi: usize,
    idx: usize,
) -> (Vec<Detection>, [f64; 3]) {
    let frame: &GtFrame = &gt.frames[gi];
    let spec = &scenario.agents[idx];
    let noise: AgentNoise = spec.noise.parse().expect("checked");
    let place = place_agents(frame, scenario.agents.len(), scenario.seed)[idx].position;
    (
        detect(frame, gi, idx, &noise, place, spec.range_m, scenario.seed),
        place,
    )
}

/// Runs one agent role until its schedule ends or `stop` fires.
pub async fn agent_role(
    session: &zenoh::Session,
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    idx: usize,
    epoch_us: u64,
) -> anyhow::Result<AgentTotals> {
    let spec = &scenario.agents[idx];
    let mut agent = Agent::start(
        session,
        &scenario.namespace,
        &spec.name,
        spec.kind,
        spec.link.clone(),
        scenario.seed.wrapping_add(idx as u64 * 7919),
    )
    .await?;
    agent.wait_for_subscriber(Duration::from_secs(30)).await?;
    for (k, &gi) in schedule.frames.iter().enumerate() {
        let due = schedule.due_us(epoch_us, k, scenario.speed);
        let now = now_us();
        if due + 1000 < now {
            continue; // joined late: this frame's time has passed
        }
        tokio::time::sleep(Duration::from_micros(due.saturating_sub(now))).await;
        let (detections, origin) = agent_view(scenario, gt, gi, idx);
        agent.send(Frame {
            agent: spec.name.clone(),
            kind: spec.kind,
            seq: 0,
            capture_us: now_us(),
            origin,
            detections,
        })?;
    }
    // Let delayed frames leave.
    tokio::time::sleep(Duration::from_secs_f64(
        (spec.link.latency_ms + spec.link.jitter_ms) / 1000.0 + 0.1,
    ))
    .await;
    Ok(agent.counters().totals())
}

/// What the fuser role collected.
pub struct FuserOutcome {
    /// The node's statistics.
    pub stats: NodeStats,
    /// Fused detections per scheduled frame index.
    pub fused: BTreeMap<usize, Vec<Detection>>,
}

/// Runs the fuser role until `stop` resolves.
pub async fn fuser_role(
    session: &zenoh::Session,
    scenario: &Scenario,
    schedule: &Schedule,
    epoch_us: u64,
    stop: impl std::future::Future<Output = ()>,
) -> anyhow::Result<FuserOutcome> {
    let cfg = NodeConfig {
        ns: scenario.namespace.clone(),
        method: scenario.method(),
        window_ms: (scenario.fuser.window_ms / scenario.speed)
            .min(schedule.period_us as f64 / 1000.0 / scenario.speed),
        max_wait_ms: scenario.fuser.max_wait_ms,
    };
    let epoch_key = epoch_key(&scenario.namespace);
    let queryable = session
        .declare_queryable(&epoch_key)
        .await
        .map_err(|e| anyhow!("{e}"))?;
    let answer = tokio::spawn(async move {
        while let Ok(q) = queryable.recv_async().await {
            let _ = q.reply(&epoch_key, epoch_us.to_string()).await;
        }
    });
    let mut fused = BTreeMap::new();
    let speed = scenario.speed;
    let stats = node::run(
        session,
        cfg,
        |f| {
            if let Some(k) = schedule.frame_of(epoch_us, f.frame.capture_us, speed) {
                fused.insert(k, f.frame.detections.clone());
            }
        },
        stop,
    )
    .await?;
    answer.abort();
    Ok(FuserOutcome { stats, fused })
}

fn epoch_key(ns: &str) -> String {
    format!("v2x/{ns}/sim/epoch")
}

/// Asks the fuser role for the epoch, retrying until `timeout`.
pub async fn query_epoch(
    session: &zenoh::Session,
    ns: &str,
    timeout: Duration,
) -> anyhow::Result<u64> {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        if let Ok(replies) = session
            .get(epoch_key(ns))
            .timeout(Duration::from_secs(1))
            .await
        {
            while let Ok(r) = replies.recv_async().await {
                if let Ok(s) = r.result() {
                    if let Ok(t) = String::from_utf8_lossy(&s.payload().to_bytes()).parse::<u64>() {
                        return Ok(t);
                    }
                }
            }
        }
        if tokio::time::Instant::now() > deadline {
            bail!(
                "no fuser answered {} within {timeout:?}: is the fuser role running and reachable?",
                epoch_key(ns)
            );
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// Builds the summary from what the roles produced.
pub fn summarize(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    outcome: &FuserOutcome,
    totals: &BTreeMap<String, (AgentTotals, Option<u64>)>,
    wall_s: f64,
) -> Summary {
    let mut fused_acc = Accumulator::new();
    let mut agent_acc: Vec<Accumulator> = vec![Accumulator::new(); scenario.agents.len()];
    for (&k, dets) in &outcome.fused {
        let gi = schedule.frames[k];
        let objects = &gt.frames[gi].objects;
        fused_acc.add_frame(objects, dets);
        for (idx, acc) in agent_acc.iter_mut().enumerate() {
            acc.add_frame(objects, &agent_view(scenario, gt, gi, idx).0);
        }
    }
    let mut bandwidth = BTreeMap::new();
    let mut counts = BTreeMap::new();
    for a in &scenario.agents {
        let st = outcome
            .stats
            .agents
            .get(&a.name)
            .cloned()
            .unwrap_or_default();
        let (t, wire) = totals.get(&a.name).copied().unwrap_or_default();
        let frames = if t.published > 0 {
            t.published
        } else {
            st.frames_in
        };
        let payload = if t.payload_bytes > 0 {
            t.payload_bytes
        } else {
            st.payload_bytes
        };
        let objects = if t.objects > 0 { t.objects } else { st.objects };
        let per = |x: u64, n: u64| if n > 0 { x as f64 / n as f64 } else { 0.0 };
        let secs =
            (schedule.frames.len() as f64 * schedule.period_us as f64 / 1e6 / scenario.speed)
                .max(1e-9);
        bandwidth.insert(
            a.name.clone(),
            Bandwidth {
                frames,
                objects_per_frame: per(objects, frames),
                payload_bytes_per_frame: per(payload, frames),
                payload_bytes_per_object: per(payload, objects),
                wire_bytes_per_frame: wire.map(|w| per(w, frames)),
                kbit_s: wire.unwrap_or(payload) as f64 * 8.0 / 1000.0 / secs,
            },
        );
        counts.insert(
            a.name.clone(),
            Counts {
                sent: t.frames,
                dropped_by_link: t.dropped,
                received: st.frames_in,
                fused: st.fused,
                late: st.late,
                duplicate: st.duplicate,
                invalid: st.invalid,
            },
        );
    }
    Summary {
        namespace: scenario.namespace.clone(),
        method: scenario.method().name(),
        noise: scenario.noise().name,
        frames_scheduled: schedule.frames.len(),
        windows: outcome.stats.windows,
        windows_incomplete: outcome.stats.windows_incomplete,
        wall_s,
        fused: fused_acc.summary(),
        agents: scenario
            .agents
            .iter()
            .zip(&agent_acc)
            .map(|(a, acc)| (a.name.clone(), acc.summary()))
            .collect(),
        bandwidth,
        counts,
        e2e_latency_ms: outcome.stats.e2e_latency_ms.clone(),
        fusion_latency_ms: outcome.stats.fusion_latency_ms.clone(),
    }
}

/// Runs every role of a scenario in this process over loopback.
pub async fn run_local(
    scenario: &Scenario,
    gt: &GroundTruth,
) -> anyhow::Result<(Summary, FuserOutcome)> {
    let schedule = Schedule::of(gt, scenario.duration_s);
    let fuser_port = free_port()?;
    let fuser_session = open_session(&ZenohArgs::loopback(
        &[format!("tcp/127.0.0.1:{fuser_port}")],
        &[],
    ))
    .await?;
    let mut agent_sessions = Vec::new();
    let mut wire = Vec::new();
    for _ in &scenario.agents {
        let counter = Arc::new(AtomicU64::new(0));
        let port = counting_relay(fuser_port, counter.clone()).await?;
        agent_sessions.push(
            open_session(&ZenohArgs::loopback(
                &[],
                &[format!("tcp/127.0.0.1:{port}")],
            ))
            .await?,
        );
        wire.push(counter);
    }
    let start = std::time::Instant::now();
    let epoch = now_us() + 1_000_000;
    let (done_tx, done_rx) = tokio::sync::oneshot::channel::<()>();
    let max_wait = scenario.fuser.max_wait_ms;
    let stop = async move {
        let _ = done_rx.await;
        tokio::time::sleep(Duration::from_secs_f64(max_wait / 1000.0 + 0.3)).await;
    };
    let fuser = fuser_role(&fuser_session, scenario, &schedule, epoch, stop);
    let agents = async {
        let runs =
            scenario.agents.iter().enumerate().map(|(idx, _)| {
                agent_role(&agent_sessions[idx], scenario, gt, &schedule, idx, epoch)
            });
        let results = futures::future::join_all(runs).await;
        let _ = done_tx.send(());
        results
    };
    let (outcome, results) = tokio::join!(fuser, agents);
    let outcome = outcome?;
    let mut totals = BTreeMap::new();
    for ((a, r), w) in scenario.agents.iter().zip(results).zip(&wire) {
        totals.insert(
            a.name.clone(),
            (
                r.with_context(|| format!("agent {}", a.name))?,
                Some(w.load(Ordering::Relaxed)),
            ),
        );
    }
    for s in agent_sessions {
        let _ = s.close().await;
    }
    let _ = fuser_session.close().await;
    let summary = summarize(
        scenario,
        gt,
        &schedule,
        &outcome,
        &totals,
        start.elapsed().as_secs_f64(),
    );
    Ok((summary, outcome))
}

/// The fused output as a results file keyed by the ground truth's sample tokens.
pub fn recorded(gt: &GroundTruth, schedule: &Schedule, outcome: &FuserOutcome) -> Results {
    let mut r = Results::default();
    for (&k, dets) in &outcome.fused {
        r.samples.insert(
            gt.frames[schedule.frames[k]].sample_token.clone(),
            dets.clone(),
        );
    }
    r
}

/// Prints the summary as tables.
pub fn print_table(s: &Summary) {
    println!("scenario {} · method {} · noise {} · {} frames scheduled · {} windows fused ({} incomplete) · {:.1} s", s.namespace, s.method, s.noise, s.frames_scheduled, s.windows, s.windows_incomplete, s.wall_s);
    println!();
    let mut rows = vec![crate::bench::Row {
        noise: s.noise.clone(),
        method: format!("fused ({})", s.method),
        metrics: s.fused.clone(),
    }];
    for (n, m) in &s.agents {
        rows.push(crate::bench::Row {
            noise: s.noise.clone(),
            method: format!("{n} alone"),
            metrics: m.clone(),
        });
    }
    print!("{}", crate::bench::table(&rows));
    println!();
    println!("| agent | frames | objects/frame | payload B/frame | payload B/object | wire B/frame | kbit/s | late | duplicate | invalid | dropped by link |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (n, b) in &s.bandwidth {
        let c = &s.counts[n];
        let wire = b
            .wire_bytes_per_frame
            .map_or("-".into(), |w| format!("{w:.0}"));
        println!(
            "| {n} | {} | {:.1} | {:.0} | {:.1} | {wire} | {:.1} | {} | {} | {} | {} |",
            b.frames,
            b.objects_per_frame,
            b.payload_bytes_per_frame,
            b.payload_bytes_per_object,
            b.kbit_s,
            c.late,
            c.duplicate,
            c.invalid,
            c.dropped_by_link
        );
    }
    println!("(late-fusion reference in the paper: 2^9 = 512 bytes per frame)");
    println!();
    let l = |x: &Latency| {
        format!(
            "p50 {} · p95 {} · p99 {} ms",
            f(x.p50_ms),
            f(x.p95_ms),
            f(x.p99_ms)
        )
    };
    println!(
        "end-to-end latency (capture to fused publish): {}",
        l(&s.e2e_latency_ms)
    );
    println!(
        "fusion latency (window close to publish):      {}",
        l(&s.fusion_latency_ms)
    );
}

fn f(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{x:.2}"))
}

/// Entry point of `v2x-sim run`.
pub async fn run_command(cmd: RunCommand) -> anyhow::Result<()> {
    let RunCommand::Run(args) = cmd;
    let scenario = match &args.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::parse(crate::scenario::DEFAULT, "the default scenario", None)?,
    };
    let gt = scenario.dataset.data_args().load()?;
    for r in &args.roles {
        if r != "fuser" && !scenario.agents.iter().any(|a| &a.name == r) {
            let names: Vec<_> = scenario.agents.iter().map(|a| a.name.as_str()).collect();
            bail!(
                "--role {r}: not a role of this scenario (roles: fuser, {})",
                names.join(", ")
            );
        }
    }
    let schedule = Schedule::of(&gt, scenario.duration_s);
    let summary_and_outcome = if args.roles.is_empty() {
        eprintln!(
            "running {} agents and the fuser in this process over loopback ({} frames)...",
            scenario.agents.len(),
            schedule.frames.len()
        );
        Some(run_local(&scenario, &gt).await?)
    } else {
        run_roles(&scenario, &gt, &schedule, &args.roles).await?
    };
    if let Some((summary, outcome)) = summary_and_outcome {
        if let Some(path) = &args.record {
            let mut r = Results::default();
            for (&k, dets) in &outcome.fused {
                r.samples.insert(
                    gt.frames[schedule.frames[k]].sample_token.clone(),
                    dets.clone(),
                );
            }
            write_results(path, &r, &gt.tokens)?;
            eprintln!(
                "recorded {} fused frames -> {}",
                r.samples.len(),
                path.display()
            );
        }
        match args.format {
            RunFormat::Json => println!("{}", serde_json::to_string_pretty(&summary)?),
            RunFormat::Table => print_table(&summary),
        }
    }
    Ok(())
}

/// Runs the named roles with the scenario's endpoints; returns the summary if the fuser ran here.
async fn run_roles(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    roles: &[String],
) -> anyhow::Result<Option<(Summary, FuserOutcome)>> {
    let start = std::time::Instant::now();
    let run_fuser = roles.iter().any(|r| r == "fuser");
    let fuser = async {
        if !run_fuser {
            return anyhow::Ok(None);
        }
        let session = open_session(&scenario.fuser.zenoh).await?;
        let epoch = now_us() + 3_000_000;
        let end = schedule.due_us(epoch, schedule.frames.len(), scenario.speed)
            + 2_000_000
            + (scenario.fuser.max_wait_ms * 1000.0) as u64;
        eprintln!(
            "fuser: epoch in 3 s, running for {:.1} s",
            (end - now_us()) as f64 / 1e6
        );
        let stop = tokio::time::sleep(Duration::from_micros(end.saturating_sub(now_us())));
        let outcome = fuser_role(&session, scenario, schedule, epoch, stop).await?;
        let _ = session.close().await;
        Ok(Some(outcome))
    };
    let agents = async {
        let mut out = BTreeMap::new();
        let runs = scenario
            .agents
            .iter()
            .enumerate()
            .filter(|(_, a)| roles.contains(&a.name))
            .map(|(idx, a)| async move {
                let session = open_session(&a.zenoh).await?;
                let epoch =
                    query_epoch(&session, &scenario.namespace, Duration::from_secs(60)).await?;
                let t = agent_role(&session, scenario, gt, schedule, idx, epoch).await?;
                let _ = session.close().await;
                eprintln!(
                    "agent {}: sent {} frames ({} dropped by the link), {} payload bytes",
                    a.name, t.frames, t.dropped, t.payload_bytes
                );
                anyhow::Ok((a.name.clone(), t))
            });
        for r in futures::future::join_all(runs).await {
            let (name, t) = r?;
            out.insert(name, (t, None));
        }
        anyhow::Ok(out)
    };
    let (outcome, totals) = tokio::join!(fuser, agents);
    let totals = totals?;
    Ok(outcome?.map(|o| {
        let s = summarize(
            scenario,
            gt,
            schedule,
            &o,
            &totals,
            start.elapsed().as_secs_f64(),
        );
        (s, o)
    }))
}
