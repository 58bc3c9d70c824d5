//! Admission of agents' frames, sans-IO: every payload that reaches the fuser passes here before
//! it may join a window. The caller passes the agent name taken from the key, the payload, and
//! "now" on the fuser's clock (microseconds since the Unix epoch).
//!
//! - **Bounded state.** At most `max_agents` agents are tracked. An agent not heard from (no
//!   frame, no liveliness token) for `forget_after` is forgotten; when the table is full, the
//!   least recently heard agent without a token makes room, and if every agent holds a token the
//!   newcomer is refused and counted.
//! - **Validation.** The payload is checked for size and object count before its objects are
//!   decoded, then decoded and validated; the frame must name the agent of its key.
//! - **Clock.** Capture times are the sender's real-time clock. A frame stamped more than
//!   `max_clock_skew` ahead of the fuser's clock, or older than that, is rejected, so no single
//!   frame can move the window state. Each agent's lag (arrival minus capture: latency plus
//!   clock offset) is kept over its recent frames and reported as a median.
//! - **Who is awaited.** A window waits for the agents that hold a liveliness token and are
//!   expected in it: an agent whose frame period is known (the median spacing of its recent
//!   captures) is expected in a window anchored a whole number of periods after its last capture,
//!   so a slow agent is not waited for between its frames. An agent that is expected and missing
//!   in [`MAX_MISSES`] windows in a row is no longer waited for until it sends again, so a token
//!   alone, or an agent that stopped sending, costs at most that many incomplete windows. A frame
//!   that then comes too late for its window, but within `max_wait` of its capture (it would have
//!   made it had the window waited), makes the agent awaited again; a slower one does not. Late
//!   frames count towards the frame period as well.
//!
//! - **Isolation.** What one agent sends costs the others nothing: its frames carry at most
//!   `max_objects` boxes into a window (the highest-scoring; the rest are counted as
//!   `over_budget`), boxes outside the fuser's area of interest ([`Area`]) are dropped and counted
//!   as `outside`, so that no far box can push the others out of the fused frame's reach, and an
//!   agent whose latest frame lies beyond a window is not awaited in it, so frames stamped ahead
//!   hold open only their own window (they are counted as `ahead`). The names of the other
//!   roles (`fuser`, `observer`, `router`) are refused, and a token re-declared without frames
//!   is not awaited again.
//!
//! Every rejection is counted per agent and in totals by reason.
//!
//! The admission itself is in `admission` (a payload checked into a frame, its boxes confined),
//! the agent table and who a window awaits in `roster`, the area of interest in `area`.

mod admission;
mod area;
mod roster;

pub use admission::Rejection;
pub use area::Area;
pub use roster::MAX_MISSES;

use roster::{median, AgentState};
use serde::Serialize;
use std::collections::BTreeMap;

/// Admission limits.
#[derive(Clone, Debug, PartialEq)]
pub struct IngestConfig {
    /// Largest accepted |capture time - fuser clock| (us); `None` accepts any capture time
    /// (replays of recorded data on their own clock).
    pub max_clock_skew_us: Option<u64>,
    /// Most agents tracked at once.
    pub max_agents: usize,
    /// An agent with no frame and no token for this long is forgotten (us).
    pub forget_after_us: u64,
    /// How long a window waits for an awaited agent (us): a late frame that arrived within this
    /// of its capture makes its agent awaited again.
    pub max_wait_us: u64,
    /// Most boxes one agent's frame brings into a window (the highest-scoring stay).
    pub max_objects: usize,
    /// Where the fuser stands: boxes outside are dropped.
    pub area: Area,
    /// A frame stamped more than this ahead of the fuser's clock is counted as `ahead` (us).
    pub ahead_us: u64,
}

/// The default budget of boxes per agent and window: the most a nuScenes detection result may
/// hold per sample, far above what a detector sees in one sweep.
pub const MAX_OBJECTS_PER_AGENT: usize = 500;

impl Default for IngestConfig {
    fn default() -> Self {
        IngestConfig {
            max_clock_skew_us: Some(1_000_000),
            max_agents: 256,
            forget_after_us: 60_000_000,
            max_wait_us: 150_000,
            max_objects: MAX_OBJECTS_PER_AGENT,
            area: Area::DEFAULT,
            ahead_us: 50_000,
        }
    }
}

/// Something admitted with a change worth a (rate-limited) log line.
#[derive(Clone, Debug, PartialEq)]
pub enum Note {
    /// Boxes dropped beyond the agent's budget.
    OverBudget {
        /// The agent.
        agent: String,
        /// Boxes dropped.
        dropped: usize,
    },
    /// Boxes dropped outside the area of interest.
    Outside {
        /// The agent.
        agent: String,
        /// Boxes dropped.
        dropped: usize,
    },
    /// A frame stamped this many us ahead of the fuser's clock.
    Ahead {
        /// The agent.
        agent: String,
        /// How far ahead (us).
        ahead_us: u64,
    },
}

