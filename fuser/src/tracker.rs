//! Track-level fusion over time (`docs/method.md` §8): the fused boxes of each window update a
//! set of tracks, SORT's loop with the covariances WLS-3D already gives.
//!
//! Per window at time t:
//! 1. **predict** every track to t with two constant-velocity models on (x, y, vx, vy), an
//!    agile and a quiet one (white-acceleration Q of std `accel_std` and `quiet_accel_std`),
//!    mixed as an interacting multiple model: each x_j <- F x_j, P_j <- F P_j F^T + Q_j from
//!    the models' mixture by the chance of a change, the track's state their mixture by mu;
//! 2. **cost** of a (track, box) pair of the same class: the innovation y = z - H x with
//!    S = H P H^T + R (R the box's own covariance; H measures the centre, and the velocity too
//!    when the box has one) gives d^2 = y^T S^-1 y and the cost d^2 + ln det S, twice the
//!    negative log-likelihood; pairs beyond the chi-square gate are not eligible (with
//!    [`Association::ById`], a simulation's perfect association, a box's only pair is the track its
//!    ground-truth id had);
//! 3. **assign** with the association's exact solver (`association::assign`), or with
//!    [`Association::Soft`]
//!    weigh each track's boxes by the chance each is its own (`soft.rs`, `docs/method.md` §8.2);
//! 4. **update** matched tracks: each model with the Kalman gain (Joseph form) and its
//!    probability by its likelihood; size by WLS against the box,
//!    yaw as WLS-3D fuses it (period pi for barriers, a heading turned by pi beyond 4 stds taken
//!    as a flip); unmatched boxes start tentative tracks;
//! 5. **lifecycle**: a tentative track is confirmed after `confirm_hits` consecutive hits and
//!    dropped at its first miss; a confirmed track dies after more than `max_misses` misses in a
//!    row. A gap longer than `max_gap_s` (a new scene) or time going back starts afresh.
//!
//! Confirmed tracks updated in the window are the output, with their `tracking_id`, velocity and
//! covariance. Sans-IO: times and boxes in, tracks out.

use crate::maths::association::{assign, Edge};
use crate::maths::fusion::FLIP_SIGMAS;
use nalgebra::{Const, DimMin, Matrix2, Matrix2x4, Matrix4, SMatrix, SVector, Vector2, Vector4};
use v2x_protocol::{wrap_angle, Class, Detection, Uncertainty, Velocity, NO_ID};

pub use params::{Association, AssociationParams, Management, TrackMotion, TrackerParams};

/// One track.
#[derive(Clone, Debug)]
struct Track {
    id: u32,
    class: Class,
    /// (x, y, vx, vy) and its covariance: the two motion models' mixture.
    x: Vector4<f64>,
    p: Matrix4<f64>,
    /// Each motion model's (x, y, vx, vy) and covariance, quiet first, and its probability.
    modes: [(Vector4<f64>, Matrix4<f64>); 2],
    mu: [f64; 2],
    z: (f64, f64),
    size: [(f64, f64); 3],
    yaw: (f64, f64),
    score: f64,
    /// The ground-truth id of the last box (simulation only), for `eval --match id`.
    truth: u32,
    hits: u32,
    misses: u32,
    confirmed: bool,
}

/// A tracked box: the box as the track estimates it, and the track's id.
#[derive(Clone, Debug, PartialEq)]
pub struct Tracked {
    /// The track's stable id.
    pub tracking_id: u32,
    /// Centre, size, yaw, velocity and their uncertainty, from the track's state.
    pub det: Detection,
}

/// Live tracks and the lifecycle counters.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TrackStats {
    /// Confirmed tracks alive now.
    pub live: usize,
    /// Tracks confirmed so far.
    pub births: u64,
    /// Confirmed tracks ended so far.
    pub deaths: u64,
}

/// The tracker: call [`Tracker::step`] once per window, in time order.
#[derive(Clone, Debug)]
pub struct Tracker {
    params: TrackerParams,
    tracks: Vec<Track>,
    next_id: u32,
    /// The ids new tracks take: `ids.0..ids.1`, cycling.
    ids: (u32, u32),
    last_us: Option<u64>,
    births: u64,
    deaths: u64,
}

