//! The fuser node: the thin Zenoh shell around [`crate::window`] and a [`Method`].
//!
//! It subscribes to `v2x/NS/det/*`, decodes and validates each frame (invalid ones are counted
//! per agent and dropped), follows the agents' liveliness tokens on `v2x/NS/alive/*`, feeds the
//! window state machine, fuses each closed window and publishes the result on `v2x/NS/fused`,
//! and answers `v2x/NS/fuser/stats` with its counters and latencies as JSON.

use crate::window::{Closed, Verdict, Windows};
use crate::Method;
use anyhow::anyhow;
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use std::future::Future;
use std::time::{Duration, Instant};
use v2x_protocol::net::ZenohArgs;
use v2x_protocol::{keys, wire, AgentKind, Frame};
use zenoh::sample::SampleKind;

/// How the node runs.
#[derive(Clone, Debug)]
pub struct NodeConfig {
    /// Scenario namespace.
    pub ns: String,
    /// Fusion method.
    pub method: Method,
    /// Window width delta t (ms).
    pub window_ms: f64,
    /// Longest wait for missing agents after a window's first frame (ms).
    pub max_wait_ms: f64,
}

/// Per-agent counters.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct AgentStats {
    /// Frames received (valid or not).
    pub frames_in: u64,
    /// Frames that joined a window.
    pub accepted: u64,
    /// Frames fused into a published window.
    pub fused: u64,
    /// Frames for a window already closed.
    pub late: u64,
    /// Frames seen before, or a second frame in one window.
    pub duplicate: u64,
    /// Frames that failed to decode or validate.
    pub invalid: u64,
    /// Payload bytes received.
    pub payload_bytes: u64,
    /// Objects received in accepted frames.
    pub objects: u64,
}

/// Latency percentiles (ms).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Latency {
    /// Number of samples.
    pub count: usize,
    /// Median.
    pub p50_ms: Option<f64>,
    /// 95th percentile.
    pub p95_ms: Option<f64>,
    /// 99th percentile.
    pub p99_ms: Option<f64>,
    /// Largest.
    pub max_ms: Option<f64>,
}

impl Latency {
    /// Percentiles of a sample (nearest rank).
    pub fn of(samples: &[f64]) -> Latency {
        let mut v: Vec<f64> = samples.iter().copied().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        let pick = |q: f64| {
            (!v.is_empty()).then(|| v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1])
        };
        Latency {
            count: v.len(),
            p50_ms: pick(0.50),
            p95_ms: pick(0.95),
            p99_ms: pick(0.99),
            max_ms: v.last().copied(),
        }
    }
}

/// What the node reports (`v2x/NS/fuser/stats`, and at the end of a run).
#[derive(Clone, Debug, Default, Serialize)]
pub struct NodeStats {
    /// Namespace.
    pub ns: String,
    /// Method name.
    pub method: String,
    /// Agents with a live token now.
    pub live: Vec<String>,
    /// Counters per agent.
    pub agents: BTreeMap<String, AgentStats>,
    /// Windows fused and published.
    pub windows: u64,
    /// Of those, windows closed by their deadline with a live agent missing.
    pub windows_incomplete: u64,
    /// Fused objects published.
    pub fused_objects: u64,
    /// Windows open now.
    pub open_windows: usize,
    /// Capture (sensor clock) to fused publish (fuser clock); meaningful with synchronised clocks.
    pub e2e_latency_ms: Latency,
    /// Window close to fused publish: fusion, encoding and hand-off to Zenoh.
    pub fusion_latency_ms: Latency,
    /// Windows still open when the node was told to stop (then flushed).
    pub open_windows_at_stop: usize,
    /// Every fusion latency sample (ms), in window order; only in the final statistics.
    #[serde(skip)]
    pub fusion_samples: Vec<f64>,
}

/// A fused window as published.
#[derive(Clone, Debug)]
pub struct Fused {
    /// The fused frame (agent "fuser", capture time = the window's anchor).
    pub frame: Frame,
    /// Agents whose frames were fused.
    pub members: Vec<String>,
    /// Whether every live agent contributed.
    pub complete: bool,
}

/// Opens a Zenoh session with the given options.
pub async fn open_session(args: &ZenohArgs) -> anyhow::Result<zenoh::Session> {
    v2x_protocol::net::open_session(args)
        .await
        .map_err(|e| anyhow!(e))
}