impl Note {
    /// The counter name of the note.
    pub fn reason(&self) -> &'static str {
        match self {
            Note::OverBudget { .. } => "over_budget",
            Note::Outside { .. } => "outside",
            Note::Ahead { .. } => "ahead",
        }
    }
}

impl std::fmt::Display for Note {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Note::OverBudget { agent, dropped } => write!(
                f,
                "agent {agent}: {dropped} boxes beyond its budget per window dropped (the lowest scores)"
            ),
            Note::Outside { agent, dropped } => write!(
                f,
                "agent {agent}: {dropped} boxes outside the fuser's area of interest dropped"
            ),
            Note::Ahead { agent, ahead_us } => write!(
                f,
                "agent {agent}: frame stamped {:.3} s ahead of the fuser's clock (it holds only its own window)",
                *ahead_us as f64 / 1e6
            ),
        }
    }
}

/// Per-agent counters (the `agents` entries of the stats).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct AgentStats {
    /// Frames received (valid or not).
    pub frames_in: u64,
    /// Frames that joined a window.
    pub accepted: u64,
    /// Frames fused into a published window.
    pub fused: u64,
    /// Frames that failed to decode or validate.
    pub invalid: u64,
    /// Frames naming another agent than their key.
    pub wrong_agent: u64,
    /// Frames stamped too far ahead of the fuser's clock.
    pub future: u64,
    /// Frames stamped too far behind the fuser's clock.
    pub stale: u64,
    /// Frames for a window already closed.
    pub late: u64,
    /// Frames seen before (same sequence number and capture time).
    pub duplicate: u64,
    /// Frames dropped for another frame of the same agent closer to a window's anchor.
    pub replaced: u64,
    /// Payload bytes received.
    pub payload_bytes: u64,
    /// Objects received in accepted frames.
    pub objects: u64,
    /// Boxes dropped beyond the budget per window.
    pub over_budget: u64,
    /// Boxes dropped outside the area of interest.
    pub outside: u64,
    /// Frames stamped ahead of the fuser's clock (by more than the tolerance, within the skew).
    pub ahead: u64,
    /// Median arrival minus capture time over recent frames (ms): latency plus clock offset.
    pub clock_lag_ms: Option<f64>,
    /// Whether the agent holds a liveliness token.
    pub token: bool,
    /// Boxes its CPMs carried of classes the project has no name for (an animal, a group):
    /// left out.
    pub unnamed: u64,
}

/// The admission state.
#[derive(Debug)]
pub struct Ingest {
    cfg: IngestConfig,
    agents: BTreeMap<String, AgentState>,
    rejected: BTreeMap<&'static str, u64>,
    forgotten: u64,
    evicted: Vec<String>,
    notes: Vec<Note>,
    /// Totals of the notes by reason: boxes over budget or outside, frames ahead.
    noted: BTreeMap<&'static str, u64>,
    /// The area's centre as learned (or given), once known.
    center: Option<[f64; 2]>,
}

impl Ingest {
    /// Empty state with the given limits.
    pub fn new(cfg: IngestConfig) -> Self {
        Ingest {
            agents: BTreeMap::new(),
            rejected: BTreeMap::new(),
            forgotten: 0,
            evicted: Vec::new(),
            notes: Vec::new(),
            noted: BTreeMap::new(),
            center: match cfg.area {
                Area::Given { center, .. } => Some(center),
                Area::Learned { .. } => None,
            },
            cfg,
        }
    }

    /// The limits.
    pub fn config(&self) -> &IngestConfig {
        &self.cfg
    }

    fn note(&mut self, n: Note, count: u64) {
        *self.noted.entry(n.reason()).or_default() += count;
        self.notes.push(n);
    }

    /// Totals of what admission dropped or flagged without rejecting a frame: boxes
    /// `over_budget` and `outside`, frames `ahead`.
    pub fn noted(&self) -> &BTreeMap<&'static str, u64> {
        &self.noted
    }

    /// The notes of admitted frames since the last call.
    pub fn take_notes(&mut self) -> Vec<Note> {
        std::mem::take(&mut self.notes)
    }

    /// Counts `n` boxes of an admitted CPM that were left out for their class.
    pub fn unnamed(&mut self, agent: &str, n: u64) {
        if let Some(st) = self.agents.get_mut(agent) {
            st.stats.unnamed += n;
        }
    }

    /// Rejections so far by reason, forgotten agents included.
    pub fn rejected(&self) -> &BTreeMap<&'static str, u64> {
        &self.rejected
    }

    /// Counters of every tracked agent, with their clock lag medians.
    pub fn agent_stats(&self) -> BTreeMap<String, AgentStats> {
        self.agents
            .iter()
            .map(|(n, s)| {
                let mut st = s.stats.clone();
                st.token = s.token;
                st.clock_lag_ms = median(&s.lags).map(|us| us / 1000.0);
                (n.clone(), st)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
