//! Timelines of a scenario, sans-IO: `[[events]]` entries (what happens to which agent when, in
//! seconds of the scenario's data time), checked on load, and each agent's state as the events
//! change it over the run ([`AgentTimeline`]).
//!
//! Actions: `leave` (the agent stops sending and withdraws its liveliness token), `join` (it
//! comes back), `link` (new latency, jitter and/or drop rate), `loss_burst` (every frame lost
//! for `duration_s`), `clock_jump` (its clock moves by `jump_ms`), `noise` (a new noise profile,
//! with `faults` if given); and for the target `fuser`, `restart` (the fuser node stops, down
//! for `duration_s`, default 0, and starts afresh: its windows, tracks and clock estimates lost).

use crate::faults::Faults;
use crate::noise::AgentNoise;
use serde::Deserialize;
use v2x_agent::Link;
use v2x_protocol::InvalidValue;
use v2x_truth::spec::SpecError;

/// What an event does.
#[derive(Copy, Clone, Debug, Deserialize, serde::Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Action {
    /// The agent stops sending frames and withdraws its liveliness token.
    Leave,
    /// The agent sends again.
    Join,
    /// Latency, jitter and/or drop rate change.
    Link,
    /// Every frame is lost for `duration_s`.
    LossBurst,
    /// The agent's clock moves by `jump_ms`.
    ClockJump,
    /// A new noise profile (and `faults`).
    Noise,
    /// The fuser restarts (target `fuser`), down for `duration_s` (default 0).
    Restart,
}

/// The target name of events that concern the fuser.
pub const FUSER: &str = "fuser";

/// One `[[events]]` entry as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EventSpec {
    /// When, in seconds from the start of the run (data time).
    pub at_s: f64,
    /// The agent's name, or `fuser`.
    pub target: String,
    /// What happens.
    pub action: Action,
    /// `link`: the new latency (ms).
    #[serde(default)]
    pub latency_ms: Option<f64>,
    /// `link`: the new jitter (ms).
    #[serde(default)]
    pub jitter_ms: Option<f64>,
    /// `link`: the new drop rate.
    #[serde(default)]
    pub drop_rate: Option<f64>,
    /// `loss_burst`: how long (s); `restart`: how long the fuser is down (s).
    #[serde(default)]
    pub duration_s: Option<f64>,
    /// `clock_jump`: by how much (ms, either sign).
    #[serde(default)]
    pub jump_ms: Option<f64>,
    /// `noise`: the new noise (as an agent's `noise`).
    #[serde(default)]
    pub noise: Option<String>,
    /// `noise`: the new faults (as an agent's `faults`).
    #[serde(default)]
    pub faults: Option<String>,
}

impl EventSpec {
    /// The fields this event sets, by name.
    fn fields(&self) -> Vec<&'static str> {
        let mut f = Vec::new();
        let set = [
            ("latency_ms", self.latency_ms.is_some()),
            ("jitter_ms", self.jitter_ms.is_some()),
            ("drop_rate", self.drop_rate.is_some()),
            ("duration_s", self.duration_s.is_some()),
            ("jump_ms", self.jump_ms.is_some()),
            ("noise", self.noise.is_some()),
            ("faults", self.faults.is_some()),
        ];
        for (name, on) in set {
            if on {
                f.push(name);
            }
        }
        f
    }
}

/// An event that cannot happen as written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("events[{index}] (at_s {at_s}, {target}): {problem}")]
pub struct EventError {
    /// Its place in `[[events]]`.
    pub index: usize,
    /// Its time (s).
    pub at_s: f64,
    /// Its target.
    pub target: String,
    /// What is wrong with it.
    pub problem: Box<EventProblem>,
}

