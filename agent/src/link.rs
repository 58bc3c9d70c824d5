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
    pub fn validate(&self) -> Result<(), String> {
        if !(self.latency_ms.is_finite() && self.latency_ms >= 0.0) {
            return Err(format!("latency_ms must be >= 0 (got {})", self.latency_ms));
        }
        if !(self.jitter_ms.is_finite() && self.jitter_ms >= 0.0) {
            return Err(format!("jitter_ms must be >= 0 (got {})", self.jitter_ms));
        }
        if !(0.0..=1.0).contains(&self.drop_rate) {
            return Err(format!(
                "drop_rate must be in [0, 1] (got {})",
                self.drop_rate
            ));
        }
        if !self.clock_offset_ms.is_finite() {
            return Err("clock_offset_ms must be finite".into());
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
    publisher: Arc<zenoh::pubsub::Publisher<'static>>,
    counters: Arc<AgentCounters>,
    name: String,
) -> mpsc::UnboundedSender<InFlight> {
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
                    let len = f.payload.len() as u64;
                    match publisher.put(f.payload).await {
                        Ok(()) => {
                            counters.published.fetch_add(1, Ordering::Relaxed);
                            counters.payload_bytes.fetch_add(len, Ordering::Relaxed);
                            counters.objects.fetch_add(f.objects, Ordering::Relaxed);
                        }
                        Err(e) => tracing::warn!("agent {name}: publish failed: {e}"),
                    }
                }
            }
        }
    });
    tx
}
