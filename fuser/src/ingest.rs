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

use crate::window::Verdict;
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use v2x_protocol::{wire, Frame};

/// Where the fuser stands: boxes whose centre lies outside are dropped at admission.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Area {
    /// A disc of the map frame's xy plane, given in the configuration.
    Given {
        /// Its centre (x, y), m.
        center: [f64; 2],
        /// Its radius, m.
        radius_m: f64,
    },
    /// A disc of this radius around where the agents are: each agent's position is the median
    /// centre of its first boxes, and the area is centred on the positions of the largest group
    /// of agents within the radius of one another (the earliest agent's on a tie), so that a
    /// minority of agents far away cannot move it.
    Learned {
        /// Its radius, m.
        radius_m: f64,
    },
}

impl Area {
    /// The default: learned, 10 km across every way from where the agents are.
    pub const DEFAULT: Area = Area::Learned { radius_m: 10_000.0 };

    /// The radius, m.
    pub fn radius_m(&self) -> f64 {
        match *self {
            Area::Given { radius_m, .. } | Area::Learned { radius_m } => radius_m,
        }
    }

    /// Parses `X,Y,RADIUS` (m, map frame) into a given area.
    pub fn parse(s: &str) -> Result<Area, String> {
        let v: Vec<f64> = s
            .split(',')
            .map(|p| p.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("area '{s}': expected X,Y,RADIUS in metres"))?;
        match v[..] {
            [x, y, r] => {
                let a = Area::Given {
                    center: [x, y],
                    radius_m: r,
                };
                a.validate().map(|()| a)
            }
            _ => Err(format!("area '{s}': expected X,Y,RADIUS in metres")),
        }
    }

    /// Checks the values: a finite centre and a finite radius > 0.
    pub fn validate(&self) -> Result<(), String> {
        let r = self.radius_m();
        if !(r.is_finite() && r > 0.0) {
            return Err(format!(
                "the area's radius must be finite and > 0 (got {r})"
            ));
        }
        if let Area::Given { center, .. } = self {
            if !center
                .iter()
                .all(|c| v2x_protocol::limits::coord_in_range(*c))
            {
                return Err(format!(
                    "the area's centre {center:?} is out of the map's range"
                ));
            }
        }
        Ok(())
    }
}

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

/// Why a payload was not admitted.
#[derive(Clone, Debug, PartialEq)]
pub enum Rejection {
    /// The key's agent name is not a valid agent name.
    BadKey,
    /// The name belongs to another role (`fuser`, `observer`, `router`).
    ReservedName,
    /// The agent table is full of agents holding tokens.
    AgentCap,
    /// The payload does not decode or validate.
    Invalid(wire::DecodeError),
    /// The payload, sent as an ETSI CPM, does not decode or validate.
    InvalidCpm(String),
    /// The frame names another agent than its key.
    WrongAgent(String),
    /// Stamped this many us ahead of the fuser's clock, beyond the tolerance.
    Future(u64),
    /// Stamped this many us behind the fuser's clock, beyond the tolerance.
    Stale(u64),
    /// With regions: the part's attachment does not hold a valid tile list.
    BadTiles(String),
    /// With regions: the part does not fit its capture ([`crate::parts`]).
    Part(crate::parts::PartError),
}

impl Rejection {
    /// The counter name of the reason.
    pub fn reason(&self) -> &'static str {
        match self {
            Rejection::BadKey => "bad_key",
            Rejection::ReservedName => "reserved_name",
            Rejection::AgentCap => "agent_cap",
            Rejection::Invalid(_) | Rejection::InvalidCpm(_) => "invalid",
            Rejection::WrongAgent(_) => "wrong_agent",
            Rejection::Future(_) => "future",
            Rejection::Stale(_) => "stale",
            Rejection::BadTiles(_) => "bad_tiles",
            Rejection::Part(crate::parts::PartError::Late) => "late_part",
            Rejection::Part(_) => "bad_part",
        }
    }
}

impl std::fmt::Display for Rejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rejection::BadKey => write!(f, "the key's agent name is not valid"),
            Rejection::ReservedName => {
                write!(
                    f,
                    "the name belongs to another role (fuser, observer, router)"
                )
            }
            Rejection::AgentCap => write!(f, "too many agents tracked"),
            Rejection::Invalid(e) => write!(f, "invalid frame: {e}"),
            Rejection::InvalidCpm(e) => write!(f, "invalid CPM: {e}"),
            Rejection::WrongAgent(a) => write!(f, "the frame claims to be from '{a}'"),
            Rejection::Future(us) => write!(
                f,
                "stamped {:.1} s ahead of the fuser's clock",
                *us as f64 / 1e6
            ),
            Rejection::BadTiles(e) => write!(f, "bad tile list: {e}"),
            Rejection::Part(e) => write!(f, "{e}"),
            Rejection::Stale(us) => write!(
                f,
                "stamped {:.1} s behind the fuser's clock",
                *us as f64 / 1e6
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
}

