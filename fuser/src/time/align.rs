//! Box-level registration (`docs/method.md` §3.1): an agent whose own pose is wrong reports every
//! box shifted and turned together. Before association, each agent's rigid offset to a reference
//! agent is estimated from the boxes both see, and undone only when the evidence says so.
//!
//! Per window (the measurement):
//! 1. candidate matches: same class, both scores >= `min_score`, centres within `gate_m`;
//! 2. a guess of the motion: the agent's filtered estimate when it has one, else the shift
//!    most candidate pairs agree on (a vote over their offsets, robust to the many pairs of
//!    different objects when few are shared);
//! 3. under the guess, mutual nearest neighbours within `inlier_m` are the matches;
//! 4. the weighted 2D Procrustes (Kabsch) solution over them about their weighted centroid m,
//!    w_i = 1 / s_i^2 with s_i^2 = s_a^2 + s_b^2 + d^2 (both boxes' x-y variances and the
//!    agents' disagreement d beyond them, `disagreement_m`):
//!    theta = atan2(sum w (a x b), sum w (a . b)) over centred points, t = b_mean - a_mean;
//! 5. an iterative-closest-point step: the matches are taken again under that solution, those
//!    beyond 3 s_i are left out, and step 4 solves again;
//! 6. its covariance, from the matches' geometry and their residuals r_i:
//!    Var t_x = Var t_y = k / sum w, Var theta = k / sum w |a_i - m|^2, with
//!    k = max(1, sum w r_i^2 / (2n - 3)) (residuals wider than the weights say widen it).
//!
//! With fewer than `min_matches` matches a window measures nothing.
//!
//! Per agent (the filter): the state x = (t_x, t_y, theta) about a pivot c, covariance P,
//! starts at the agent's first measurement. Over dt it drifts (P += diag(q_t, q_t, q_r) dt);
//! past [`GAP_GRACE_S`] without a measurement it also decays toward the prior (no correction,
//! P0 = diag(prior_shift^2, prior_shift^2, prior_turn^2)): x <- a x, P <- a^2 P + (1 - a^2) P0,
//! a = exp(-gap / tau), so an estimate fades across a gap without shared objects. A measurement
//! about pivot m first moves the state to that pivot (t <- t + (R(theta) - I)(m - c)), then the
//! Kalman update with H = I. Each part of the correction is applied only when it differs
//! significantly from none: the shift when t^T P_t^-1 t > `chi2` (2 degrees of freedom), the turn
//! when theta^2 / P_theta > `turn_chi2` (1 degree of freedom, stricter: a turn moves far boxes by
//! its lever arm). Sans-IO: lists in, lists out.

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use std::collections::HashMap;
use v2x_protocol::{wrap_angle, AgentKind, Detection, InvalidValue};

mod measure;
pub use measure::estimate;
use measure::{measure, window_matches, Measurement};

/// Parameters of the registration.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct AlignParams {
    /// Largest centre distance (m) of a candidate match before any correction.
    pub gate_m: f64,
    /// Largest centre distance (m) of a match after the guess.
    pub inlier_m: f64,
    /// Fewest matches a window measures an offset from.
    pub min_matches: usize,
    /// Lowest score of a box used as a match.
    pub min_score: f64,
    /// Std per axis (m) of how far two agents' boxes of one object disagree at least, beyond
    /// their stated stds (labels or detectors that place an object differently); wider scatter
    /// in a window's residuals widens its measurement further (step 6).
    pub disagreement_m: f64,
    /// Prior std (m) of an agent's shift, what the estimate decays to.
    pub prior_shift_m: f64,
    /// Prior std (rad) of an agent's turn.
    pub prior_turn_rad: f64,
    /// Time constant (s) of the decay toward the prior once no window has measured the agent
    /// for [`GAP_GRACE_S`].
    pub tau_s: f64,
    /// How long (s) the same objects keep two agents' boxes disagreeing the same way (an
    /// object's stay in the shared view): measurements closer together than this are not
    /// independent, and each counts for the share dt / `correlation_s` of a measurement.
    pub correlation_s: f64,
    /// How fast (m per square root of a second) an agent's shift may drift while measured.
    pub drift_m: f64,
    /// How fast (rad per square root of a second) an agent's turn may drift while measured.
    pub drift_rad: f64,
    /// The chi-square (2 degrees of freedom) an estimated shift must exceed to be applied: 5.99,
    /// the 95% quantile.
    pub chi2: f64,
    /// The chi-square (1 degree of freedom) an estimated turn must exceed to be applied: 10.83,
    /// the 99.9% quantile. A turn moves far boxes by its lever arm, and few shared objects close
    /// together (whose labels disagree the same way window after window) make a spurious one.
    pub turn_chi2: f64,
}

