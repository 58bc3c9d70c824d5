//! A payload received on an agent's key, checked into a frame: the key's name, the agent
//! table's room, the decoding, the clock; then its boxes confined to the area and the budget
//! (`super::area`). What became of each admitted frame is recorded here too.

use super::roster::{CAPTURES, LAGS};
use super::{Ingest, Note};
use crate::time::window::Verdict;
use v2x_protocol::{wire, Frame};

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
    BadTiles(v2x_protocol::tiles::TileError),
    /// With regions: the part does not fit its capture ([`crate::intake::parts`]).
    Part(crate::intake::parts::PartError),
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
            Rejection::Part(crate::intake::parts::PartError::Late) => "late_part",
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

impl Ingest {
    /// Counts a rejection made outside [`Ingest::offer`] (a part that does not fit its capture).
    pub fn refuse(&mut self, r: Rejection) -> Rejection {
        self.reject(r)
    }

    pub(super) fn reject(&mut self, r: Rejection) -> Rejection {
        *self.rejected.entry(r.reason()).or_default() += 1;
        r
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
}
