//! The simulated radio link of an agent: its parameters ([`Link`]) and the outbox that carries
//! frames to the network after their latency and jitter. One task per agent publishes frames in
//! order of their due time (ties in sending order), so a link without jitter never reorders
//! frames and a jittery one reorders them as a real one would.

use crate::AgentCounters;
use serde::{Deserialize, Serialize};
use std::cmp::Ordering as CmpOrdering;
use std::collections::BinaryHeap;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use tokio::sync::mpsc;
use v2x_protocol::tiles::Tile;
use v2x_protocol::{keys, InvalidValue};

/// Most per-tile publishers an agent keeps declared; beyond, the least recently used goes.
const MAX_TILE_PUBLISHERS: usize = 64;

/// Where an agent's frames go: its own key, and with regions one key per tile.
pub(crate) struct Outlet {
    pub publisher: Arc<zenoh::pubsub::Publisher<'static>>,
    pub session: zenoh::Session,
    pub ns: String,
    pub name: String,
    tiles: Vec<(Tile, zenoh::pubsub::Publisher<'static>)>,
}

impl Outlet {
    /// An outlet publishing on `publisher` (and, with regions, on tile keys of `session`).
    pub fn new(
        publisher: Arc<zenoh::pubsub::Publisher<'static>>,
        session: zenoh::Session,
        ns: &str,
        name: &str,
    ) -> Self {
        Outlet {
            publisher,
            session,
            ns: ns.to_string(),
            name: name.to_string(),
            tiles: Vec::new(),
        }
    }

    /// Publishes one frame or part.
    async fn put(&mut self, f: InFlight) -> zenoh::Result<()> {
        let encoding = if f.cpm {
            v2x_protocol::net::cpm_encoding()
        } else {
            v2x_protocol::net::frame_encoding()
        };
        let Some((tile, attachment)) = f.tile else {
            return self.publisher.put(f.payload).encoding(encoding).await;
        };
        let i = match self.tiles.iter().position(|(t, _)| *t == tile) {
            Some(i) => i,
            None => {
                if self.tiles.len() >= MAX_TILE_PUBLISHERS {
                    self.tiles.remove(0);
                }
                let p = self
                    .session
                    .declare_publisher(keys::detections_in(&self.ns, tile, &self.name))
                    .encoding(v2x_protocol::net::frame_encoding())
                    .congestion_control(zenoh::qos::CongestionControl::Block)
                    .await?;
                self.tiles.push((tile, p));
                self.tiles.len() - 1
            }
        };
        // Most recently used last.
        let entry = self.tiles.remove(i);
        let put = entry
            .1
            .put(f.payload)
            .encoding(encoding)
            .attachment(attachment.as_slice().to_vec())
            .await;
        self.tiles.push(entry);
        put
    }
}

/// The simulated link and sensor clock of an agent.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Link {
    /// Fixed one-way latency (ms).
    pub latency_ms: f64,
    /// Uniform jitter added to the latency, in [0, jitter_ms] (ms).
    pub jitter_ms: f64,
    /// Probability that a frame is lost, in [0, 1].
    pub drop_rate: f64,
    /// Offset of the sensor clock from true time (ms), added to every capture time.
    pub clock_offset_ms: f64,
}

impl Link {
    /// Checks the values are usable, naming the bad field.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        if !(self.latency_ms.is_finite() && self.latency_ms >= 0.0) {
            return Err(InvalidValue::new("latency_ms", ">= 0", self.latency_ms));
        }
        if !(self.jitter_ms.is_finite() && self.jitter_ms >= 0.0) {
            return Err(InvalidValue::new("jitter_ms", ">= 0", self.jitter_ms));
        }
        if !(0.0..=1.0).contains(&self.drop_rate) {
            return Err(InvalidValue::new("drop_rate", "in [0, 1]", self.drop_rate));
        }
        if !self.clock_offset_ms.is_finite() {
            let got = self.clock_offset_ms;
            return Err(InvalidValue::new("clock_offset_ms", "finite", got));
        }
        Ok(())
    }
}

/// A frame on its way through the link.
pub(crate) struct InFlight {
    /// When it leaves.
    pub due: tokio::time::Instant,
    /// Sending order, to break ties.
    pub order: u64,
    /// Objects in it.
    pub objects: u64,
    /// The encoded frame.
    pub payload: Vec<u8>,
    /// Its boxes as ETSI CPMs (bytes), when the agent counts them.
    pub cpm_bytes: u64,
    /// The payload is an ETSI CPM, not a frame.
    pub cpm: bool,
    /// With regions: the tile of this part and the attachment listing the capture's tiles
    /// (`None`: the agent's own key, no attachment).
    pub tile: Option<(Tile, Arc<Vec<u8>>)>,
    /// Whether this is the last part of its capture.
    pub last_part: bool,
}

impl PartialEq for InFlight {
    fn eq(&self, other: &Self) -> bool {
        (self.due, self.order) == (other.due, other.order)
    }
}

impl Eq for InFlight {}

impl PartialOrd for InFlight {
    fn partial_cmp(&self, other: &Self) -> Option<CmpOrdering> {
        Some(self.cmp(other))
    }
}

impl Ord for InFlight {
    /// Reversed, so that the max-heap pops the earliest due first.
    fn cmp(&self, other: &Self) -> CmpOrdering {
        (other.due, other.order).cmp(&(self.due, self.order))
    }
}

/// Starts the outbox task of an agent; frames sent into the returned channel are published
/// when due. When the channel closes, the frames still in flight are published at their time.
pub(crate) fn spawn(
    mut outlet: Outlet,
    counters: Arc<AgentCounters>,
) -> mpsc::UnboundedSender<InFlight> {
    let name = outlet.name.clone();
    let (tx, mut rx) = mpsc::unbounded_channel::<InFlight>();
    tokio::spawn(async move {
        let mut heap: BinaryHeap<InFlight> = BinaryHeap::new();
        let mut open = true;
        while open || !heap.is_empty() {
            let next = heap.peek().map(|f| f.due);
            tokio::select! {
                m = rx.recv(), if open => match m {
                    Some(f) => heap.push(f),
                    None => open = false,
                },
                _ = tokio::time::sleep_until(next.unwrap_or_else(tokio::time::Instant::now)), if next.is_some() => {
                    let Some(f) = heap.pop() else { continue };
                    let (len, objects, cpm, last) = (f.payload.len() as u64, f.objects, f.cpm_bytes, f.last_part);
                    match outlet.put(f).await {
                        Ok(()) => {
                            if last {
                                counters.published.fetch_add(1, Ordering::Relaxed);
                            }
                            counters.parts.fetch_add(1, Ordering::Relaxed);
                            counters.payload_bytes.fetch_add(len, Ordering::Relaxed);
                            counters.objects.fetch_add(objects, Ordering::Relaxed);
                            counters.cpm_bytes.fetch_add(cpm, Ordering::Relaxed);
                        }
                        Err(e) => tracing::warn!("agent {name}: publish failed: {e}"),
                    }
                }
            }
        }
    });
    tx
}
