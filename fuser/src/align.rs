//! Box-level registration (`docs/method.md` §3.1): an agent whose own pose is wrong reports every
//! box shifted and turned together. Before association, each agent's rigid offset to a reference
//! agent is estimated from the boxes both see, and undone:
//!
//! 1. candidate matches: same class, both scores >= `min_score`, centres within `gate_m`;
//! 2. a robust first guess of the shift: the per-axis median of every box's offset to its
//!    nearest candidate;
//! 3. after that shift, mutual nearest neighbours within `inlier_m` are the matches;
//! 4. the weighted 2D Procrustes (Kabsch) solution over them, weights 1 / (s_a^2 + s_b^2):
//!    theta = atan2(sum w (a x b), sum w (a . b)) over centred points, t = b_mean - R a_mean;
//! 5. once more, an iterative-closest-point step: the matches are taken again under that
//!    solution (so far boxes a rotation had pushed out come back), those beyond 3 combined
//!    stds are left out, and step 4 solves again.
//!
//! With fewer than `min_matches` matches the agent is left as it is. [`Aligner`] solves each
//! agent's matches of its last few windows together. Sans-IO: lists in, lists out.

use std::collections::{HashMap, VecDeque};
use v2x_protocol::{wrap_angle, AgentKind, Detection};

/// Parameters of the registration.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct AlignParams {
    /// Largest centre distance (m) of a candidate match before any correction.
    pub gate_m: f64,
    /// Largest centre distance (m) of a match after the first shift.
    pub inlier_m: f64,
    /// Fewest matches to estimate an offset from.
    pub min_matches: usize,
    /// Lowest score of a box used as a match.
    pub min_score: f64,
}

impl Default for AlignParams {
    fn default() -> Self {
        AlignParams {
            gate_m: 4.0,
            inlier_m: 1.5,
            min_matches: 3,
            min_score: 0.3,
        }
    }
}

/// How many windows an [`Aligner`] pools by default: 1 s at 10 Hz.
pub const ALIGN_WINDOWS: usize = 10;

/// A rigid 2D motion: p' = R(theta) (p - from) + to.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Rigid {
    /// Pivot in the agent's (wrong) frame.
    pub from: [f64; 2],
    /// Where the pivot goes.
    pub to: [f64; 2],
    /// Rotation (rad).
    pub theta: f64,
    /// How many matches the estimate rests on.
    pub matches: usize,
}

impl Rigid {
    /// Where a point goes.
    pub fn apply_point(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.theta.sin_cos();
        let (x, y) = (p[0] - self.from[0], p[1] - self.from[1]);
        [self.to[0] + c * x - s * y, self.to[1] + s * x + c * y]
    }

    /// The shift it gives a point at `p` (m): how far the agent's boxes there were off.
    pub fn shift_at(&self, p: [f64; 2]) -> [f64; 2] {
        let q = self.apply_point(p);
        [q[0] - p[0], q[1] - p[1]]
    }

    /// Moves a box: centre, heading, velocity and centre covariance.
    pub fn apply(&self, d: &mut Detection) {
        let [x, y] = self.apply_point([d.center[0], d.center[1]]);
        d.center[0] = x;
        d.center[1] = y;
        d.yaw = wrap_angle(d.yaw + self.theta);
        let (s, c) = self.theta.sin_cos();
        if let Some(v) = &mut d.velocity {
            v.v = [c * v.v[0] - s * v.v[1], s * v.v[0] + c * v.v[1]];
        }
        if let Some(p) = &mut d.pos_cov {
            // R P R^T on the horizontal block and the cross terms with z
            let r = [[c, -s], [s, c]];
            let old = **p;
            for i in 0..2 {
                for j in 0..2 {
                    p[i][j] = (0..2)
                        .flat_map(|k| (0..2).map(move |l| (k, l)))
                        .map(|(k, l)| r[i][k] * old[k][l] * r[j][l])
                        .sum();
                }
                p[i][2] = r[i][0] * old[0][2] + r[i][1] * old[1][2];
                p[2][i] = p[i][2];
            }
        }
    }
}

/// The reference agent: the first infrastructure agent (surveyed, so its pose is the best
/// known), else the first agent.
pub fn reference_agent(kinds: &[AgentKind]) -> usize {
    kinds
        .iter()
        .position(|k| *k == AgentKind::Infrastructure)
        .unwrap_or(0)
}

