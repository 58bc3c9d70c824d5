//! CSBA-3D: cost-based association of two lists of 3D detections (paper §3.2, `docs/method.md` §1).
//!
//! For a pair (a, b) of the same class the method scores
//! - the **dimension score** DS from the volume ratio and its propagated uncertainty,
//! - the **centre score** CS from the Mahalanobis distance of the centres,
//! - the **orientation score** OS from the yaws and their stds,
//!
//! combines them into the weighted cost C, gates (same class, CS > 0 and, with a velocity gate,
//! velocities that agree), and solves the rectangular minimum-cost assignment. Unmatched
//! detections stay unmatched: the caller keeps them. The solve is split into independent
//! connected components of the gated pair graph, so well-separated scenes cost near-linear time;
//! a component is solved exactly with a Jonker-Volgenant shortest-augmenting-path solver (the
//! scipy algorithm).

use v2x_protocol::{wrap_angle, Class, Detection};

pub use candidates::eligible_pairs;
use candidates::eligible_pairs_into;

mod assignment;
pub use assignment::{assign, bounds_applied, Edge, MAX_CANDIDATES, MAX_EXACT_CELLS};
#[cfg(test)]
use assignment::{assign_dense, assign_with, Kept};
use assignment::{count_bound, EDGES};

/// How the centre-score scale lambda_max is chosen.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Gate {
    /// The paper's: lambda_max = `factor` x the position std (m) of the noisier detection.
    Paper {
        /// The multiplier (6 in the paper).
        factor: f64,
    },
    /// Scale-consistent: lambda_max is a fixed Mahalanobis distance (unitless), e.g. a
    /// chi-square quantile with 3 degrees of freedom.
    Mahalanobis {
        /// The gate on the Mahalanobis distance.
        lambda: f64,
    },
}

/// Which orientation score to use.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Orientation {
    /// The paper's: alpha = theta / sigma; OS = (1 + cos(alpha_a - alpha_b)) / 2.
    Paper,
    /// Wrapped Gaussian: d = wrap(theta_a - theta_b) (period pi for barriers);
    /// OS = exp(-d^2 / (2 (sa^2 + sb^2))).
    Wrapped,
}

/// Which dimension score to use.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Dimension {
    /// The paper's volume-ratio form (not symmetric in a and b).
    Paper,
    /// The log volume ratio, symmetric in a and b.
    LogRatio,
    /// Per-axis Gaussian on (l, w, h): Z^2 = sum_k (a_k - b_k)^2 / (s_a,k^2 + s_b,k^2).
    Axes,
}

/// How the centre score depends on the Mahalanobis distance.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Centre {
    /// The paper's: CS = 1 - d_M / lambda_max.
    Linear,
    /// Gaussian likelihood: CS = exp(-d_M^2 / 2) inside the gate d_M < lambda_max.
    Gaussian,
}

/// How the three scores combine into a cost.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Combine {
    /// The paper's weighted mean of (1 - score).
    Sum,
    /// Weighted negative log of the scores: with Gaussian scores, a weighted log-likelihood.
    LogProduct,
}

/// Parameters of CSBA-3D.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct CsbaParams {
    /// Weights of (1 - DS), (1 - CS), (1 - OS): 0.2 / 0.5 / 0.3 by default.
    pub weights: [f64; 3],
    /// How lambda_max is chosen.
    pub gate: Gate,
    /// Which orientation score.
    pub orientation: Orientation,
    /// Which dimension score.
    pub dimension: Dimension,
    /// Which centre score.
    pub centre: Centre,
    /// How scores combine.
    pub combine: Combine,
    /// The consistency test of a new member against its group (`docs/method.md` §2.1): the
    /// chi-square bound on the squared Mahalanobis distance of the member's centre to the
    /// group's fused centre; a member beyond it starts a group of its own. `None`: no test.
    pub consistency: Option<f64>,
    /// The velocity gate (`docs/method.md` §1): the bound on the squared Mahalanobis distance
    /// of a pair's velocities, when both boxes have one; a pair beyond it is not eligible.
    /// `None`: velocities are not compared.
    pub velocity_gate: Option<f64>,
}

