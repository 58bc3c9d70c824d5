//! `v2x-sim run`: a scenario over Zenoh. With no `--role`, every role runs in this process on
//! loopback: the fuser listens on a free local port and each agent reaches it through a small
//! byte-counting TCP relay ([`relay`]). With `--role NAME` only those roles run, each with the
//! endpoints its scenario entry gives, so one file drives a multi-machine experiment (one role
//! per host). Every role's session counts its own traffic with Zenoh's statistics ([`meter`]):
//! agent roles report what they sent, the fuser role what it received; the relay adds what Zenoh
//! does not count (TLS records and the sessions' opening handshakes).
//!
//! Agents replay the ground truth's frames on a shared [`schedule`]: frame k is captured at
//! epoch + k x period / speed on each agent's (possibly offset) clock. The fuser role fixes the
//! epoch and answers it ([`epoch`]); agent roles ask for it, and an agent that joins late starts
//! at the current frame. At the end the fuser role maps each fused window back to its
//! ground-truth frame and prints the [`summary`]. SIGINT and SIGTERM end a run early, with the
//! recording and the summary of what ran.

pub mod city;
pub mod epoch;
pub mod meter;
pub mod relay;
pub mod roles;
pub mod schedule;
pub mod secure;
pub mod series;
pub mod series_plot;
pub mod summary;
pub mod tables;

pub use relay::{counting_relay, free_port};
pub use roles::{agent_captures, agent_role, agent_view, fuser_role, FuserOutcome};
pub use schedule::Schedule;
pub use summary::{
    agent_bandwidth, recorded, summarize, AgentSide, Bandwidth, Counts, RegionReport,
    SecurityReport, Summary,
};
pub use tables::{print_agent_table, print_table, AgentReport};

use crate::dataset::GroundTruth;
use crate::scenario::{Scenario, SecurityMode};
use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use secure::Role;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::watch;
use v2x_agent::now_us;
use v2x_protocol::net::{shutdown_signal, ZenohArgs};
use v2x_protocol::nuscenes_json::write_results;

mod city_command;
use city_command::run_city_command;

/// Output format of the summary.
#[derive(Copy, Clone, Debug, ValueEnum, PartialEq, Eq)]
pub enum RunFormat {
    /// Human-readable tables.
    Table,
    /// One JSON object (fields in docs/guide.md).
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
    /// Write the run's per-second series as the fuser saw it (windows, incomplete, latency,
    /// fused metrics, each agent's frames, objects and bytes received): CSV if FILE ends in
    /// .csv, else JSON (which `v2x-sim plot --timeline` draws).
    #[arg(long)]
    pub timeline: Option<PathBuf>,
    /// Foxglove output: --mcap FILE and --foxglove [ADDR:]PORT.
    #[command(flatten)]
    pub viz: v2x_fuser::viz::VizArgs,
}

/// The `run` subcommand.
#[derive(clap::Subcommand, Clone, Debug)]
pub enum RunCommand {
    /// Run a scenario over Zenoh (whole, or only the named roles) and report metrics, bandwidth
    /// and latency.
    Run(RunArgs),
}

/// A stop flag that turns true on SIGINT or SIGTERM.
fn stop_on_signal() -> watch::Receiver<bool> {
    let (tx, rx) = watch::channel(false);
    tokio::spawn(async move {
        shutdown_signal().await;
        eprintln!("stopping: the recording and the summary cover what ran");
        let _ = tx.send(true);
    });
    rx
}

/// Resolves when the stop flag turns true (never, once nobody can set it).
async fn stopped(mut stop: watch::Receiver<bool>) {
    if stop.wait_for(|s| *s).await.is_err() {
        std::future::pending::<()>().await;
    }
}

/// Runs every role of a scenario in this process over loopback.
pub async fn run_local(
    scenario: &Scenario,
    gt: &GroundTruth,
) -> anyhow::Result<(Summary, FuserOutcome)> {
    run_local_until(scenario, gt, watch::channel(false).1, None).await
}