fn variance(d: &Detection) -> f64 {
    d.std.pos[0] * d.std.pos[0] + d.std.pos[1] * d.std.pos[1]
}

fn dist2(a: &Detection, b: &Detection, shift: [f64; 2]) -> f64 {
    (a.center[0] + shift[0] - b.center[0]).powi(2) + (a.center[1] + shift[1] - b.center[1]).powi(2)
}

/// The nearest same-class box of `to` within `gate` of `d` shifted by `shift`.
fn nearest(d: &Detection, to: &[&Detection], shift: [f64; 2], gate: f64) -> Option<usize> {
    to.iter()
        .enumerate()
        .filter(|(_, b)| b.class == d.class)
        .map(|(j, b)| (j, dist2(d, b, shift)))
        .filter(|(_, d2)| *d2 <= gate * gate)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(j, _)| j)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Weighted 2D Procrustes of pairs (a, b, w): the rigid motion taking the a's onto the b's.
fn procrustes(pairs: &[Pair]) -> Rigid {
    let w: f64 = pairs.iter().map(|p| p.2).sum();
    let mean = |f: &dyn Fn(&Pair) -> [f64; 2]| -> [f64; 2] {
        let mut m = [0.0; 2];
        for p in pairs {
            let v = f(p);
            m[0] += p.2 * v[0] / w;
            m[1] += p.2 * v[1] / w;
        }
        m
    };
    let (ma, mb) = (mean(&|p| p.0), mean(&|p| p.1));
    let (mut dot, mut cross) = (0.0, 0.0);
    for (a, b, w) in pairs {
        let (ax, ay) = (a[0] - ma[0], a[1] - ma[1]);
        let (bx, by) = (b[0] - mb[0], b[1] - mb[1]);
        dot += w * (ax * bx + ay * by);
        cross += w * (ax * by - ay * bx);
    }
    Rigid {
        from: ma,
        to: mb,
        theta: cross.atan2(dot),
        matches: pairs.len(),
    }
}

/// A match: the point in the agent's frame, the reference's point, the weight.
type Pair = ([f64; 2], [f64; 2], f64);

/// Estimates the rigid motion taking `agent`'s boxes onto `reference`'s, or `None` with too few
/// matches.
pub fn estimate(agent: &[Detection], reference: &[&Detection], p: &AlignParams) -> Option<Rigid> {
    solve(&window_matches(agent, reference, None, p), p)
}

/// One window's matches (steps 1-5), starting from `guess` when there is one (the last
/// estimate) and from the median shift otherwise; empty when too few.
fn window_matches(
    agent: &[Detection],
    reference: &[&Detection],
    guess: Option<&Rigid>,
    p: &AlignParams,
) -> Vec<Pair> {
    let mine: Vec<&Detection> = agent.iter().filter(|d| d.score >= p.min_score).collect();
    let theirs: Vec<&Detection> = reference
        .iter()
        .copied()
        .filter(|d| d.score >= p.min_score)
        .collect();
    let guess = match guess {
        Some(g) => *g,
        None => {
            // 2. the first guess of the shift
            let offsets: Vec<[f64; 2]> = mine
                .iter()
                .filter_map(|d| {
                    let b = theirs[nearest(d, &theirs, [0.0; 2], p.gate_m)?];
                    Some([b.center[0] - d.center[0], b.center[1] - d.center[1]])
                })
                .collect();
            if offsets.len() < p.min_matches {
                return Vec::new();
            }
            Rigid {
                from: [0.0; 2],
                to: [
                    median(offsets.iter().map(|o| o[0]).collect()),
                    median(offsets.iter().map(|o| o[1]).collect()),
                ],
                theta: 0.0,
                matches: offsets.len(),
            }
        }
    };
    // 3 and 4: match under the guess, solve; 5: match under that solution, keep residuals
    // within 3 combined stds.
    match solve(
        &matches(&mine, &theirs, &guess, p.inlier_m, f64::INFINITY),
        p,
    ) {
        Some(first) => matches(&mine, &theirs, &first, p.inlier_m, 3.0),
        None => Vec::new(),
    }
}

/// Registration smoothed over windows: each agent's matches of its last `windows` windows are
/// solved together (a pose error changes slowly, so matches from nearby windows constrain the
/// same motion), which keeps the estimate steady when agents share few boxes per window.
#[derive(Clone, Debug)]
pub struct Aligner {
    params: AlignParams,
    windows: usize,
    pooled: HashMap<String, VecDeque<Vec<Pair>>>,
    last: HashMap<String, Rigid>,
}

