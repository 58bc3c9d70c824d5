//! A V2X agent on the network: publishes its detections as compact [`Frame`]s on
//! `v2x/NS/det/AGENT` (with regions, [`Agent::with_tiling`]: one part per tile it sees on
//! `v2x/NS/det/TILE/AGENT`, each naming the capture's tiles in its attachment), declares a liveliness token on `v2x/NS/alive/AGENT` so the fuser knows it
//! is there, and simulates its radio link (fixed latency, jitter, drop rate) and its sensor clock
//! (an offset added to capture times). [`replay`] sends a sequence of frames at the data's own
//! clock, sped up or slowed down by a factor.

pub mod ros_in;

use anyhow::{anyhow, Context};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use v2x_protocol::tiles::{self, Tile, Tiling};
use v2x_protocol::{keys, wire, AgentKind, Frame};

mod link;
pub use link::Link;

/// Counters of what an agent sent.
#[derive(Debug, Default)]
pub struct AgentCounters {
    /// Frames handed to the link.
    pub frames: AtomicU64,
    /// Frames the link dropped.
    pub dropped: AtomicU64,
    /// Frames published (with regions: captures whose every part was published).
    pub published: AtomicU64,
    /// Messages published: one per frame, or with regions one per part.
    pub parts: AtomicU64,
    /// Payload bytes published.
    pub payload_bytes: AtomicU64,
    /// Objects published.
    pub objects: AtomicU64,
    /// Bytes the published messages' boxes take as ETSI CPMs, when counted
    /// ([`Agent::counting_cpm`]).
    pub cpm_bytes: AtomicU64,
}

/// A snapshot of [`AgentCounters`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct AgentTotals {
    /// Frames handed to the link.
    pub frames: u64,
    /// Frames the link dropped.
    pub dropped: u64,
    /// Frames published (with regions: captures whose every part was published).
    pub published: u64,
    /// Messages published: one per frame, or with regions one per part.
    pub parts: u64,
    /// Payload bytes published.
    pub payload_bytes: u64,
    /// Objects published.
    pub objects: u64,
    /// Bytes the published messages' boxes take as ETSI CPMs, when counted (else 0).
    pub cpm_bytes: u64,
}

impl AgentCounters {
    /// The current values.
    pub fn totals(&self) -> AgentTotals {
        AgentTotals {
            frames: self.frames.load(Ordering::Relaxed),
            dropped: self.dropped.load(Ordering::Relaxed),
            published: self.published.load(Ordering::Relaxed),
            parts: self.parts.load(Ordering::Relaxed),
            payload_bytes: self.payload_bytes.load(Ordering::Relaxed),
            objects: self.objects.load(Ordering::Relaxed),
            cpm_bytes: self.cpm_bytes.load(Ordering::Relaxed),
        }
    }
}

/// A publishing agent.
pub struct Agent {
    name: String,
    kind: AgentKind,
    link: Link,
    rng: ChaCha8Rng,
    seq: u32,
    /// Messages handed to the link, to keep parts in order.
    order: u64,
    tiling: Option<Tiling>,
    /// Counts what each message would take as an ETSI CPM.
    count_cpm: bool,
    /// Sends ETSI CPMs instead of frames, the map placed on the earth by this origin.
    cpm: Option<v2x_cpm::Geo>,
    session: zenoh::Session,
    ns: String,
    publisher: Arc<zenoh::pubsub::Publisher<'static>>,
    outbox: tokio::sync::mpsc::UnboundedSender<link::InFlight>,
    /// The liveliness token while the agent is there (`None` after [`Agent::leave`]).
    token: Option<zenoh::liveliness::LivelinessToken>,
    alive_key: String,
    counters: Arc<AgentCounters>,
}

