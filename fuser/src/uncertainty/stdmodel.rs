//! An agent's error model calibrated against ground truth (`v2x-sim calibrate`): the bias and
//! std of each field of its boxes per class and score bin, kept in a JSON file and applied to
//! its boxes before fusion (`--std-model AGENT=FILE`): the bias taken off, the stds replaced.
//!
//! From the errors e_n = box_n - truth_n of the N boxes of a cell (yaw wrapped to the class's
//! period, velocity where both have one):
//!
//! ```text
//! bias = mean e_n,   std = sqrt(sum (e_n - bias)^2 / (N - 1)),
//! 95% interval of the std: std sqrt((N - 1) / chi2_{0.975, N-1}) .. std sqrt((N - 1) / chi2_{0.025, N-1})
//! ```
//!
//! (chi-square quantiles from its CDF, the regularized incomplete gamma). A box takes its class's score
//! bin when that holds at least [`MIN_COUNT`] boxes, else its class's cell, else the cell of all
//! classes. Sans-IO: the model is read and written as text by the shells.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use v2x_protocol::limits::clamp_std;
use v2x_protocol::{wrap_angle, Class, Detection, Velocity};

/// The format tag of a model file.
pub const FORMAT: &str = "v2x-std-model/1";

/// Fewest boxes a cell needs to be used.
pub const MIN_COUNT: usize = 10;

/// Largest bias a model may state (m, rad, m/s).
const MAX_BIAS: f64 = 1e3;

/// One number per field of a box.
#[derive(Copy, Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Fields {
    /// Centre x, y, z (m).
    pub center: [f64; 3],
    /// Size l, w, h (m).
    pub size: [f64; 3],
    /// Yaw (rad).
    pub yaw: f64,
    /// Velocity x, y (m/s), when the boxes had velocities.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 2]>,
}

impl Fields {
    fn values(&self) -> impl Iterator<Item = f64> + '_ {
        self.center
            .iter()
            .chain(&self.size)
            .chain(std::iter::once(&self.yaw))
            .chain(self.velocity.iter().flatten())
            .copied()
    }
}

/// The errors of the boxes of one cell.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Cell {
    /// Boxes it rests on.
    pub count: usize,
    /// Mean error.
    pub bias: Fields,
    /// Std of the error about the bias.
    pub std: Fields,
    /// The 95% confidence interval of the std: its lower bound.
    pub std_low: Fields,
    /// The 95% confidence interval of the std: its upper bound.
    pub std_high: Fields,
}

/// One class's errors: over all its boxes, and per score bin.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ClassModel {
    /// Over all the class's boxes.
    pub all: Cell,
    /// Per score bin of [`ErrorModel::score_edges`] (`None`: no box in it).
    pub by_score: Vec<Option<Cell>>,
}

/// An agent's error model, as its file holds it.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ErrorModel {
    /// [`FORMAT`].
    pub format: String,
    /// How its boxes were matched to the ground truth, for the reader.
    pub matched_by: String,
    /// Score bin edges, ascending in (0, 1): bin k holds scores in [edge k-1, edge k).
    pub score_edges: Vec<f64>,
    /// Over all its boxes.
    pub all: Cell,
    /// Per class (nuScenes name).
    pub classes: BTreeMap<String, ClassModel>,
}

/// One box's error against the object it detected.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ErrorSample {
    /// The box's class.
    pub class: Class,
    /// The box's score.
    pub score: f64,
    /// Box minus truth: centre, size, yaw (wrapped to the class's period).
    pub error: [f64; 7],
    /// Box velocity minus true velocity, when both are known.
    pub velocity: Option<[f64; 2]>,
}

impl ErrorSample {
    /// The error of box `d` against the true box `truth` (its velocity, if known).
    pub fn of(d: &Detection, truth: &Detection) -> Self {
        let period = d.class.yaw_period();
        let k = std::f64::consts::TAU / period;
        let mut error = [0.0; 7];
        for i in 0..3 {
            error[i] = d.center[i] - truth.center[i];
            error[3 + i] = d.size[i] - truth.size[i];
        }
        error[6] = wrap_angle(k * (d.yaw - truth.yaw)) / k;
        let velocity = match (&d.velocity, &truth.velocity) {
            (Some(v), Some(t)) => Some([v.v[0] - t.v[0], v.v[1] - t.v[1]]),
            _ => None,
        };
        ErrorSample {
            class: d.class,
            score: d.score,
            error,
            velocity,
        }
    }
}

/// ln Gamma(a) for a > 0 (Lanczos, g = 7: 15 digits).
fn ln_gamma(a: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = a - 1.0;
    let t = x + 7.5;
    let sum = C[0] + (1..9).map(|i| C[i] / (x + i as f64)).sum::<f64>();
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

/// The regularized lower incomplete gamma P(a, x): a series below a + 1, a continued fraction
/// above.
fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let front = (a * x.ln() - x - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        while term.abs() > sum.abs() * 1e-15 {
            n += 1.0;
            term *= x / n;
            sum += term;
        }
        return sum * front;
    }
    // Lentz's continued fraction for Q(a, x).
    let tiny = 1e-300;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / tiny;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..1000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        d = if d.abs() < tiny { tiny } else { d };
        c = b + an / c;
        c = if c.abs() < tiny { tiny } else { c };
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-15 {
            break;
        }
    }
    1.0 - front * h
}

