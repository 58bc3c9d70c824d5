//! What the fuser node reports: per-agent counters, rejections by reason, windows published and
//! lost, and latency percentiles. The same object answers `v2x/NS/fuser/stats` and is printed at
//! the end of a run; its size is bounded by the number of agents tracked.

use crate::intake::ingest::AgentStats;
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

/// Latencies recorded in microseconds, 0 to one hour at 3 significant figures, in fixed memory
/// however long the node runs.
pub struct LatencyHistogram(hdrhistogram::Histogram<u64>);

impl Default for LatencyHistogram {
    fn default() -> Self {
        LatencyHistogram(
            hdrhistogram::Histogram::new_with_max(3_600_000_000, 3).expect("valid bounds"),
        )
    }
}

impl LatencyHistogram {
    /// Records one latency (us); negative ones (clock skew) count as 0, longer than an hour as
    /// an hour.
    pub fn record(&mut self, us: i64) {
        self.0.saturating_record(us.max(0) as u64);
    }

    /// Its percentiles (ms), within 0.1%.
    pub fn latency(&self) -> Latency {
        let h = &self.0;
        let at = |q: f64| (!h.is_empty()).then(|| h.value_at_quantile(q) as f64 / 1000.0);
        Latency {
            count: h.len() as usize,
            p50_ms: at(0.50),
            p95_ms: at(0.95),
            p99_ms: at(0.99),
            max_ms: (!h.is_empty()).then(|| h.max() as f64 / 1000.0),
        }
    }
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

/// The area of interest the node admits boxes in.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct AreaReport {
    /// Its centre (x, y) in the map frame, m.
    pub center: [f64; 2],
    /// Its radius, m.
    pub radius_m: f64,
    /// Whether it was learned from the agents (else given).
    pub learned: bool,
}

/// How often the association's work bounds applied since the node started (in this process):
/// the fusion of such windows is no longer exact, but it stays within its time.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Degraded {
    /// Boxes whose candidate partners were capped to the cheapest.
    pub candidates_capped: u64,
    /// Groups of boxes too large to solve exactly, matched greedily.
    pub components_greedy: u64,
}

/// What the node reports (`v2x/NS/fuser/stats`, and at the end of a run).
#[derive(Clone, Debug, Default, Serialize)]
pub struct NodeStats {
    /// Namespace.
    pub ns: String,
    /// Method name.
    pub method: String,
    /// The tile of a regional fuser (`COLUMN_ROW`); `None` for the single fuser.
    pub region: Option<String>,
    /// Regional fuser: captures fused without every part (a part missing after the wait).
    pub captures_incomplete: u64,
    /// Regional fuser: detections dropped because its subscriptions' queue was full.
    pub inbox_overflow: u64,
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
    /// What admission dropped or flagged without refusing a frame, over the whole run: boxes
    /// `over_budget` and `outside` the area, frames stamped `ahead` of the fuser's clock.
    pub dropped: BTreeMap<String, u64>,
    /// The area of interest, once given or learned.
    pub area: Option<AreaReport>,
    /// Where the association's work bounds made fusion inexact.
    pub degraded: Degraded,
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
    /// With registration (`--align`): each agent's latest estimate, its stds, its matches and
    /// whether it is applied.
    pub registration: BTreeMap<String, crate::time::align::Registration>,
    /// With learned stds (`--learn-std`): per agent, the stds it states and the ones learned,
    /// over all its classes and per class, and whether it is flagged as inconsistent.
    pub learned_std: BTreeMap<String, crate::uncertainty::learn::AgentReport>,
    /// Tracks (live, confirmed so far, ended so far), when the node tracks.
    pub tracks: Option<crate::tracker::TrackStats>,
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
    /// The first fusion latency samples (ms, up to 200,000), in window order; only in the final
    /// statistics (the load test compares the run's halves with them).
    #[serde(skip)]
    pub fusion_samples: Vec<f64>,
}

#[cfg(test)]
mod tests {
    use super::{Latency, LatencyHistogram};

    #[test]
    fn the_histogram_agrees_with_the_exact_percentiles() {
        let mut h = LatencyHistogram::default();
        let v: Vec<f64> = (1..=10_000)
            .map(|x| (x * 37 % 10_007) as f64 / 10.0)
            .collect();
        for x in &v {
            h.record((x * 1000.0) as i64);
        }
        h.record(-5); // a clock ahead: counted as 0
        let (a, b) = (h.latency(), Latency::of(&v));
        assert_eq!(a.count, 10_001);
        for (x, y) in [
            (a.p50_ms, b.p50_ms),
            (a.p99_ms, b.p99_ms),
            (a.max_ms, b.max_ms),
        ] {
            let (x, y) = (x.unwrap(), y.unwrap());
            assert!((x - y).abs() <= 1e-3 * y + 1e-3, "{x} vs {y}");
        }
        assert_eq!(LatencyHistogram::default().latency().p50_ms, None);
    }

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