fn wall_us() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

const MAX_LATENCY_SAMPLES: usize = 200_000;

struct State {
    cfg: NodeConfig,
    windows: Windows,
    live: BTreeSet<String>,
    stats: NodeStats,
    e2e: Vec<f64>,
    fusion: Vec<f64>,
    seq: u32,
    start: Instant,
}

impl State {
    fn now(&self) -> u64 {
        self.start.elapsed().as_micros() as u64
    }

    fn snapshot(&self) -> NodeStats {
        let mut s = self.stats.clone();
        s.live = self.live.iter().cloned().collect();
        s.open_windows = self.windows.open_windows();
        s.e2e_latency_ms = Latency::of(&self.e2e);
        s.fusion_latency_ms = Latency::of(&self.fusion);
        s
    }

    fn on_payload(&mut self, key: &str, payload: &[u8]) {
        let Some(agent) = keys::agent_of_detections(&self.cfg.ns, key) else {
            return;
        };
        let now = self.now();
        let st = self.stats.agents.entry(agent.clone()).or_default();
        st.frames_in += 1;
        st.payload_bytes += payload.len() as u64;
        let frame = match wire::decode(payload) {
            Ok(f) if f.agent == agent => f,
            Ok(f) => {
                st.invalid += 1;
                tracing::warn!("frame on {key} claims to be from '{}': dropped", f.agent);
                return;
            }
            Err(e) => {
                st.invalid += 1;
                tracing::warn!("invalid frame on {key}: {e}");
                return;
            }
        };
        let n = frame.detections.len() as u64;
        match self.windows.insert(frame, now) {
            Verdict::Accepted => {
                st.accepted += 1;
                st.objects += n;
            }
            Verdict::Late => st.late += 1,
            Verdict::Duplicate => st.duplicate += 1,
        }
    }

    fn fuse(&mut self, closed: Closed) -> Fused {
        let members: Vec<String> = closed.frames.keys().cloned().collect();
        let lists: Vec<Vec<v2x_protocol::Detection>> =
            closed.frames.into_values().map(|f| f.detections).collect();
        let detections = self.cfg.method.fuse(&lists);
        for m in &members {
            self.stats.agents.entry(m.clone()).or_default().fused += 1;
        }
        self.stats.windows += 1;
        if !closed.complete {
            self.stats.windows_incomplete += 1;
        }
        self.stats.fused_objects += detections.len() as u64;
        let frame = Frame {
            agent: "fuser".into(),
            kind: AgentKind::Infrastructure,
            seq: self.seq,
            capture_us: closed.anchor_us,
            origin: [0.0; 3],
            detections,
        }
        .with_centroid_origin();
        self.seq = self.seq.wrapping_add(1);
        Fused {
            frame,
            members,
            complete: closed.complete,
        }
    }

    fn record_latency(&mut self, closed_at: u64, capture_us: u64) {
        if self.fusion.len() < MAX_LATENCY_SAMPLES {
            self.fusion
                .push((self.now().saturating_sub(closed_at)) as f64 / 1000.0);
            self.e2e
                .push((wall_us() as f64 - capture_us as f64) / 1000.0);
        }
    }
}