async fn run_local_until(
    scenario: &Scenario,
    gt: &GroundTruth,
    stop: watch::Receiver<bool>,
    viz: Option<std::sync::Arc<v2x_fuser::viz::Viz>>,
) -> anyhow::Result<(Summary, FuserOutcome)> {
    let schedule = Schedule::of(gt, scenario.duration_s);
    let hub_port = free_port()?;
    let (router_session, fuser_session, certs) = open_hub(scenario, hub_port).await?;
    let (agent_sessions, wire, setup) = open_agents(scenario, hub_port, certs.as_deref()).await?;
    let start = std::time::Instant::now();
    let epoch = now_us() + 1_000_000;
    let (done_tx, done_rx) = tokio::sync::oneshot::channel::<()>();
    let max_wait = scenario.fuser.settings.max_wait_ms;
    let fuser_stop = {
        let stop = stop.clone();
        async move {
            tokio::select! {
                _ = done_rx => {}
                _ = stopped(stop) => {}
            }
            tokio::time::sleep(Duration::from_secs_f64(max_wait / 1000.0 + 0.3)).await;
        }
    };
    let fuser = fuser_role(&fuser_session, scenario, &schedule, epoch, viz, fuser_stop);
    let agents = async {
        let results =
            roles::all_agents(&agent_sessions, scenario, gt, &schedule, epoch, &stop).await;
        let _ = done_tx.send(());
        results
    };
    let (outcome, results) = tokio::join!(fuser, agents);
    let mut outcome = outcome?;
    if let Some(r) = &router_session {
        outcome.router_traffic = meter::snapshot(r, "router")
            .await
            .map(|t| vec![(now_us(), t)])
            .unwrap_or_default();
    }
    let mut totals = BTreeMap::new();
    for (((a, r), w), session) in scenario
        .agents
        .iter()
        .zip(results)
        .zip(&wire)
        .zip(&agent_sessions)
    {
        totals.insert(
            a.name.clone(),
            AgentSide {
                totals: r.with_context(|| format!("agent {}", a.name))?,
                sent: meter::snapshot(session, &a.name).await,
                socket_bytes: Some(w.load(Ordering::Relaxed)),
            },
        );
    }
    for s in agent_sessions {
        let _ = s.close().await;
    }
    let _ = fuser_session.close().await;
    if let Some(r) = router_session {
        let _ = r.close().await;
    }
    let wall_s = start.elapsed().as_secs_f64();
    let mut summary = summarize(scenario, gt, &schedule, &outcome, &totals, wall_s);
    summary.security.session_setup_ms = Some(setup.iter().sum::<f64>() / setup.len() as f64);
    Ok((summary, outcome))
}

/// The sessions every agent connects to, on `hub_port`: plain, the fuser's (listening); with
/// mutual TLS, a router's holding the access-control policy and the fuser's as its client, with
/// the certificates' folder.
async fn open_hub(
    scenario: &Scenario,
    hub_port: u16,
) -> anyhow::Result<(
    Option<zenoh::Session>,
    zenoh::Session,
    Option<std::path::PathBuf>,
)> {
    // Plain: the fuser listens and agents connect to it. Mutual TLS: a router listens, holding
    // the access-control policy, and the fuser and the agents are its clients.
    Ok(match scenario.security.mode {
        SecurityMode::Plain => {
            let hub = format!("tcp/127.0.0.1:{hub_port}");
            let args = ZenohArgs::loopback(&[hub], &[]);
            (
                None,
                meter::open_role_session(&args, scenario, Role::Fuser).await?,
                None,
            )
        }
        SecurityMode::Mtls => {
            let hub = format!("tls/127.0.0.1:{hub_port}");
            let dir = secure::local_certs(scenario, &hub)?;
            let listen = ZenohArgs {
                listen: vec![hub.clone()],
                ..Default::default()
            };
            let args = secure::with_certs(&listen, &dir, Role::Router)?;
            let router = meter::open_role_session(&args, scenario, Role::Router).await?;
            let connect = ZenohArgs {
                connect: vec![hub],
                ..Default::default()
            };
            let args = secure::with_certs(&connect, &dir, Role::Fuser)?;
            let fuser = meter::open_role_session(&args, scenario, Role::Fuser).await?;
            (Some(router), fuser, Some(dir))
        }
    })
}

