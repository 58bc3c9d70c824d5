//! What the fuser node reports: per-agent counters, rejections by reason, windows published and
//! lost, and latency percentiles. The same object answers `v2x/NS/fuser/stats` and is printed at
//! the end of a run; its size is bounded by the number of agents tracked.

use crate::ingest::AgentStats;
use serde::Serialize;
use std::collections::BTreeMap;

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

/// What bringing fused output into the wire's domain changed, summed over windows.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct FitStats {
    /// Stds raised to the format's floor (or lowered to its ceiling).
    pub stds_clamped: u64,
    /// Sizes clamped into range.
    pub sizes_clamped: u64,
    /// Scores clamped into [0, 1].
    pub scores_clamped: u64,
    /// Velocity components clamped into range.
    pub velocities_clamped: u64,
    /// Fused objects dropped for non-finite values or lying out of reach of the others.
    pub objects_invalid: u64,
    /// Fused objects dropped (lowest scores) to stay within the object limit.
    pub objects_capped: u64,
}

impl FitStats {
    /// Adds one window's changes.
    pub fn add(&mut self, f: &v2x_protocol::wire::Fit) {
        self.stds_clamped += f.stds_clamped as u64;
        self.sizes_clamped += f.sizes_clamped as u64;
        self.scores_clamped += f.scores_clamped as u64;
        self.velocities_clamped += f.velocities_clamped as u64;
        self.objects_invalid += f.objects_invalid as u64;
        self.objects_capped += f.objects_capped as u64;
    }
}

/// What the node reports (`v2x/NS/fuser/stats`, and at the end of a run).
#[derive(Clone, Debug, Default, Serialize)]
pub struct NodeStats {
    /// Namespace.
    pub ns: String,
    /// Method name.
    pub method: String,
    /// Agents holding a liveliness token now.
    pub live: Vec<String>,
    /// Agents windows wait for now: holding a token and sending frames.
    pub awaited: Vec<String>,
    /// Counters per tracked agent.
    pub agents: BTreeMap<String, AgentStats>,
    /// Agents tracked now.
    pub agents_tracked: usize,
    /// Agents forgotten so far (idle, or to make room).
    pub agents_forgotten: u64,
    /// Frames (and tokens) not admitted, by reason, over the whole run and every agent.
    pub rejected: BTreeMap<String, u64>,
    /// Windows fused and published.
    pub windows: u64,
    /// Of those, windows closed by their deadline with an awaited agent missing.
    pub windows_incomplete: u64,
    /// Windows fused but not published (the network refused the put).
    pub windows_unpublished: u64,
    /// Windows dropped unfused because the fusion queue was full.
    pub windows_dropped: u64,
    /// Fused objects published.
    pub fused_objects: u64,
    /// What was changed to keep fused output within the wire's domain.
    pub fit: FitStats,
    /// Windows open now.
    pub open_windows: usize,
    /// Windows closed and waiting to be fused now.
    pub fusion_queue: usize,
    /// Capture (sender's clock) to fused publish (fuser's clock); meaningful with synchronised
    /// clocks.
    pub e2e_latency_ms: Latency,
    /// Window close to fused publish: queueing, fusion, encoding and hand-off to Zenoh.
    pub fusion_latency_ms: Latency,
    /// Windows still open when the node was told to stop (then flushed).
    pub open_windows_at_stop: usize,
    /// Every fusion latency sample (ms), in window order; only in the final statistics.
    #[serde(skip)]
    pub fusion_samples: Vec<f64>,
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
