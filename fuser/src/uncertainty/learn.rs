//! Each agent's error model learned from its own boxes as they flow, without ground truth
//! (`docs/method.md` §10), and the consistency monitor that flags an agent whose stated stds
//! are wrong.
//!
//! An agent's detection errors are independent from frame to frame; the objects it sees move
//! smoothly. So each agent's boxes are followed over time by a tracker of their own, and every
//! box that lies between two others of its track is compared with the straight line through
//! them. At capture times t0 < t1 < t2, with a = (t2 - t1) / (t2 - t0) and b = (t1 - t0) / (t2 - t0):
//!
//! ```text
//! (1)  u = x1 - (a x0 + b x2),          Var u = s1^2 + a^2 s0^2 + b^2 s2^2
//! (2)  e = u / sqrt(1 + a^2 + b^2)      has the std s of an agent whose boxes share it
//! (3)  w = u / sqrt(Var u)              with the stated s_i: std 1 when they are honest
//! (4)  s_hat = 1.4826 median |e|,  rho = 1.4826 median |w|   over the last N residuals
//! ```
//!
//! (the motion between the frames adds about accel dt^2: centimetres at 10 Hz). Medians make
//! the estimates indifferent to the few residuals of a track that swapped objects. Each field
//! group (centre x-y, centre z, size, yaw, velocity) is estimated per agent and class, and over
//! all the agent's classes for classes with too few residuals. `rho` is the consistency
//! monitor's figure: how many times too small (> 1) or too large (< 1) the stated stds are;
//! `rho^2` is the median normalised innovation squared over its chi-square median. The stds
//! the agent's boxes are fused with are the stated ones times `rho`; until a group has
//! `min_samples` residuals, the stated ones but at least the prior's (a cautious start: an
//! overconfident agent must not split groups while it is learned). Sans-IO: boxes and their
//! capture times in, corrected boxes and reports out.

use crate::tracker::{Tracker, TrackerParams};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap, VecDeque};
use v2x_protocol::limits::clamp_std;
use v2x_protocol::{wrap_angle, Class, Detection, NoiseProfile, Uncertainty, NO_ID};

/// The field groups estimated, in order.
pub const GROUPS: [&str; 5] = ["pos_xy", "pos_z", "size", "yaw", "velocity"];

/// A scale-free factor 1.4826 = 1 / Phi^-1(3/4): median |x| times it is the std of a normal x.
const MAD_TO_STD: f64 = 1.482_602_218_505_602;

/// An agent that sent nothing for this long (us) is forgotten, as the node forgets it.
pub const FORGET_AFTER_US: u64 = 60_000_000;

/// How the learner works.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct LearnParams {
    /// Residuals kept per agent, class and group: the estimate follows the last this many (at
    /// 10 Hz and 40 cars in view, 600 is about 1.5 s of an agent's cars).
    pub window: usize,
    /// Residuals a group needs before its estimate replaces the prior.
    pub min_samples: usize,
    /// The stds an agent's boxes get at least until learned.
    pub prior: Uncertainty,
    /// The velocity std (m/s) a box gets at least until learned.
    pub prior_velocity: f64,
    /// Longest span t2 - t0 (s) of three boxes compared.
    pub max_span_s: f64,
    /// An agent is flagged when its centre's rho is beyond this factor, either way.
    pub flag_ratio: f64,
    /// The per-agent tracker that follows each agent's boxes.
    pub tracker: TrackerParams,
}

impl Default for LearnParams {
    fn default() -> Self {
        LearnParams {
            window: 600,
            min_samples: 60,
            prior: NoiseProfile::Large.std(),
            prior_velocity: NoiseProfile::Large.velocity_std(),
            max_span_s: 1.0,
            flag_ratio: 2.0,
            tracker: {
                let mut p = TrackerParams::default();
                p.management.all_classes = true;
                p
            },
        }
    }
}

/// The last residuals of one group: the scaled one e, the normalised one w, the stated std.
#[derive(Clone, Debug, Default)]
struct Ring {
    e: VecDeque<f64>,
    w: VecDeque<f64>,
    stated: VecDeque<f64>,
}