/// Each agent's session, through a relay counting its bytes to the hub, with those counters
/// and the set-up time of each (ms).
async fn open_agents(
    scenario: &Scenario,
    hub_port: u16,
    certs: Option<&std::path::Path>,
) -> anyhow::Result<(Vec<zenoh::Session>, Vec<Arc<AtomicU64>>, Vec<f64>)> {
    let mut agent_sessions = Vec::new();
    let mut wire = Vec::new();
    let mut setup = Vec::new();
    for a in &scenario.agents {
        let counter = Arc::new(AtomicU64::new(0));
        let port = counting_relay(hub_port, counter.clone()).await?;
        let opened = std::time::Instant::now();
        let args = match certs {
            None => ZenohArgs::loopback(&[], &[format!("tcp/127.0.0.1:{port}")]),
            Some(dir) => {
                let connect = ZenohArgs {
                    connect: vec![format!("tls/127.0.0.1:{port}")],
                    ..Default::default()
                };
                secure::with_certs(&connect, dir, Role::Agent(&a.name))?
            }
        };
        let session = meter::open_role_session(&args, scenario, Role::Agent(&a.name)).await?;
        setup.push(opened.elapsed().as_secs_f64() * 1000.0);
        agent_sessions.push(session);
        wire.push(counter);
    }
    Ok((agent_sessions, wire, setup))
}

/// Entry point of `v2x-sim run`.
pub async fn run_command(cmd: RunCommand) -> anyhow::Result<()> {
    let RunCommand::Run(args) = cmd;
    let scenario = match &args.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::parse(crate::scenario::DEFAULT, "the default scenario", None)?,
    };
    let gt = scenario.dataset.data_args().load()?;
    if let Some(regions) = &scenario.regions {
        return run_city_command(&args, &scenario, regions, &gt).await;
    }
    check_roles(&scenario, &args.roles)?;
    let schedule = Schedule::of(&gt, scenario.duration_s);
    let viz = args.viz.open().await?;
    let stop = stop_on_signal();
    let summary_and_outcome = if args.roles.is_empty() {
        eprintln!(
            "running {} agents and the fuser in this process over loopback ({} frames)...",
            scenario.agents.len(),
            schedule.frames.len()
        );
        Some(run_local_until(&scenario, &gt, stop, viz.clone()).await?)
    } else {
        run_roles(
            &scenario,
            &gt,
            &schedule,
            &args.roles,
            args.format,
            stop,
            viz.clone(),
        )
        .await?
    };
    if let Some(v) = &viz {
        if let Some((_, outcome)) = &summary_and_outcome {
            show_ground_truth(v, &scenario, &gt, &schedule, outcome);
        }
        v.close()?;
    }
    let Some((summary, outcome)) = summary_and_outcome else {
        return Ok(());
    };
    if let Some(path) = &args.record {
        record(path, &gt, &schedule, &outcome)?;
    }
    if let Some(path) = &args.timeline {
        let tl = series::timeline(&scenario, &gt, &schedule, &outcome);
        tl.write(path)?;
        eprintln!("timeline of {} s -> {}", tl.seconds.len(), path.display());
    }
    print_summary(&summary, args.format)
}

/// Refuses a `--role` that is not one of the scenario's, listing those that are.
fn check_roles(scenario: &Scenario, roles: &[String]) -> anyhow::Result<()> {
    let secure = scenario.security.mode == SecurityMode::Mtls;
    for r in roles {
        let is_agent = scenario.agents.iter().any(|a| &a.name == r);
        if !(r == "fuser" || (secure && r == "router") || is_agent) {
            let mut names: Vec<_> = scenario.agents.iter().map(|a| a.name.as_str()).collect();
            names.insert(0, "fuser");
            if secure {
                names.insert(0, "router");
            }
            bail!(
                "--role {r}: not a role of this scenario (roles: {})",
                names.join(", ")
            );
        }
    }
    Ok(())
}