impl CsbaParams {
    /// The method exactly as the paper prints it.
    pub const PAPER: CsbaParams = CsbaParams {
        weights: [0.2, 0.5, 0.3],
        gate: Gate::Paper { factor: 6.0 },
        orientation: Orientation::Paper,
        dimension: Dimension::Paper,
        centre: Centre::Linear,
        combine: Combine::Sum,
        consistency: None,
        velocity_gate: None,
    };
    /// The improved variant `csba-wls+`: a scale-consistent gate, the wrapped orientation
    /// score and the symmetric dimension score (docs/results.md, "The method, and csba-wls+").
    pub const PLUS: CsbaParams = CsbaParams {
        weights: [0.2, 0.5, 0.3],
        gate: Gate::Mahalanobis {
            lambda: MAHALANOBIS_GATE,
        },
        orientation: Orientation::Wrapped,
        dimension: Dimension::LogRatio,
        centre: Centre::Gaussian,
        combine: Combine::LogProduct,
        consistency: None,
        velocity_gate: None,
    };
}

impl Default for CsbaParams {
    fn default() -> Self {
        CsbaParams::PAPER
    }
}

/// The gate of `csba-wls+` on the (unitless) Mahalanobis distance: the paper's factor 6 read in
/// standard deviations. A true pair's 3D distance (chi, 3 degrees of freedom) exceeds it about
/// once in 13 million, where the paper's 6 x sigma gate rejects 2.9% of true pairs at mild noise.
pub const MAHALANOBIS_GATE: f64 = 6.0;

/// The 99.9% quantile of the chi-square distribution with 3 degrees of freedom: a consistent
/// member's squared centre distance to its group exceeds it once in a thousand.
pub const CHI2_3_999: f64 = 16.266;

/// The 99.9% quantile of the chi-square distribution with 2 degrees of freedom (-2 ln 0.001): a
/// true pair's squared velocity distance exceeds it once in a thousand.
pub const CHI2_2_999: f64 = 13.816;

// ---------------------------------------------------------------------------------------------
// The three scores
// ---------------------------------------------------------------------------------------------

/// Volume V = l w h and its std sigma_V = V sqrt((sl/l)^2 + (sw/w)^2 + (sh/h)^2).
pub fn volume_with_std(d: &Detection) -> (f64, f64) {
    let [l, w, h] = d.size;
    let [sl, sw, sh] = d.std.size;
    let v = l * w * h;
    (
        v,
        v * ((sl / l).powi(2) + (sw / w).powi(2) + (sh / h).powi(2)).sqrt(),
    )
}

/// Dimension score DS = exp(-min(Z_r^2, Z_inv^2) / 2), with r = Va / Vb,
/// sigma_r = r sqrt((sVa/Va)^2 + (sVb/Vb)^2), Z_r = (r - 1)/sigma_r, Z_inv = (1/r - 1)/sigma_r.
pub fn dimension_score(a: &Detection, b: &Detection) -> f64 {
    let (va, sva) = volume_with_std(a);
    let (vb, svb) = volume_with_std(b);
    let r = va / vb;
    let sigma_r = r * ((sva / va).powi(2) + (svb / vb).powi(2)).sqrt();
    let z_r = (r - 1.0) / sigma_r;
    let z_inv = (1.0 / r - 1.0) / sigma_r;
    (-(z_r * z_r).min(z_inv * z_inv) / 2.0).exp()
}

/// **[ours]** Symmetric dimension score on the log volume ratio:
/// Z = ln(Va / Vb) / sqrt((sVa/Va)^2 + (sVb/Vb)^2), DS = exp(-Z^2 / 2).
pub fn dimension_score_log(a: &Detection, b: &Detection) -> f64 {
    let (va, sva) = volume_with_std(a);
    let (vb, svb) = volume_with_std(b);
    let z = (va / vb).ln() / ((sva / va).powi(2) + (svb / vb).powi(2)).sqrt();
    (-z * z / 2.0).exp()
}

/// **[ours]** Per-axis size score: DS = exp(-Z^2 / 2), Z^2 = sum_k (a_k - b_k)^2 / (s_a,k^2 + s_b,k^2).
pub fn dimension_score_axes(a: &Detection, b: &Detection) -> f64 {
    let z2: f64 = (0..3)
        .map(|k| (a.size[k] - b.size[k]).powi(2) / (a.std.size[k].powi(2) + b.std.size[k].powi(2)))
        .sum();
    (-z2 / 2.0).exp()
}

/// Inverse of a symmetric positive-definite 3x3 matrix (None if singular).
fn inverse3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let m = nalgebra::Matrix3::from_fn(|i, j| m[i][j]);
    let inv = m.try_inverse()?;
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| inv[(i, j)])
    }))
}