impl Ring {
    fn push(&mut self, cap: usize, e: f64, w: f64, stated: f64) {
        if !(e.is_finite() && w.is_finite() && stated.is_finite()) {
            return;
        }
        if self.e.len() == cap {
            self.e.pop_front();
            self.w.pop_front();
            self.stated.pop_front();
        }
        self.e.push_back(e.abs());
        self.w.push_back(w.abs());
        self.stated.push_back(stated);
    }

    fn report(&self) -> Option<GroupReport> {
        (!self.e.is_empty()).then(|| GroupReport {
            samples: self.e.len(),
            stated: median(&self.stated),
            estimated: MAD_TO_STD * median(&self.e),
            ratio: MAD_TO_STD * median(&self.w),
        })
    }
}

/// The median of some non-negative numbers (0 for none).
fn median(v: &VecDeque<f64>) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().collect();
    if s.is_empty() {
        return 0.0;
    }
    let k = s.len() / 2;
    let (_, m, _) = s.select_nth_unstable_by(k, f64::total_cmp);
    let m = *m;
    if s.len() % 2 == 1 {
        m
    } else {
        let below = s[..k].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (m + below)
    }
}

/// One group's estimate.
#[derive(Copy, Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GroupReport {
    /// Residuals it rests on.
    pub samples: usize,
    /// The median std the agent stated.
    pub stated: f64,
    /// The std estimated from the residuals, s_hat of (4).
    pub estimated: f64,
    /// rho of (4): the factor the stated stds are off by (1 honest, > 1 overconfident).
    pub ratio: f64,
}

/// The estimates of one class (or of all an agent's classes), by group; `None` before any
/// residual.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct ClassReport {
    /// Centre x and y.
    pub pos_xy: Option<GroupReport>,
    /// Centre z.
    pub pos_z: Option<GroupReport>,
    /// Length, width and height.
    pub size: Option<GroupReport>,
    /// Yaw.
    pub yaw: Option<GroupReport>,
    /// Velocity x and y.
    pub velocity: Option<GroupReport>,
}

impl ClassReport {
    fn of(rings: &[Ring; 5]) -> Self {
        let [a, b, c, d, e] = rings.each_ref().map(Ring::report);
        ClassReport {
            pos_xy: a,
            pos_z: b,
            size: c,
            yaw: d,
            velocity: e,
        }
    }
}

/// What is learned of one agent.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AgentReport {
    /// Whether its stated centre stds are off by more than `flag_ratio` either way.
    pub flagged: bool,
    /// rho of its centre (x-y) over all classes, once learned.
    pub ratio_xy: Option<f64>,
    /// Over all its classes.
    pub all: ClassReport,
    /// Per class (nuScenes name).
    pub classes: BTreeMap<String, ClassReport>,
}

/// A box seen before, as stated.
#[derive(Clone, Debug)]
struct Seen {
    t_us: u64,
    det: Detection,
}

/// One agent's learning state.
#[derive(Clone, Debug)]
struct AgentState {
    /// Its latest capture time.
    last_us: u64,
    tracker: Tracker,
    /// The last two boxes of each of the agent's own tracks, older first.
    last: HashMap<u32, (Option<Seen>, Seen)>,
    classes: BTreeMap<Class, [Ring; 5]>,
    all: [Ring; 5],
    /// rho per group once learned, per class and over all classes.
    ratio: BTreeMap<Class, [Option<f64>; 5]>,
    ratio_all: [Option<f64>; 5],
}

/// Every agent's learned error model; call [`Learner::observe`] with each agent's frame in
/// capture order, and [`Learner::correct`] on the boxes to fuse.
#[derive(Clone, Debug)]
pub struct Learner {
    params: LearnParams,
    agents: BTreeMap<String, AgentState>,
}

impl Learner {
    /// A learner that knows nothing yet.
    pub fn new(params: LearnParams) -> Self {
        Learner {
            params,
            agents: BTreeMap::new(),
        }
    }