impl Tracker {
    /// A tracker without tracks.
    pub fn new(params: TrackerParams) -> Self {
        Self::with_ids(params, 1..NO_ID)
    }

    /// A tracker whose new tracks take their ids from `ids` (cycling through it; [`NO_ID`]
    /// never), so that trackers given disjoint ranges never give two tracks one id.
    pub fn with_ids(params: TrackerParams, ids: std::ops::Range<u32>) -> Self {
        let ids = (ids.start, ids.end.max(ids.start.saturating_add(1)));
        Tracker {
            params,
            tracks: Vec::new(),
            next_id: ids.0,
            ids,
            last_us: None,
            births: 0,
            deaths: 0,
        }
    }

    /// The parameters it was made with.
    pub fn params(&self) -> &TrackerParams {
        &self.params
    }

    /// The lifecycle counters.
    pub fn stats(&self) -> TrackStats {
        TrackStats {
            live: self.tracks.iter().filter(|t| t.confirmed).count(),
            births: self.births,
            deaths: self.deaths,
        }
    }

    /// Ends every track (a new scene).
    pub fn reset(&mut self) {
        self.deaths += self.tracks.iter().filter(|t| t.confirmed).count() as u64;
        self.tracks.clear();
        self.last_us = None;
    }

    /// Takes the fused boxes of the window at `t_us` (of the tracking classes only, unless
    /// `all_classes`) and returns the confirmed tracks it updated.
    pub fn step(&mut self, t_us: u64, boxes: &[Detection]) -> Vec<Tracked> {
        self.step_ids(t_us, boxes).0
    }

    /// [`Tracker::step`], also returning the id of the track (tentative or confirmed) each box
    /// went to, [`NO_ID`] for a box of a class not tracked.
    pub fn step_ids(&mut self, t_us: u64, all: &[Detection]) -> (Vec<Tracked>, Vec<u32>) {
        let (index, boxes) = self.tracked_classes(all);
        let boxes = &*boxes;
        let mut ids = vec![NO_ID; all.len()];
        // 1. predict
        let dt = self.advance(t_us);
        // 2. cost of every eligible pair, 3. assignment, 4. update
        let (hit, taken) = if self.params.association.mode == Association::Soft {
            self.associate_soft(boxes, dt)
        } else {
            self.associate_hard(boxes, dt)
        };
        for (j, i) in taken.iter().enumerate() {
            if let Some(i) = i {
                ids[index[j]] = self.tracks[*i].id;
            }
        }
        // 5. lifecycle
        let mut out = self.lifecycle(&hit);
        for (j, (b, taken)) in boxes.iter().zip(taken).enumerate() {
            if taken.is_none() {
                ids[index[j]] = self.next_id;
                out.extend(self.birth(b));
            }
        }
        (out, ids)
    }

    /// Steps 2 to 4 with one best assignment: which tracks took a box, and the track each box
    /// went to (`None`: it starts a track).
    fn associate_hard(&mut self, boxes: &[Detection], dt: f64) -> (Vec<bool>, Vec<Option<usize>>) {
        let edges = if self.params.association.mode == Association::ById {
            by_id_edges(&self.tracks, boxes)
        } else {
            self.likelihood_edges(boxes)
        };
        let mut hit = vec![false; self.tracks.len()];
        let mut taken = vec![None; boxes.len()];
        for (i, j) in assign(self.tracks.len(), boxes.len(), &edges) {
            hit[i] = true;
            taken[j] = Some(i);
            update(&mut self.tracks[i], &boxes[j], dt, &self.params.motion);
        }
        (hit, taken)
    }