/// What is wrong with an event.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EventProblem {
    /// Before the start or after the end of the run.
    #[error("at_s must be within the run, 0 to {0} s")]
    OutsideRun(f64),
    /// `restart` of an agent.
    #[error("restart applies to the target fuser")]
    RestartOfAgent,
    /// Another action than `restart` for the fuser.
    #[error("the fuser can only restart, not {0:?}")]
    FuserOnlyRestarts(Action),
    /// A field the action does not take.
    #[error("{field} does not apply to {action:?}")]
    Field {
        /// The field.
        field: &'static str,
        /// The action.
        action: Action,
    },
    /// A restart's negative or infinite duration.
    #[error("restart: duration_s must be 0 or more")]
    RestartDuration,
    /// A target that is no agent.
    #[error("no agent of that name (agents: {})", .0.join(", "))]
    NoAgent(Vec<String>),
    /// `leave` of an agent that has left.
    #[error("the agent has already left")]
    AlreadyLeft,
    /// `join` of an agent that is there.
    #[error("the agent is already there")]
    AlreadyThere,
    /// A value the action needs, missing or out of its domain.
    #[error("{0}")]
    Needs(&'static str),
    /// A link value out of its domain.
    #[error(transparent)]
    BadLink(InvalidValue),
    /// A noise or faults setting that cannot be read.
    #[error(transparent)]
    Spec(SpecError),
}

/// Checks every event against the scenario's agents and length; errors name the event.
pub fn check(events: &[EventSpec], agents: &[&str], duration_s: f64) -> Result<(), EventError> {
    // per agent, whether it is present, in time order
    let mut order: Vec<usize> = (0..events.len()).collect();
    order.sort_by(|&a, &b| events[a].at_s.total_cmp(&events[b].at_s).then(a.cmp(&b)));
    let mut present = vec![true; agents.len()];
    for index in order {
        let e = &events[index];
        check_event(e, agents, &mut present, duration_s).map_err(|problem| EventError {
            index,
            at_s: e.at_s,
            target: e.target.clone(),
            problem: Box::new(problem),
        })?;
    }
    Ok(())
}

/// Checks one event, in time order; `present` tells, per agent, whether it is there.
fn check_event(
    e: &EventSpec,
    agents: &[&str],
    present: &mut [bool],
    duration_s: f64,
) -> Result<(), EventProblem> {
    use EventProblem::*;
    if !(e.at_s.is_finite() && (0.0..=duration_s).contains(&e.at_s)) {
        return Err(OutsideRun(duration_s));
    }
    if e.target == FUSER || e.action == Action::Restart {
        return check_restart(e);
    }
    let Some(a) = agents.iter().position(|a| *a == e.target) else {
        return Err(NoAgent(agents.iter().map(|a| a.to_string()).collect()));
    };
    let allowed: &[&str] = match e.action {
        Action::Leave | Action::Join => &[],
        Action::Link => &["latency_ms", "jitter_ms", "drop_rate"],
        Action::LossBurst => &["duration_s"],
        Action::ClockJump => &["jump_ms"],
        Action::Noise => &["noise", "faults"],
        Action::Restart => &["duration_s"],
    };
    if let Some(field) = e.fields().into_iter().find(|f| !allowed.contains(f)) {
        let action = e.action;
        return Err(Field { field, action });
    }
    match e.action {
        Action::Leave if !present[a] => return Err(AlreadyLeft),
        Action::Join if present[a] => return Err(AlreadyThere),
        Action::Leave => present[a] = false,
        Action::Join => present[a] = true,
        Action::Link => {
            if e.fields().is_empty() {
                return Err(Needs("link needs latency_ms, jitter_ms or drop_rate"));
            }
            let link = Link {
                latency_ms: e.latency_ms.unwrap_or(0.0),
                jitter_ms: e.jitter_ms.unwrap_or(0.0),
                drop_rate: e.drop_rate.unwrap_or(0.0),
                clock_offset_ms: 0.0,
            };
            link.validate().map_err(BadLink)?;
        }
        Action::LossBurst => match e.duration_s {
            Some(d) if d.is_finite() && d > 0.0 => {}
            _ => return Err(Needs("loss_burst needs duration_s > 0")),
        },
        Action::Restart => {}
        Action::ClockJump => match e.jump_ms {
            Some(j) if j.is_finite() => {}
            _ => return Err(Needs("clock_jump needs a finite jump_ms")),
        },
        Action::Noise => {
            let Some(n) = &e.noise else {
                return Err(Needs("noise needs noise (e.g. \"large\")"));
            };
            n.parse::<AgentNoise>().map_err(Spec)?;
            if let Some(f) = &e.faults {
                f.parse::<Faults>().map_err(Spec)?;
            }
        }
    }
    Ok(())
}

