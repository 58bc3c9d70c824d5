//! The fuser node: the thin Zenoh shell around [`crate::intake::ingest`], [`crate::time::window`] and a
//! [`Method`].
//!
//! The receive loop subscribes to `v2x/NS/det/*` and `v2x/NS/alive/*`, admits each frame
//! ([`Ingest`]: size, count, validity, clock tolerance, bounded agent table), feeds the window
//! state machine, and hands each closed window to the fusion [`worker`] through a bounded queue;
//! the worker fuses, fits the result to the wire's domain, and publishes it on `v2x/NS/fused`.
//! The loop also answers `v2x/NS/fuser/stats` with [`NodeStats`] as JSON, logs rejections at a
//! bounded rate ([`RateLog`]), and forgets idle agents.
//!
//! A regional fuser ([`NodeConfig::region`]) subscribes instead to `v2x/NS/det/TILE/*` for its
//! tile and every tile reaching into its halo, puts each capture's parts back together
//! ([`Parts`]), keeps the boxes within its tile and halo, and publishes only the fused boxes
//! whose centre lies in its own tile, on its region's keys ([`keys::FuserKeys`]).

mod config;
mod cpm;
mod handover;
mod query;
pub mod ratelog;
pub mod ros_out;
mod stats;
mod worker;

pub use config::{Clock, Fused, NodeConfig};
use query::reply_stats;
pub use query::{query_stats, query_stats_at};
pub use stats::{FitStats, Latency, NodeStats};
pub use v2x_protocol::net::shutdown_signal;
pub use worker::fuse_window;

use crate::intake::ingest::{Ingest, IngestConfig, Rejection};
use crate::intake::parts::{Assembled, Parts};
use crate::intake::region::Scope;
use crate::node::ratelog::RateLog;
use crate::time::window::{Closed, Windows};
use anyhow::anyhow;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;
use v2x_protocol::{keys, Frame};
use zenoh::sample::SampleKind;

mod wiring;
use wiring::{declare_frames, start_worker, subscribe_detections, z};

const MAX_LATENCY_SAMPLES: usize = 200_000;

struct State {
    ns: String,
    clock: Clock,
    ingest: Ingest,
    windows: Windows,
    log: RateLog,
    stats: NodeStats,
    e2e: stats::LatencyHistogram,
    fusion_hist: stats::LatencyHistogram,
    fusion: Vec<f64>,
    queued: usize,
    last_prune_us: u64,
    viz: Option<Arc<crate::viz::Viz>>,
    scope: Scope,
    /// Where the map lies, to read CPMs.
    map_origin: v2x_cpm::Geo,
    parts: Parts,
    /// The association's bounds applied in this process before the node started.
    /// How often the association's bounds applied in this node's windows (capped, greedy).
    degraded: (u64, u64),
}

/// Agents' live and left lines told per log interval; beyond, they are counted.
const LIVE_LINES: u64 = 16;
/// Most captures a regional fuser puts together at once, per agent it may track.
const PENDING_PER_AGENT: usize = 4;
/// Samples a regional fuser's subscriptions may queue for its loop; beyond, they are dropped
/// and counted.
const INBOX: usize = 8192;

/// Where the detections come in: one subscription, or one per tile of a region.
enum Inbox {
    Whole(zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>),
    Tiles {
        rx: mpsc::Receiver<zenoh::sample::Sample>,
        _subs: Vec<zenoh::pubsub::Subscriber<()>>,
    },
}

impl Inbox {
    async fn recv(&mut self) -> Option<zenoh::sample::Sample> {
        match self {
            Inbox::Whole(s) => s.recv_async().await.ok(),
            Inbox::Tiles { rx, .. } => rx.recv().await,
        }
    }
}

