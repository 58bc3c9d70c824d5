//! The agent table: each agent's state, who holds a liveliness token, who is awaited in a
//! window, and who is forgotten.

use super::{AgentStats, Ingest, Rejection};
use std::collections::{BTreeSet, VecDeque};
use v2x_protocol::wire;

#[derive(Clone, Debug, Default)]
pub(super) struct AgentState {
    pub(super) stats: AgentStats,
    pub(super) token: bool,
    pub(super) last_heard_us: u64,
    /// Recent capture times of accepted frames, oldest first.
    pub(super) captures: VecDeque<u64>,
    /// Windows in a row the agent was expected in and missing.
    pub(super) misses: u32,
    pub(super) lags: VecDeque<i64>,
    /// Where the agent is: the median centre (x, y) of its first boxes.
    pub(super) position: Option<[f64; 2]>,
    /// When it was first heard (orders agents for the area's ties).
    pub(super) first_heard_us: u64,
}

impl AgentState {
    /// The frame period: the median spacing of the recent captures, once there are two.
    pub(super) fn period_us(&self) -> Option<u64> {
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
    pub(super) fn expected(&self, anchor_us: u64, half_us: u64) -> bool {
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
pub(super) const LAGS: usize = 32;
/// How many recent captures per agent the frame period is taken over.
pub(super) const CAPTURES: usize = 9;
/// Windows in a row an awaited agent may miss before it is no longer waited for.
pub const MAX_MISSES: u32 = 3;

impl Ingest {
    /// Finds or makes room for an agent; `None` when the table is full of token holders.
    pub(super) fn entry(&mut self, agent: &str, now_us: u64) -> Option<&mut AgentState> {
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
}

pub(super) fn median(v: &VecDeque<i64>) -> Option<f64> {
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