impl Default for AlignParams {
    fn default() -> Self {
        AlignParams {
            gate_m: 4.0,
            inlier_m: 1.5,
            min_matches: 3,
            min_score: 0.3,
            disagreement_m: 0.2,
            prior_shift_m: 2.0,
            prior_turn_rad: 3f64.to_radians(),
            tau_s: 10.0,
            correlation_s: 10.0,
            drift_m: 0.005,
            drift_rad: 0.0001,
            chi2: 5.99,
            turn_chi2: 10.83,
        }
    }
}

impl AlignParams {
    /// Checks that every parameter is in its domain; the error names the parameter.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        let positive = [
            ("gate_m", self.gate_m),
            ("inlier_m", self.inlier_m),
            ("prior_shift_m", self.prior_shift_m),
            ("prior_turn_rad", self.prior_turn_rad),
            ("tau_s", self.tau_s),
        ];
        for (name, v) in positive {
            if !(v > 0.0 && v.is_finite()) {
                return Err(InvalidValue::new(name, "a finite value > 0", v));
            }
        }
        for (name, v) in [
            ("min_score", self.min_score),
            ("disagreement_m", self.disagreement_m),
            ("correlation_s", self.correlation_s),
            ("drift_m", self.drift_m),
            ("drift_rad", self.drift_rad),
            ("chi2", self.chi2),
            ("turn_chi2", self.turn_chi2),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(InvalidValue::new(name, "a finite value >= 0", v));
            }
        }
        if self.min_matches < 2 {
            let expected = "at least 2 (a turn needs 2 matches)";
            return Err(InvalidValue::new("min_matches", expected, self.min_matches));
        }
        Ok(())
    }

    fn prior(&self) -> Matrix3<f64> {
        let (s, r) = (self.prior_shift_m.powi(2), self.prior_turn_rad.powi(2));
        Matrix3::from_diagonal(&Vector3::new(s, s, r))
    }
}

/// Seconds without a measurement after which an agent's estimate starts to decay: a few
/// windows without shared boxes are not a gap.
pub const GAP_GRACE_S: f64 = 0.5;

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

/// One agent's registration in a window: the filtered estimate, its uncertainty, what this
/// window measured and whether it was applied.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct Registration {
    /// The pivot (m, the agent's frame): the centroid of the latest matches.
    pub pivot: [f64; 2],
    /// The estimated shift of the pivot (m).
    pub shift_m: [f64; 2],
    /// The estimated turn about the pivot (rad).
    pub turn_rad: f64,
    /// Stds of the shift (m, x and y) and of the turn (rad).
    pub std: [f64; 3],
    /// Matches in this window (0: nothing measured, the estimate carried over).
    pub matches: usize,
    /// The shift's chi-square against no shift (2 degrees of freedom).
    pub chi2: f64,
    /// The turn's chi-square against no turn (1 degree of freedom).
    pub turn_chi2: f64,
    /// Whether the shift was applied (`chi2` above its threshold).
    pub applied: bool,
    /// Whether the turn was applied too (`turn_chi2` above its threshold).
    pub turn_applied: bool,
}

impl Registration {
    /// The correction applied to the agent's boxes: the shift and turn that passed their tests
    /// (none, the shift alone, or both).
    pub fn applied_motion(&self) -> Rigid {
        let shift = if self.applied { self.shift_m } else { [0.0; 2] };
        Rigid {
            from: self.pivot,
            to: [self.pivot[0] + shift[0], self.pivot[1] + shift[1]],
            theta: if self.turn_applied {
                self.turn_rad
            } else {
                0.0
            },
            matches: self.matches,
        }
    }