impl State {
    /// The loop's state at the start: no agent, no window.
    fn new(cfg: &NodeConfig, clock: Clock, subscribed: &[v2x_protocol::tiles::Tile]) -> Self {
        let now = clock.now_us();
        State {
            viz: cfg.viz.clone(),
            ns: cfg.ns.clone(),
            clock,
            ingest: Ingest::new(IngestConfig {
                max_wait_us: (cfg.max_wait_ms * 1000.0) as u64,
                ahead_us: (cfg.window_ms * 500.0) as u64,
                ..cfg.ingest.clone()
            }),
            windows: Windows::new(
                (cfg.window_ms * 1000.0) as u64,
                (cfg.max_wait_ms * 1000.0) as u64,
            ),
            log: RateLog::new((cfg.log_interval_s.max(0.1) * 1e6) as u64, now),
            stats: NodeStats {
                ns: cfg.ns.clone(),
                method: cfg.steps.method.name(),
                region: cfg.scope().tile().map(|t| t.to_string()),
                ..Default::default()
            },
            e2e: Default::default(),
            fusion_hist: Default::default(),
            fusion: Vec::new(),
            queued: 0,
            last_prune_us: now,
            scope: cfg.scope(),
            map_origin: cfg.map_origin,
            // A capture's parts leave its agent together: waiting half the window's wait for
            // a missing one leaves the other half for the capture to make its window.
            parts: Parts::new(
                subscribed,
                (cfg.max_wait_ms * 500.0) as u64,
                cfg.ingest.max_agents.saturating_mul(PENDING_PER_AGENT),
            ),
            degraded: (0, 0),
        }
    }

    /// At a stop: every waiting capture and open window goes to the worker, whose queue then
    /// closes.
    async fn flush(&mut self, job_tx: mpsc::Sender<worker::Job>) {
        let expired = self.parts.expire(u64::MAX);
        self.admit_parts(expired, self.clock.now_us());
        self.stats.open_windows_at_stop = self.windows.open_windows();
        let now = self.clock.now_us();
        for closed in self.close_ready(u64::MAX) {
            self.queued += 1;
            let job = worker::Job {
                closed,
                closed_at_us: now,
            };
            if job_tx.send(job).await.is_err() {
                self.queued -= 1;
                self.stats.windows_dropped += 1;
            }
        }
    }

    fn snapshot(&self) -> NodeStats {
        let now = self.clock.now_us();
        let mut s = self.stats.clone();
        s.live = self.ingest.tokens();
        s.awaited = self
            .ingest
            .awaited(now, self.windows.half_us())
            .into_iter()
            .collect();
        s.agents = self.ingest.agent_stats();
        s.agents_tracked = self.ingest.tracked();
        s.agents_forgotten = self.ingest.forgotten();
        s.rejected = self
            .ingest
            .rejected()
            .iter()
            .map(|(k, v)| (k.to_string(), *v))
            .collect();
        s.dropped = self
            .ingest
            .noted()
            .iter()
            .map(|(k, v)| (k.to_string(), *v))
            .collect();
        s.area = self.ingest.area_center().map(|center| stats::AreaReport {
            center,
            radius_m: self.ingest.config().area.radius_m(),
            learned: matches!(
                self.ingest.config().area,
                crate::intake::ingest::Area::Learned { .. }
            ),
        });
        s.degraded = stats::Degraded {
            candidates_capped: self.degraded.0,
            components_greedy: self.degraded.1,
        };
        s.open_windows = self.windows.open_windows();
        s.fusion_queue = self.queued;
        s.e2e_latency_ms = self.e2e.latency();
        s.fusion_latency_ms = self.fusion_hist.latency();
        s
    }

    /// Logs what admission dropped or flagged, at a bounded rate.
    fn log_notes(&mut self) {
        for n in self.ingest.take_notes() {
            if let Some(line) = self.log.note(n.reason(), &n.to_string()) {
                tracing::warn!("{line}");
            }
        }
    }

    fn warn(&mut self, r: &Rejection, key: &str) {
        if let Some(line) = self.log.note(r.reason(), &format!("{key}: {r}")) {
            tracing::warn!("{line}");
        }
    }