/// Shows the ground truth of every scheduled frame, on the capture clock of the run.
fn show_ground_truth(
    v: &v2x_fuser::viz::Viz,
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    outcome: &FuserOutcome,
) {
    for &i in &schedule.frames {
        let f = &gt.frames[i];
        let wall = schedule.wall_us(outcome.epoch_us, f.timestamp_us, scenario.speed);
        let boxes: Vec<_> = f
            .objects
            .iter()
            .map(crate::dataset::GtObject::as_detection)
            .collect();
        v.boxes(
            "/ground_truth",
            "gt",
            wall,
            &boxes,
            v2x_fuser::viz::GROUND_TRUTH,
        );
    }
}

/// Writes the fused output as a results file (`--record`).
fn record(
    path: &std::path::Path,
    gt: &GroundTruth,
    schedule: &Schedule,
    outcome: &FuserOutcome,
) -> anyhow::Result<()> {
    let r = recorded(gt, schedule, outcome);
    write_results(path, &r, &gt.tokens)?;
    eprintln!(
        "recorded {} fused frames -> {}",
        r.samples.len(),
        path.display()
    );
    Ok(())
}

/// Prints the run's summary in the chosen format.
fn print_summary(summary: &Summary, format: RunFormat) -> anyhow::Result<()> {
    match format {
        RunFormat::Json => println!("{}", serde_json::to_string_pretty(summary)?),
        RunFormat::Table => print_table(summary),
    }
    Ok(())
}

/// Runs the named roles with the scenario's endpoints; returns the summary if the fuser ran here.
async fn run_roles(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    roles: &[String],
    format: RunFormat,
    stop: watch::Receiver<bool>,
    viz: Option<std::sync::Arc<v2x_fuser::viz::Viz>>,
) -> anyhow::Result<Option<(Summary, FuserOutcome)>> {
    let start = std::time::Instant::now();
    let run_fuser = roles.iter().any(|r| r == "fuser");
    // The router first (its clients connect to it), until the run ends or is stopped.
    let router = if roles.iter().any(|r| r == "router") {
        Some(open_router(scenario).await?)
    } else {
        None
    };
    let fuser = async {
        if !run_fuser {
            return anyhow::Ok(None);
        }
        Ok(Some(
            fuser_side(scenario, schedule, viz, stop.clone()).await?,
        ))
    };
    let agents = async {
        let mut out = BTreeMap::new();
        let runs = scenario
            .agents
            .iter()
            .enumerate()
            .filter(|(_, a)| roles.contains(&a.name))
            .map(|(idx, a)| agent_side(scenario, gt, schedule, idx, &a.name, stop.clone()));
        for r in futures::future::join_all(runs).await {
            let (name, side) = r?;
            out.insert(name, side);
        }
        anyhow::Ok(out)
    };
    let router_only = router.is_some() && !run_fuser && !roles.iter().any(|r| r != "router");
    // The router's traffic is sampled while it serves: agents on other hosts leave before the end.
    let (sampling, sampled) = watch::channel(false);
    let router_samples = router
        .as_ref()
        .map(|r| meter::sample_every_second(r.clone(), sampled));
    let (outcome, totals) = tokio::join!(fuser, agents);
    if router_only {
        // A router alone serves until stopped.
        stopped(stop.clone()).await;
    }
    let _ = sampling.send(true);
    let router_traffic = match router_samples {
        Some(task) => task.await.unwrap_or_default(),
        None => Vec::new(),
    };
    if let Some(r) = router {
        let _ = r.close().await;
    }
    let totals = totals?;
    let mut outcome = outcome?;
    if let Some(o) = &mut outcome {
        o.router_traffic = router_traffic;
    }
    if outcome.is_none() && !totals.is_empty() {
        report_agents_alone(scenario, schedule, &totals, format)?;
    }
    let elapsed = start.elapsed().as_secs_f64();
    Ok(outcome.map(|o| (summarize(scenario, gt, schedule, &o, &totals, elapsed), o)))
}

/// The router's session, with the scenario's access control.
async fn open_router(scenario: &Scenario) -> anyhow::Result<zenoh::Session> {
    let args = secure::role_args(scenario, Role::Router)?;
    let session = meter::open_role_session(&args, scenario, Role::Router).await?;
    eprintln!("router: running with access control");
    Ok(session)
}

