//! A window's offset of one agent from the reference: the candidate matches, a vote on the
//! shift, and the rigid shift and turn that best map one onto the other (Procrustes).

use super::*;

pub(super) fn variance(d: &Detection) -> f64 {
    d.std.pos[0] * d.std.pos[0] + d.std.pos[1] * d.std.pos[1]
}

pub(super) fn dist2(a: &Detection, b: &Detection, shift: [f64; 2]) -> f64 {
    (a.center[0] + shift[0] - b.center[0]).powi(2) + (a.center[1] + shift[1] - b.center[1]).powi(2)
}

/// The nearest same-class box of `to` within `gate` of `d` shifted by `shift`.
pub(super) fn nearest(
    d: &Detection,
    to: &[&Detection],
    shift: [f64; 2],
    gate: f64,
) -> Option<usize> {
    to.iter()
        .enumerate()
        .filter(|(_, b)| b.class == d.class)
        .map(|(j, b)| (j, dist2(d, b, shift)))
        .filter(|(_, d2)| *d2 <= gate * gate)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(j, _)| j)
}

pub(super) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Step 2 without an estimate: the shift most candidate pairs agree on. Every same-class pair
/// within `gate_m` votes for its offset in cells of `inlier_m / 2`; the cell whose 3 x 3
/// neighbourhood holds most votes, weighted by the prior of a shift that large
/// (exp(-|c|^2 / (2 prior_shift^2))), wins, and the guess is the per-axis median of the offsets
/// within `inlier_m` of its centre. Pairs of different objects scatter their votes; the shared
/// objects' pile up. `None` with fewer than `min_matches`.
pub(super) fn vote(mine: &[&Detection], theirs: &[&Detection], p: &AlignParams) -> Option<Rigid> {
    let cell = p.inlier_m / 2.0;
    let mut offsets = Vec::new();
    for a in mine {
        for b in theirs.iter().filter(|b| b.class == a.class) {
            let o = [b.center[0] - a.center[0], b.center[1] - a.center[1]];
            if o[0].hypot(o[1]) <= p.gate_m {
                offsets.push(o);
            }
        }
    }
    let key = |o: &[f64; 2]| ((o[0] / cell).round() as i64, (o[1] / cell).round() as i64);
    let mut votes: HashMap<(i64, i64), usize> = HashMap::new();
    for o in &offsets {
        *votes.entry(key(o)).or_default() += 1;
    }
    let around = |(x, y): (i64, i64)| -> usize {
        (-1..=1)
            .flat_map(|dx| (-1..=1).map(move |dy| (x + dx, y + dy)))
            .filter_map(|k| votes.get(&k))
            .sum()
    };
    // votes weighted by the prior of the shift, so that pairs of different objects that happen to
    // agree far from no shift do not outvote the few shared objects near it
    let prior = |(x, y): (i64, i64)| {
        let d2 = ((x * x + y * y) as f64) * cell * cell;
        (-d2 / (2.0 * p.prior_shift_m.powi(2))).exp()
    };
    let best = votes
        .keys()
        .map(|&k| (around(k) as f64 * prior(k), k))
        .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)))?
        .1;
    let centre = [best.0 as f64 * cell, best.1 as f64 * cell];
    let near: Vec<&[f64; 2]> = offsets
        .iter()
        .filter(|o| (o[0] - centre[0]).hypot(o[1] - centre[1]) <= p.inlier_m)
        .collect();
    (near.len() >= p.min_matches).then(|| Rigid {
        from: [0.0; 2],
        to: [
            median(near.iter().map(|o| o[0]).collect()),
            median(near.iter().map(|o| o[1]).collect()),
        ],
        theta: 0.0,
        matches: near.len(),
    })
}

/// A match: the point in the agent's frame, the reference's point, the weight.
type Pair = ([f64; 2], [f64; 2], f64);

/// Weighted 2D Procrustes of pairs (a, b, w) (step 4): the rigid motion taking the a's onto
/// the b's about the a's weighted centroid.
pub(super) fn procrustes(pairs: &[Pair]) -> Rigid {
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

/// One window's measurement: the motion about the matches' centroid and its covariance over
/// (t_x, t_y, theta) (step 6).
#[derive(Copy, Clone, Debug, PartialEq)]
pub(super) struct Measurement {
    pub(super) motion: Rigid,
    pub(super) cov: Matrix3<f64>,
}

/// The Procrustes solution over `pairs` with its covariance, or `None` with fewer than
/// `min_matches`.
pub(super) fn measure(pairs: &[Pair], p: &AlignParams) -> Option<Measurement> {
    if pairs.len() < p.min_matches.max(2) {
        return None;
    }
    let motion = procrustes(pairs);
    let w: f64 = pairs.iter().map(|q| q.2).sum();
    let (mut spread, mut chi2) = (0.0, 0.0);
    for (a, b, wi) in pairs {
        let (dx, dy) = (a[0] - motion.from[0], a[1] - motion.from[1]);
        spread += wi * (dx * dx + dy * dy);
        let q = motion.apply_point(*a);
        chi2 += wi * ((q[0] - b[0]).powi(2) + (q[1] - b[1]).powi(2));
    }
    let dof = (2 * pairs.len()).saturating_sub(3).max(1) as f64;
    let k = (chi2 / dof).max(1.0);
    // matches all at one point say nothing of the turn: the prior's width, as unknown
    let turn_var = if spread > 0.0 {
        k / spread
    } else {
        p.prior_turn_rad.powi(2)
    };
    let cov = Matrix3::from_diagonal(&Vector3::new(k / w, k / w, turn_var));
    Some(Measurement { motion, cov })
}

/// Estimates the rigid motion taking `agent`'s boxes onto `reference`'s from one window, or
/// `None` with too few matches (no filter, no significance test).
pub fn estimate(agent: &[Detection], reference: &[&Detection], p: &AlignParams) -> Option<Rigid> {
    measure(&window_matches(agent, reference, None, p), p).map(|m| m.motion)
}

/// One window's matches (steps 1-5), starting from `guess` when there is one and from the
/// median shift otherwise; empty when too few.
pub(super) fn window_matches(
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
        None => match vote(&mine, &theirs, p) {
            Some(g) => g,
            None => return Vec::new(),
        },
    };
    // 3 and 4: match under the guess, solve; 5: match under that solution, keep residuals
    // within 3 combined stds.
    match measure(&matches(&mine, &theirs, &guess, p, f64::INFINITY), p) {
        Some(first) => matches(&mine, &theirs, &first.motion, p, 3.0),
        None => Vec::new(),
    }
}

/// Mutual nearest same-class neighbours once `agent`'s boxes are moved by `by`, within
/// `inlier_m` and within `sigmas` combined stds: (moved-from point, reference point, weight).
pub(super) fn matches(
    mine: &[&Detection],
    theirs: &[&Detection],
    by: &Rigid,
    p: &AlignParams,
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
        let Some(j) = nearest(d, theirs, [0.0; 2], p.inlier_m) else {
            continue;
        };
        if nearest(theirs[j], &moved_refs, [0.0; 2], p.inlier_m) != Some(i) {
            continue;
        }
        // x-y variances of both boxes and the disagreement on each axis
        let var = variance(d) + variance(theirs[j]) + 2.0 * p.disagreement_m.powi(2);
        if dist2(d, theirs[j], [0.0; 2]) > sigmas * sigmas * var {
            continue;
        }
        out.push((
            [mine[i].center[0], mine[i].center[1]],
            [theirs[j].center[0], theirs[j].center[1]],
            // per axis
            2.0 / var,
        ));
    }
    out
}