    /// Learns from one frame of `agent` captured at `t_us`, its boxes as the agent stated them.
    pub fn observe(&mut self, agent: &str, t_us: u64, stated: &[Detection]) {
        let p = self.params;
        if !self.agents.contains_key(agent) {
            self.agents.insert(
                agent.to_owned(),
                AgentState {
                    last_us: t_us,
                    tracker: Tracker::new(p.tracker),
                    last: HashMap::new(),
                    classes: BTreeMap::new(),
                    all: Default::default(),
                    ratio: BTreeMap::new(),
                    ratio_all: [None; 5],
                },
            );
        }
        let corrected: Vec<Detection> = stated
            .iter()
            .map(|d| self.corrected(agent, d.clone()))
            .collect();
        let a = self.agents.get_mut(agent).expect("inserted above");
        a.last_us = t_us;
        let (_, ids) = a.tracker.step_ids(t_us, &corrected);
        let max_span_us = (p.max_span_s * 1e6) as u64;
        for (d, id) in stated.iter().zip(ids) {
            if id == NO_ID {
                continue;
            }
            let now = Seen {
                t_us,
                det: d.clone(),
            };
            let (older, newer) = match a.last.remove(&id) {
                Some((older, newer)) => (older, Some(newer)),
                None => (None, None),
            };
            if let (Some(s0), Some(s1)) = (&older, &newer) {
                if s0.t_us < s1.t_us && s1.t_us < t_us && t_us - s0.t_us <= max_span_us {
                    let r = residuals(s0, s1, &now);
                    let rings = a.classes.entry(s1.det.class).or_default();
                    for (g, samples) in r.iter().enumerate() {
                        for &(e, w, s) in samples {
                            rings[g].push(p.window, e, w, s);
                            a.all[g].push(p.window, e, w, s);
                        }
                    }
                }
            }
            a.last.insert(id, (newer, now));
        }
        a.last
            .retain(|_, (_, s)| t_us.saturating_sub(s.t_us) <= max_span_us);
        let learned = |rings: &[Ring; 5]| {
            rings
                .each_ref()
                .map(|r| (r.w.len() >= p.min_samples).then(|| MAD_TO_STD * median(&r.w)))
        };
        a.ratio = a.classes.iter().map(|(c, r)| (*c, learned(r))).collect();
        a.ratio_all = learned(&a.all);
    }

    /// Learns from each frame of a closed window, then gives its boxes the learned stds;
    /// agents silent for [`FORGET_AFTER_US`] before it are forgotten.
    pub fn learn_window(&mut self, closed: &mut crate::time::window::Closed) {
        let mut latest = 0;
        for (agent, f) in &mut closed.frames {
            self.observe(agent, f.capture_us, &f.detections);
            self.correct(agent, &mut f.detections);
            latest = latest.max(f.capture_us);
        }
        self.agents
            .retain(|_, a| latest.saturating_sub(a.last_us) <= FORGET_AFTER_US);
    }

    /// The boxes of `agent` with the stds it is learned to have.
    pub fn correct(&self, agent: &str, dets: &mut [Detection]) {
        for d in dets {
            *d = self.corrected(agent, d.clone());
        }
    }