    fn on_sample(&mut self, s: &zenoh::sample::Sample) {
        let key = s.key_expr().as_str();
        let payload = s.payload().to_bytes();
        let cpm = v2x_protocol::net::is_cpm(s.encoding());
        if self.scope == Scope::Whole {
            if let Some(agent) = keys::agent_of_detections(&self.ns, key) {
                let now = self.clock.now_us();
                match self.offer(&agent, cpm, &payload, now) {
                    Ok(frame) => self.admit(&agent, frame, now),
                    Err(r) => self.warn(&r, key),
                }
            }
            return;
        }
        let Some((tile, agent)) = keys::tile_agent_of_detections(&self.ns, key) else {
            return;
        };
        let listed = match s.attachment() {
            Some(a) => v2x_protocol::tiles::decode_tiles(&a.to_bytes()),
            None => Err(v2x_protocol::tiles::TileError::Missing),
        };
        let listed = match listed {
            Ok(l) => l,
            Err(e) => {
                let r = self.ingest.refuse(Rejection::BadTiles(e));
                return self.warn(&r, key);
            }
        };
        let now = self.clock.now_us();
        let frame = match self.offer(&agent, cpm, &payload, now) {
            Ok(f) => f,
            Err(r) => return self.warn(&r, key),
        };
        match self.parts.offer(tile, &listed, frame, now) {
            Ok(done) => self.admit_parts(done, now),
            Err(e) => {
                let r = self.ingest.refuse(Rejection::Part(e));
                self.warn(&r, key);
            }
        }
    }

    /// A payload heard on `agent`'s key through admission: a frame, or a CPM (`cpm`) whose
    /// boxes of classes without a name here are counted as `unnamed`.
    fn offer(
        &mut self,
        agent: &str,
        cpm: bool,
        payload: &[u8],
        now: u64,
    ) -> Result<v2x_protocol::Frame, Rejection> {
        let geo = self.map_origin;
        let unnamed = std::cell::Cell::new(0);
        let result = self.ingest.offer_decoded(agent, payload.len(), now, || {
            cpm::decode(cpm, agent, payload, &geo, &unnamed)
        });
        if result.is_ok() {
            self.ingest.unnamed(agent, unnamed.get());
        }
        self.drop_evicted();
        self.log_notes();
        result
    }

    fn drop_evicted(&mut self) {
        for gone in self.ingest.take_evicted() {
            self.windows.forget_agent(&gone);
            self.parts.forget_agent(&gone);
        }
    }

    /// Admits reassembled captures (regional fuser).
    fn admit_parts(&mut self, done: Vec<Assembled>, now: u64) {
        for a in done {
            if !a.complete {
                self.stats.captures_incomplete += 1;
            }
            let agent = a.frame.agent.clone();
            self.admit(&agent, a.frame, now);
        }
    }

    /// Puts an admitted frame into its window (a regional fuser first keeps the boxes within
    /// its tile and halo).
    fn admit(&mut self, agent: &str, mut frame: Frame, now: u64) {
        let scope = self.scope;
        frame.detections.retain(|d| scope.takes(d));
        let (n, t) = (frame.detections.len(), frame.capture_us);
        if let Some(v) = &self.viz {
            let topic = format!("/agents/{agent}");
            v.boxes(
                &topic,
                agent,
                t,
                &frame.detections,
                crate::viz::agent_colour(agent),
            );
        }
        let verdict = self.windows.insert(frame, now);
        self.ingest.record(agent, verdict, n, t);
    }

    fn on_token(&mut self, agent: &str, live: bool) {
        let now = self.clock.now_us();
        if live {
            // A new token is a restart: its sequence numbers start again.
            self.windows.reset_agent(agent);
            self.parts.forget_agent(agent);
        }
        let tracked = self.ingest.token(agent, live, now);
        self.drop_evicted();
        if tracked {
            // Agents coming and going are told one by one, up to a few an interval.
            let line = format!("agent {agent} {}", if live { "is live" } else { "left" });
            if let Some(line) = self
                .log
                .note_up_to("agents_live_or_left", &line, LIVE_LINES)
            {
                tracing::info!("{line}");
            }
        } else {
            let r = Rejection::AgentCap;
            if let Some(line) = self
                .log
                .note(r.reason(), &format!("token of '{agent}' ignored: {r}"))
            {
                tracing::warn!("{line}");
            }
        }
    }