    /// The boxes of the classes tracked (all of them with `all_classes`) and their indices in
    /// `all`.
    fn tracked_classes<'a>(
        &self,
        all: &'a [Detection],
    ) -> (Vec<usize>, std::borrow::Cow<'a, [Detection]>) {
        let index: Vec<usize> = (0..all.len())
            .filter(|&j| self.params.management.all_classes || all[j].class.is_tracking())
            .collect();
        let boxes = if index.len() == all.len() {
            all.into()
        } else {
            index
                .iter()
                .map(|&j| all[j].clone())
                .collect::<Vec<_>>()
                .into()
        };
        (index, boxes)
    }

    /// Step 1: the time since the last window (s of motion), every track predicted over it; a
    /// gap beyond `max_gap_s` or time going back ends every track first.
    fn advance(&mut self, t_us: u64) -> f64 {
        let scale = self.params.motion.time_scale;
        let dt = match self.last_us {
            Some(last)
                if t_us >= last
                    && (t_us - last) as f64 * scale <= self.params.management.max_gap_s * 1e6 =>
            {
                (t_us - last) as f64 / 1e6 * scale
            }
            Some(_) => {
                self.reset();
                0.0
            }
            None => 0.0,
        };
        self.last_us = Some(t_us);
        for t in &mut self.tracks {
            predict(t, dt, &self.params.motion);
        }
        dt
    }

    /// Step 5 for the existing tracks, `hit` saying which got a box: confirmed after
    /// `confirm_hits` hits, a tentative track dropped at its first miss, a confirmed one after
    /// `max_misses`; returns the confirmed tracks updated, and those coasting at their
    /// prediction with their score halved per miss, that score at least `min_score`.
    fn lifecycle(&mut self, hit: &[bool]) -> Vec<Tracked> {
        let mut out = Vec::new();
        let mut kept = Vec::with_capacity(self.tracks.len());
        for (t, &hit) in std::mem::take(&mut self.tracks).into_iter().zip(hit) {
            let mut t = t;
            if hit {
                t.hits += 1;
                t.misses = 0;
                if !t.confirmed && t.hits >= self.params.management.confirm_hits {
                    t.confirmed = true;
                    self.births += 1;
                }
                if t.confirmed {
                    out.push(Tracked {
                        tracking_id: t.id,
                        det: estimate(&t),
                    });
                }
            } else {
                t.misses += 1;
                if !t.confirmed {
                    continue;
                }
                if t.misses > self.params.management.max_misses {
                    self.deaths += 1;
                    continue;
                }
                if t.misses <= self.params.management.coast_output {
                    // Shown where the track predicts it, with its score halved per miss.
                    let mut det = estimate(&t);
                    det.score *= 0.5f64.powi(t.misses as i32);
                    out.push(Tracked {
                        tracking_id: t.id,
                        det,
                    });
                }
            }
            kept.push(t);
        }
        self.tracks = kept;
        out.retain(|t| t.det.score >= self.params.management.min_score);
        out
    }

    /// Step 5 for a box no track took: a new track, output at once when one hit confirms it
    /// and it scores at least the operating point.
    fn birth(&mut self, b: &Detection) -> Option<Tracked> {
        let mut t = birth(self.next_id, b, &self.params.motion);
        self.next_id = if self.next_id + 1 >= self.ids.1 {
            self.ids.0
        } else {
            self.next_id + 1
        };
        let shown = (t.hits >= self.params.management.confirm_hits).then(|| {
            t.confirmed = true;
            self.births += 1;
            Tracked {
                tracking_id: t.id,
                det: estimate(&t),
            }
        });
        let shown = shown.filter(|s| s.det.score >= self.params.management.min_score);
        self.tracks.push(t);
        shown
    }

    /// Step 2: every (track, box) pair of the same class inside the gate, costed d^2 + ln det S.
    fn likelihood_edges(&self, boxes: &[Detection]) -> Vec<Edge> {
        let mut edges = Vec::new();
        let var: Vec<[f64; 2]> = boxes
            .iter()
            .map(|b| {
                let c = b.position_covariance();
                [c[0][0], c[1][1]]
            })
            .collect();
        for (i, t) in self.tracks.iter().enumerate() {
            for (j, b) in boxes.iter().enumerate() {
                if b.class != t.class || !may_pass(t, b, var[j], self.params.association.gate) {
                    continue;
                }
                if let Some((d2, ln_det)) = distance(t, b) {
                    if d2 <= self.params.association.gate {
                        edges.push(Edge::new(i, j, d2 + ln_det));
                    }
                }
            }
        }
        edges
    }
}

/// Step 2 by ground truth: each box's track is the one whose last box had its id.
fn by_id_edges(tracks: &[Track], boxes: &[Detection]) -> Vec<Edge> {
    let mut edges = Vec::new();
    for (i, t) in tracks.iter().enumerate() {
        for (j, b) in boxes.iter().enumerate() {
            if b.id != NO_ID && b.id == t.truth && b.class == t.class {
                edges.push(Edge::new(i, j, 0.0));
            }
        }
    }
    edges
}