/// Mahalanobis distance d_M = sqrt(dp^T (Sa + Sb)^-1 dp) of the two centres.
pub fn mahalanobis(a: &Detection, b: &Detection) -> f64 {
    let dp: [f64; 3] = std::array::from_fn(|k| a.center[k] - b.center[k]);
    if a.pos_cov.is_none() && b.pos_cov.is_none() {
        // Diagonal covariances: the common case, no inverse needed.
        return (0..3)
            .map(|k| dp[k] * dp[k] / (a.std.pos[k].powi(2) + b.std.pos[k].powi(2)))
            .sum::<f64>()
            .sqrt();
    }
    let (ca, cb) = (a.position_covariance(), b.position_covariance());
    let s: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| ca[i][j] + cb[i][j]));
    match inverse3(&s) {
        Some(inv) => (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| dp[i] * inv[i][j] * dp[j])
            .sum::<f64>()
            .max(0.0)
            .sqrt(),
        None => f64::INFINITY,
    }
}

/// Squared Mahalanobis distance d^T S^-1 d of an offset `d` in the plane (x, y) under its
/// covariance `s`, or `None` when `s` is singular.
pub fn mahalanobis2_plane([dx, dy]: [f64; 2], s: [[f64; 2]; 2]) -> Option<f64> {
    let (sxx, sxy, syy) = (s[0][0], s[0][1], s[1][1]);
    let det = sxx * syy - sxy * sxy;
    (det > 0.0).then(|| (syy * dx * dx - 2.0 * sxy * dx * dy + sxx * dy * dy) / det)
}

/// Position std (m) of a detection: the root mean of its three centre variances.
pub fn position_std(d: &Detection) -> f64 {
    let c = d.position_covariance();
    ((c[0][0] + c[1][1] + c[2][2]) / 3.0).sqrt()
}

/// How spread the boxes' centres are stated to be, gathered one box at a time, for
/// [`Spread::x_reach`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Spread {
    /// The largest x variance.
    var_x: f64,
    /// The largest trace of a centre's covariance (position_std's, squared and tripled).
    trace: f64,
    /// Whether a box has a full covariance.
    full: bool,
}

impl Spread {
    /// Takes in one box.
    pub fn add(&mut self, d: &Detection) {
        let [x, y, z] = d.std.pos.map(|s| s * s);
        self.var_x = self.var_x.max(x);
        self.trace = self.trace.max(x + y + z);
        self.full |= d.pos_cov.is_some();
    }

    /// The boxes of both taken in.
    pub fn merge(self, other: &Spread) -> Spread {
        Spread {
            var_x: self.var_x.max(other.var_x),
            trace: self.trace.max(other.trace),
            full: self.full || other.full,
        }
    }

    /// The farthest apart along x two of the boxes taken in, or boxes WLS-3D fused from them,
    /// can lie and still be eligible: lambda_max sqrt(Sa_xx + Sb_xx) at its largest, since
    /// fusing only shrinks the variances and keeps a centre within its members' span. `None`
    /// when a box has a full covariance (a fused centre may then leave its members' span) or the
    /// bound is not finite.
    pub fn x_reach(&self, p: &CsbaParams) -> Option<f64> {
        if self.full {
            return None;
        }
        let lambda = match p.gate {
            Gate::Paper { factor } => factor * (self.trace / 3.0).sqrt(),
            Gate::Mahalanobis { lambda } => lambda,
        };
        let reach = lambda * (2.0 * self.var_x).sqrt();
        (reach.is_finite() && reach >= 0.0).then_some(reach)
    }
}

/// lambda_max for a pair under the chosen gate.
pub fn lambda_max(gate: Gate, a: &Detection, b: &Detection) -> f64 {
    match gate {
        Gate::Paper { factor } => factor * position_std(a).max(position_std(b)),
        Gate::Mahalanobis { lambda } => lambda,
    }
}

/// Centre score CS = 1 - d_M / lambda_max, clamped to [0, 1].
pub fn centre_score(d_m: f64, lambda_max: f64) -> f64 {
    (1.0 - d_m / lambda_max).clamp(0.0, 1.0)
}

/// Orientation score in the chosen form.
pub fn orientation_score(form: Orientation, a: &Detection, b: &Detection) -> f64 {
    match form {
        Orientation::Paper => {
            let alpha_a = a.yaw / a.std.yaw;
            let alpha_b = b.yaw / b.std.yaw;
            (1.0 + (alpha_a - alpha_b).cos()) / 2.0
        }
        Orientation::Wrapped => {
            let d = yaw_difference(a.class, a.yaw, b.yaw);
            (-d * d / (2.0 * (a.std.yaw.powi(2) + b.std.yaw.powi(2)))).exp()
        }
    }
}