impl Agent {
    /// Declares the agent's publisher and liveliness token on `session`.
    pub async fn start(
        session: &zenoh::Session,
        ns: &str,
        name: &str,
        kind: AgentKind,
        link: Link,
        seed: u64,
    ) -> anyhow::Result<Agent> {
        keys::validate_chunk("namespace", ns).map_err(|e| anyhow!(e))?;
        wire::check_agent_name(name).map_err(|e| anyhow!(e))?;
        if v2x_protocol::acl::reserved(name) {
            anyhow::bail!("agent name '{name}' belongs to another role (fuser, observer, router)");
        }
        link.validate().map_err(|e| anyhow!("agent {name}: {e}"))?;
        let publisher = session
            .declare_publisher(keys::detections(ns, name))
            .encoding(v2x_protocol::net::frame_encoding())
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .await
            .map_err(|e| anyhow!("agent {name}: cannot declare its publisher: {e}"))?;
        let token = session
            .liveliness()
            .declare_token(keys::alive(ns, name))
            .await
            .map_err(|e| anyhow!("agent {name}: cannot declare its liveliness token: {e}"))?;
        let publisher = Arc::new(publisher);
        let counters = Arc::new(AgentCounters::default());
        let outbox = link::spawn(
            link::Outlet::new(publisher.clone(), session.clone(), ns, name),
            counters.clone(),
        );
        Ok(Agent {
            name: name.to_string(),
            kind,
            link,
            rng: ChaCha8Rng::seed_from_u64(seed),
            seq: 0,
            order: 0,
            tiling: None,
            count_cpm: false,
            cpm: None,
            session: session.clone(),
            ns: ns.to_string(),
            publisher,
            outbox,
            token: Some(token),
            alive_key: keys::alive(ns, name),
            counters,
        })
    }

    /// Publishes per tile of `tiling` from now on: each capture as one part per tile its boxes
    /// lie in (a capture without boxes as one empty part in the tile of its origin).
    pub fn with_tiling(mut self, tiling: Tiling) -> Self {
        self.tiling = Some(tiling);
        self
    }

    /// Counts, beside each message's payload, the bytes its boxes would take as ETSI CPMs
    /// ([`AgentCounters::cpm_bytes`]), so a run reports both encodings of the same traffic.
    pub fn counting_cpm(mut self) -> Self {
        self.count_cpm = true;
        self
    }

    /// Sends each message as an ETSI CPM (UPER, docs/cpm.md) instead of a frame, its positions
    /// placed on the earth by `map_origin` (the fuser must give the same).
    pub fn sending_cpm(mut self, map_origin: v2x_cpm::Geo) -> Self {
        self.cpm = Some(map_origin);
        self
    }

    /// Replaces the simulated link (a scripted change); the values are checked first.
    pub fn set_link(&mut self, link: Link) -> anyhow::Result<()> {
        link.validate()
            .map_err(|e| anyhow!("agent {}: {e}", self.name))?;
        self.link = link;
        Ok(())
    }

    /// Withdraws the liveliness token: the fuser stops waiting for this agent.
    pub fn leave(&mut self) {
        self.token = None;
    }

    /// Declares the liveliness token again after [`Agent::leave`].
    pub async fn join(&mut self, session: &zenoh::Session) -> anyhow::Result<()> {
        if self.token.is_none() {
            let token = session
                .liveliness()
                .declare_token(self.alive_key.clone())
                .await
                .map_err(|e| {
                    anyhow!(
                        "agent {}: cannot declare its liveliness token: {e}",
                        self.name
                    )
                })?;
            self.token = Some(token);
        }
        Ok(())
    }

    /// The agent's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The agent's counters.
    pub fn counters(&self) -> Arc<AgentCounters> {
        self.counters.clone()
    }

    /// Waits until a subscriber (the fuser) matches the agent's detections, or the timeout.
    pub async fn wait_for_subscriber(&self, timeout: Duration) -> anyhow::Result<()> {
        let key = self.publisher.key_expr().to_string();
        wait_matching(&self.publisher, &self.name, &key, timeout).await
    }

