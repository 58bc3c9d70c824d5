//! The roles of a run: an agent replays its view of the ground truth on the shared schedule; the
//! fuser runs the fuser node and maps each fused window back to its scheduled frame.

use super::epoch::serve_epoch;
use super::schedule::Schedule;
use crate::dataset::GroundTruth;
use crate::noise::AgentNoise;
use crate::noise::{detect, place_agents, recorded_view, Capture};
use crate::scenario::Scenario;
use crate::timeline::fuser_restarts;
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::sync::watch;
use v2x_agent::{now_us, Agent, AgentTotals};
use v2x_fuser::node::{self, NodeConfig, NodeStats};
use v2x_protocol::traffic::Traffic;
use v2x_protocol::{Detection, Frame};

/// The detections agent `idx` of a scenario makes at data time `t_us` (its `draw`-th capture)
/// with `noise` (its own, or as the timeline has changed it), and where it stands.
pub fn agent_view(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    idx: usize,
    draw: usize,
    t_us: u64,
    noise: &AgentNoise,
) -> (Vec<Detection>, [f64; 3]) {
    let spec = &scenario.agents[idx];
    if let Some(rec) = &gt.recorded {
        // The recorded agent's own view at the scheduled frame it captured for.
        let Some(&i) = schedule
            .frames
            .iter()
            .find(|&&i| rec.capture_us(idx, i) == t_us)
        else {
            return (Vec::new(), [0.0; 3]);
        };
        if let Some(dets) = rec.detections(idx, i) {
            // A detector's own boxes, replayed as they are.
            return (dets.to_vec(), rec.position(idx, i));
        }
        let view = recorded_view(gt, rec.as_ref(), idx, i, noise, scenario.seed, spec.range_m);
        return (view, rec.position(idx, i));
    }
    let objects = gt.in_draw_order(gt.objects_at(schedule.scene, t_us));
    let near = gt
        .nearest_frame(schedule.scene, t_us)
        .map(|i| &gt.frames[i]);
    let place = near.map_or([0.0; 3], |f| {
        place_agents(f, scenario.agents.len(), scenario.seed)[idx].position
    });
    (
        detect(
            &objects,
            Capture {
                draw: draw as u64,
                scene: schedule.scene,
                t_us,
            },
            idx,
            noise,
            place,
            spec.range_m,
            scenario.seed,
        ),
        place,
    )
}

/// An agent's capture times (data time) in a run: a recorded agent's own, once each (a
/// roadside frame paired with two vehicle frames is sent once), else on its rate and phase.
pub fn agent_captures(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    idx: usize,
) -> Vec<u64> {
    if let Some(rec) = &gt.recorded {
        let mut times: Vec<u64> = Vec::with_capacity(schedule.frames.len());
        for &i in &schedule.frames {
            let t = rec.capture_us(idx, i);
            if times.last().is_none_or(|&last| t > last) {
                times.push(t);
            }
        }
        return times;
    }
    let spec = &scenario.agents[idx];
    schedule.captures(spec.hz, spec.phase_ms)
}