impl Aligner {
    /// An aligner pooling `windows` windows (at least 1; 1 is per-window registration).
    pub fn new(params: AlignParams, windows: usize) -> Self {
        Aligner {
            params,
            windows: windows.max(1),
            pooled: HashMap::new(),
            last: HashMap::new(),
        }
    }

    /// Aligns one window: every agent (named, for its history) to agent `reference`, in agent
    /// order, each against the reference and the agents already aligned. Returns the aligned
    /// lists and each agent's motion (`None` for the reference and for agents without enough
    /// matches, which stay as they were).
    pub fn align(
        &mut self,
        names: &[&str],
        agents: &[Vec<Detection>],
        reference: usize,
    ) -> (Vec<Vec<Detection>>, Vec<Option<Rigid>>) {
        let mut out: Vec<Vec<Detection>> = agents.to_vec();
        let mut rigid = vec![None; agents.len()];
        if reference >= agents.len() || names.len() != agents.len() {
            return (out, rigid);
        }
        // Agents absent from this window age their history too, and are forgotten once empty.
        let absent: Vec<String> = self
            .pooled
            .keys()
            .filter(|k| !names.contains(&k.as_str()))
            .cloned()
            .collect();
        for k in absent {
            let h = self.pooled.get_mut(&k).expect("listed");
            h.push_back(Vec::new());
            while h.len() > self.windows {
                h.pop_front();
            }
            if h.iter().all(Vec::is_empty) {
                self.pooled.remove(&k);
                self.last.remove(&k);
            }
        }
        let mut done = vec![reference];
        for k in (0..agents.len()).filter(|k| *k != reference) {
            let anchor: Vec<&Detection> = done.iter().flat_map(|&a| &out[a]).collect();
            let name = names[k];
            let pairs = window_matches(&agents[k], &anchor, self.last.get(name), &self.params);
            let history = self.pooled.entry(name.to_string()).or_default();
            history.push_back(pairs);
            while history.len() > self.windows {
                history.pop_front();
            }
            let all: Vec<Pair> = history.iter().flatten().copied().collect();
            match solve(&all, &self.params) {
                Some(r) => {
                    for d in &mut out[k] {
                        r.apply(d);
                    }
                    self.last.insert(name.to_string(), r);
                    rigid[k] = Some(r);
                }
                None => {
                    self.last.remove(name);
                }
            }
            done.push(k);
        }
        (out, rigid)
    }
}

/// Mutual nearest same-class neighbours once `agent`'s boxes are moved by `by`, within `gate_m`
/// and within `sigmas` combined stds: (moved-from point, reference point, weight).
fn matches(
    mine: &[&Detection],
    theirs: &[&Detection],
    by: &Rigid,
    gate_m: f64,
    sigmas: f64,
) -> Vec<Pair> {
    let moved: Vec<Detection> = mine
        .iter()
        .map(|d| {
            let mut m = (*d).clone();
            by.apply(&mut m);
            m
        })
        .collect();
    let moved_refs: Vec<&Detection> = moved.iter().collect();
    let mut out = Vec::new();
    for (i, d) in moved.iter().enumerate() {
        let Some(j) = nearest(d, theirs, [0.0; 2], gate_m) else {
            continue;
        };
        if nearest(theirs[j], &moved_refs, [0.0; 2], gate_m) != Some(i) {
            continue;
        }
        let var = variance(d) + variance(theirs[j]);
        if dist2(d, theirs[j], [0.0; 2]) > sigmas * sigmas * var {
            continue;
        }
        out.push((
            [mine[i].center[0], mine[i].center[1]],
            [theirs[j].center[0], theirs[j].center[1]],
            1.0 / var,
        ));
    }
    out
}

/// The Procrustes solution over `pairs`, or `None` with fewer than `min_matches`.
fn solve(pairs: &[Pair], p: &AlignParams) -> Option<Rigid> {
    (pairs.len() >= p.min_matches).then(|| procrustes(pairs))
}