/// The `p` quantile of chi-square with `k` degrees of freedom, by bisection of its CDF.
fn chi2_quantile(k: f64, p: f64) -> f64 {
    let cdf = |x: f64| gamma_p(k / 2.0, x / 2.0);
    let (mut lo, mut hi) = (0.0, k + 10.0 * (2.0 * k).sqrt() + 100.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Mean and std (N - 1) of some numbers, with the std's 95% interval.
fn moments(x: &[f64]) -> (f64, f64, f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    if x.len() < 2 {
        return (mean, f64::NAN, f64::NAN, f64::NAN);
    }
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let s = var.sqrt();
    let k = n - 1.0;
    let low = s * (k / chi2_quantile(k, 0.975)).sqrt();
    let high = s * (k / chi2_quantile(k, 0.025)).sqrt();
    (mean, s, low, high)
}

impl Cell {
    /// The cell of some samples (at least two).
    pub fn fit(samples: &[&ErrorSample]) -> Cell {
        let mut bias = Fields::default();
        let mut std = Fields::default();
        let mut low = Fields::default();
        let mut high = Fields::default();
        let mut set = |i: usize, m: (f64, f64, f64, f64)| {
            let slot = |f: &mut Fields, v: f64| match i {
                0..=2 => f.center[i] = v,
                3..=5 => f.size[i - 3] = v,
                _ => f.yaw = v,
            };
            slot(&mut bias, m.0);
            slot(&mut std, m.1);
            slot(&mut low, m.2);
            slot(&mut high, m.3);
        };
        for i in 0..7 {
            let x: Vec<f64> = samples.iter().map(|s| s.error[i]).collect();
            set(i, moments(&x));
        }
        let v: Vec<[f64; 2]> = samples.iter().filter_map(|s| s.velocity).collect();
        if v.len() >= 2 {
            let m: [(f64, f64, f64, f64); 2] =
                std::array::from_fn(|k| moments(&v.iter().map(|e| e[k]).collect::<Vec<_>>()));
            bias.velocity = Some(m.map(|m| m.0));
            std.velocity = Some(m.map(|m| m.1));
            low.velocity = Some(m.map(|m| m.2));
            high.velocity = Some(m.map(|m| m.3));
        }
        Cell {
            count: samples.len(),
            bias,
            std,
            std_low: low,
            std_high: high,
        }
    }

    fn check(&self, at: &str) -> Result<(), ModelError> {
        let bad = |field: &str, value: f64, expected: String| ModelError::Cell {
            field: format!("{at}.{field}"),
            value,
            expected,
        };
        if let Some(b) = self.bias.values().find(|b| !(b.abs() <= MAX_BIAS)) {
            return Err(bad("bias", b, format!("a bias within +-{MAX_BIAS}")));
        }
        for (name, f) in [
            ("std", &self.std),
            ("std_low", &self.std_low),
            ("std_high", &self.std_high),
        ] {
            if let Some(s) = f.values().find(|s| !(*s >= 0.0 && s.is_finite())) {
                return Err(bad(name, s, "a std".into()));
            }
        }
        if self.count < 2 {
            let n = self.count as f64;
            return Err(bad("count", n, "at least 2 (boxes in a cell)".into()));
        }
        Ok(())
    }
}

/// Why a model file cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// Not JSON, or not a model's fields.
    #[error("{0}")]
    Json(String),
    /// Another format than this build's.
    #[error("format: '{0}' is not '{FORMAT}' (write the model with `v2x-sim calibrate`)")]
    Format(String),
    /// Score edges out of order or outside (0, 1).
    #[error("score_edges: must ascend strictly within (0, 1)")]
    ScoreEdges,
    /// A class that does not exist.
    #[error("classes: unknown class '{0}'")]
    UnknownClass(String),
    /// A cell's value outside its domain.
    #[error("{field}: {value} is not {expected}")]
    Cell {
        /// The field, e.g. `classes.car.all.std`.
        field: String,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: String,
    },
    /// Not one score bin more than the score edges.
    #[error("classes.{class}.by_score: {bins} bins for {edges} score edges (expected {})", edges + 1)]
    Bins {
        /// The class.
        class: String,
        /// Bins given.
        bins: usize,
        /// Score edges.
        edges: usize,
    },
}

impl ErrorModel {
    /// The model of an agent's errors, with `bins` score bins at the scores' quantiles;
    /// `None` when fewer than two samples.
    pub fn fit(samples: &[ErrorSample], bins: usize, matched_by: &str) -> Option<ErrorModel> {
        if samples.len() < 2 {
            return None;
        }
        let mut scores: Vec<f64> = samples.iter().map(|s| s.score).collect();
        scores.sort_by(f64::total_cmp);
        let mut score_edges: Vec<f64> = (1..bins.max(1))
            .map(|k| {
                let q = scores[k * scores.len() / bins];
                (q * 100.0).round() / 100.0
            })
            .filter(|e| *e > 0.0 && *e < 1.0)
            .collect();
        score_edges.dedup();
        let all: Vec<&ErrorSample> = samples.iter().collect();
        let mut classes = BTreeMap::new();
        for class in Class::ALL {
            let of: Vec<&ErrorSample> = samples.iter().filter(|s| s.class == class).collect();
            if of.len() < 2 {
                continue;
            }
            let by_score = (0..=score_edges.len())
                .map(|k| {
                    let bin: Vec<&ErrorSample> = of
                        .iter()
                        .copied()
                        .filter(|s| bin_of(&score_edges, s.score) == k)
                        .collect();
                    (bin.len() >= 2).then(|| Cell::fit(&bin))
                })
                .collect();
            classes.insert(
                class.name().to_owned(),
                ClassModel {
                    all: Cell::fit(&of),
                    by_score,
                },
            );
        }
        Some(ErrorModel {
            format: FORMAT.into(),
            matched_by: matched_by.into(),
            score_edges,
            all: Cell::fit(&all),
            classes,
        })
    }

    /// Reads a model from its JSON text, every field checked.
    pub fn from_json(text: &str) -> Result<ErrorModel, ModelError> {
        let m: ErrorModel =
            serde_json::from_str(text).map_err(|e| ModelError::Json(e.to_string()))?;
        if m.format != FORMAT {
            return Err(ModelError::Format(m.format));
        }
        let edges_ok = m.score_edges.iter().all(|e| *e > 0.0 && *e < 1.0)
            && m.score_edges.windows(2).all(|w| w[0] < w[1]);
        if !edges_ok {
            return Err(ModelError::ScoreEdges);
        }
        m.all.check("all")?;
        for (name, c) in &m.classes {
            Class::from_name(name).ok_or_else(|| ModelError::UnknownClass(name.clone()))?;
            c.all.check(&format!("classes.{name}.all"))?;
            if c.by_score.len() != m.score_edges.len() + 1 {
                return Err(ModelError::Bins {
                    class: name.clone(),
                    bins: c.by_score.len(),
                    edges: m.score_edges.len(),
                });
            }
            for (k, cell) in c.by_score.iter().enumerate() {
                if let Some(cell) = cell {
                    cell.check(&format!("classes.{name}.by_score[{k}]"))?;
                }
            }
        }
        Ok(m)
    }

    /// The cell a box of `class` with `score` takes.
    pub fn cell(&self, class: Class, score: f64) -> &Cell {
        let Some(c) = self.classes.get(class.name()) else {
            return &self.all;
        };
        match c.by_score.get(bin_of(&self.score_edges, score)) {
            Some(Some(cell)) if cell.count >= MIN_COUNT => cell,
            _ if c.all.count >= MIN_COUNT => &c.all,
            _ => &self.all,
        }
    }

    /// The box with its bias taken off and the model's stds.
    pub fn apply(&self, d: &mut Detection) {
        let cell = self.cell(d.class, d.score);
        let (b, s) = (&cell.bias, &cell.std);
        for i in 0..3 {
            d.center[i] -= b.center[i];
            d.size[i] = (d.size[i] - b.size[i]).max(0.05);
            d.std.pos[i] = clamp_std(s.center[i]);
            d.std.size[i] = clamp_std(s.size[i]);
        }
        d.yaw = wrap_angle(d.yaw - b.yaw);
        d.std.yaw = clamp_std(s.yaw);
        d.pos_cov = None;
        if let (Some(v), Some(bv), Some(sv)) = (&mut d.velocity, b.velocity, s.velocity) {
            *v = Velocity {
                v: [v.v[0] - bv[0], v.v[1] - bv[1]],
                std: sv.map(clamp_std),
            };
        }
    }
}

/// The score bin of `score` among `edges`.
fn bin_of(edges: &[f64], score: f64) -> usize {
    edges.iter().take_while(|e| score >= **e).count()
}

/// Each agent's model, by agent name.
#[derive(Clone, Debug, Default)]
pub struct Models(pub BTreeMap<String, ErrorModel>);

impl Models {
    /// Applies each agent's model to its frame of a closed window.
    pub fn apply_window(&self, closed: &mut crate::time::window::Closed) {
        for (agent, f) in &mut closed.frames {
            self.apply(agent, &mut f.detections);
        }
    }

    /// Applies `agent`'s model, if it has one, to its boxes.
    pub fn apply(&self, agent: &str, dets: &mut [Detection]) {
        if let Some(m) = self.0.get(agent) {
            for d in dets {
                m.apply(d);
            }
        }
    }
}

#[cfg(test)]
mod tests;
