//! The roles of a run: an agent replays its view of the ground truth on the shared schedule; the
//! fuser runs the fuser node and maps each fused window back to its scheduled frame.

use super::epoch::serve_epoch;
use super::schedule::Schedule;
use crate::dataset::{GroundTruth, GtFrame};
use crate::noise::{detect, place_agents, AgentNoise};
use crate::scenario::Scenario;
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::sync::watch;
use v2x_agent::{now_us, Agent, AgentTotals};
use v2x_fuser::node::{self, NodeConfig, NodeStats};
use v2x_protocol::{Detection, Frame};

/// The detections agent `idx` of a scenario makes of ground-truth frame `gi`, and where it
/// stands.
pub fn agent_view(
    scenario: &Scenario,
    gt: &GroundTruth,
    gi: usize,
    idx: usize,
) -> (Vec<Detection>, [f64; 3]) {
    let frame: &GtFrame = &gt.frames[gi];
    let spec = &scenario.agents[idx];
    let noise: AgentNoise = spec
        .noise
        .parse()
        .expect("checked when the scenario loaded");
    let place = place_agents(frame, scenario.agents.len(), scenario.seed)[idx].position;
    (
        detect(frame, gi, idx, &noise, place, spec.range_m, scenario.seed),
        place,
    )
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
        tokio::select! {
            _ = tokio::time::sleep(Duration::from_micros(due.saturating_sub(now))) => {}
            _ = stop.wait_for(|s| *s) => break,
        }
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
    let mut cfg = NodeConfig::new(&scenario.namespace, scenario.method());
    cfg.window_ms = (scenario.fuser.window_ms / scenario.speed)
        .min(schedule.period_us as f64 / 1000.0 / scenario.speed);
    cfg.max_wait_ms = scenario.fuser.max_wait_ms;
    let answer = serve_epoch(session, &scenario.namespace, epoch_us).await?;
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