    /// How long the loop may sleep: until the next deadline, at most a second (housekeeping).
    fn wait(&self) -> Duration {
        let next = match (self.windows.next_deadline(), self.parts.next_deadline()) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        next.map_or(Duration::from_secs(1), |d| {
            Duration::from_micros(d.saturating_sub(self.clock.now_us())).min(Duration::from_secs(1))
        })
    }

    /// After every event: the parts whose time is up admitted, the windows that are ready
    /// queued for the worker, and housekeeping.
    fn tick(&mut self, jobs: &mpsc::Sender<worker::Job>) {
        let now = self.clock.now_us();
        let expired = self.parts.expire(now);
        self.admit_parts(expired, now);
        let ready = self.close_ready(now);
        self.enqueue(ready, jobs);
        self.housekeeping();
    }

    /// Forgets idle agents (once a second) and logs the interval's summaries.
    fn housekeeping(&mut self) {
        let now = self.clock.now_us();
        if now.saturating_sub(self.last_prune_us) >= 1_000_000 {
            self.last_prune_us = now;
            for agent in self.ingest.prune(now) {
                self.windows.forget_agent(&agent);
                self.parts.forget_agent(&agent);
                self.stats.registration.remove(&agent);
                self.stats.learned_std.remove(&agent);
            }
        }
        for line in self.log.tick(now) {
            tracing::warn!("{line}");
        }
    }

    fn on_done(&mut self, d: worker::Done, on_fused: &mut impl FnMut(&Fused)) {
        self.queued = self.queued.saturating_sub(1);
        self.stats.fit.add(&d.fit);
        self.degraded.0 += d.degraded.0;
        self.degraded.1 += d.degraded.1;
        if d.tracks.is_some() {
            self.stats.tracks = d.tracks;
        }
        if !d.fit.is_clean() {
            if let Some(line) = self.log.note(
                "fit",
                &format!(
                    "fused frame {} changed to fit the wire: {:?}",
                    d.fused.frame.seq, d.fit
                ),
            ) {
                tracing::warn!("{line}");
            }
        }
        if let Some(e) = &d.error {
            self.stats.windows_unpublished += 1;
            if let Some(line) = self.log.note(
                "unpublished",
                &format!("fused frame {} not published: {e}", d.fused.frame.seq),
            ) {
                tracing::warn!("{line}");
            }
            return;
        }
        self.ingest.fused(&d.fused.provenance.agents);
        for (agent, r) in &d.fused.registration {
            self.stats.registration.insert(agent.clone(), *r);
        }
        for (agent, r) in &d.fused.learned {
            self.stats.learned_std.insert(agent.clone(), r.clone());
        }
        self.stats.windows += 1;
        if !d.fused.provenance.complete {
            self.stats.windows_incomplete += 1;
        }
        self.stats.fused_objects += d.fused.frame.detections.len() as u64;
        let fusion_us = d.done_at_us.saturating_sub(d.closed_at_us);
        if let Some(v) = &self.viz {
            let f = &d.fused;
            v.fused(f.frame.capture_us, &f.frame.detections, &f.provenance);
            let e2e_ms = (d.done_at_us as f64 - f.frame.capture_us as f64) / 1000.0;
            v.window(
                f.frame.capture_us,
                &f.provenance.agents,
                f.provenance.complete,
                f.frame.detections.len(),
                fusion_us as f64 / 1000.0,
                e2e_ms,
                &f.registration,
                &f.learned,
            );
        }
        self.fusion_hist.record(fusion_us as i64);
        self.e2e
            .record(d.done_at_us as i64 - d.fused.frame.capture_us.min(i64::MAX as u64) as i64);
        if self.fusion.len() < MAX_LATENCY_SAMPLES {
            self.fusion.push(fusion_us as f64 / 1000.0);
        }
        on_fused(&d.fused);
    }