    /// Waits until a subscriber (a regional fuser) matches the agent's detections in `tile`, or
    /// the timeout.
    pub async fn wait_for_subscriber_in(
        &self,
        tile: Tile,
        timeout: Duration,
    ) -> anyhow::Result<()> {
        let key = keys::detections_in(&self.ns, tile, &self.name);
        let publisher = self
            .session
            .declare_publisher(key.clone())
            .await
            .map_err(|e| anyhow!("agent {}: cannot declare {key}: {e}", self.name))?;
        wait_matching(&publisher, &self.name, &key, timeout).await
    }

    /// Stamps, encodes and sends a frame through the simulated link: it may be dropped, is
    /// delayed by latency + jitter, and its capture time is shifted by the clock offset.
    /// Returns the payload size, or `None` if the link dropped the frame.
    pub fn send(&mut self, mut frame: Frame) -> anyhow::Result<Option<usize>> {
        frame.agent = self.name.clone();
        frame.kind = self.kind;
        frame.seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        let offset_us = (self.link.clock_offset_ms * 1000.0).round() as i64;
        frame.capture_us = frame.capture_us.saturating_add_signed(offset_us);
        let parts = self.parts(&frame)?;
        self.counters.frames.fetch_add(1, Ordering::Relaxed);
        if self.link.drop_rate > 0.0 && self.rng.gen::<f64>() < self.link.drop_rate {
            self.counters.dropped.fetch_add(1, Ordering::Relaxed);
            return Ok(None);
        }
        let delay_ms = self.link.latency_ms
            + if self.link.jitter_ms > 0.0 {
                self.rng.gen_range(0.0..self.link.jitter_ms)
            } else {
                0.0
            };
        let due = tokio::time::Instant::now() + Duration::from_secs_f64(delay_ms / 1000.0);
        let (count, mut len) = (parts.len(), 0);
        for (i, part) in parts.into_iter().enumerate() {
            len += part.payload.len();
            self.order += 1;
            let _ = self.outbox.send(link::InFlight {
                due,
                order: self.order,
                objects: part.objects,
                payload: part.payload,
                cpm: part.cpm,
                cpm_bytes: part.cpm_bytes,
                tile: part.tile,
                last_part: i + 1 == count,
            });
        }
        Ok(Some(len))
    }

    /// The encoded messages of one capture: the whole frame, or with regions one part per tile.
    fn parts(&self, frame: &Frame) -> anyhow::Result<Vec<Part>> {
        let encode = |f: &Frame, tile| {
            let payload = match &self.cpm {
                None => wire::encode(f).map_err(anyhow::Error::from),
                Some(geo) => v2x_cpm::encode(f, geo).map_err(anyhow::Error::from),
            }
            .with_context(|| format!("agent {}: frame {} does not encode", self.name, f.seq))?;
            // A message sent as a CPM is its own count; a frame's CPM is encoded to be counted.
            let cpm_bytes = match (self.count_cpm, self.cpm.is_some()) {
                (false, _) => 0,
                (true, true) => payload.len() as u64,
                (true, false) => v2x_cpm::message_bytes(f) as u64,
            };
            Ok(Part {
                payload,
                cpm: self.cpm.is_some(),
                objects: f.detections.len() as u64,
                cpm_bytes,
                tile,
            })
        };
        let Some(tiling) = self.tiling else {
            return Ok(vec![encode(frame, None)?]);
        };
        let mut by_tile: std::collections::BTreeMap<Tile, Vec<_>> = Default::default();
        for d in &frame.detections {
            by_tile
                .entry(tiling.tile_of(d.center))
                .or_default()
                .push(d.clone());
        }
        if by_tile.is_empty() {
            by_tile.insert(tiling.tile_of(frame.origin), Vec::new());
        }
        let list: Vec<Tile> = by_tile.keys().copied().collect();
        let attachment = Arc::new(tiles::encode_tiles(&list).map_err(|e| {
            anyhow!(
                "agent {}: frame {} spans too many tiles: {e}",
                self.name,
                frame.seq
            )
        })?);
        by_tile
            .into_iter()
            .map(|(tile, detections)| {
                let part = Frame {
                    detections,
                    ..frame.clone()
                }
                .with_centroid_origin();
                encode(&part, Some((tile, attachment.clone())))
            })
            .collect()
    }
}

