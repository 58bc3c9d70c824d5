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
use nalgebra::{Matrix4, Vector4};
use v2x_protocol::{Class, Detection, NO_ID};

pub use params::{Association, AssociationParams, Management, TrackMotion, TrackerParams};

use filter::{birth, distance, estimate, may_pass, predict, update};

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

mod filter;
mod guided;
pub mod handover;
mod params;
mod soft;

#[cfg(test)]
mod tests;
