//! Track-level fusion over time (`docs/method.md` §8): the fused boxes of each window update a
//! set of tracks, SORT's loop with the covariances WLS-3D already gives.
//!
//! Per window at time t:
//! 1. **predict** every track to t with a constant-velocity model on (x, y, vx, vy):
//!    x <- F x, P <- F P F^T + Q, Q the white-acceleration noise of std `accel_std`;
//! 2. **cost** of a (track, box) pair of the same class: the innovation y = z - H x with
//!    S = H P H^T + R (R the box's own covariance; H measures the centre, and the velocity too
//!    when the box has one) gives d^2 = y^T S^-1 y and the cost d^2 + ln det S, twice the
//!    negative log-likelihood; pairs beyond the chi-square gate are not eligible (with
//!    `by_id`, a simulation's perfect association, a box's only pair is the track its
//!    ground-truth id had);
//! 3. **assign** with the association's exact solver (`association::assign`);
//! 4. **update** matched tracks with the Kalman gain (Joseph form); size by WLS against the box,
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
use nalgebra::{DMatrix, DVector, Matrix4, Vector4};
use v2x_protocol::{wrap_angle, Class, Detection, Uncertainty, Velocity, NO_ID};

/// Parameters of the tracker.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct TrackerParams {
    /// Std of the unmodelled acceleration (m/s^2), as in motion compensation.
    pub accel_std: f64,
    /// Gate on d^2 of a (track, box) pair: the 99.9% chi-square quantile for 4 degrees of
    /// freedom (centre and velocity measured); with the centre alone the same bound is looser.
    pub gate: f64,
    /// Hits in a row (the first box included) that confirm a track. 2: a box seen in one
    /// window only (a false positive, an object glimpsed once) never becomes a track.
    pub confirm_hits: u32,
    /// Misses in a row a confirmed track survives. 3: at 10 Hz a track coasts through 300 ms
    /// without boxes (an occlusion, lost windows); at 2 Hz, 1.5 s.
    pub max_misses: u32,
    /// Misses in a row during which a confirmed track is still output, at its prediction with
    /// its score halved per miss. 3, as `max_misses`: a window without a box (two tracks'
    /// boxes merged, a lost window) neither drops the object nor hands it to a neighbouring
    /// track, and the halved score lets the benchmark's thresholds drop long coasts.
    pub coast_output: u32,
    /// Longest gap between windows (s) tracks are carried over; beyond, they all end.
    pub max_gap_s: f64,
    /// Std (m/s) of the velocity of a new track from a box without one.
    pub init_velocity_std: f64,
    /// Std (rad/s) of the yaw's change per second.
    pub yaw_rate_std: f64,
    /// Variance (m^2) the centre's height gains per second between boxes: 1, so that the
    /// height follows its boxes (a detector's heights scatter by tenths of a metre, and another
    /// car's pitch moves them more) instead of keeping the first box's.
    pub height_var_per_s: f64,
    /// Seconds of motion per second of window time: the replay speed when agents replay
    /// recorded data faster than real time on the wall clock (1 live).
    pub time_scale: f64,
    /// Simulation only: a box goes to the track of its ground-truth id (`Detection::id`;
    /// `NO_ID` never matching) instead of the likeliest track, ungated: what a perfect
    /// association gives with this filter (`bench --tracking`, row `gt-wls tracked by id`).
    pub by_id: bool,
    /// Also follow the classes the nuScenes tracking benchmark does not score (barrier, traffic
    /// cone, construction vehicle); by default their boxes are passed over.
    pub all_classes: bool,
    /// How the tracker's callers feed it: each agent's boxes through the tracks first
    /// ([`Tracker::step_agents`], `docs/method.md` §8.1), or (false) the fused boxes
    /// ([`Tracker::step`]).
    pub guided: bool,
}