/// Squared Mahalanobis distance of two boxes' velocities,
/// sum_k (v_a,k - v_b,k)^2 / (s_a,k^2 + s_b,k^2); `None` unless both have one.
pub fn velocity_distance2(a: &Detection, b: &Detection) -> Option<f64> {
    let (va, vb) = (a.velocity.as_ref()?, b.velocity.as_ref()?);
    Some(
        (0..2)
            .map(|k| (va.v[k] - vb.v[k]).powi(2) / (va.std[k].powi(2) + vb.std[k].powi(2)))
            .sum(),
    )
}

/// Smallest absolute yaw difference, with period pi for barriers and 2 pi otherwise.
pub fn yaw_difference(class: Class, ya: f64, yb: f64) -> f64 {
    let d = wrap_angle(ya - yb).abs();
    if class == Class::Barrier {
        d.min(std::f64::consts::PI - d)
    } else {
        d
    }
}

/// [`yaw_difference`] for yaws near (-pi, pi] (as validated boxes carry): their difference
/// needs at most one turn added or taken, without a division.
fn yaw_difference_near(class: Class, ya: f64, yb: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let d = ya - yb;
    let d = if d > PI {
        d - TAU
    } else if d <= -PI {
        d + TAU
    } else {
        d
    };
    if !(d > -PI && d <= PI) {
        return yaw_difference(class, ya, yb);
    }
    let d = d.abs();
    if class == Class::Barrier {
        d.min(PI - d)
    } else {
        d
    }
}

/// The weighted cost C = (w_ds (1-DS) + w_cs (1-CS) + w_os (1-OS)) / (w_ds + w_cs + w_os).
pub fn cost(weights: [f64; 3], ds: f64, cs: f64, os: f64) -> f64 {
    let [w_ds, w_cs, w_os] = weights;
    (w_ds * (1.0 - ds) + w_cs * (1.0 - cs) + w_os * (1.0 - os)) / (w_ds + w_cs + w_os)
}

/// The cost of a pair, or `None` when the gate rejects it (classes differ or CS = 0).
pub fn pair_cost(p: &CsbaParams, a: &Detection, b: &Detection) -> Option<f64> {
    prepared_cost(p, a, &Prepared::of(p, a), b, &Prepared::of(p, b))
}

/// **[ours]** C = -(w_ds ln DS + w_cs ln CS + w_os ln OS) / (w_ds + w_cs + w_os).
pub fn log_cost(weights: [f64; 3], ds: f64, cs: f64, os: f64) -> f64 {
    let [w_ds, w_cs, w_os] = weights;
    let ln = |s: f64| s.max(1e-300).ln();
    -(w_ds * ln(ds) + w_cs * ln(cs) + w_os * ln(os)) / (w_ds + w_cs + w_os)
}

/// What every pair of a detection needs, computed once per detection: [`pair_cost`] over
/// prepared detections gives the same bits without recomputing them per pair, and reads the
/// detection itself only for a full covariance or the per-axis size score.
#[derive(Copy, Clone, Debug)]
struct Prepared {
    class: Class,
    center: [f64; 3],
    yaw: f64,
    /// The yaw's std.
    yaw_std: f64,
    /// cos and sin of the paper's orientation angle alpha = yaw / its std (the paper's
    /// orientation score only).
    alpha: (f64, f64),
    /// The centre variances when the covariance is diagonal (`pos_cov` absent).
    var: Option<[f64; 3]>,
    /// [`position_std`].
    pos_std: f64,
    /// [`volume_with_std`].
    volume: (f64, f64),
    /// ln V and (sigma_V / V)^2, the log-ratio dimension score's terms (that score only).
    ln_volume: (f64, f64),
}

impl Prepared {
    fn of(p: &CsbaParams, d: &Detection) -> Self {
        let volume = volume_with_std(d);
        Prepared {
            class: d.class,
            center: d.center,
            yaw: d.yaw,
            yaw_std: d.std.yaw,
            alpha: match p.orientation {
                Orientation::Paper => {
                    let (sin, cos) = (d.yaw / d.std.yaw).sin_cos();
                    (cos, sin)
                }
                Orientation::Wrapped => (1.0, 0.0),
            },
            var: d.pos_cov.is_none().then(|| d.std.pos.map(|s| s.powi(2))),
            pos_std: position_std(d),
            volume,
            ln_volume: match p.dimension {
                Dimension::LogRatio => {
                    let (v, sv) = volume;
                    (v.ln(), (sv / v).powi(2))
                }
                Dimension::Paper | Dimension::Axes => (0.0, 0.0),
            },
        }
    }
}

/// A score, held as its value or as its logarithm (a Gaussian score's exponent), so that the
/// log-product cost never takes the logarithm of an exponential.
#[derive(Copy, Clone, Debug)]
enum Score {
    Value(f64),
    Ln(f64),
}