/// Per-window registration ([`Aligner`] without history): every agent aligned to agent
/// `reference`.
pub fn align(
    agents: &[Vec<Detection>],
    reference: usize,
    p: &AlignParams,
) -> (Vec<Vec<Detection>>, Vec<Option<Rigid>>) {
    let names: Vec<String> = (0..agents.len()).map(|a| a.to_string()).collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    Aligner::new(*p, 1).align(&names, agents, reference)
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::{Class, Uncertainty, NO_ID};

    fn det(x: f64, y: f64, class: Class) -> Detection {
        Detection {
            class,
            center: [x, y, 0.0],
            size: class.typical_size(),
            yaw: 0.5,
            score: 0.8,
            std: Uncertainty::uniform(0.2, 0.1, 0.1),
            pos_cov: None,
            velocity: None,
            id: NO_ID,
        }
    }

    /// A known motion: turned 1 degree about (10, 5), then shifted (0.8, -0.5).
    fn known() -> Rigid {
        Rigid {
            from: [10.0, 5.0],
            to: [10.8, 4.5],
            theta: 1f64.to_radians(),
            matches: 0,
        }
    }

    #[test]
    fn an_exact_motion_is_recovered_exactly() {
        let truth: Vec<Detection> = (0..12)
            .map(|i| {
                det(
                    7.0 * i as f64 - 30.0,
                    11.0 * (i % 4) as f64 - 15.0,
                    Class::Car,
                )
            })
            .collect();
        // the agent reports every box moved by the inverse of `known`
        let inv = Rigid {
            from: known().to,
            to: known().from,
            theta: -known().theta,
            matches: 0,
        };
        let mut moved = truth.clone();
        for d in &mut moved {
            inv.apply(d);
        }
        let refs: Vec<&Detection> = truth.iter().collect();
        let r = estimate(&moved, &refs, &AlignParams::default()).unwrap();
        assert_eq!(r.matches, 12);
        assert!((r.theta - known().theta).abs() < 1e-12, "{}", r.theta);
        for d in &moved {
            let q = r.apply_point([d.center[0], d.center[1]]);
            let back = known().apply_point([d.center[0], d.center[1]]);
            assert!((q[0] - back[0]).abs() < 1e-9 && (q[1] - back[1]).abs() < 1e-9);
        }
        let mut d = moved[0].clone();
        r.apply(&mut d);
        assert!((d.yaw - truth[0].yaw).abs() < 1e-12);
    }

    #[test]
    fn too_few_or_other_class_matches_leave_the_agent_alone() {
        let a = vec![det(0.0, 0.0, Class::Car), det(10.0, 0.0, Class::Car)];
        let b = [det(0.5, 0.0, Class::Car), det(10.5, 0.0, Class::Car)];
        let refs: Vec<&Detection> = b.iter().collect();
        assert_eq!(estimate(&a, &refs, &AlignParams::default()), None);
        let c = [
            det(0.5, 0.0, Class::Truck),
            det(10.5, 0.0, Class::Truck),
            det(20.5, 0.0, Class::Truck),
        ];
        let mut a3 = a.clone();
        a3.push(det(20.0, 0.0, Class::Car));
        let refs: Vec<&Detection> = c.iter().collect();
        assert_eq!(estimate(&a3, &refs, &AlignParams::default()), None);
        let (out, r) = align(&[a3.clone(), c.to_vec()], 1, &AlignParams::default());
        assert_eq!(out[0], a3);
        assert_eq!(r, vec![None, None]);
    }

    #[test]
    fn reference_is_the_roadside_unit() {
        use AgentKind::*;
        assert_eq!(reference_agent(&[Vehicle, Infrastructure, Vehicle]), 1);
        assert_eq!(reference_agent(&[Vehicle, Vehicle]), 0);
    }

    #[test]
    fn rotating_a_covariance_keeps_it_symmetric_and_turns_it() {
        let mut d = det(1.0, 0.0, Class::Car);
        d.pos_cov = Some(Box::new([
            [4.0, 0.0, 0.5],
            [0.0, 1.0, 0.0],
            [0.5, 0.0, 1.0],
        ]));
        let r = Rigid {
            from: [0.0; 2],
            to: [0.0; 2],
            theta: std::f64::consts::FRAC_PI_2,
            matches: 0,
        };
        r.apply(&mut d);
        let p = d.pos_cov.unwrap();
        assert!((p[0][0] - 1.0).abs() < 1e-12 && (p[1][1] - 4.0).abs() < 1e-12);
        assert!(p[0][1].abs() < 1e-12 && (p[1][2] - 0.5).abs() < 1e-12 && p[0][2].abs() < 1e-12);
        assert!((d.center[1] - 1.0).abs() < 1e-12);
    }
}