/// Runs one agent role until its schedule ends or `stop` turns true.
pub async fn agent_role(
    session: &zenoh::Session,
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    idx: usize,
    epoch_us: u64,
    mut stop: watch::Receiver<bool>,
) -> anyhow::Result<AgentTotals> {
    let spec = &scenario.agents[idx];
    let agent = Agent::start(
        session,
        &scenario.namespace,
        &spec.name,
        spec.kind,
        spec.link.clone(),
        scenario.seed.wrapping_add(idx as u64 * 7919),
    )
    .await?
    .counting_cpm();
    let agent = match spec.cpm {
        true => agent.sending_cpm(scenario.geo()),
        false => agent,
    };
    let mut agent = wait_for_fuser(agent, scenario, gt, schedule, idx).await?;
    let mut timeline = spec.timeline(&scenario.events);
    let mut state = timeline.at(0);
    for (j, t) in agent_captures(scenario, gt, schedule, idx)
        .into_iter()
        .enumerate()
    {
        let due = schedule.wall_us(epoch_us, t, scenario.speed);
        let now = now_us();
        if due + 1000 < now {
            continue; // joined late: this frame's time has passed
        }
        tokio::select! {
            _ = tokio::time::sleep(Duration::from_micros(due.saturating_sub(now))) => {}
            Ok(_) = stop.wait_for(|s| *s) => break,
        }
        // The scripted events due by this capture, on the scenario's clock.
        let now_state = timeline.at(t.saturating_sub(schedule.t0_us));
        if now_state.present != state.present {
            if now_state.present {
                agent.join(session).await?;
            } else {
                agent.leave();
            }
        }
        if now_state.link != state.link {
            agent.set_link(now_state.link.clone())?;
        }
        state = now_state;
        if !state.present {
            continue;
        }
        let (detections, origin) = agent_view(scenario, gt, schedule, idx, j, t, &state.noise);
        agent.send(Frame {
            agent: spec.name.clone(),
            kind: spec.kind,
            seq: 0,
            // the sensor time this view stands for, in wall time
            capture_us: due,
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

/// Waits, 30 s at most, until the agent's fuser hears it: the single fuser, or per tile the fuser
/// of the tile the agent starts in, if it has one (the agent then publishes per tile).
async fn wait_for_fuser(
    mut agent: Agent,
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    idx: usize,
) -> anyhow::Result<Agent> {
    let Some(r) = &scenario.regions else {
        agent.wait_for_subscriber(Duration::from_secs(30)).await?;
        return Ok(agent);
    };
    let tiling = r.tiling();
    agent = agent.with_tiling(tiling);
    let first = agent_captures(scenario, gt, schedule, idx).first().copied();
    if let Some(t) = first {
        let noise = scenario.agents[idx].agent_noise();
        let (_, place) = agent_view(scenario, gt, schedule, idx, 0, t, &noise);
        let home = tiling.tile_of(place);
        if r.regions().iter().any(|g| g.tile == home) {
            agent
                .wait_for_subscriber_in(home, Duration::from_secs(30))
                .await?;
        }
    }
    Ok(agent)
}

/// Every agent role of a scenario, each on its own session, until its schedule ends or `stop`.
pub async fn all_agents(
    sessions: &[zenoh::Session],
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    epoch_us: u64,
    stop: &watch::Receiver<bool>,
) -> Vec<anyhow::Result<AgentTotals>> {
    let runs = (0..scenario.agents.len()).map(|idx| {
        agent_role(
            &sessions[idx],
            scenario,
            gt,
            schedule,
            idx,
            epoch_us,
            stop.clone(),
        )
    });
    futures::future::join_all(runs).await
}

/// What the fuser role collected.
#[derive(Default)]
pub struct FuserOutcome {
    /// The node's statistics.
    pub stats: NodeStats,
    /// Fused detections by their reference time in data time (us).
    pub fused: BTreeMap<u64, Vec<Detection>>,
    /// With tracking: the tracks each window updated, by the same time (ids: tracking ids).
    pub tracks: BTreeMap<u64, Vec<Detection>>,
    /// Each window's agents, completeness and end-to-end latency, by the same time.
    pub windows: BTreeMap<u64, WindowRecord>,
    /// The data time the run reached before the fuser stopped (us): scheduled frames up to it
    /// are scored.
    pub reached_us: u64,
    /// The wall-clock time of the data's first scheduled frame (us).
    pub epoch_us: u64,
    /// The fuser session's traffic, sampled about once a second (wall clock, us), from Zenoh's
    /// statistics (empty if the session was opened without them).
    pub traffic: Vec<(u64, Traffic)>,
    /// When the fuser restarted (scripted), on the wall clock (us).
    pub restarts_us: Vec<u64>,
    /// The router's traffic, sampled over the run, when the router ran in this process.
    pub router_traffic: Vec<(u64, Traffic)>,
}

/// What the fuser role saw of one window.
#[derive(Clone, Debug, PartialEq)]
pub struct WindowRecord {
    /// The agents whose frames it fused.
    pub agents: Vec<String>,
    /// How many fused boxes each of those agents' boxes went into (its objects in the window).
    pub objects: Vec<u64>,
    /// Closed with every live agent's frame.
    pub complete: bool,
    /// Capture (the window's reference time) to publish, on this host's clock (ms).
    pub e2e_ms: f64,
    /// With learned stds: the agents flagged as stating inconsistent stds after it.
    pub flagged: Vec<String>,
}

/// Runs the fuser role until `stop` resolves.
pub async fn fuser_role(
    session: &zenoh::Session,
    scenario: &Scenario,
    schedule: &Schedule,
    epoch_us: u64,
    viz: Option<std::sync::Arc<v2x_fuser::viz::Viz>>,
    stop: impl std::future::Future<Output = ()>,
) -> anyhow::Result<FuserOutcome> {
    regional_fuser_role(session, scenario, schedule, epoch_us, None, true, viz, stop).await
}

/// The fuser node's configuration for a scenario (a region's, with `region`).
fn node_config(
    scenario: &Scenario,
    region: Option<v2x_fuser::intake::region::Region>,
    viz: Option<std::sync::Arc<v2x_fuser::viz::Viz>>,
) -> anyhow::Result<NodeConfig> {
    let mut cfg = scenario
        .fuser
        .node_config(&scenario.namespace, scenario.speed)?;
    // Real detectors' boxes: their groups scored and their tail dropped, as `--detector` does.
    if scenario.dataset.kind == crate::cli::DatasetKind::V2v4real {
        cfg.steps.detector = Some(v2x_fuser::uncertainty::detector::DetectorParams::default());
    }
    cfg.region = region;
    cfg.handover = scenario.regions.as_ref().is_none_or(|r| r.track_handover);
    cfg.viz = viz;
    cfg.map_origin = scenario.geo();
    Ok(cfg)
}

/// What a run keeps of a fused window.
fn window_record(f: &node::Fused) -> WindowRecord {
    let p = &f.provenance;
    let mut objects = vec![0u64; p.agents.len()];
    for set in &p.sources {
        for i in set.iter() {
            if let Some(n) = objects.get_mut(i) {
                *n += 1;
            }
        }
    }
    WindowRecord {
        agents: p.agents.clone(),
        objects,
        complete: p.complete,
        e2e_ms: (now_us() as f64 - f.frame.capture_us as f64) / 1000.0,
        flagged: f
            .learned
            .iter()
            .filter(|(_, r)| r.flagged)
            .map(|(a, _)| a.clone())
            .collect(),
    }
}

/// Runs a fuser role, the single fuser or (with `region`) a regional one, until `stop`
/// resolves; `serves_epoch`: it answers the run's shared start.
#[allow(clippy::too_many_arguments)]
pub async fn regional_fuser_role(
    session: &zenoh::Session,
    scenario: &Scenario,
    schedule: &Schedule,
    epoch_us: u64,
    region: Option<v2x_fuser::intake::region::Region>,
    serves_epoch: bool,
    viz: Option<std::sync::Arc<v2x_fuser::viz::Viz>>,
    stop: impl std::future::Future<Output = ()>,
) -> anyhow::Result<FuserOutcome> {
    let cfg = node_config(scenario, region, viz)?;
    let answer = match serves_epoch {
        true => Some(serve_epoch(session, &scenario.namespace, epoch_us).await?),
        false => None,
    };
    let (sampling, sampled) = watch::channel(false);
    let sampler = super::meter::sample_every_second(session.clone(), sampled);
    let mut outcome = run_segments(session, &cfg, scenario, schedule, epoch_us, stop).await?;
    if let Some(a) = answer {
        a.abort();
    }
    let _ = sampling.send(true);
    outcome.traffic = sampler.await.unwrap_or_default();
    // The fuser stops max_wait after the last frame at the earliest: what it had not seen by then
    // was not going to come.
    let stopped = now_us().saturating_sub((scenario.fuser.settings.max_wait_ms * 1000.0) as u64);
    outcome.reached_us = schedule.data_us(epoch_us, stopped, scenario.speed);
    Ok(outcome)
}

/// The node until `stop`, restarted afresh (after its downtime) at each scripted restart: its
/// counters over every run, what it fused and tracked, and when it restarted.
async fn run_segments(
    session: &zenoh::Session,
    cfg: &NodeConfig,
    scenario: &Scenario,
    schedule: &Schedule,
    epoch_us: u64,
    stop: impl std::future::Future<Output = ()>,
) -> anyhow::Result<FuserOutcome> {
    let mut fused = BTreeMap::new();
    let mut tracks = BTreeMap::new();
    let mut windows = BTreeMap::new();
    let speed = scenario.speed;
    let restarts = fuser_restarts(&scenario.events);
    let mut restarts_us = Vec::new();
    let mut stats: Option<NodeStats> = None;
    tokio::pin!(stop);
    let mut stopped = false;
    for segment in 0..=restarts.len() {
        let until = restarts
            .get(segment)
            .map(|(at, _)| schedule.wall_us(epoch_us, schedule.t0_us + at, speed));
        let segment_stop = async {
            match until {
                Some(w) => tokio::select! {
                    _ = &mut stop => stopped = true,
                    _ = tokio::time::sleep(Duration::from_micros(w.saturating_sub(now_us()))) => {}
                },
                None => {
                    (&mut stop).await;
                    stopped = true;
                }
            }
        };
        let s = node::run(
            session,
            cfg.clone(),
            |f| {
                let t = schedule.data_us(epoch_us, f.frame.capture_us, speed);
                fused.insert(t, f.frame.detections.clone());
                if let Some(tracked) = &f.tracks {
                    tracks.insert(t, tracked.clone());
                }
                windows.insert(t, window_record(f));
            },
            segment_stop,
        )
        .await?;
        stats = Some(match stats {
            None => s,
            Some(all) => absorbed(all, s),
        });
        if stopped || segment == restarts.len() {
            break;
        }
        restarts_us.push(now_us());
        tokio::select! {
            _ = &mut stop => break,
            _ = tokio::time::sleep(Duration::from_micros(restarts[segment].1)) => {}
        }
    }
    let mut stats = stats.unwrap_or_default();
    if !restarts_us.is_empty() {
        // Latency over every run of the node (percentiles do not add up).
        let e2e: Vec<f64> = windows.values().map(|w: &WindowRecord| w.e2e_ms).collect();
        stats.e2e_latency_ms = node::Latency::of(&e2e);
        stats.fusion_latency_ms = node::Latency::of(&stats.fusion_samples);
    }
    let (reached_us, traffic, router_traffic) = (0, Vec::new(), Vec::new());
    Ok(FuserOutcome {
        stats,
        fused,
        tracks,
        windows,
        reached_us,
        epoch_us,
        traffic,
        restarts_us,
        router_traffic,
    })
}

/// [`absorb`] by value.
fn absorbed(mut all: NodeStats, later: NodeStats) -> NodeStats {
    absorb(&mut all, later);
    all
}

/// Adds a later run of the node's counters (or another region's) to the earlier runs'
/// (latencies are recomputed by the caller).
pub fn absorb(all: &mut NodeStats, later: NodeStats) {
    for (name, a) in later.agents {
        let e = all.agents.entry(name).or_default();
        e.frames_in += a.frames_in;
        e.accepted += a.accepted;
        e.fused += a.fused;
        e.invalid += a.invalid;
        e.wrong_agent += a.wrong_agent;
        e.future += a.future;
        e.stale += a.stale;
        e.late += a.late;
        e.duplicate += a.duplicate;
        e.replaced += a.replaced;
        e.payload_bytes += a.payload_bytes;
        e.objects += a.objects;
        e.clock_lag_ms = a.clock_lag_ms;
        e.token = a.token;
    }
    for (reason, n) in later.rejected {
        *all.rejected.entry(reason).or_default() += n;
    }
    all.windows += later.windows;
    all.windows_incomplete += later.windows_incomplete;
    all.windows_unpublished += later.windows_unpublished;
    all.windows_dropped += later.windows_dropped;
    all.fused_objects += later.fused_objects;
    all.agents_forgotten += later.agents_forgotten;
    all.fusion_samples.extend(later.fusion_samples);
    all.live = later.live;
    all.awaited = later.awaited;
    all.tracks = later.tracks;
}