/// One message of a capture: its payload, object count and CPM bytes, and with regions its
/// tile and attachment.
struct Part {
    payload: Vec<u8>,
    cpm: bool,
    objects: u64,
    cpm_bytes: u64,
    tile: Option<(Tile, Arc<Vec<u8>>)>,
}

/// Waits until a subscriber matches `publisher` (on `key`, of agent `name`), or the timeout.
async fn wait_matching(
    publisher: &zenoh::pubsub::Publisher<'_>,
    name: &str,
    key: &str,
    timeout: Duration,
) -> anyhow::Result<()> {
    let wait = async {
        loop {
            let status = publisher
                .matching_status()
                .await
                .map_err(|e| anyhow!("matching status: {e}"))?;
            if status.matching() {
                return anyhow::Ok(());
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    };
    tokio::time::timeout(timeout, wait)
        .await
        .with_context(|| format!("agent {name}: no fuser subscribed to {key} within {timeout:?}"))?
}

/// Microseconds since the Unix epoch on this machine's clock.
pub fn now_us() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// Which clock a replay stamps frames with.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum ReplayClock {
    /// The sender's real-time clock: frame i is captured (and sent) at
    /// `start_us + (t_i - t_0) / speed` on this machine's clock. Agents given the same start
    /// replay in step.
    Real {
        /// Wall-clock time of the first frame (us since the Unix epoch).
        start_us: u64,
        /// The data time replayed at `start_us` (default: the first frame's). Agents whose
        /// files start at different phases share it to keep their offsets.
        data_start_us: Option<u64>,
    },
    /// The data's own timestamps (for a fuser that accepts any capture time); frames are still
    /// sent at the data's pace.
    Data,
}

/// What a replay did.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct ReplayReport {
    /// Frames handed to the link.
    pub sent: usize,
    /// Frames skipped because their time had passed by more than half a second when the replay
    /// reached them (a start in the past).
    pub skipped: usize,
}

/// Replays frames at their own pace, `speed` times faster than recorded, stamped by `clock`.
/// Stops early when `stop` resolves.
pub async fn replay(
    agent: &mut Agent,
    frames: Vec<Frame>,
    speed: f64,
    clock: ReplayClock,
    stop: impl std::future::Future<Output = ()>,
) -> anyhow::Result<ReplayReport> {
    if !(speed.is_finite() && speed > 0.0) {
        anyhow::bail!("speed must be > 0 (got {speed})");
    }
    let mut report = ReplayReport::default();
    let Some(mut first) = frames.first().map(|f| f.capture_us) else {
        return Ok(report);
    };
    let start_us = match clock {
        ReplayClock::Real {
            start_us,
            data_start_us,
        } => {
            first = data_start_us.map_or(first, |d| d.min(first));
            start_us
        }
        ReplayClock::Data => now_us(),
    };
    tokio::pin!(stop);
    for mut f in frames {
        let due = start_us + (f.capture_us.saturating_sub(first) as f64 / speed) as u64;
        let now = now_us();
        if due + 500_000 < now {
            report.skipped += 1;
            continue;
        }
        tokio::select! {
            _ = tokio::time::sleep(Duration::from_micros(due.saturating_sub(now))) => {}
            _ = &mut stop => break,
        }
        if let ReplayClock::Real { .. } = clock {
            f.capture_us = due;
        }
        agent.send(f)?;
        report.sent += 1;
    }
    Ok(report)
}