/// A tentative track from a box.
fn birth(id: u32, b: &Detection, p: &TrackMotion) -> Track {
    let c = b.position_covariance();
    let (v, vv) = match &b.velocity {
        Some(v) => (v.v, [v.std[0] * v.std[0], v.std[1] * v.std[1]]),
        None => ([0.0; 2], [p.init_velocity_std.powi(2); 2]),
    };
    let mut cov = Matrix4::zeros();
    cov[(0, 0)] = c[0][0];
    cov[(0, 1)] = c[0][1];
    cov[(1, 0)] = c[1][0];
    cov[(1, 1)] = c[1][1];
    cov[(2, 2)] = vv[0];
    cov[(3, 3)] = vv[1];
    let x = Vector4::new(b.center[0], b.center[1], v[0], v[1]);
    Track {
        id,
        class: b.class,
        x,
        p: cov,
        modes: [(x, cov); 2],
        mu: [0.5; 2],
        z: (b.center[2], c[2][2]),
        size: std::array::from_fn(|k| (b.size[k], b.std.size[k].powi(2))),
        yaw: (b.yaw, b.std.yaw.powi(2)),
        score: b.score,
        truth: b.id,
        hits: 1,
        misses: 0,
        confirmed: false,
    }
}

/// The interacting multiple model's prediction over dt: the two models mixed by the chance
/// that the object changed model (each stays with probability 1 - s, s = (1 - e^(-dt/hold))/2),
/// each predicted x <- F x, P <- F P F^T + Q with its own acceleration std, and the track's
/// state their mixture; the yaw variance grows with the yaw rate std.
fn predict(t: &mut Track, dt: f64, p: &TrackMotion) {
    if dt == 0.0 {
        return;
    }
    let mut f = Matrix4::identity();
    f[(0, 2)] = dt;
    f[(1, 3)] = dt;
    let s = if p.mode_hold_s > 0.0 {
        0.5 * (1.0 - (-dt / p.mode_hold_s).exp())
    } else {
        0.5
    };
    let stay = [[1.0 - s, s], [s, 1.0 - s]];
    // c_j = sum_i Pi_ij mu_i; the mixed start of model j weighs model i by Pi_ij mu_i / c_j.
    let c: [f64; 2] = std::array::from_fn(|j| (0..2).map(|i| stay[i][j] * t.mu[i]).sum());
    let mixed: [(Vector4<f64>, Matrix4<f64>); 2] = std::array::from_fn(|j| {
        let w: [f64; 2] = std::array::from_fn(|i| stay[i][j] * t.mu[i] / c[j].max(1e-300));
        mixture(&t.modes, w)
    });
    for (j, (x, cov)) in mixed.into_iter().enumerate() {
        let accel = if j == 0 {
            p.quiet_accel_std
        } else {
            p.accel_std
        };
        let q = (accel * accel_scale(t.class)).powi(2);
        let (a, b, c) = (dt.powi(4) / 4.0 * q, dt.powi(3) / 2.0 * q, dt * dt * q);
        #[rustfmt::skip]
        let qm = Matrix4::new(
            a, 0.0, b, 0.0,
            0.0, a, 0.0, b,
            b, 0.0, c, 0.0,
            0.0, b, 0.0, c,
        );
        t.modes[j] = (f * x, f * cov * f.transpose() + qm);
    }
    t.mu = c;
    (t.x, t.p) = mixture(&t.modes, t.mu);
    t.yaw.1 += (p.yaw_rate_std * dt).powi(2);
}

/// The moment-matched mixture of the models' states weighted `w`: the mean, and the covariance
/// with the spread of the means.
fn mixture(modes: &[(Vector4<f64>, Matrix4<f64>); 2], w: [f64; 2]) -> (Vector4<f64>, Matrix4<f64>) {
    let x = modes[0].0 * w[0] + modes[1].0 * w[1];
    let mut cov = Matrix4::zeros();
    for ((xi, pi), wi) in modes.iter().zip(w) {
        let d = xi - x;
        cov += (pi + d * d.transpose()) * wi;
    }
    (x, cov)
}