    /// One box with its stds corrected: the stated ones times rho of its class (of all the
    /// agent's classes when its class has too few residuals), at least the prior's until learned.
    fn corrected(&self, agent: &str, mut d: Detection) -> Detection {
        let state = self.agents.get(agent);
        let ratio = |g: usize| -> Option<f64> {
            let s = state?;
            s.ratio.get(&d.class).and_then(|r| r[g]).or(s.ratio_all[g])
        };
        let p = &self.params;
        let stated = d.std;
        let factor = |g: usize, stated: f64, prior: f64| match ratio(g) {
            Some(rho) => rho.max(1e-3),
            None => (prior / stated).max(1.0),
        };
        let cov = d.position_covariance();
        let f: [f64; 3] = std::array::from_fn(|k| factor(k / 2, cov[k][k].sqrt(), p.prior.pos[k]));
        for k in 0..3 {
            d.std.pos[k] = clamp_std(stated.pos[k] * f[k]);
            d.std.size[k] = clamp_std(stated.size[k] * factor(2, stated.size[k], p.prior.size[k]));
        }
        d.std.yaw = clamp_std(stated.yaw * factor(3, stated.yaw, p.prior.yaw));
        if let Some(c) = d.pos_cov.as_deref_mut() {
            for (i, row) in c.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v *= f[i] * f[j];
                }
            }
        }
        if let Some(v) = &mut d.velocity {
            for s in &mut v.std {
                *s = clamp_std(*s * factor(4, *s, p.prior_velocity));
            }
        }
        d
    }

    /// What is learned of each agent so far.
    pub fn report(&self) -> BTreeMap<String, AgentReport> {
        self.agents
            .iter()
            .map(|(name, a)| {
                let ratio_xy = a.ratio_all[0];
                let f = self.params.flag_ratio;
                let report = AgentReport {
                    flagged: ratio_xy.is_some_and(|r| r > f || r < 1.0 / f),
                    ratio_xy,
                    all: ClassReport::of(&a.all),
                    classes: a
                        .classes
                        .iter()
                        .map(|(c, r)| (c.name().to_owned(), ClassReport::of(r)))
                        .collect(),
                };
                (name.clone(), report)
            })
            .collect()
    }

    /// Forgets an agent (it left).
    pub fn forget(&mut self, agent: &str) {
        self.agents.remove(agent);
    }
}

/// The residuals (e, w, stated std) of (1)-(3) of the middle box of three, per group.
fn residuals(s0: &Seen, s1: &Seen, s2: &Seen) -> [Vec<(f64, f64, f64)>; 5] {
    let span = (s2.t_us - s0.t_us) as f64;
    let a = (s2.t_us - s1.t_us) as f64 / span;
    let b = (s1.t_us - s0.t_us) as f64 / span;
    let n = (1.0 + a * a + b * b).sqrt();
    let (d0, d1, d2) = (&s0.det, &s1.det, &s2.det);
    let one = |u: f64, s: [f64; 3]| {
        let var = s[1] * s[1] + a * a * s[0] * s[0] + b * b * s[2] * s[2];
        (u / n, u / var.sqrt(), s[1])
    };
    let line = |x: [f64; 3]| x[1] - (a * x[0] + b * x[2]);
    let pos = |k: usize| {
        let sd = |d: &Detection| d.position_covariance()[k][k].sqrt();
        one(
            line([d0.center[k], d1.center[k], d2.center[k]]),
            [sd(d0), sd(d1), sd(d2)],
        )
    };
    let size = |k: usize| {
        one(
            line([d0.size[k], d1.size[k], d2.size[k]]),
            [d0.std.size[k], d1.std.size[k], d2.std.size[k]],
        )
    };
    // The yaw against the middle box's: each end turned by the class's period to lie nearest.
    let period = d1.class.yaw_period();
    let near = |y: f64| {
        let k = 2.0 * std::f64::consts::PI / period;
        wrap_angle(k * (y - d1.yaw)) / k
    };
    let yaw = one(
        -(a * near(d0.yaw) + b * near(d2.yaw)),
        [d0.std.yaw, d1.std.yaw, d2.std.yaw],
    );
    let velocity = match (&d0.velocity, &d1.velocity, &d2.velocity) {
        (Some(v0), Some(v1), Some(v2)) => (0..2)
            .map(|k| {
                one(
                    line([v0.v[k], v1.v[k], v2.v[k]]),
                    [v0.std[k], v1.std[k], v2.std[k]],
                )
            })
            .collect(),
        _ => Vec::new(),
    };
    [
        vec![pos(0), pos(1)],
        vec![pos(2)],
        (0..3).map(size).collect(),
        vec![yaw],
        velocity,
    ]
}

#[cfg(test)]
mod tests;