/// Runs the fuser on `session` until `shutdown` resolves; `on_fused` sees every published
/// window. Returns the final statistics.
pub async fn run(
    session: &zenoh::Session,
    cfg: NodeConfig,
    mut on_fused: impl FnMut(&Fused),
    shutdown: impl Future<Output = ()>,
) -> anyhow::Result<NodeStats> {
    keys::validate_chunk("namespace", &cfg.ns).map_err(|e| anyhow!(e))?;
    if !(cfg.window_ms > 0.0 && cfg.max_wait_ms >= 0.0) {
        anyhow::bail!("the window must be > 0 ms and the wait >= 0 ms");
    }
    let ns = cfg.ns.clone();
    let z = |e: zenoh::Error| anyhow!("{e}");
    let det = session
        .declare_subscriber(keys::all_detections(&ns))
        .await
        .map_err(z)?;
    let alive = session
        .liveliness()
        .declare_subscriber(keys::all_alive(&ns))
        .history(true)
        .await
        .map_err(z)?;
    let queryable = session
        .declare_queryable(keys::fuser_stats(&ns))
        .await
        .map_err(z)?;
    let publisher = session
        .declare_publisher(keys::fused(&ns))
        .await
        .map_err(z)?;
    let _token = session
        .liveliness()
        .declare_token(keys::fuser_alive(&ns))
        .await
        .map_err(z)?;
    let mut st = State {
        windows: Windows::new(
            (cfg.window_ms * 1000.0) as u64,
            (cfg.max_wait_ms * 1000.0) as u64,
        ),
        stats: NodeStats {
            ns: ns.clone(),
            method: cfg.method.name(),
            ..Default::default()
        },
        cfg,
        live: BTreeSet::new(),
        e2e: Vec::new(),
        fusion: Vec::new(),
        seq: 0,
        start: Instant::now(),
    };
    tracing::info!(
        "fuser on v2x/{ns}: method {}, window {} ms",
        st.stats.method,
        st.cfg.window_ms
    );
    tokio::pin!(shutdown);
    loop {
        let wait = st
            .windows
            .next_deadline()
            .map(|d| Duration::from_micros(d.saturating_sub(st.now())));
        tokio::select! {
            s = det.recv_async() => match s {
                Ok(s) => st.on_payload(s.key_expr().as_str(), &s.payload().to_bytes()),
                Err(_) => break,
            },
            s = alive.recv_async() => match s {
                Ok(s) => if let Some(agent) = keys::agent_of_alive(&ns, s.key_expr().as_str()) {
                    if s.kind() == SampleKind::Put {
                        tracing::info!("agent {agent} is live");
                        st.windows.reset_agent(&agent);
                        st.live.insert(agent);
                    } else {
                        tracing::info!("agent {agent} left");
                        st.live.remove(&agent);
                    }
                },
                Err(_) => break,
            },
            q = queryable.recv_async() => if let Ok(q) = q {
                let body = serde_json::to_vec(&st.snapshot()).expect("stats serialize");
                if let Err(e) = q.reply(keys::fuser_stats(&ns), body).await {
                    tracing::warn!("stats reply failed: {e}");
                }
            },
            _ = tokio::time::sleep(wait.unwrap_or(Duration::from_secs(3600))) => {}
            _ = &mut shutdown => break,
        }
        let now = st.now();
        let ready = st.windows.poll(now, &st.live);
        for closed in ready {
            publish(&mut st, &publisher, closed, now, &mut on_fused).await;
        }
    }
    st.stats.open_windows_at_stop = st.windows.open_windows();
    let now = st.now();
    let rest = st.windows.flush(&st.live);
    for closed in rest {
        publish(&mut st, &publisher, closed, now, &mut on_fused).await;
    }
    let mut stats = st.snapshot();
    stats.fusion_samples = std::mem::take(&mut st.fusion);
    Ok(stats)
}

async fn publish(
    st: &mut State,
    publisher: &zenoh::pubsub::Publisher<'_>,
    closed: Closed,
    closed_at: u64,
    on_fused: &mut impl FnMut(&Fused),
) {
    let fused = st.fuse(closed);
    match wire::encode(&fused.frame) {
        Ok(bytes) => {
            if let Err(e) = publisher.put(bytes).await {
                tracing::warn!("publishing fused frame {}: {e}", fused.frame.seq);
            }
        }
        Err(e) => tracing::warn!("fused frame {} does not encode: {e}", fused.frame.seq),
    }
    st.record_latency(closed_at, fused.frame.capture_us);
    on_fused(&fused);
}

/// Asks a running fuser for its statistics.
pub async fn query_stats(
    session: &zenoh::Session,
    ns: &str,
    timeout: Duration,
) -> anyhow::Result<serde_json::Value> {
    let replies = session
        .get(keys::fuser_stats(ns))
        .timeout(timeout)
        .await
        .map_err(|e| anyhow!("{e}"))?;
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            return Ok(serde_json::from_slice(&sample.payload().to_bytes())?);
        }
    }
    anyhow::bail!(
        "no fuser answered on {} within {timeout:?}",
        keys::fuser_stats(ns)
    )
}

#[cfg(test)]
mod tests {
    use super::Latency;

    #[test]
    fn percentiles_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(|x| x as f64).collect();
        let l = Latency::of(&v);
        assert_eq!(
            (l.p50_ms, l.p95_ms, l.p99_ms, l.max_ms),
            (Some(50.0), Some(95.0), Some(99.0), Some(100.0))
        );
        assert_eq!(Latency::of(&[]).p50_ms, None);
    }
}