/// How much of `accel_std` a class's motion has: vehicles all of it, people and bicycles half,
/// barriers and cones (which stand still) a fortieth.
fn accel_scale(class: Class) -> f64 {
    match class {
        Class::Pedestrian | Class::Bicycle => 0.5,
        Class::Barrier | Class::TrafficCone => 0.025,
        _ => 1.0,
    }
}

/// A box as a measurement of (x, y, vx, vy): H, z and R, of the centre, and of the velocity too
/// when the box has one.
enum Measurement {
    /// The centre alone.
    Centre(Matrix2x4<f64>, Vector2<f64>, Matrix2<f64>),
    /// The centre and the velocity (H the identity).
    Full(Matrix4<f64>, Vector4<f64>, Matrix4<f64>),
}

/// The box as a measurement.
fn measurement(b: &Detection) -> Measurement {
    let c = b.position_covariance();
    match &b.velocity {
        Some(v) => {
            #[rustfmt::skip]
            let r = Matrix4::new(
                c[0][0], c[0][1], 0.0, 0.0,
                c[1][0], c[1][1], 0.0, 0.0,
                0.0, 0.0, v.std[0].powi(2), 0.0,
                0.0, 0.0, 0.0, v.std[1].powi(2),
            );
            let z = Vector4::new(b.center[0], b.center[1], v.v[0], v.v[1]);
            Measurement::Full(Matrix4::identity(), z, r)
        }
        None => {
            let h = Matrix2x4::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
            let z = Vector2::new(b.center[0], b.center[1]);
            let r = Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1]);
            Measurement::Centre(h, z, r)
        }
    }
}

/// A cheap bound first: the full d^2 is at least each axis' own dx^2 / S_xx, so a pair whose
/// x or y alone is beyond the gate cannot pass it (`var`: the box's x and y variances).
fn may_pass(t: &Track, b: &Detection, [vx, vy]: [f64; 2], gate: f64) -> bool {
    let dx = b.center[0] - t.x[0];
    let dy = b.center[1] - t.x[1];
    dx * dx <= gate * (t.p[(0, 0)] + vx) && dy * dy <= gate * (t.p[(1, 1)] + vy)
}

/// The squared Mahalanobis distance d^2 = y^T S^-1 y of a box from a track's state, and ln det S
/// (`None` when S is singular).
fn distance(t: &Track, b: &Detection) -> Option<(f64, f64)> {
    measurement(b).distance(&t.x, &t.p)
}

impl Measurement {
    /// d^2 and ln det S of the state (x, P); `None` when S is singular.
    fn distance(&self, x: &Vector4<f64>, p: &Matrix4<f64>) -> Option<(f64, f64)> {
        match self {
            Measurement::Centre(h, z, r) => gaussian(x, p, h, z, r).map(|g| (g.d2, g.ln_det)),
            Measurement::Full(h, z, r) => gaussian(x, p, h, z, r).map(|g| (g.d2, g.ln_det)),
        }
    }

    /// [`kalman`] of the state (x, P) by this measurement.
    fn update(&self, x: &mut Vector4<f64>, p: &mut Matrix4<f64>) -> Option<f64> {
        match self {
            Measurement::Centre(h, z, r) => kalman(x, p, h, z, r),
            Measurement::Full(h, z, r) => kalman(x, p, h, z, r),
        }
    }
}

/// A state's innovation y by a measurement, S^-1, d^2 = y^T S^-1 y and ln det S.
struct Innovation<const M: usize> {
    y: SVector<f64, M>,
    s_inv: SMatrix<f64, M, M>,
    d2: f64,
    ln_det: f64,
}

/// y = z - H x and S = H P H^T + R of the state (x, P); `None` when S is singular.
fn gaussian<const M: usize>(
    x: &Vector4<f64>,
    p: &Matrix4<f64>,
    h: &SMatrix<f64, M, 4>,
    z: &SVector<f64, M>,
    r: &SMatrix<f64, M, M>,
) -> Option<Innovation<M>>
where
    Const<M>: DimMin<Const<M>, Output = Const<M>>,
{
    let y = z - h * x;
    let s = h * p * h.transpose() + r;
    let s_inv = s.try_inverse()?;
    let d2 = (y.transpose() * s_inv * y)[0];
    Some(Innovation {
        y,
        s_inv,
        d2,
        ln_det: s.determinant().max(1e-300).ln(),
    })
}