    /// The motion it stands for.
    pub fn motion(&self) -> Rigid {
        Rigid {
            from: self.pivot,
            to: [
                self.pivot[0] + self.shift_m[0],
                self.pivot[1] + self.shift_m[1],
            ],
            theta: self.turn_rad,
            matches: self.matches,
        }
    }
}

/// One agent's filter.
#[derive(Clone, Debug)]
struct Filter {
    /// (t_x, t_y, theta) about `pivot`.
    x: Vector3<f64>,
    p: Matrix3<f64>,
    pivot: [f64; 2],
    /// Time of the state (us).
    t_us: u64,
    /// Time of the last measurement (us).
    measured_us: u64,
}

impl Filter {
    fn motion(&self) -> Rigid {
        Rigid {
            from: self.pivot,
            to: [self.pivot[0] + self.x[0], self.pivot[1] + self.x[1]],
            theta: self.x[2],
            matches: 0,
        }
    }

    /// Predicts the state to `t_us`: it drifts, and beyond [`GAP_GRACE_S`] without a
    /// measurement it decays toward the prior.
    fn predict(&mut self, t_us: u64, p: &AlignParams) {
        if t_us <= self.t_us {
            return;
        }
        let dt = (t_us - self.t_us) as f64 / 1e6;
        let gap = |t: u64| (t.saturating_sub(self.measured_us) as f64 / 1e6 - GAP_GRACE_S).max(0.0);
        let a = (-(gap(t_us) - gap(self.t_us)) / p.tau_s).exp();
        self.x *= a;
        self.p = self.p * (a * a) + p.prior() * (1.0 - a * a);
        self.p += Matrix3::from_diagonal(&Vector3::new(
            p.drift_m.powi(2) * dt,
            p.drift_m.powi(2) * dt,
            p.drift_rad.powi(2) * dt,
        ));
        self.t_us = t_us;
    }

    /// Moves the state to pivot `m`: the same motion, written about another point.
    fn repivot(&mut self, m: [f64; 2]) {
        let (s, c) = self.x[2].sin_cos();
        let (dx, dy) = (m[0] - self.pivot[0], m[1] - self.pivot[1]);
        self.x[0] += (c - 1.0) * dx - s * dy;
        self.x[1] += s * dx + (c - 1.0) * dy;
        // d/dtheta of (R - I) d
        let j = Matrix3::new(
            1.0,
            0.0,
            -s * dx - c * dy,
            0.0,
            1.0,
            c * dx - s * dy,
            0.0,
            0.0,
            1.0,
        );
        self.p = j * self.p * j.transpose();
        self.pivot = m;
    }

    /// The Kalman update with a measurement of the whole state.
    fn update(&mut self, z: &Measurement) {
        self.repivot(z.motion.from);
        let zv = Vector3::new(
            z.motion.to[0] - z.motion.from[0],
            z.motion.to[1] - z.motion.from[1],
            z.motion.theta,
        );
        let Some(s_inv) = (self.p + z.cov).try_inverse() else {
            return;
        };
        let k = self.p * s_inv;
        let mut y = zv - self.x;
        y[2] = wrap_angle(y[2]);
        self.x += k * y;
        self.p = (Matrix3::identity() - k) * self.p;
        self.p = (self.p + self.p.transpose()) * 0.5;
    }

    /// The shift's chi-square against no shift, from its marginal covariance.
    fn shift_chi2(&self) -> f64 {
        let t = nalgebra::Vector2::new(self.x[0], self.x[1]);
        self.p
            .fixed_view::<2, 2>(0, 0)
            .into_owned()
            .try_inverse()
            .map_or(0.0, |pi| (t.transpose() * pi * t)[(0, 0)])
    }

    /// The turn's chi-square against no turn.
    fn turn_chi2(&self) -> f64 {
        let v = self.p[(2, 2)];
        if v > 0.0 {
            self.x[2] * self.x[2] / v
        } else {
            0.0
        }
    }
}

