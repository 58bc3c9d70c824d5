//! What a node is given (its configuration, usually built from
//! [`crate::settings::FuserSettings`]), what it hands out per fused window, and its clock.

use crate::intake::ingest::IngestConfig;
use crate::intake::region::Region;
use crate::intake::region::Scope;
use crate::pipeline::Steps;
use crate::time::motion::MotionParams;
use crate::Method;
use anyhow::anyhow;
use std::sync::Arc;
use std::time::Instant;
use v2x_protocol::keys;
use v2x_protocol::{Frame, Provenance};

/// How the node runs.
#[derive(Clone, Debug)]
pub struct NodeConfig {
    /// Scenario namespace.
    pub ns: String,
    /// What each window goes through (`crate::pipeline`): the method, a detector's scoring and
    /// tail, motion compensation (on by default), registration, learned stds and calibrated
    /// models by agent name.
    pub steps: Steps,
    /// Window width delta t (ms).
    pub window_ms: f64,
    /// Longest wait for missing agents after a window's first frame (ms).
    pub max_wait_ms: f64,
    /// Admission limits: clock tolerance, agent table, boxes per agent, area of interest.
    pub ingest: IngestConfig,
    /// Closed windows that may wait for fusion; beyond, windows are dropped and counted.
    pub queue: usize,
    /// Interval of the rate-limited log summaries (s).
    pub log_interval_s: f64,
    /// Tracking of the fused boxes, published on `v2x/NS/tracks` (`None`: no tracks).
    pub track: Option<crate::tracker::TrackerParams>,
    /// Where the boxes are shown (an MCAP file, a live Foxglove server), if anywhere.
    pub viz: Option<Arc<crate::viz::Viz>>,
    /// The region this fuser serves (`None`: the single fuser of the namespace, on
    /// `v2x/NS/det/*`).
    pub region: Option<Region>,
    /// With a region and tracking: hear the neighbours' tracks and keep an object's tracking id
    /// across tile borders (`crate::tracker::handover`); off, each region's ids are its own.
    pub handover: bool,
    /// Where the map frame lies on the earth, to read agents' ETSI CPMs (docs/cpm.md); the
    /// agents must give the same.
    pub map_origin: v2x_cpm::Geo,
}

impl NodeConfig {
    /// Refuses a configuration the node cannot run with.
    pub(super) fn check(&self) -> anyhow::Result<()> {
        let cfg = self;
        keys::validate_chunk("namespace", &cfg.ns).map_err(|e| anyhow!(e))?;
        let window_ok = cfg.window_ms > 0.0 && cfg.window_ms.is_finite();
        let wait_ok = cfg.max_wait_ms >= 0.0 && cfg.max_wait_ms.is_finite();
        if !window_ok || !wait_ok {
            anyhow::bail!("the window must be > 0 ms and the wait >= 0 ms");
        }
        if cfg.ingest.max_agents == 0 || cfg.queue == 0 || cfg.ingest.max_objects == 0 {
            anyhow::bail!(
                "the agent table, the fusion queue and the budget of boxes per agent must hold at least one entry"
            );
        }
        cfg.ingest.area.validate().map_err(|e| anyhow!(e))?;
        if cfg.ingest.max_agents > v2x_protocol::limits::MAX_WINDOW_AGENTS {
            anyhow::bail!(
                "the agent table may hold at most {} agents (the most a fused frame can name)",
                v2x_protocol::limits::MAX_WINDOW_AGENTS
            );
        }
        Ok(())
    }

    /// Says what the node serves.
    pub(super) fn log_start(&self, method: &str) {
        let cfg = self;
        let ns = &cfg.ns;
        match cfg.scope() {
            Scope::Whole => tracing::info!(
                "fuser on v2x/{ns}: method {method}, window {} ms",
                cfg.window_ms
            ),
            Scope::Tile(r) => tracing::info!(
                "fuser of tile {} ({} m, halo {} m) on v2x/{ns}: method {method}, window {} ms",
                r.tile,
                r.tiling.size_m(),
                r.halo_m,
                cfg.window_ms
            ),
        }
    }
}

impl NodeConfig {
    /// The defaults: windows of 100 ms waiting at most 150 ms, 1 s clock tolerance, 256 agents,
    /// a fusion queue of 16 windows, log summaries every 10 s, motion compensation on.
    pub fn new(ns: &str, method: Method) -> Self {
        NodeConfig {
            ns: ns.to_string(),
            steps: Steps {
                motion: Some(MotionParams::default()),
                ..Steps::method(method)
            },
            window_ms: 100.0,
            max_wait_ms: 150.0,
            ingest: IngestConfig::default(),
            queue: 16,
            log_interval_s: 10.0,
            track: None,
            viz: None,
            region: None,
            handover: true,
            map_origin: Default::default(),
        }
    }

    /// What the node serves: the whole namespace, or its region's tile and halo.
    pub fn scope(&self) -> crate::intake::region::Scope {
        self.region.into()
    }

    /// Sets the replay speed of motion compensation, tracking and the learner at once
    /// ([`crate::pipeline::set_time_scale`]): call it after setting them.
    pub fn set_time_scale(&mut self, s: f64) {
        crate::pipeline::set_time_scale(
            s,
            self.steps.motion.as_mut(),
            self.steps.learn.as_mut(),
            self.track.as_mut(),
        );
    }
}

/// A fused window as published.
#[derive(Clone, Debug)]
pub struct Fused {
    /// The fused frame (agent "fuser", capture time = the window's reference time: its latest
    /// capture).
    pub frame: Frame,
    /// The window's agents, whether it was complete, and each fused box's contributing agents
    /// (published with the frame).
    pub provenance: Provenance,
    /// With tracking: the confirmed tracks the window updated, each box's id its tracking id
    /// (as published on the tracks key).
    pub tracks: Option<Vec<v2x_protocol::Detection>>,
    /// With registration: each registered agent's estimate in this window.
    pub registration: std::collections::BTreeMap<String, crate::time::align::Registration>,
    /// With learned stds: what is learned of each agent after this window.
    pub learned: std::collections::BTreeMap<String, crate::uncertainty::learn::AgentReport>,
}

/// The fuser's clock: the wall clock read once at start, advanced by a monotonic clock, in
/// microseconds since the Unix epoch (the time base of capture times).
#[derive(Clone, Copy, Debug)]
pub struct Clock {
    wall0_us: u64,
    mono0: Instant,
}

impl Clock {
    /// Starts now.
    pub fn start() -> Self {
        Clock {
            wall0_us: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_micros() as u64),
            mono0: Instant::now(),
        }
    }

    /// Now, in microseconds since the Unix epoch.
    pub fn now_us(&self) -> u64 {
        self.wall0_us + self.mono0.elapsed().as_micros() as u64
    }
}
