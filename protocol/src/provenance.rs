//! Where a fused frame came from: the agents whose frames its window held, whether every awaited
//! agent was there, and, per fused box, which of those agents contributed to it ([`AgentSet`], a
//! bitmask over the window's agent list). The wire carries it in fused frames
//! (`docs/wire-format.md`, "Provenance").

use crate::keys::NameError;
use crate::limits::MAX_WINDOW_AGENTS;

/// A set of agents, as indices into a window's agent list (bit k of byte k / 8: agent k); up to
/// 64 agents without an allocation.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct AgentSet(smallvec::SmallVec<[u8; 8]>);

impl AgentSet {
    /// The empty set.
    pub fn new() -> Self {
        AgentSet(smallvec::SmallVec::new())
    }

    /// The set holding only agent `k`.
    pub fn single(k: usize) -> Self {
        let mut s = AgentSet::new();
        s.insert(k);
        s
    }

    /// Adds agent `k`.
    pub fn insert(&mut self, k: usize) {
        if self.0.len() <= k / 8 {
            self.0.resize(k / 8 + 1, 0);
        }
        self.0[k / 8] |= 1 << (k % 8);
    }

    /// Adds every agent of `other`.
    pub fn union_with(&mut self, other: &AgentSet) {
        if self.0.len() < other.0.len() {
            self.0.resize(other.0.len(), 0);
        }
        for (a, b) in self.0.iter_mut().zip(&other.0) {
            *a |= b;
        }
    }

    /// True when agent `k` is in the set.
    pub fn contains(&self, k: usize) -> bool {
        self.0.get(k / 8).is_some_and(|b| b & (1 << (k % 8)) != 0)
    }

    /// The agents in the set, ascending.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.0.len() * 8).filter(|&k| self.contains(k))
    }

    /// How many agents the set holds.
    pub fn len(&self) -> usize {
        self.0.iter().map(|b| b.count_ones() as usize).sum()
    }

    /// True when the set holds no agent.
    pub fn is_empty(&self) -> bool {
        self.0.iter().all(|&b| b == 0)
    }

    /// One more than the largest agent in the set (0 when empty): the list length it needs.
    pub fn bound(&self) -> usize {
        match self.0.iter().rposition(|&b| b != 0) {
            Some(i) => i * 8 + 8 - self.0[i].leading_zeros() as usize,
            None => 0,
        }
    }

    /// The mask as the wire writes it for a list of `n` agents: exactly `ceil(n / 8)` bytes.
    /// The set must lie within the list (`bound() <= n`).
    pub fn to_bytes(&self, n: usize) -> Vec<u8> {
        let mut b = self.0.to_vec();
        b.resize(n.div_ceil(8), 0);
        b
    }

    /// The set a wire mask stands for.
    pub fn from_bytes(bytes: &[u8]) -> Self {
        let len = bytes.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
        AgentSet(smallvec::SmallVec::from_slice(&bytes[..len]))
    }
}

impl FromIterator<usize> for AgentSet {
    fn from_iter<I: IntoIterator<Item = usize>>(iter: I) -> Self {
        let mut s = AgentSet::new();
        for k in iter {
            s.insert(k);
        }
        s
    }
}

/// The provenance of a fused frame.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Provenance {
    /// The agents whose frames the window held, in the order the masks index them.
    pub agents: Vec<String>,
    /// Whether every agent the fuser awaited had a frame in the window.
    pub complete: bool,
    /// Per fused box (in frame order), the agents whose boxes went into it.
    pub sources: Vec<AgentSet>,
}

/// Why a provenance does not fit its frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ProvenanceError {
    /// More agents than [`MAX_WINDOW_AGENTS`].
    #[error("{0} agents, more than the limit {MAX_WINDOW_AGENTS}")]
    TooManyAgents(usize),
    /// An agent's name is not a valid agent name.
    #[error("agent {index}: {error}")]
    BadAgent {
        /// The agent's place in the list.
        index: usize,
        /// What is wrong with its name.
        error: NameError,
    },
    /// An agent is listed twice.
    #[error("agent {index}: '{agent}' is listed twice")]
    Twice {
        /// The second place it holds in the list.
        index: usize,
        /// Its name.
        agent: String,
    },
    /// Not one source set per box.
    #[error("{sets} source sets for {boxes} boxes")]
    Sources {
        /// Source sets given.
        sets: usize,
        /// Boxes in the frame.
        boxes: usize,
    },
    /// A box has no source agent.
    #[error("box {0}: no source agent")]
    NoSource(usize),
    /// A box names an agent beyond the list.
    #[error("box {index}: source agent {agent} beyond the {listed} listed")]
    Beyond {
        /// The box.
        index: usize,
        /// The highest agent it names.
        agent: usize,
        /// Agents listed.
        listed: usize,
    },
    /// The completeness byte is neither 0 nor 1.
    #[error("complete must be 0 or 1, not {0}")]
    BadComplete(u8),
    /// A decoded source mask names no agent or one beyond the list.
    #[error("object {object}: source mask names no agent or one beyond the {listed} listed")]
    BadMask {
        /// The object.
        object: usize,
        /// Agents listed.
        listed: usize,
    },
}

