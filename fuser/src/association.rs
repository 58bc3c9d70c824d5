//! CSBA-3D: cost-based association of two lists of 3D detections (paper §3.2, `docs/method.md` §1).
//!
//! For a pair (a, b) of the same class the method scores
//! - the **dimension score** DS from the volume ratio and its propagated uncertainty,
//! - the **centre score** CS from the Mahalanobis distance of the centres,
//! - the **orientation score** OS from the yaws and their stds,
//!
//! combines them into the weighted cost C, gates (same class and CS > 0), and solves the
//! rectangular minimum-cost assignment. Unmatched detections stay unmatched: the caller keeps
//! them. The solve is split into independent connected components of the gated pair graph, so
//! well-separated scenes cost near-linear time; a component is solved exactly with a
//! Jonker-Volgenant shortest-augmenting-path solver (the scipy algorithm).

use v2x_protocol::{wrap_angle, Class, Detection};

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
    };
    /// The improved variant `csba-wls+`: a scale-consistent gate, the wrapped orientation
    /// score and the symmetric dimension score (README, "csba-wls+").
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

/// Position std (m) of a detection: the root mean of its three centre variances.
pub fn position_std(d: &Detection) -> f64 {
    let c = d.position_covariance();
    ((c[0][0] + c[1][1] + c[2][2]) / 3.0).sqrt()
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

/// Smallest absolute yaw difference, with period pi for barriers and 2 pi otherwise.
pub fn yaw_difference(class: Class, ya: f64, yb: f64) -> f64 {
    let d = wrap_angle(ya - yb).abs();
    if class == Class::Barrier {
        d.min(std::f64::consts::PI - d)
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
    prepared_cost(p, a, &Prepared::of(a), b, &Prepared::of(b))
}

/// **[ours]** C = -(w_ds ln DS + w_cs ln CS + w_os ln OS) / (w_ds + w_cs + w_os).
pub fn log_cost(weights: [f64; 3], ds: f64, cs: f64, os: f64) -> f64 {
    let [w_ds, w_cs, w_os] = weights;
    let ln = |s: f64| s.max(1e-300).ln();
    -(w_ds * ln(ds) + w_cs * ln(cs) + w_os * ln(os)) / (w_ds + w_cs + w_os)
}

/// What every pair of a detection needs, computed once per detection: [`pair_cost`] over
/// prepared detections gives the same bits without recomputing them per pair.
#[derive(Copy, Clone, Debug)]
struct Prepared {
    /// The centre variances when the covariance is diagonal (`pos_cov` absent).
    var: Option<[f64; 3]>,
    /// [`position_std`].
    pos_std: f64,
    /// [`volume_with_std`].
    volume: (f64, f64),
}

impl Prepared {
    fn of(d: &Detection) -> Self {
        Prepared {
            var: d.pos_cov.is_none().then(|| d.std.pos.map(|s| s.powi(2))),
            pos_std: position_std(d),
            volume: volume_with_std(d),
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
fn prepared_cost(
    p: &CsbaParams,
    a: &Detection,
    pa: &Prepared,
    b: &Detection,
    pb: &Prepared,
) -> Option<f64> {
    if a.class != b.class {
        return None;
    }
    let d_m = match (pa.var, pb.var) {
        (Some(va), Some(vb)) => (0..3)
            .map(|k| (a.center[k] - b.center[k]).powi(2) / (va[k] + vb[k]))
            .sum::<f64>()
            .sqrt(),
        _ => mahalanobis(a, b),
    };
    let lambda = match p.gate {
        Gate::Paper { factor } => factor * pa.pos_std.max(pb.pos_std),
        Gate::Mahalanobis { lambda } => lambda,
    };
    let cs = centre_score(d_m, lambda);
    if cs <= 0.0 {
        return None;
    }
    // CS, DS, OS as in centre_score, dimension_score*, orientation_score
    let cs = match p.centre {
        Centre::Linear => Score::Value(cs),
        Centre::Gaussian => Score::Ln(-d_m * d_m / 2.0),
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
            let z = (va / vb).ln() / ((sva / va).powi(2) + (svb / vb).powi(2)).sqrt();
            Score::Ln(-z * z / 2.0)
        }
        Dimension::Axes => Score::Value(dimension_score_axes(a, b)),
    };
    let os = match p.orientation {
        Orientation::Paper => Score::Value(orientation_score(p.orientation, a, b)),
        Orientation::Wrapped => {
            let d = yaw_difference(a.class, a.yaw, b.yaw);
            Score::Ln(-d * d / (2.0 * (a.std.yaw.powi(2) + b.std.yaw.powi(2))))
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

// ---------------------------------------------------------------------------------------------
// Gating and assignment
// ---------------------------------------------------------------------------------------------

/// An eligible pair: indices into the two lists and its cost.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Edge {
    /// Index in the first list.
    pub a: usize,
    /// Index in the second list.
    pub b: usize,
    /// The pair's cost.
    pub cost: f64,
}

/// The most eligible partners kept per detection of the first list (the cheapest). Honest scenes
/// stay far below it even with the paper's wide gate; it bounds memory and time when boxes are
/// piled up (thousands of co-located boxes), where the association is no longer exact.
pub const MAX_CANDIDATES: usize = 128;
/// The largest component (rows x columns) solved exactly; a larger one is matched greedily by
/// cost, which bounds the time a pile of boxes can take.
pub const MAX_EXACT_CELLS: usize = 1 << 20;

static CAPPED_ROWS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
static GREEDY_COMPONENTS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// How often, in this process so far, the bounds above applied: (detections whose candidates
/// were capped, components matched greedily).
pub fn bounds_applied() -> (u64, u64) {
    use std::sync::atomic::Ordering::Relaxed;
    (CAPPED_ROWS.load(Relaxed), GREEDY_COMPONENTS.load(Relaxed))
}

/// Detections bucketed on a square grid over their bounding box (x, y), cells at least a given
/// width: a point's own and neighbouring cells hold everything within that width of it.
struct Grid {
    origin: [f64; 2],
    cell: f64,
    n: [usize; 2],
    /// Cell k's detections: `items[start[k]..start[k + 1]]`.
    start: Vec<usize>,
    items: Vec<usize>,
}

impl Grid {
    /// The grid of `dets` with cells at least `min_cell` wide, widened if need be so that
    /// there are at most about four cells per detection (far-flung input stays small).
    fn of(dets: &[Detection], min_cell: f64) -> Option<Grid> {
        if dets.is_empty() || !(min_cell.is_finite() && min_cell > 0.0) {
            return None;
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for d in dets {
            for k in 0..2 {
                lo[k] = lo[k].min(d.center[k]);
                hi[k] = hi[k].max(d.center[k]);
            }
        }
        let budget = (4 * dets.len() + 64) as f64;
        let mut cell = min_cell;
        let cells = |cell: f64| ((hi[0] - lo[0]) / cell + 1.0) * ((hi[1] - lo[1]) / cell + 1.0);
        if cells(cell) > budget {
            cell *= (cells(cell) / budget).sqrt();
        }
        while cells(cell) > budget {
            cell *= 1.5;
        }
        let n = [0, 1].map(|k| ((hi[k] - lo[k]) / cell) as usize + 1);
        let mut grid = Grid {
            origin: lo,
            cell,
            n,
            start: vec![0; n[0] * n[1] + 1],
            items: vec![0; dets.len()],
        };
        let keys: Vec<usize> = dets.iter().map(|d| grid.key(d.center)).collect();
        for &k in &keys {
            grid.start[k + 1] += 1;
        }
        for k in 0..n[0] * n[1] {
            grid.start[k + 1] += grid.start[k];
        }
        let mut fill = grid.start.clone();
        for (i, &k) in keys.iter().enumerate() {
            grid.items[fill[k]] = i;
            fill[k] += 1;
        }
        Some(grid)
    }

    /// The cell column and row of a point, clamped to the grid.
    fn index(&self, p: [f64; 3]) -> [usize; 2] {
        [0, 1].map(|k| (((p[k] - self.origin[k]) / self.cell).max(0.0) as usize).min(self.n[k] - 1))
    }

    fn key(&self, p: [f64; 3]) -> usize {
        let [i, j] = self.index(p);
        i * self.n[1] + j
    }

    /// Every detection in the point's cell and the eight around it.
    fn near(&self, p: [f64; 3]) -> impl Iterator<Item = usize> + '_ {
        let [i, j] = self.index(p);
        let rows = i.saturating_sub(1)..=(i + 1).min(self.n[0] - 1);
        rows.flat_map(move |i| {
            let lo = i * self.n[1] + j.saturating_sub(1);
            let hi = i * self.n[1] + (j + 1).min(self.n[1] - 1);
            self.items[self.start[lo]..self.start[hi + 1]]
                .iter()
                .copied()
        })
    }
}

/// All eligible pairs (at most [`MAX_CANDIDATES`] per detection of `a`, the cheapest).
/// No eligible pair can exceed |dx| <= lambda_max sqrt(Sa_xx + Sb_xx), nor the same in y: `b` is
/// bucketed on a grid of cells at least that wide, each `a` looks at its own and the eight
/// neighbouring cells, and only pairs of its class within both bounds are scored exactly. At a
/// steady density the work per detection is constant however large the scene.
pub fn eligible_pairs(p: &CsbaParams, a: &[Detection], b: &[Detection]) -> Vec<Edge> {
    let mut edges = Vec::with_capacity(2 * a.len());
    if a.is_empty() || b.is_empty() {
        return edges;
    }
    let max_var_b = |k: usize| {
        b.iter()
            .map(|d| d.position_covariance()[k][k])
            .fold(0.0, f64::max)
    };
    let (max_var_x_b, max_var_y_b) = (max_var_b(0), max_var_b(1));
    let prep_a: Vec<Prepared> = a.iter().map(Prepared::of).collect();
    let prep_b: Vec<Prepared> = b.iter().map(Prepared::of).collect();
    let max_std_b = prep_b.iter().map(|q| q.pos_std).fold(0.0, f64::max);
    // Per a: the largest |dx| and |dy| an eligible partner can have.
    let radii: Vec<[f64; 2]> = a
        .iter()
        .zip(&prep_a)
        .map(|(da, pa)| {
            let lambda_bound = match p.gate {
                Gate::Paper { factor } => factor * pa.pos_std.max(max_std_b),
                Gate::Mahalanobis { lambda } => lambda,
            };
            let c = da.position_covariance();
            [
                lambda_bound * (c[0][0] + max_var_x_b).sqrt(),
                lambda_bound * (c[1][1] + max_var_y_b).sqrt(),
            ]
        })
        .collect();
    let cell = radii.iter().map(|r| r[0].max(r[1])).fold(0.0, f64::max);
    let Some(grid) = Grid::of(b, cell) else {
        return edges;
    };
    for (ia, da) in a.iter().enumerate() {
        let [rx, ry] = radii[ia];
        let row_start = edges.len();
        for ib in grid.near(da.center) {
            let db = &b[ib];
            if db.class != da.class
                || (db.center[0] - da.center[0]).abs() > rx
                || (db.center[1] - da.center[1]).abs() > ry
            {
                continue;
            }
            if let Some(cost) = prepared_cost(p, da, &prep_a[ia], db, &prep_b[ib]) {
                edges.push(Edge { a: ia, b: ib, cost });
            }
        }
        let row = &mut edges[row_start..];
        if row.len() > MAX_CANDIDATES {
            row.select_nth_unstable_by(MAX_CANDIDATES, |x, y| {
                x.cost.total_cmp(&y.cost).then(x.b.cmp(&y.b))
            });
            edges.truncate(row_start + MAX_CANDIDATES);
            CAPPED_ROWS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    }
    edges
}

/// Minimum-cost assignment restricted to the given eligible edges: among the matchings of
/// largest size, the one of least total cost. Returns the matched (a, b) pairs sorted by a.
/// Solved exactly over the edges alone (`association/sparse.rs`); a component of more than
/// [`MAX_EXACT_CELLS`] possible pairs is matched greedily by cost.
pub fn assign(n_a: usize, n_b: usize, edges: &[Edge]) -> Vec<(usize, usize)> {
    if edges.is_empty() {
        return Vec::new();
    }
    // Connected components of the bipartite edge graph (union-find over a's then b's), each
    // with its a's, b's and largest cost.
    let mut parent: Vec<usize> = (0..n_a + n_b).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for e in edges {
        let (ra, rb) = (find(&mut parent, e.a), find(&mut parent, n_a + e.b));
        if ra != rb {
            parent[ra] = rb;
        }
    }
    let mut size = vec![(0usize, 0usize, 0.0f64); n_a + n_b];
    let mut seen = vec![false; n_a + n_b];
    for e in edges {
        let r = find(&mut parent, e.a);
        size[r].2 = size[r].2.max(e.cost);
        for (node, is_a) in [(e.a, true), (n_a + e.b, false)] {
            if !seen[node] {
                seen[node] = true;
                if is_a {
                    size[r].0 += 1;
                } else {
                    size[r].1 += 1;
                }
            }
        }
    }
    let too_big = |r: usize| size[r].0.saturating_mul(size[r].1) > MAX_EXACT_CELLS;
    let mut pairs = Vec::new();
    let mut exact: Vec<Edge> = Vec::new();
    let mut greedy_edges: Vec<Edge> = Vec::new();
    for e in edges {
        let r = find(&mut parent, e.a);
        if too_big(r) {
            greedy_edges.push(*e);
        } else {
            exact.push(*e);
        }
    }
    if !greedy_edges.is_empty() {
        GREEDY_COMPONENTS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        greedy(&greedy_edges, &mut pairs);
    }
    // Rows: the smaller side (one path search per row). Leaving a row unmatched costs more
    // than any set of its component's real edges: (min(rows, cols) + 1) x (largest + 1).
    let transpose = n_a > n_b;
    let (n_rows, n_cols) = if transpose { (n_b, n_a) } else { (n_a, n_b) };
    if transpose {
        for e in &mut exact {
            std::mem::swap(&mut e.a, &mut e.b);
        }
    }
    let unmatched: Vec<f64> = (0..n_rows)
        .map(|r| {
            let node = if transpose { n_a + r } else { r };
            let (na, nb, largest) = size[find(&mut parent, node)];
            (na.min(nb) + 1) as f64 * (largest + 1.0)
        })
        .collect();
    for (r, c) in sparse::solve(n_rows, n_cols, &exact, &unmatched) {
        pairs.push(if transpose { (c, r) } else { (r, c) });
    }
    pairs.sort_unstable();
    pairs
}

/// The dense solve of one component, kept as the reference the sparse solve is tested against:
/// rows are its a's, columns its b's, absent edges cost more than any complete set of present
/// ones (so the matching is as large as possible first).
#[cfg(test)]
fn assign_dense(n_a: usize, n_b: usize, edges: &[Edge]) -> Vec<(usize, usize)> {
    let _ = (n_a, n_b);
    let mut pairs = Vec::new();
    if !edges.is_empty() {
        solve_component(edges, &mut pairs);
    }
    pairs.sort_unstable();
    pairs
}

/// Solves edges densely: rows are their a's, columns their b's.
#[cfg(test)]
fn solve_component(comp: &[Edge], pairs: &mut Vec<(usize, usize)>) {
    let mut rows: Vec<usize> = comp.iter().map(|e| e.a).collect();
    let mut cols: Vec<usize> = comp.iter().map(|e| e.b).collect();
    rows.sort_unstable();
    rows.dedup();
    cols.sort_unstable();
    cols.dedup();
    let (nr, nc) = (rows.len(), cols.len());
    // (min(nr, nc) + 1) x (largest cost + 1) outweighs any set of present costs.
    let largest = comp.iter().map(|e| e.cost).fold(0.0, f64::max);
    let absent = (nr.min(nc) + 1) as f64 * (largest + 1.0);
    let mut m = vec![absent; nr * nc];
    for e in comp {
        // rows and cols hold every edge's ends, so both searches find them
        if let (Ok(r), Ok(c)) = (rows.binary_search(&e.a), cols.binary_search(&e.b)) {
            m[r * nc + c] = e.cost;
        }
    }
    match lsap::solve(nr, nc, &m, false) {
        Ok((rr, cc)) => {
            for (r, c) in rr.into_iter().zip(cc) {
                if m[r * nc + c] < absent {
                    pairs.push((rows[r], cols[c]));
                }
            }
        }
        // Finite costs always have an assignment; should the solver still refuse, match greedily
        // by cost rather than lose the component.
        Err(_) => greedy(comp, pairs),
    }
}

/// Greedy matching by increasing cost: each edge is taken when both its ends are free.
fn greedy(comp: &[Edge], pairs: &mut Vec<(usize, usize)>) {
    let mut order: Vec<&Edge> = comp.iter().collect();
    order.sort_by(|x, y| x.cost.total_cmp(&y.cost));
    let mut used_a = std::collections::HashSet::new();
    let mut used_b = std::collections::HashSet::new();
    for e in order {
        if !used_a.contains(&e.a) && !used_b.contains(&e.b) {
            used_a.insert(e.a);
            used_b.insert(e.b);
            pairs.push((e.a, e.b));
        }
    }
}

/// CSBA-3D on two lists: the matched (index in `a`, index in `b`) pairs.
pub fn associate(p: &CsbaParams, a: &[Detection], b: &[Detection]) -> Vec<(usize, usize)> {
    let edges = eligible_pairs(p, a, b);
    assign(a.len(), b.len(), &edges)
}

mod sparse;
#[cfg(test)]
mod tests;