impl Score {
    fn value(self) -> f64 {
        match self {
            Score::Value(v) => v,
            Score::Ln(l) => l.exp(),
        }
    }

    /// ln of the score, floored at ln(1e-300) as [`log_cost`] floors the score.
    fn ln(self) -> f64 {
        match self {
            Score::Value(v) => v.max(1e-300).ln(),
            Score::Ln(l) => l.max(LN_FLOOR),
        }
    }
}

/// ln(1e-300).
const LN_FLOOR: f64 = -690.7755278982137;

/// [`pair_cost`] with each side's [`Prepared`] quantities.
#[inline(always)]
fn prepared_cost(
    p: &CsbaParams,
    a: &Detection,
    pa: &Prepared,
    b: &Detection,
    pb: &Prepared,
) -> Option<f64> {
    if pa.class != pb.class {
        return None;
    }
    // d_M^2: the gate and the Gaussian centre score need no square root.
    let d2 = match (pa.var, pb.var) {
        (Some(va), Some(vb)) => (0..3)
            .map(|k| (pa.center[k] - pb.center[k]).powi(2) / (va[k] + vb[k]))
            .sum::<f64>(),
        _ => mahalanobis(a, b).powi(2),
    };
    let lambda = match p.gate {
        Gate::Paper { factor } => factor * pa.pos_std.max(pb.pos_std),
        Gate::Mahalanobis { lambda } => lambda,
    };
    // CS > 0 exactly when d_M < lambda_max.
    if !(d2 < lambda * lambda) {
        return None;
    }
    if let Some(gate) = p.velocity_gate {
        // A pair whose velocities disagree beyond the gate is two objects, however close.
        if velocity_distance2(a, b).is_some_and(|dv2| !(dv2 <= gate)) {
            return None;
        }
    }
    // CS, DS, OS as in centre_score, dimension_score*, orientation_score
    let cs = match p.centre {
        Centre::Linear => {
            let cs = centre_score(d2.sqrt(), lambda);
            if cs <= 0.0 {
                return None;
            }
            Score::Value(cs)
        }
        Centre::Gaussian => Score::Ln(-d2 / 2.0),
    };
    let ((va, sva), (vb, svb)) = (pa.volume, pb.volume);
    let ds = match p.dimension {
        Dimension::Paper => {
            let r = va / vb;
            let sigma_r = r * ((sva / va).powi(2) + (svb / vb).powi(2)).sqrt();
            let z_r = (r - 1.0) / sigma_r;
            let z_inv = (1.0 / r - 1.0) / sigma_r;
            Score::Ln(-(z_r * z_r).min(z_inv * z_inv) / 2.0)
        }
        Dimension::LogRatio => {
            let ((la, ra), (lb, rb)) = (pa.ln_volume, pb.ln_volume);
            Score::Ln(-(la - lb).powi(2) / (ra + rb) / 2.0)
        }
        Dimension::Axes => Score::Value(dimension_score_axes(a, b)),
    };
    let os = match p.orientation {
        Orientation::Paper => {
            // cos(alpha_a - alpha_b) from each side's cos and sin
            let cos = pa.alpha.0 * pb.alpha.0 + pa.alpha.1 * pb.alpha.1;
            Score::Value((1.0 + cos) / 2.0)
        }
        Orientation::Wrapped => {
            let d = yaw_difference_near(pa.class, pa.yaw, pb.yaw);
            Score::Ln(-d * d / (2.0 * (pa.yaw_std.powi(2) + pb.yaw_std.powi(2))))
        }
    };
    let c = match p.combine {
        Combine::Sum => cost(p.weights, ds.value(), cs.value(), os.value()),
        Combine::LogProduct => {
            let [w_ds, w_cs, w_os] = p.weights;
            -(w_ds * ds.ln() + w_cs * cs.ln() + w_os * os.ln()) / (w_ds + w_cs + w_os)
        }
    };
    // Validated inputs always give a finite cost; anything else is not a usable pair.
    c.is_finite().then_some(c)
}

/// CSBA-3D on two lists: the matched (index in `a`, index in `b`) pairs.
pub fn associate<A, B>(p: &CsbaParams, a: &[A], b: &[B]) -> Vec<(usize, usize)>
where
    A: std::borrow::Borrow<Detection>,
    B: std::borrow::Borrow<Detection>,
{
    EDGES.with_borrow_mut(|edges| {
        eligible_pairs_into(p, a, b, edges);
        let pairs = assign(a.len(), b.len(), edges);
        sparse::trim(edges);
        pairs
    })
}

mod candidates;
mod components;
mod sparse;
#[cfg(test)]
mod tests;