/// Checks an event of the fuser or a restart: only the fuser restarts, for `duration_s` >= 0.
fn check_restart(e: &EventSpec) -> Result<(), EventProblem> {
    if e.target != FUSER {
        return Err(EventProblem::RestartOfAgent);
    }
    if e.action != Action::Restart {
        return Err(EventProblem::FuserOnlyRestarts(e.action));
    }
    if let Some(field) = e.fields().into_iter().find(|f| *f != "duration_s") {
        let action = e.action;
        return Err(EventProblem::Field { field, action });
    }
    if e.duration_s.is_some_and(|d| !(d.is_finite() && d >= 0.0)) {
        return Err(EventProblem::RestartDuration);
    }
    Ok(())
}

/// The fuser's restarts: (when, how long down), in microseconds from the run's start, in order.
pub fn fuser_restarts(events: &[EventSpec]) -> Vec<(u64, u64)> {
    let mut r: Vec<(u64, u64)> = events
        .iter()
        .filter(|e| e.target == FUSER && e.action == Action::Restart)
        .map(|e| {
            (
                (e.at_s * 1e6).round() as u64,
                (e.duration_s.unwrap_or(0.0) * 1e6).round() as u64,
            )
        })
        .collect();
    r.sort();
    r
}

/// An agent's state at one time of the run.
#[derive(Clone, Debug, PartialEq)]
pub struct AgentState {
    /// Whether it sends (and holds its liveliness token).
    pub present: bool,
    /// Its link and clock, a loss burst included.
    pub link: Link,
    /// Its noise and faults.
    pub noise: AgentNoise,
}

/// One agent's events in time order, replayed as the run advances.
#[derive(Clone, Debug)]
pub struct AgentTimeline {
    events: Vec<(u64, EventSpec)>,
    next: usize,
    present: bool,
    link: Link,
    noise: AgentNoise,
    burst_until_us: Option<u64>,
}

impl AgentTimeline {
    /// The events of agent `name` (checked with [`check`]), at microseconds from the run's
    /// start, beginning with its link and noise.
    pub fn new(name: &str, link: Link, noise: AgentNoise, events: &[EventSpec]) -> Self {
        let mut mine: Vec<(u64, EventSpec)> = events
            .iter()
            .filter(|e| e.target == name)
            .map(|e| ((e.at_s * 1e6).round() as u64, e.clone()))
            .collect();
        mine.sort_by_key(|(t, _)| *t);
        AgentTimeline {
            events: mine,
            next: 0,
            present: true,
            link,
            noise,
            burst_until_us: None,
        }
    }

    /// The state at `t_us` from the run's start, applying every event due by then (times must
    /// not go back).
    pub fn at(&mut self, t_us: u64) -> AgentState {
        while let Some((at, e)) = self.events.get(self.next) {
            if *at > t_us {
                break;
            }
            let at = *at;
            match e.action {
                Action::Leave => self.present = false,
                Action::Join => self.present = true,
                Action::Link => {
                    self.link.latency_ms = e.latency_ms.unwrap_or(self.link.latency_ms);
                    self.link.jitter_ms = e.jitter_ms.unwrap_or(self.link.jitter_ms);
                    self.link.drop_rate = e.drop_rate.unwrap_or(self.link.drop_rate);
                }
                Action::LossBurst => {
                    let end = at + (e.duration_s.unwrap_or(0.0) * 1e6).round() as u64;
                    self.burst_until_us = Some(self.burst_until_us.map_or(end, |u| u.max(end)));
                }
                Action::ClockJump => self.link.clock_offset_ms += e.jump_ms.unwrap_or(0.0),
                Action::Noise => {
                    let mut n: AgentNoise = e
                        .noise
                        .as_deref()
                        .unwrap_or_default()
                        .parse()
                        .expect("checked when the scenario loaded");
                    if let Some(f) = &e.faults {
                        n.faults = f.parse().expect("checked when the scenario loaded");
                    }
                    self.noise = n;
                }
                Action::Restart => {}
            }
            self.next += 1;
        }
        let mut link = self.link.clone();
        if self.burst_until_us.is_some_and(|u| t_us < u) {
            link.drop_rate = 1.0;
        }
        AgentState {
            present: self.present,
            link,
            noise: self.noise.clone(),
        }
    }
}

#[cfg(test)]
mod tests;