/// Registration filtered over windows, one filter per agent (named): see the module doc.
#[derive(Clone, Debug)]
pub struct Aligner {
    params: AlignParams,
    filters: HashMap<String, Filter>,
    /// The previous window's time.
    last_window_us: Option<u64>,
}

impl Aligner {
    /// An aligner with no history.
    pub fn new(params: AlignParams) -> Self {
        Aligner {
            params,
            filters: HashMap::new(),
            last_window_us: None,
        }
    }

    /// Aligns the window at `t_us` (`None`: a window with no time, registered on its own
    /// evidence alone): every agent (named, for its history) to agent `reference`, in agent
    /// order, each against the reference and the agents already aligned. Returns the lists,
    /// corrected where the correction was applied, and each agent's registration (`None` for
    /// the reference and for an agent that has never been measured).
    pub fn align(
        &mut self,
        t_us: Option<u64>,
        names: &[&str],
        agents: &[Vec<Detection>],
        reference: usize,
    ) -> (Vec<Vec<Detection>>, Vec<Option<Registration>>) {
        let mut out: Vec<Vec<Detection>> = agents.to_vec();
        let mut regs = vec![None; agents.len()];
        if reference >= agents.len() || names.len() != agents.len() {
            return (out, regs);
        }
        let p = self.params;
        match t_us {
            // a filter that has decayed to the prior holds nothing: forget it
            Some(t) => self.filters.retain(|_, f| {
                t < f.measured_us || (t - f.measured_us) as f64 / 1e6 <= 5.0 * p.tau_s
            }),
            None => self.filters.clear(),
        }
        let now = t_us.unwrap_or(0);
        // a window's share of an independent measurement: dt / correlation_s since the agent's
        // last measurement (else the last window; 10 Hz at the first); all of one without time
        let spacing_s = match (t_us, self.last_window_us) {
            (Some(t), Some(l)) if t > l => (t - l) as f64 / 1e6,
            _ => 0.1,
        };
        self.last_window_us = t_us;
        let share = |f: Option<&Filter>| -> f64 {
            if t_us.is_none() {
                return 1.0;
            }
            let dt = f.map_or(spacing_s, |f| {
                now.saturating_sub(f.measured_us) as f64 / 1e6
            });
            (dt / p.correlation_s).clamp(1e-6, 1.0)
        };
        let mut done = vec![reference];
        for k in (0..agents.len()).filter(|k| *k != reference) {
            let anchor: Vec<&Detection> = done.iter().flat_map(|&a| &out[a]).collect();
            let name = names[k];
            if let Some(f) = self.filters.get_mut(name) {
                f.predict(now, &p);
            }
            // the filter guides the matching while it still holds a recent measurement
            let guess = self
                .filters
                .get(name)
                .filter(|f| (now.saturating_sub(f.measured_us) as f64 / 1e6) < p.tau_s)
                .map(Filter::motion);
            let pairs = window_matches(&agents[k], &anchor, guess.as_ref(), &p);
            let z = measure(&pairs, &p).map(|mut z| {
                z.cov /= share(self.filters.get(name));
                z
            });
            if let Some(z) = &z {
                self.measured(name, z, now);
            }
            if let Some(f) = self.filters.get(name) {
                let reg = f.registration(z.map_or(0, |z| z.motion.matches), &p);
                if reg.applied || reg.turn_applied {
                    let r = reg.applied_motion();
                    for d in &mut out[k] {
                        r.apply(d);
                    }
                }
                regs[k] = Some(reg);
            }
            done.push(k);
        }
        (out, regs)
    }
}

impl Aligner {
    /// Updates agent `name`'s filter with a measurement at `now`; the first one starts it
    /// (nothing is known before it).
    fn measured(&mut self, name: &str, z: &Measurement, now: u64) {
        match self.filters.get_mut(name) {
            Some(f) => f.update(z),
            None => {
                let m = z.motion;
                let x = Vector3::new(m.to[0] - m.from[0], m.to[1] - m.from[1], m.theta);
                let f = Filter {
                    x,
                    p: z.cov,
                    pivot: m.from,
                    t_us: now,
                    measured_us: now,
                };
                self.filters.insert(name.to_string(), f);
            }
        }
        self.filters.get_mut(name).expect("there").measured_us = now;
    }
}