#[derive(Clone, Debug, Default)]
struct AgentState {
    stats: AgentStats,
    token: bool,
    last_heard_us: u64,
    /// Recent capture times of accepted frames, oldest first.
    captures: VecDeque<u64>,
    /// Windows in a row the agent was expected in and missing.
    misses: u32,
    lags: VecDeque<i64>,
    /// Where the agent is: the median centre (x, y) of its first boxes.
    position: Option<[f64; 2]>,
    /// When it was first heard (orders agents for the area's ties).
    first_heard_us: u64,
}

impl AgentState {
    /// The frame period: the median spacing of the recent captures, once there are two.
    fn period_us(&self) -> Option<u64> {
        let mut d: Vec<u64> = self
            .captures
            .iter()
            .zip(self.captures.iter().skip(1))
            .map(|(a, b)| b - a)
            .filter(|&d| d > 0)
            .collect();
        d.sort_unstable();
        d.get(d.len() / 2).copied()
    }

    /// Whether a frame of this agent is expected in a window anchored at `anchor_us` of
    /// half-width `half_us`.
    fn expected(&self, anchor_us: u64, half_us: u64) -> bool {
        if self.misses >= MAX_MISSES {
            return false;
        }
        // Its latest frame lies past this window already: it has nothing more for it (frames
        // stamped ahead hold only their own window).
        if self
            .captures
            .back()
            .is_some_and(|&last| last > anchor_us.saturating_add(half_us))
        {
            return false;
        }
        let (Some(&last), Some(p)) = (self.captures.back(), self.period_us()) else {
            return true;
        };
        // Its latest frame reaches this window (windows need not lie on its grid: another
        // agent's frame may have opened it off the grid).
        if anchor_us < last.saturating_add(half_us) {
            return true;
        }
        let k = ((anchor_us - last) as f64 / p as f64).round().max(1.0);
        let next = last as f64 + k * p as f64;
        (anchor_us as f64 - next).abs() <= half_us as f64 + p as f64 / 8.0
    }
}