    /// Closes the windows ready at `now_us` and counts them against the awaited agents missing.
    fn close_ready(&mut self, now_us: u64) -> Vec<Closed> {
        let half = self.windows.half_us();
        let ingest = &self.ingest;
        let closed = self
            .windows
            .poll(now_us, |anchor| ingest.awaited(anchor, half));
        for c in &closed {
            let members: Vec<&String> = c.frames.keys().collect();
            self.ingest.window_closed(c.anchor_us, half, &members);
        }
        closed
    }

    /// Queues closed windows for fusion; a full queue drops the window (counted).
    fn enqueue(&mut self, closed: Vec<Closed>, jobs: &mpsc::Sender<worker::Job>) {
        let now = self.clock.now_us();
        for c in closed {
            let anchor = c.anchor_us;
            match jobs.try_send(worker::Job {
                closed: c,
                closed_at_us: now,
            }) {
                Ok(()) => self.queued += 1,
                Err(_) => {
                    self.stats.windows_dropped += 1;
                    if let Some(line) = self.log.note(
                        "fusion_backlog",
                        &format!("window at {anchor} us dropped: the fusion queue is full"),
                    ) {
                        tracing::warn!("{line}");
                    }
                }
            }
        }
    }
}

/// Runs the fuser on `session` until `shutdown` resolves; `on_fused` sees every published
/// window, in capture order. Returns the final statistics.
pub async fn run(
    session: &zenoh::Session,
    cfg: NodeConfig,
    mut on_fused: impl FnMut(&Fused),
    shutdown: impl Future<Output = ()>,
) -> anyhow::Result<NodeStats> {
    cfg.check()?;
    let ns = cfg.ns.clone();
    let fk = cfg.scope().keys(&ns);
    let overflow = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let (mut det, subscribed) = subscribe_detections(session, &cfg, overflow.clone()).await?;
    let alive = session
        .liveliness()
        .declare_subscriber(keys::all_alive(&ns))
        .history(true)
        .await
        .map_err(z("liveliness subscriber", keys::all_alive(&ns)))?;
    let queryable = session
        .declare_queryable(fk.stats.clone())
        .await
        .map_err(z("statistics queryable", fk.stats.clone()))?;
    let publisher = declare_frames(session, &fk.fused, "fused-frame publisher").await?;
    let _token = session
        .liveliness()
        .declare_token(fk.alive.clone())
        .await
        .map_err(z("liveliness token", fk.alive.clone()))?;
    let clock = Clock::start();
    let (job_tx, job_rx) = mpsc::channel(cfg.queue);
    let (done_tx, mut done_rx) = mpsc::unbounded_channel();
    let (worker, _handover) =
        start_worker(session, &cfg, publisher, clock, job_rx, done_tx).await?;
    let mut st = State::new(&cfg, clock, &subscribed);
    cfg.log_start(&st.stats.method);
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            s = det.recv() => match s {
                Some(s) => st.on_sample(&s),
                None => break,
            },
            s = alive.recv_async() => match s {
                Ok(s) => if let Some(agent) = keys::agent_of_alive(&ns, s.key_expr().as_str()) {
                    st.on_token(&agent, s.kind() == SampleKind::Put);
                },
                Err(_) => break,
            },
            q = queryable.recv_async() => if let Ok(q) = q {
                reply_stats(&q, &fk.stats, &st.snapshot()).await;
            },
            d = done_rx.recv() => if let Some(d) = d {
                st.on_done(d, &mut on_fused);
            },
            _ = tokio::time::sleep(st.wait()) => {}
            _ = &mut shutdown => break,
        }
        st.stats.inbox_overflow = overflow.load(std::sync::atomic::Ordering::Relaxed);
        st.tick(&job_tx);
    }
    st.flush(job_tx).await;
    while let Some(d) = done_rx.recv().await {
        st.on_done(d, &mut on_fused);
    }
    let _ = worker.await;
    for line in st.log.flush(st.clock.now_us()) {
        tracing::warn!("{line}");
    }
    let mut stats = st.snapshot();
    stats.fusion_samples = std::mem::take(&mut st.fusion);
    Ok(stats)
}