impl Filter {
    /// The registration the filter holds, applied where its test passes; `matches` pairs of
    /// boxes measured it this window.
    fn registration(&self, matches: usize, p: &AlignParams) -> Registration {
        let (chi2, turn_chi2) = (self.shift_chi2(), self.turn_chi2());
        Registration {
            pivot: self.pivot,
            shift_m: [self.x[0], self.x[1]],
            turn_rad: self.x[2],
            std: [
                self.p[(0, 0)].sqrt(),
                self.p[(1, 1)].sqrt(),
                self.p[(2, 2)].sqrt(),
            ],
            matches,
            chi2,
            turn_chi2,
            applied: chi2 > p.chi2,
            turn_applied: turn_chi2 > p.turn_chi2,
        }
    }
}

/// Per-window registration ([`Aligner`] without history): every agent aligned to agent
/// `reference`.
pub fn align(
    agents: &[Vec<Detection>],
    reference: usize,
    p: &AlignParams,
) -> (Vec<Vec<Detection>>, Vec<Option<Registration>>) {
    let names: Vec<String> = (0..agents.len()).map(|a| a.to_string()).collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    Aligner::new(*p).align(None, &names, agents, reference)
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

    /// A window of a [`Road`]: its time, the vehicle's boxes, the roadside unit's, and where the
    /// cars either side saw truly are.
    pub(crate) type Window = (u64, Vec<Detection>, Vec<Detection>, Vec<[f64; 2]>);

    /// A road seen by a roadside unit (x in [-60, 20]) and a vehicle (x in [20 - `overlap_m`,
    /// 100]): `lanes` lanes 4 m apart of cars at 8 m/s entering about once a second per lane,
    /// and with `parked` a row of parked cars 5.5-7.5 m apart along the curb. Each side places
    /// each car with a bias of its own (0.35 m per axis, fixed per car) and noise (0.3 m per
    /// axis per frame): the two sides' boxes of one car sit about 0.8 m apart (median). Each
    /// side misses each car with probability `occluded` (for good: it never labels it). The
    /// vehicle reports everything moved by -`offset`; in the `blind` windows (by index) the
    /// roadside unit sees nothing.
    #[derive(Clone, Debug)]
    pub(crate) struct Road {
        pub lanes: usize,
        pub seconds: f64,
        pub overlap_m: f64,
        pub offset: [f64; 2],
        pub blind: std::ops::Range<usize>,
        pub parked: bool,
        pub occluded: f64,
    }

    impl Road {
        pub(crate) fn new(lanes: usize, seconds: f64, overlap_m: f64, offset: [f64; 2]) -> Self {
            Road {
                lanes,
                seconds,
                overlap_m,
                offset,
                blind: 0..0,
                parked: false,
                occluded: 0.0,
            }
        }

        /// Per 10 Hz window: its time, the vehicle's boxes, the roadside unit's.
        pub(crate) fn windows(&self, seed: u64) -> Vec<(u64, Vec<Detection>, Vec<Detection>)> {
            self.windows_with_truth(seed)
                .into_iter()
                .map(|(t, veh, rsu, _)| (t, veh, rsu))
                .collect()
        }

        /// [`Road::windows`], and each window's cars either side saw, where they truly are.
        pub(crate) fn windows_with_truth(&self, seed: u64) -> Vec<Window> {
            use rand::{Rng, SeedableRng};
            use rand_distr::{Distribution, Normal};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let bias = Normal::new(0.0, 0.35).unwrap();
            let noise = Normal::new(0.0, 0.3).unwrap();
            // cars: (x at t = 0 and y, speed, per-side biases, per-side labelled)
            type Car = ([f64; 2], f64, [[f64; 2]; 2], [bool; 2]);
            let mut cars: Vec<Car> = Vec::new();
            let add = |cars: &mut Vec<_>, rng: &mut rand_chacha::ChaCha8Rng, xy, v| {
                let b = [
                    [bias.sample(rng), bias.sample(rng)],
                    [bias.sample(rng), bias.sample(rng)],
                ];
                let seen = [
                    rng.gen::<f64>() >= self.occluded,
                    rng.gen::<f64>() >= self.occluded,
                ];
                cars.push((xy, v, b, seen));
            };
            for lane in (0..self.lanes).map(|l| 4.0 * l as f64) {
                let mut t = -10.0;
                while t < self.seconds {
                    add(&mut cars, &mut rng, [-60.0 - 8.0 * t, lane], 8.0);
                    t += rng.gen_range(0.8..1.4);
                }
            }
            if self.parked {
                let mut x = -60.0;
                while x < 100.0 {
                    add(&mut cars, &mut rng, [x, -3.5], 0.0);
                    x += rng.gen_range(5.5..7.5);
                }
            }
            let steps = (self.seconds * 10.0) as usize;
            (0..steps)
                .map(|k| {
                    let t = k as f64 / 10.0;
                    let (mut veh, mut rsu, mut truth) = (Vec::new(), Vec::new(), Vec::new());
                    for (id, (xy, v, b, labelled)) in cars.iter().enumerate() {
                        let x = xy[0] + v * t;
                        let seen = [
                            (20.0 - self.overlap_m..100.0).contains(&x),
                            (-60.0..20.0).contains(&x) && !self.blind.contains(&k),
                        ];
                        if (0..2).any(|side| seen[side] && labelled[side]) {
                            truth.push([x, xy[1]]);
                        }
                        for side in 0..2 {
                            if !seen[side] || !labelled[side] {
                                continue;
                            }
                            let mut d = det(
                                x + b[side][0] + noise.sample(&mut rng),
                                xy[1] + b[side][1] + noise.sample(&mut rng),
                                Class::Car,
                            );
                            d.std = Uncertainty::uniform(0.3, 0.1, 0.1);
                            d.id = id as u32;
                            if side == 0 {
                                d.center[0] -= self.offset[0];
                                d.center[1] -= self.offset[1];
                                veh.push(d);
                            } else {
                                rsu.push(d);
                            }
                        }
                    }
                    ((k as u64 + 1) * 100_000, veh, rsu, truth)
                })
                .collect()
        }
    }

    /// Runs the aligner over `road` windows: each window's registration of the vehicle.
    fn register(windows: &[(u64, Vec<Detection>, Vec<Detection>)]) -> Vec<Option<Registration>> {
        let mut a = Aligner::new(AlignParams::default());
        windows
            .iter()
            .map(|(t, veh, rsu)| {
                a.align(Some(*t), &["rsu", "veh"], &[rsu.clone(), veh.clone()], 0)
                    .1[1]
            })
            .collect()
    }

    #[test]
    fn a_constant_offset_is_recovered_to_a_tenth_of_a_metre() {
        // the calibration error of real vehicle-infrastructure data: 0.66 m on each axis
        for seed in 1..=4 {
            let regs = register(&Road::new(4, 60.0, 20.0, [0.66, 0.66]).windows(seed));
            // after the first 20 s every window applies it, and the last estimate is within 0.1 m
            for r in &regs[200..] {
                let r = r.expect("measured");
                assert!(r.applied, "seed {seed}: {r:?}");
            }
            let r = regs.last().unwrap().unwrap();
            let shift = r.motion().shift_at([10.0, 3.0]);
            let err = (shift[0] - 0.66).hypot(shift[1] - 0.66);
            assert!(err < 0.1, "seed {seed}: {shift:?} ({err:.3} m off)");
        }
    }

    #[test]
    fn label_disagreement_alone_is_not_corrected() {
        // no offset; 1-5 shared cars a window (a 20 m or 8 m overlap)
        for (seed, overlap) in [(1, 20.0), (2, 20.0), (3, 8.0), (4, 8.0)] {
            let regs = register(&Road::new(2, 60.0, overlap, [0.0, 0.0]).windows(seed));
            let applied: Vec<f64> = regs
                .iter()
                .flatten()
                .filter(|r| r.applied)
                .map(|r| r.shift_m[0].hypot(r.shift_m[1]))
                .collect();
            let worst = applied.iter().copied().fold(0.0, f64::max);
            assert!(
                applied.len() * 10 <= regs.len() && worst < 0.3,
                "seed {seed}, overlap {overlap}: applied in {} of {} windows, up to {worst:.2} m",
                applied.len(),
                regs.len()
            );
        }
    }

    #[test]
    fn an_estimate_fades_to_none_across_a_gap() {
        // 40 s with the offset, then the roadside unit sees nothing for 1.5 s, then for 100 s
        let road = Road {
            blind: 400..1450,
            ..Road::new(4, 145.0, 20.0, [0.66, 0.66])
        };
        let windows = road.windows(1);
        let regs = register(&windows);
        let before = regs[399].unwrap();
        assert!(before.applied && before.matches >= 3);
        // 1.5 s later: nothing measured, the estimate carried on, shrunk by exp(-1.5 / tau)
        let short = regs[414].unwrap();
        assert_eq!(short.matches, 0);
        let a = (-1.5f64 / AlignParams::default().tau_s).exp();
        assert!((short.shift_m[0] - a * before.shift_m[0] - 0.0).abs() < 0.05 + (1.0 - a));
        assert!(short.std[0] > before.std[0]);
        // long after: faded to no correction, not applied
        let long = regs[1449];
        assert!(long.is_none_or(|r| !r.applied), "{long:?}");
        // the fuser applies nothing it does not report
        for r in regs.iter().flatten() {
            assert_eq!(r.applied, r.chi2 > AlignParams::default().chi2);
            assert_eq!(
                r.turn_applied,
                r.turn_chi2 > AlignParams::default().turn_chi2
            );
        }
    }

    /// Precision and recall of csba-wls+ over `road` windows, registered or not, as a
    /// detection benchmark counts them: each fused box takes the nearest free car within 2 m of
    /// where that car truly is, the cars are those either agent saw.
    fn precision_recall(windows: &[Window], register: bool) -> (f64, f64) {
        let method: crate::Method = "csba-wls+".parse().unwrap();
        let mut a = Aligner::new(AlignParams::default());
        let (mut tp, mut boxes, mut objects) = (0usize, 0usize, 0usize);
        for (t, veh, rsu, truth) in windows {
            let mut lists = vec![rsu.clone(), veh.clone()];
            if register {
                lists = a.align(Some(*t), &["rsu", "veh"], &lists, 0).0;
            }
            let fused = method.fuse(&lists);
            let mut free = vec![true; truth.len()];
            for d in &fused {
                let near = (0..truth.len())
                    .filter(|&i| free[i])
                    .map(|i| {
                        (
                            i,
                            (d.center[0] - truth[i][0]).hypot(d.center[1] - truth[i][1]),
                        )
                    })
                    .filter(|(_, dist)| *dist < 2.0)
                    .min_by(|x, y| x.1.total_cmp(&y.1));
                if let Some((i, _)) = near {
                    free[i] = false;
                    tp += 1;
                }
            }
            boxes += fused.len();
            objects += truth.len();
        }
        (tp as f64 / boxes as f64, tp as f64 / objects as f64)
    }

    #[test]
    fn registration_never_costs_precision_or_recall_on_sparse_overlap() {
        // 1-5 shared cars a window, labels 0.8 m apart, a 1.5 s gap; with and without a
        // calibration offset, four seeds: registered, precision and recall stay within 0.01
        // of unregistered
        for seed in 1..=4 {
            for offset in [[0.0, 0.0], [0.66, 0.66]] {
                for overlap in [8.0, 20.0] {
                    // a parked row, and a third of the cars labelled by one side only
                    let road = Road {
                        blind: 150..165,
                        parked: true,
                        occluded: 0.2,
                        ..Road::new(2, 40.0, overlap, offset)
                    };
                    let windows = road.windows_with_truth(seed);
                    let (p0, r0) = precision_recall(&windows, false);
                    let (p1, r1) = precision_recall(&windows, true);
                    assert!(
                        p1 >= p0 - 0.01 && r1 >= r0 - 0.01,
                        "seed {seed}, offset {offset:?}, overlap {overlap}: precision {p0:.3} -> {p1:.3}, recall {r0:.3} -> {r1:.3}"
                    );
                }
            }
        }
    }
}