/// The Kalman update of one model's state (Joseph form); its log-likelihood
/// -(d^2 + ln det S) / 2, or `None` (the state kept) when S is singular.
fn kalman<const M: usize>(
    x: &mut Vector4<f64>,
    p: &mut Matrix4<f64>,
    h: &SMatrix<f64, M, 4>,
    z: &SVector<f64, M>,
    r: &SMatrix<f64, M, M>,
) -> Option<f64>
where
    Const<M>: DimMin<Const<M>, Output = Const<M>>,
{
    let g = gaussian(x, p, h, z, r)?;
    let k = *p * h.transpose() * g.s_inv;
    *x += k * g.y;
    let i_kh = Matrix4::identity() - k * h;
    *p = i_kh * *p * i_kh.transpose() + k * r * k.transpose();
    Some(-0.5 * (g.d2 + g.ln_det))
}

/// The Kalman update of each motion model, each model's probability times its likelihood
/// N(y; 0, S), the track's state their mixture; then size, z and yaw.
fn update(t: &mut Track, b: &Detection, dt: f64, p: &TrackMotion) {
    let m = measurement(b);
    let mut log_l = [f64::NEG_INFINITY; 2];
    for ((x, cov), l) in t.modes.iter_mut().zip(&mut log_l) {
        if let Some(v) = m.update(x, cov) {
            *l = v;
        }
    }
    if log_l.iter().any(|l| l.is_finite()) {
        let top = log_l[0].max(log_l[1]);
        let w: [f64; 2] = std::array::from_fn(|j| t.mu[j] * (log_l[j] - top).exp());
        let sum = w[0] + w[1];
        if sum > 0.0 && sum.is_finite() {
            t.mu = w.map(|v| v / sum);
        }
        (t.x, t.p) = mixture(&t.modes, t.mu);
    }
    let c = b.position_covariance();
    t.z = blend(t.z, (b.center[2], c[2][2]), p.height_var_per_s * dt);
    for k in 0..3 {
        t.size[k] = blend(t.size[k], (b.size[k], b.std.size[k].powi(2)), 0.0);
    }
    // Yaw as WLS-3D fuses it: the box's yaw unwrapped against the track's, turned by pi when
    // it is a flip (or, for a barrier, the same orientation).
    let (yaw, var) = t.yaw;
    let r = b.std.yaw.powi(2);
    let mut d = wrap_angle(b.yaw - yaw);
    if d.abs() > std::f64::consts::FRAC_PI_2 && d * d > FLIP_SIGMAS.powi(2) * (r + var) {
        d = wrap_angle(d + std::f64::consts::PI);
    }
    let (m, v) = blend((0.0, var), (d, r), 0.0);
    t.yaw = (wrap_angle(yaw + m), v);
    t.score = 0.5 * (t.score + b.score);
    t.truth = b.id;
}

/// WLS of a state (value, variance) and a measurement, after `q` of process variance.
fn blend((x, p): (f64, f64), (z, r): (f64, f64), q: f64) -> (f64, f64) {
    let p = p + q;
    if !(p > 0.0) {
        return (z, r);
    }
    let k = p / (p + r);
    (x + k * (z - x), (1.0 - k) * p)
}

/// The track as a box.
fn estimate(t: &Track) -> Detection {
    let p = &t.p;
    let pos_cov = [
        [p[(0, 0)], p[(0, 1)], 0.0],
        [p[(1, 0)], p[(1, 1)], 0.0],
        [0.0, 0.0, t.z.1],
    ];
    Detection {
        class: t.class,
        center: [t.x[0], t.x[1], t.z.0],
        size: t.size.map(|s| s.0),
        yaw: t.yaw.0,
        score: t.score,
        std: Uncertainty {
            pos: [p[(0, 0)].sqrt(), p[(1, 1)].sqrt(), t.z.1.sqrt()],
            size: t.size.map(|s| s.1.sqrt()),
            yaw: t.yaw.1.sqrt(),
        },
        pos_cov: Some(Box::new(pos_cov)),
        velocity: Some(Velocity {
            v: [t.x[2], t.x[3]],
            std: [p[(2, 2)].sqrt(), p[(3, 3)].sqrt()],
        }),
        id: t.truth,
    }
}

mod guided;
pub mod handover;
mod params;
mod soft;

#[cfg(test)]
mod tests;