impl Provenance {
    /// Checks the provenance of a frame of `n_boxes` boxes: at most [`MAX_WINDOW_AGENTS`]
    /// distinct agents, one non-empty source set per box, each within the agent list.
    pub fn check(&self, n_boxes: usize) -> Result<(), ProvenanceError> {
        if self.agents.len() > MAX_WINDOW_AGENTS {
            return Err(ProvenanceError::TooManyAgents(self.agents.len()));
        }
        let mut seen = std::collections::HashSet::with_capacity(self.agents.len());
        for (index, a) in self.agents.iter().enumerate() {
            crate::wire::check_agent_name(a)
                .map_err(|error| ProvenanceError::BadAgent { index, error })?;
            if !seen.insert(a) {
                return Err(ProvenanceError::Twice {
                    index,
                    agent: a.clone(),
                });
            }
        }
        if self.sources.len() != n_boxes {
            return Err(ProvenanceError::Sources {
                sets: self.sources.len(),
                boxes: n_boxes,
            });
        }
        for (i, s) in self.sources.iter().enumerate() {
            if s.is_empty() {
                return Err(ProvenanceError::NoSource(i));
            }
            if s.bound() > self.agents.len() {
                return Err(ProvenanceError::Beyond {
                    index: i,
                    agent: s.bound() - 1,
                    listed: self.agents.len(),
                });
            }
        }
        Ok(())
    }

    /// The names of the agents in `set`.
    pub fn names<'a>(&'a self, set: &'a AgentSet) -> impl Iterator<Item = &'a str> + 'a {
        set.iter()
            .filter_map(|k| self.agents.get(k).map(String::as_str))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_as_bits() {
        let s: AgentSet = [0, 3, 9].into_iter().collect();
        assert_eq!(s.len(), 3);
        assert_eq!(s.bound(), 10);
        assert!(s.contains(3) && !s.contains(4) && !s.contains(100));
        assert_eq!(s.iter().collect::<Vec<_>>(), vec![0, 3, 9]);
        // bits 0 and 3 in the first byte, bit 1 in the second.
        assert_eq!(s.to_bytes(10), vec![0b0000_1001, 0b0000_0010]);
        assert_eq!(s.to_bytes(16), vec![0b0000_1001, 0b0000_0010]);
        assert_eq!(AgentSet::from_bytes(&[9, 2, 0, 0]), s);
        assert_eq!(AgentSet::single(7).bound(), 8);
        assert_eq!(AgentSet::single(8).to_bytes(9), vec![0, 1]);
        assert!(AgentSet::from_bytes(&[0, 0]).is_empty());
        assert_eq!(AgentSet::new().bound(), 0);
        let mut u = AgentSet::single(1);
        u.union_with(&s);
        assert_eq!(u.iter().collect::<Vec<_>>(), vec![0, 1, 3, 9]);
    }

    #[test]
    fn check_names_the_problem() {
        let p = Provenance {
            agents: vec!["a".into(), "b".into()],
            complete: true,
            sources: vec![AgentSet::single(0), [0, 1].into_iter().collect()],
        };
        assert_eq!(p.check(2), Ok(()));
        assert_eq!(p.names(&p.sources[1]).collect::<Vec<_>>(), vec!["a", "b"]);
        let e = p.check(3).unwrap_err();
        assert_eq!(e, ProvenanceError::Sources { sets: 2, boxes: 3 });
        assert_eq!(e.to_string(), "2 source sets for 3 boxes");
        let mut q = p.clone();
        q.sources[0] = AgentSet::single(2);
        let e = ProvenanceError::Beyond {
            index: 0,
            agent: 2,
            listed: 2,
        };
        assert_eq!(q.check(2), Err(e));
        q.sources[0] = AgentSet::new();
        assert_eq!(q.check(2), Err(ProvenanceError::NoSource(0)));
        let mut q = p.clone();
        q.agents[1] = "a".into();
        let e = ProvenanceError::Twice {
            index: 1,
            agent: "a".into(),
        };
        assert_eq!(q.check(2), Err(e));
        q.agents[1] = "a/b".into();
        let e = q.check(2).unwrap_err();
        assert!(matches!(e, ProvenanceError::BadAgent { index: 1, .. }));
        assert_eq!(
            e.to_string(),
            "agent 1: agent name 'a/b' contains '/'; use letters, digits, '-', '_' or '.'"
        );
    }
}