/// How many recent lags per agent the median is taken over.
const LAGS: usize = 32;
/// How many recent captures per agent the frame period is taken over.
const CAPTURES: usize = 9;
/// Windows in a row an awaited agent may miss before it is no longer waited for.
pub const MAX_MISSES: u32 = 3;

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

    /// Counts a rejection made outside [`Ingest::offer`] (a part that does not fit its capture).
    pub fn refuse(&mut self, r: Rejection) -> Rejection {
        self.reject(r)
    }

    fn reject(&mut self, r: Rejection) -> Rejection {
        *self.rejected.entry(r.reason()).or_default() += 1;
        r
    }

    /// Finds or makes room for an agent; `None` when the table is full of token holders.
    fn entry(&mut self, agent: &str, now_us: u64) -> Option<&mut AgentState> {
        if !self.agents.contains_key(agent) {
            if self.agents.len() >= self.cfg.max_agents {
                let victim = self
                    .agents
                    .iter()
                    .filter(|(_, s)| !s.token)
                    .min_by_key(|(_, s)| s.last_heard_us)
                    .map(|(n, _)| n.clone())?;
                self.agents.remove(&victim);
                self.forgotten += 1;
                self.evicted.push(victim);
            }
            self.agents.insert(
                agent.to_string(),
                AgentState {
                    last_heard_us: now_us,
                    first_heard_us: now_us,
                    ..Default::default()
                },
            );
        }
        self.agents.get_mut(agent)
    }

    /// Admits or rejects a payload received on `agent`'s detections key at `now_us`.
    pub fn offer(&mut self, agent: &str, payload: &[u8], now_us: u64) -> Result<Frame, Rejection> {
        self.offer_decoded(agent, payload.len(), now_us, || {
            wire::decode(payload).map_err(Rejection::Invalid)
        })
    }

    /// Admits or rejects a payload of `len` bytes received on `agent`'s detections key at
    /// `now_us`, decoded by `decode` (a frame, or another encoding of one, such as a CPM) once
    /// the key has passed: the same checks whatever the encoding.
    pub fn offer_decoded(
        &mut self,
        agent: &str,
        len: usize,
        now_us: u64,
        decode: impl FnOnce() -> Result<Frame, Rejection>,
    ) -> Result<Frame, Rejection> {
        if wire::check_agent_name(agent).is_err() {
            return Err(self.reject(Rejection::BadKey));
        }
        if v2x_protocol::acl::reserved(agent) {
            return Err(self.reject(Rejection::ReservedName));
        }
        let skew = self.cfg.max_clock_skew_us;
        let ahead_tolerance = self.cfg.ahead_us;
        let mut ahead = None;
        let Some(st) = self.entry(agent, now_us) else {
            return Err(self.reject(Rejection::AgentCap));
        };
        st.last_heard_us = now_us;
        st.stats.frames_in += 1;
        st.stats.payload_bytes += len as u64;
        let result = match decode() {
            Err(r) => {
                match r {
                    Rejection::WrongAgent(_) => st.stats.wrong_agent += 1,
                    _ => st.stats.invalid += 1,
                }
                Err(r)
            }
            Ok(f) if f.agent != agent => {
                st.stats.wrong_agent += 1;
                Err(Rejection::WrongAgent(f.agent))
            }
            Ok(f) => match skew {
                Some(tol) if f.capture_us > now_us.saturating_add(tol) => {
                    st.stats.future += 1;
                    Err(Rejection::Future(f.capture_us - now_us))
                }
                Some(tol) if f.capture_us.saturating_add(tol) < now_us => {
                    st.stats.stale += 1;
                    Err(Rejection::Stale(now_us - f.capture_us))
                }
                _ => {
                    st.lags.push_back(now_us as i64 - f.capture_us as i64);
                    if st.lags.len() > LAGS {
                        st.lags.pop_front();
                    }
                    if f.capture_us > now_us.saturating_add(ahead_tolerance) {
                        st.stats.ahead += 1;
                        ahead = Some(f.capture_us - now_us);
                    }
                    Ok(f)
                }
            },
        };
        let mut frame = result.map_err(|r| self.reject(r))?;
        if let Some(ahead_us) = ahead {
            let agent = agent.to_string();
            self.note(Note::Ahead { agent, ahead_us }, 1);
        }
        self.confine(agent, &mut frame);
        Ok(frame)
    }

    /// Keeps the boxes of an admitted frame within the area of interest, then within the
    /// agent's budget (the highest scores, in their order), counting what it drops.
    fn confine(&mut self, agent: &str, frame: &mut Frame) {
        if let Some(st) = self.agents.get_mut(agent) {
            if st.position.is_none() && !frame.detections.is_empty() {
                st.position = Some(median_xy(&frame.detections));
                if matches!(self.cfg.area, Area::Learned { .. }) {
                    self.center = self.learned_center();
                }
            }
        }
        let (Some(c), r) = (self.center, self.cfg.area.radius_m()) else {
            return;
        };
        let before = frame.detections.len();
        frame
            .detections
            .retain(|d| (d.center[0] - c[0]).hypot(d.center[1] - c[1]) <= r);
        let outside = before - frame.detections.len();
        let budget = self.cfg.max_objects;
        let over = frame.detections.len().saturating_sub(budget);
        if over > 0 {
            let mut order: Vec<usize> = (0..frame.detections.len()).collect();
            order.sort_by(|&a, &b| {
                let (da, db) = (&frame.detections[a], &frame.detections[b]);
                db.score.total_cmp(&da.score).then(a.cmp(&b))
            });
            let mut keep = vec![false; order.len()];
            for &i in &order[..budget] {
                keep[i] = true;
            }
            let mut i = 0;
            frame.detections.retain(|_| {
                i += 1;
                keep[i - 1]
            });
        }
        let Some(st) = self.agents.get_mut(agent) else {
            return;
        };
        st.stats.outside += outside as u64;
        st.stats.over_budget += over as u64;
        if outside > 0 {
            let agent = agent.to_string();
            self.note(
                Note::Outside {
                    agent,
                    dropped: outside,
                },
                outside as u64,
            );
        }
        if over > 0 {
            let agent = agent.to_string();
            self.note(
                Note::OverBudget {
                    agent,
                    dropped: over,
                },
                over as u64,
            );
        }
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

    /// The learned area's centre: the median position of the largest group of agents within the
    /// radius of one agent (the earliest heard on a tie).
    fn learned_center(&self) -> Option<[f64; 2]> {
        let r = self.cfg.area.radius_m();
        let mut placed: Vec<(u64, [f64; 2])> = self
            .agents
            .values()
            .filter_map(|s| s.position.map(|p| (s.first_heard_us, p)))
            .collect();
        placed.sort_by_key(|(t, _)| *t);
        let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) <= r;
        let best = placed
            .iter()
            .map(|(_, p)| placed.iter().filter(|(_, q)| near(*p, *q)).count())
            .enumerate()
            // the most neighbours; of equals, the first (earliest heard)
            .max_by(|(i, a), (j, b)| a.cmp(b).then(j.cmp(i)))
            .map(|(i, _)| placed[i].1)?;
        let group: Vec<[f64; 2]> = placed
            .iter()
            .map(|(_, q)| *q)
            .filter(|q| near(best, *q))
            .collect();
        Some([0, 1].map(|k| {
            let mut v: Vec<f64> = group.iter().map(|p| p[k]).collect();
            v.sort_by(f64::total_cmp);
            v[(v.len() - 1) / 2]
        }))
    }

    /// The area of interest's centre, once given or learned.
    pub fn area_center(&self) -> Option<[f64; 2]> {
        self.center
    }

    /// The notes of admitted frames since the last call.
    pub fn take_notes(&mut self) -> Vec<Note> {
        std::mem::take(&mut self.notes)
    }

    /// Records what the window did with an admitted frame of `agent` captured at `capture_us`.
    pub fn record(&mut self, agent: &str, verdict: Verdict, objects: usize, capture_us: u64) {
        let Some(st) = self.agents.get_mut(agent) else {
            return;
        };
        match verdict {
            Verdict::Accepted | Verdict::Replaced => {
                st.stats.accepted += 1;
                st.stats.objects += objects as u64;
                if verdict == Verdict::Replaced {
                    st.stats.replaced += 1;
                }
                if st.captures.back().is_none_or(|&last| capture_us > last) {
                    st.captures.push_back(capture_us);
                    if st.captures.len() > CAPTURES {
                        st.captures.pop_front();
                    }
                }
                st.misses = 0;
            }
            Verdict::Superseded => st.stats.replaced += 1,
            Verdict::Late => {
                st.stats.late += 1;
                // It was captured then all the same: its period is learnt from it too.
                if st.captures.back().is_none_or(|&last| capture_us > last) {
                    st.captures.push_back(capture_us);
                    if st.captures.len() > CAPTURES {
                        st.captures.pop_front();
                    }
                }
                // late only because the window no longer waited for it: wait again
                let lag = st.lags.back().copied().unwrap_or(i64::MAX);
                if st.token && (0..=self.cfg.max_wait_us as i64).contains(&lag) {
                    st.misses = 0;
                }
            }
            Verdict::Duplicate => st.stats.duplicate += 1,
        }
        let reason = match verdict {
            Verdict::Accepted => return,
            Verdict::Replaced | Verdict::Superseded => "replaced",
            Verdict::Late => "late",
            Verdict::Duplicate => "duplicate",
        };
        *self.rejected.entry(reason).or_default() += 1;
    }

    /// Counts a published window's frames as fused.
    pub fn fused(&mut self, agents: &[String]) {
        for a in agents {
            if let Some(st) = self.agents.get_mut(a) {
                st.stats.fused += 1;
            }
        }
    }

    /// A liveliness token of `agent` appeared (`live`) or went away. Returns false when the
    /// agent could not be tracked (invalid name, or the table is full of token holders).
    pub fn token(&mut self, agent: &str, live: bool, now_us: u64) -> bool {
        if wire::check_agent_name(agent).is_err() {
            *self.rejected.entry(Rejection::BadKey.reason()).or_default() += 1;
            return false;
        }
        if v2x_protocol::acl::reserved(agent) {
            *self
                .rejected
                .entry(Rejection::ReservedName.reason())
                .or_default() += 1;
            return false;
        }
        if !live && !self.agents.contains_key(agent) {
            return true;
        }
        let Some(st) = self.entry(agent, now_us) else {
            *self
                .rejected
                .entry(Rejection::AgentCap.reason())
                .or_default() += 1;
            return false;
        };
        st.token = live;
        st.last_heard_us = now_us;
        if live {
            // A new token is a new life: its frame period is learnt again. It is awaited again
            // only once it sends (a frame resets its misses), so a token re-declared over and
            // over without frames costs no more windows than one token.
            st.captures.clear();
        }
        true
    }

    /// Counts a closed window against the awaited agents missing from it.
    pub fn window_closed(&mut self, anchor_us: u64, half_us: u64, members: &[&String]) {
        for (name, st) in self.agents.iter_mut() {
            if st.token && st.expected(anchor_us, half_us) && !members.contains(&name) {
                st.misses += 1;
            }
        }
    }

    /// The agents a window anchored at `anchor_us` (half-width `half_us`) waits for: holding a
    /// token and expected in it.
    pub fn awaited(&self, anchor_us: u64, half_us: u64) -> BTreeSet<String> {
        self.agents
            .iter()
            .filter(|(_, s)| s.token && s.expected(anchor_us, half_us))
            .map(|(n, _)| n.clone())
            .collect()
    }

    /// The agents holding a liveliness token.
    pub fn tokens(&self) -> Vec<String> {
        self.agents
            .iter()
            .filter(|(_, s)| s.token)
            .map(|(n, _)| n.clone())
            .collect()
    }

    /// The agents evicted to make room since the last call.
    pub fn take_evicted(&mut self) -> Vec<String> {
        std::mem::take(&mut self.evicted)
    }

    /// Forgets agents with no token not heard from for `forget_after`; returns their names and
    /// those of agents evicted to make room since the last call.
    pub fn prune(&mut self, now_us: u64) -> Vec<String> {
        let limit = self.cfg.forget_after_us;
        let idle: Vec<String> = self
            .agents
            .iter()
            .filter(|(_, s)| !s.token && now_us.saturating_sub(s.last_heard_us) > limit)
            .map(|(n, _)| n.clone())
            .collect();
        for n in &idle {
            self.agents.remove(n);
        }
        self.forgotten += idle.len() as u64;
        let mut gone = std::mem::take(&mut self.evicted);
        gone.extend(idle);
        gone
    }

    /// Whether an agent is tracked now.
    pub fn tracks(&self, agent: &str) -> bool {
        self.agents.contains_key(agent)
    }

    /// Number of agents tracked now.
    pub fn tracked(&self) -> usize {
        self.agents.len()
    }

    /// Agents forgotten so far (idle, or to make room).
    pub fn forgotten(&self) -> u64 {
        self.forgotten
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

/// The component-wise median of the boxes' centres (x, y); the boxes must not be empty.
fn median_xy(dets: &[v2x_protocol::Detection]) -> [f64; 2] {
    [0, 1].map(|k| {
        let mut v: Vec<f64> = dets.iter().map(|d| d.center[k]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    })
}

fn median(v: &VecDeque<i64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s: Vec<i64> = v.iter().copied().collect();
    s.sort_unstable();
    let n = s.len();
    Some(if n % 2 == 1 {
        s[n / 2] as f64
    } else {
        (s[n / 2 - 1] as f64 + s[n / 2] as f64) / 2.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::{AgentKind, Detection};

    const S: u64 = 1_000_000;
    const NOW: u64 = 1_700_000_000 * S;

    fn payload(agent: &str, capture_us: u64) -> Vec<u8> {
        wire::encode(&Frame {
            agent: agent.into(),
            kind: AgentKind::Vehicle,
            seq: 0,
            capture_us,
            origin: [0.0; 3],
            detections: vec![Detection::default()],
        })
        .unwrap()
    }

    #[test]
    fn frames_far_from_the_fuser_clock_are_rejected_and_counted() {
        let mut i = Ingest::new(IngestConfig::default());
        assert!(i.offer("a", &payload("a", NOW - 30_000), NOW).is_ok());
        assert_eq!(
            i.offer("a", &payload("a", NOW + 3600 * S), NOW),
            Err(Rejection::Future(3600 * S))
        );
        assert!(matches!(
            i.offer("a", &payload("a", u64::MAX), NOW),
            Err(Rejection::Future(_))
        ));
        assert!(matches!(
            i.offer("a", &payload("a", 0), NOW),
            Err(Rejection::Stale(_))
        ));
        // within the tolerance either way
        assert!(i.offer("a", &payload("a", NOW + S - 1), NOW).is_ok());
        assert!(i.offer("a", &payload("a", NOW - S + 1), NOW).is_ok());
        let st = &i.agent_stats()["a"];
        assert_eq!((st.frames_in, st.future, st.stale), (6, 2, 1));
        assert_eq!(i.rejected()["future"], 2);
        // no tolerance: a replay on its data's clock
        let mut i = Ingest::new(IngestConfig {
            max_clock_skew_us: None,
            ..Default::default()
        });
        assert!(i.offer("a", &payload("a", 0), NOW).is_ok());
    }

    #[test]
    fn the_lag_median_reports_latency_plus_offset() {
        let mut i = Ingest::new(IngestConfig::default());
        for (k, lag_ms) in [20u64, 25, 30, 500, 22].iter().enumerate() {
            let now = NOW + k as u64 * 100_000;
            i.offer("a", &payload("a", now - lag_ms * 1000), now)
                .unwrap();
        }
        assert_eq!(i.agent_stats()["a"].clock_lag_ms, Some(25.0));
    }

    #[test]
    fn wrong_names_and_bad_payloads() {
        let mut i = Ingest::new(IngestConfig::default());
        assert_eq!(
            i.offer("a", &payload("b", NOW), NOW),
            Err(Rejection::WrongAgent("b".into()))
        );
        assert!(matches!(
            i.offer("a", &[2, 0xff], NOW),
            Err(Rejection::Invalid(_))
        ));
        assert_eq!(
            i.offer("a*b", &payload("a", NOW), NOW),
            Err(Rejection::BadKey)
        );
        let st = &i.agent_stats()["a"];
        assert_eq!((st.wrong_agent, st.invalid), (1, 1));
        assert!(!i.tracks("a*b"));
    }

    #[test]
    fn the_table_stays_bounded_and_keeps_token_holders() {
        let mut i = Ingest::new(IngestConfig {
            max_agents: 10,
            ..Default::default()
        });
        assert!(i.token("honest", true, NOW));
        for k in 0..1000u64 {
            let name = format!("x{k}");
            let _ = i.offer(&name, &payload(&name, NOW), NOW + k);
        }
        assert_eq!(i.tracked(), 10);
        assert!(i.tracks("honest"), "a token holder is never evicted");
        assert_eq!(i.forgotten(), 1000 - 9);
        assert_eq!(
            i.prune(NOW).len(),
            1000 - 9,
            "evicted names are handed out once"
        );
        assert!(i.prune(NOW).is_empty());
        // token holders fill the table: newcomers are refused
        let mut i = Ingest::new(IngestConfig {
            max_agents: 3,
            ..Default::default()
        });
        for k in 0..3 {
            assert!(i.token(&format!("t{k}"), true, NOW));
        }
        assert!(!i.token("t9", true, NOW));
        assert_eq!(
            i.offer("z", &payload("z", NOW), NOW),
            Err(Rejection::AgentCap)
        );
        assert_eq!(i.rejected()["agent_cap"], 2);
    }

    #[test]
    fn idle_agents_are_forgotten() {
        let mut i = Ingest::new(IngestConfig::default());
        i.offer("a", &payload("a", NOW), NOW).unwrap();
        i.token("b", true, NOW);
        assert!(i.prune(NOW + 59 * S).is_empty());
        assert_eq!(i.prune(NOW + 61 * S), vec!["a".to_string()]);
        assert!(i.tracks("b"), "a token keeps an agent");
        i.token("b", false, NOW + 62 * S);
        assert_eq!(i.prune(NOW + 123 * S), vec!["b".to_string()]);
        assert_eq!(i.forgotten(), 2);
    }

    fn send(i: &mut Ingest, agent: &str, t: u64) {
        i.offer(agent, &payload(agent, t), t).unwrap();
        i.record(agent, Verdict::Accepted, 1, t);
    }

    const H: u64 = 50_000; // half of a 100 ms window

    #[test]
    fn a_token_alone_is_awaited_for_three_windows_at_most() {
        let mut i = Ingest::new(IngestConfig::default());
        i.token("silent", true, NOW);
        i.token("a", true, NOW);
        send(&mut i, "raw", NOW); // frames, but no token: never awaited
        for k in 0..3 {
            let t = NOW + k * 100_000;
            send(&mut i, "a", t);
            let awaited = i.awaited(t, H);
            assert_eq!(awaited.into_iter().collect::<Vec<_>>(), vec!["a", "silent"]);
            let a = "a".to_string();
            i.window_closed(t, H, &[&a]);
        }
        assert_eq!(
            i.awaited(NOW + 300_000, H).into_iter().collect::<Vec<_>>(),
            vec!["a"]
        );
        // it sends: awaited again
        send(&mut i, "silent", NOW + 310_000);
        assert!(i.awaited(NOW + 400_000, H).contains("silent"));
    }

    #[test]
    fn late_frames_teach_the_period_too() {
        let mut i = Ingest::new(IngestConfig::default());
        i.token("a", true, NOW);
        // Two captures 400 ms apart, then frames every 100 ms that all came too late.
        send(&mut i, "a", NOW);
        send(&mut i, "a", NOW + 400_000);
        for k in 1..=2 {
            let t = NOW + 400_000 + k * 100_000;
            i.offer("a", &payload("a", t), t + 20_000).unwrap();
            i.record("a", Verdict::Late, 1, t);
        }
        // Learnt from them: a 100 ms period, so expected 400 ms after the last (with a 400 ms
        // period it would be expected at 200 or 600 ms only).
        assert!(i.awaited(NOW + 1_000_000, H).contains("a"));
    }

    #[test]
    fn a_late_frame_that_waiting_would_have_caught_makes_its_agent_awaited_again() {
        let mut i = Ingest::new(IngestConfig::default()); // waits 150 ms
        i.token("a", true, NOW);
        send(&mut i, "a", NOW);
        send(&mut i, "a", NOW + 100_000);
        for k in 2..5 {
            i.window_closed(NOW + k * 100_000, H, &[]);
        }
        assert!(!i.awaited(NOW + 500_000, H).contains("a"));
        // 400 ms late: waiting would not have caught it
        let t = NOW + 500_000;
        i.offer("a", &payload("a", t), t + 400_000).unwrap();
        i.record("a", Verdict::Late, 1, t);
        assert!(!i.awaited(NOW + 600_000, H).contains("a"));
        // 120 ms late: it would have made its window
        let t = NOW + 600_000;
        i.offer("a", &payload("a", t), t + 120_000).unwrap();
        i.record("a", Verdict::Late, 1, t);
        assert!(i.awaited(NOW + 700_000, H).contains("a"));
        assert_eq!(i.agent_stats()["a"].late, 2);
    }

    #[test]
    fn a_slow_agent_is_awaited_only_where_its_frames_fall() {
        let mut i = Ingest::new(IngestConfig::default());
        i.token("slow", true, NOW);
        for k in 0..3 {
            send(&mut i, "slow", NOW + k * S); // 1 Hz
        }
        let last = NOW + 2 * S;
        assert!(!i.awaited(last + 300_000, H).contains("slow"));
        assert!(!i.awaited(last + 700_000, H).contains("slow"));
        assert!(i.awaited(last + S, H).contains("slow"));
        assert!(i.awaited(last + S + 40_000, H).contains("slow"), "jitter");
        assert!(
            i.awaited(last + 2 * S, H).contains("slow"),
            "one frame lost"
        );
        // it stops sending: three missed windows where it was expected, then no more waiting
        for k in 1..=3 {
            let anchor = last + k * S;
            assert!(i.awaited(anchor, H).contains("slow"));
            i.window_closed(anchor, H, &[]);
        }
        assert!(!i.awaited(last + 4 * S, H).contains("slow"));
    }

    /// A frame of `agent` with boxes at the given (x, score).
    fn boxes(agent: &str, capture_us: u64, at: &[(f64, f64)]) -> Vec<u8> {
        let detections = at
            .iter()
            .enumerate()
            .map(|(k, &(x, score))| Detection {
                center: [x, 5.0, 0.0],
                score,
                id: k as u32,
                ..Detection::default()
            })
            .collect();
        wire::encode(&Frame {
            agent: agent.into(),
            kind: AgentKind::Vehicle,
            seq: 0,
            capture_us,
            origin: [at.first().map_or(0.0, |b| b.0), 0.0, 0.0],
            detections,
        })
        .unwrap()
    }

    #[test]
    fn an_agent_brings_at_most_its_budget_of_boxes_the_highest_scoring() {
        let mut i = Ingest::new(IngestConfig {
            max_objects: 3,
            ..IngestConfig::default()
        });
        let at = [(1.0, 0.2), (2.0, 0.9), (3.0, 0.5), (4.0, 0.9), (5.0, 0.1)];
        let f = i.offer("a", &boxes("a", NOW, &at), NOW).unwrap();
        // The three best, in their order (of two equal scores, the first).
        let xs: Vec<f64> = f.detections.iter().map(|d| d.center[0]).collect();
        assert_eq!(xs, [2.0, 3.0, 4.0]);
        assert_eq!(i.agent_stats()["a"].over_budget, 2);
        assert_eq!(i.noted()["over_budget"], 2);
        assert_eq!(
            i.take_notes(),
            vec![Note::OverBudget {
                agent: "a".into(),
                dropped: 2
            }]
        );
        // Within the budget nothing changes.
        let f = i.offer("b", &boxes("b", NOW, &at[..3]), NOW).unwrap();
        assert_eq!(f.detections.len(), 3);
        assert!(i.take_notes().is_empty());
    }

    #[test]
    fn far_agents_cannot_move_the_learned_area() {
        let mut i = Ingest::new(IngestConfig {
            area: Area::Learned { radius_m: 1000.0 },
            ..IngestConfig::default()
        });
        // The far agent comes first: the area is its own until others come.
        let far = [(1e9 - 1.0, 1.0), (1e9, 1.0)];
        assert_eq!(
            i.offer("far", &boxes("far", NOW, &far), NOW)
                .unwrap()
                .detections
                .len(),
            2
        );
        assert_eq!(i.area_center(), Some([1e9, 5.0]));
        let honest = [(10.0, 0.5), (30.0, 0.5), (20.0, 0.5)];
        // One honest agent ties with it: the earliest stays.
        assert!(i
            .offer("a", &boxes("a", NOW, &honest), NOW + 1)
            .unwrap()
            .detections
            .is_empty());
        // Two honest agents outnumber it: the area moves to them, centred on their median.
        let f = i
            .offer("b", &boxes("b", NOW, &[(40.0, 0.5)]), NOW + 2)
            .unwrap();
        assert_eq!(f.detections.len(), 1);
        assert_eq!(i.area_center(), Some([20.0, 5.0]));
        assert_eq!(
            i.offer("a", &boxes("a", NOW, &honest), NOW + 3)
                .unwrap()
                .detections
                .len(),
            3
        );
        // The far agent's boxes are now dropped, and the honest ones kept.
        assert!(i
            .offer("far", &boxes("far", NOW, &far), NOW + 4)
            .unwrap()
            .detections
            .is_empty());
        assert_eq!(i.agent_stats()["far"].outside, 2);
        assert_eq!(i.agent_stats()["a"].outside, 3);
        assert_eq!(i.noted()["outside"], 5);
        // A box at the area's edge stays, one just beyond goes.
        let edge = [(1020.0, 0.5), (1020.1, 0.5)];
        let f = i.offer("b", &boxes("b", NOW, &edge), NOW + 5).unwrap();
        assert_eq!(f.detections.len(), 1);
    }

    #[test]
    fn a_given_area_holds_from_the_first_frame() {
        let area = Area::parse("100,-50,10").unwrap();
        assert_eq!(
            area,
            Area::Given {
                center: [100.0, -50.0],
                radius_m: 10.0
            }
        );
        for bad in ["1,2", "1,2,0", "a,b,c", "1,2,inf", "1e10,0,5"] {
            assert!(Area::parse(bad).is_err(), "{bad}");
        }
        let mut i = Ingest::new(IngestConfig {
            area,
            ..IngestConfig::default()
        });
        let f = i
            .offer("a", &boxes("a", NOW, &[(95.0, 0.5), (120.0, 0.5)]), NOW)
            .unwrap();
        // (95, 5) is 55 m from (100, -50): outside; the frame is admitted empty.
        assert!(f.detections.is_empty());
        assert_eq!(i.area_center(), Some([100.0, -50.0]));
    }

    #[test]
    fn frames_stamped_ahead_hold_only_their_own_window() {
        let mut i = Ingest::new(IngestConfig::default());
        i.token("a", true, NOW);
        i.token("early", true, NOW);
        send(&mut i, "a", NOW);
        // "early" stamps its frames 0.2-0.9 s ahead, off any grid.
        for (k, ahead) in [200_000u64, 900_000, 450_000].into_iter().enumerate() {
            let now = NOW + k as u64 * 100_000;
            i.offer("early", &payload("early", now + ahead), now)
                .unwrap();
            i.record("early", Verdict::Accepted, 1, now + ahead);
        }
        assert_eq!(i.agent_stats()["early"].ahead, 3);
        assert_eq!(i.noted()["ahead"], 3);
        // Honest windows before its latest stamp (1.0 s ahead) do not wait for it; its own does.
        for k in 0..10 {
            let anchor = NOW + k * 100_000;
            assert!(!i.awaited(anchor, H).contains("early"), "window {k}");
        }
        assert!(i.awaited(NOW + 1_000_000, H).contains("early"));
        // 30 ms ahead is within the tolerance: not counted.
        i.offer("a", &payload("a", NOW + 130_000), NOW + 100_000)
            .unwrap();
        assert_eq!(i.agent_stats()["a"].ahead, 0);
    }

    #[test]
    fn a_token_declared_again_and_again_costs_its_three_windows_once() {
        let mut i = Ingest::new(IngestConfig::default());
        i.token("a", true, NOW);
        i.token("flap", true, NOW);
        let a = "a".to_string();
        let mut missing = 0;
        for k in 0..20 {
            let t = NOW + k * 100_000;
            if k % 5 == 0 {
                i.token("flap", false, t);
                i.token("flap", true, t);
            }
            send(&mut i, "a", t);
            missing += i.awaited(t, H).contains("flap") as u32;
            i.window_closed(t, H, &[&a]);
        }
        assert_eq!(missing, MAX_MISSES);
        // Once it sends, it is awaited again.
        send(&mut i, "flap", NOW + 2_000_000);
        assert!(i.awaited(NOW + 2_100_000, H).contains("flap"));
    }

    #[test]
    fn the_names_of_other_roles_are_refused() {
        let mut i = Ingest::new(IngestConfig::default());
        for name in ["fuser", "observer", "router"] {
            assert_eq!(
                i.offer(name, &payload(name, NOW), NOW),
                Err(Rejection::ReservedName)
            );
            assert!(!i.token(name, true, NOW));
        }
        assert_eq!(i.rejected()["reserved_name"], 6);
        assert_eq!(i.tracked(), 0);
    }
}