/// The fuser's role in a run: its session, the run's shared start 3 s ahead, and the fuser until
/// the schedule's end (plus the windows' wait and 2 s) or a stop.
async fn fuser_side(
    scenario: &Scenario,
    schedule: &Schedule,
    viz: Option<std::sync::Arc<v2x_fuser::viz::Viz>>,
    stop: watch::Receiver<bool>,
) -> anyhow::Result<FuserOutcome> {
    let args = secure::role_args(scenario, Role::Fuser)?;
    let session = meter::open_role_session(&args, scenario, Role::Fuser).await?;
    let epoch = now_us() + 3_000_000;
    let end = fuser_end_us(scenario, schedule, epoch);
    eprintln!(
        "fuser: epoch in 3 s, running for {:.1} s",
        (end - now_us()) as f64 / 1e6
    );
    let until = async move {
        tokio::select! {
            _ = tokio::time::sleep(Duration::from_micros(end.saturating_sub(now_us()))) => {}
            _ = stopped(stop) => {}
        }
    };
    let outcome = fuser_role(&session, scenario, schedule, epoch, viz, until).await?;
    let _ = session.close().await;
    Ok(outcome)
}

/// When a fuser whose run starts at `epoch` (wall clock, us) stops: the schedule's end, plus
/// the windows' wait and 2 s for the last frames.
pub(crate) fn fuser_end_us(scenario: &Scenario, schedule: &Schedule, epoch: u64) -> u64 {
    schedule.wall_us(
        epoch,
        schedule.t0_us + schedule.duration_us(),
        scenario.speed,
    ) + 2_000_000
        + (scenario.fuser.settings.max_wait_ms * 1000.0) as u64
}

/// One agent's role in a run: its session, the run's shared start from the fuser, its frames,
/// and what it sent.
async fn agent_side(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    idx: usize,
    name: &str,
    stop: watch::Receiver<bool>,
) -> anyhow::Result<(String, AgentSide)> {
    let opened = std::time::Instant::now();
    let args = secure::role_args(scenario, Role::Agent(name))?;
    let session = meter::open_role_session(&args, scenario, Role::Agent(name)).await?;
    eprintln!(
        "agent {name}: session open in {:.1} ms",
        opened.elapsed().as_secs_f64() * 1000.0
    );
    let epoch = epoch::query_epoch(&session, &scenario.namespace, Duration::from_secs(60)).await?;
    let t = agent_role(&session, scenario, gt, schedule, idx, epoch, stop).await?;
    let sent = meter::snapshot(&session, name).await;
    let _ = session.close().await;
    eprintln!(
        "agent {name}: sent {} frames ({} dropped by the link), {} payload bytes, {} bytes on the wire",
        t.frames,
        t.dropped,
        t.payload_bytes,
        sent.as_ref().map_or("?".into(), |tr| {
            let key = meter::agent_key(scenario, name);
            tr.sent_with(&key).bytes.to_string()
        })
    );
    let side = AgentSide {
        totals: t,
        sent,
        socket_bytes: None,
    };
    Ok((name.to_owned(), side))
}

/// Agents run without the fuser: each reports its own side.
fn report_agents_alone(
    scenario: &Scenario,
    schedule: &Schedule,
    totals: &BTreeMap<String, AgentSide>,
    format: RunFormat,
) -> anyhow::Result<()> {
    let report = AgentReport {
        namespace: scenario.namespace.clone(),
        bandwidth: totals
            .iter()
            .map(|(n, side)| {
                let b = agent_bandwidth(scenario, schedule, n, side, None);
                (n.clone(), b)
            })
            .collect(),
        sent: totals
            .iter()
            .map(|(n, side)| (n.clone(), (side.totals.frames, side.totals.dropped)))
            .collect(),
    };
    match format {
        RunFormat::Json => println!("{}", serde_json::to_string_pretty(&report)?),
        RunFormat::Table => print_agent_table(&report),
    }
    Ok(())
}