impl Default for TrackerParams {
    fn default() -> Self {
        TrackerParams {
            accel_std: 2.0,
            gate: 18.47,
            confirm_hits: 2,
            max_misses: 3,
            coast_output: 3,
            max_gap_s: 2.0,
            init_velocity_std: 10.0,
            yaw_rate_std: 0.5,
            height_var_per_s: 1.0,
            time_scale: 1.0,
            by_id: false,
            all_classes: false,
            guided: false,
        }
    }
}

/// One track.
#[derive(Clone, Debug)]
struct Track {
    id: u32,
    class: Class,
    /// (x, y, vx, vy) and its covariance.
    x: Vector4<f64>,
    p: Matrix4<f64>,
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
        // 2. cost of every eligible pair, 3. assignment
        let edges = if self.params.by_id {
            by_id_edges(&self.tracks, boxes)
        } else {
            self.likelihood_edges(boxes)
        };
        let pairs = assign(self.tracks.len(), boxes.len(), &edges);
        // 4. update
        let mut hit = vec![false; self.tracks.len()];
        let mut used = vec![false; boxes.len()];
        for (i, j) in pairs {
            hit[i] = true;
            used[j] = true;
            ids[index[j]] = self.tracks[i].id;
            update(&mut self.tracks[i], &boxes[j], dt, &self.params);
        }
        // 5. lifecycle
        let mut out = self.lifecycle(&hit);
        for (j, (b, used)) in boxes.iter().zip(used).enumerate() {
            if !used {
                ids[index[j]] = self.next_id;
                out.extend(self.birth(b));
            }
        }
        (out, ids)
    }

    /// The boxes of the classes tracked (all of them with `all_classes`) and their indices in
    /// `all`.
    fn tracked_classes<'a>(
        &self,
        all: &'a [Detection],
    ) -> (Vec<usize>, std::borrow::Cow<'a, [Detection]>) {
        let index: Vec<usize> = (0..all.len())
            .filter(|&j| self.params.all_classes || all[j].class.is_tracking())
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
        let scale = self.params.time_scale;
        let dt = match self.last_us {
            Some(last)
                if t_us >= last && (t_us - last) as f64 * scale <= self.params.max_gap_s * 1e6 =>
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
            predict(t, dt, &self.params);
        }
        dt
    }

    /// Step 5 for the existing tracks, `hit` saying which got a box: confirmed after
    /// `confirm_hits` hits, a tentative track dropped at its first miss, a confirmed one after
    /// `max_misses`; returns the confirmed tracks updated, and those coasting at their
    /// prediction with their score halved per miss.
    fn lifecycle(&mut self, hit: &[bool]) -> Vec<Tracked> {
        let mut out = Vec::new();
        let mut kept = Vec::with_capacity(self.tracks.len());
        for (t, &hit) in std::mem::take(&mut self.tracks).into_iter().zip(hit) {
            let mut t = t;
            if hit {
                t.hits += 1;
                t.misses = 0;
                if !t.confirmed && t.hits >= self.params.confirm_hits {
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
                if t.misses > self.params.max_misses {
                    self.deaths += 1;
                    continue;
                }
                if t.misses <= self.params.coast_output {
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
        out
    }

    /// Step 5 for a box no track took: a new track, output at once when one hit confirms it.
    fn birth(&mut self, b: &Detection) -> Option<Tracked> {
        let mut t = birth(self.next_id, b, &self.params);
        self.next_id = if self.next_id + 1 >= self.ids.1 {
            self.ids.0
        } else {
            self.next_id + 1
        };
        let shown = (t.hits >= self.params.confirm_hits).then(|| {
            t.confirmed = true;
            self.births += 1;
            Tracked {
                tracking_id: t.id,
                det: estimate(&t),
            }
        });
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
                if b.class != t.class || !may_pass(t, b, var[j], self.params.gate) {
                    continue;
                }
                if let Some((d2, ln_det)) = distance(t, b) {
                    if d2 <= self.params.gate {
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
fn birth(id: u32, b: &Detection, p: &TrackerParams) -> Track {
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
    Track {
        id,
        class: b.class,
        x: Vector4::new(b.center[0], b.center[1], v[0], v[1]),
        p: cov,
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

/// x <- F x, P <- F P F^T + Q over dt; the yaw variance grows with the yaw rate std.
fn predict(t: &mut Track, dt: f64, p: &TrackerParams) {
    if dt == 0.0 {
        return;
    }
    let mut f = Matrix4::identity();
    f[(0, 2)] = dt;
    f[(1, 3)] = dt;
    let q = (p.accel_std * accel_scale(t.class)).powi(2);
    let (a, b, c) = (dt.powi(4) / 4.0 * q, dt.powi(3) / 2.0 * q, dt * dt * q);
    #[rustfmt::skip]
    let qm = Matrix4::new(
        a, 0.0, b, 0.0,
        0.0, a, 0.0, b,
        b, 0.0, c, 0.0,
        0.0, b, 0.0, c,
    );
    t.x = f * t.x;
    t.p = f * t.p * f.transpose() + qm;
    t.yaw.1 += (p.yaw_rate_std * dt).powi(2);
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

/// The measurement matrix, the measurement and its covariance for a box: the centre, and the
/// velocity when the box has one.
fn measurement(b: &Detection) -> (DMatrix<f64>, DVector<f64>, DMatrix<f64>) {
    let c = b.position_covariance();
    match &b.velocity {
        Some(v) => {
            let h = DMatrix::identity(4, 4);
            let z = DVector::from_vec(vec![b.center[0], b.center[1], v.v[0], v.v[1]]);
            let mut r = DMatrix::zeros(4, 4);
            r[(0, 0)] = c[0][0];
            r[(0, 1)] = c[0][1];
            r[(1, 0)] = c[1][0];
            r[(1, 1)] = c[1][1];
            r[(2, 2)] = v.std[0].powi(2);
            r[(3, 3)] = v.std[1].powi(2);
            (h, z, r)
        }
        None => {
            let h = DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
            let z = DVector::from_vec(vec![b.center[0], b.center[1]]);
            let r = DMatrix::from_row_slice(2, 2, &[c[0][0], c[0][1], c[1][0], c[1][1]]);
            (h, z, r)
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
    let (y, s, _) = innovation(t, b);
    let s_inv = s.clone().try_inverse()?;
    let d2 = (y.transpose() * &s_inv * &y)[0];
    Some((d2, s.determinant().max(1e-300).ln()))
}

/// The innovation y, its covariance S and H.
fn innovation(t: &Track, b: &Detection) -> (DVector<f64>, DMatrix<f64>, DMatrix<f64>) {
    let (h, z, r) = measurement(b);
    let x = DVector::from_column_slice(t.x.as_slice());
    let p = DMatrix::from_column_slice(4, 4, t.p.as_slice());
    let y = z - &h * x;
    let s = &h * p * h.transpose() + r;
    (y, s, h)
}

/// The Kalman update of the kinematic state (Joseph form), then size, z and yaw.
fn update(t: &mut Track, b: &Detection, dt: f64, p: &TrackerParams) {
    let (y, s, h) = innovation(t, b);
    let (_, _, r) = measurement(b);
    if let Some(s_inv) = s.try_inverse() {
        let p = DMatrix::from_column_slice(4, 4, t.p.as_slice());
        let k = &p * h.transpose() * s_inv;
        let x = DVector::from_column_slice(t.x.as_slice()) + &k * y;
        let i_kh = DMatrix::identity(4, 4) - &k * &h;
        let p = &i_kh * p * i_kh.transpose() + &k * r * k.transpose();
        t.x = Vector4::from_column_slice(x.as_slice());
        t.p = Matrix4::from_column_slice(p.as_slice());
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

#[cfg(test)]
mod tests;
