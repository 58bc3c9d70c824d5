//! How likely a fused box of a detector's boxes is a real object (`docs/method.md` §11.1): a
//! logistic model over what a late fuser sees of the group, fitted against labels, so that the
//! fused scores rank boxes across frames and agents alike.
//!
//! ```text
//! p(real | group) = 1 / (1 + exp(-(b + w . x)))
//! x = [logit s_1, multi logit s_2, multi, receiver, ln(1 + chi2), r / 50, multi r / 50,
//!      height span, size spread, multi logit s_1]
//! ```
//!
//! `s_1 >= s_2` are the two highest member scores (clamped to [0.01, 0.99]), `multi` is 1 when
//! two or more agents saw the object, `receiver` when the receiving agent is among them, `chi2`
//! the members' squared Mahalanobis distance from the fused centre in the ground plane (the
//! pair's own distance for two), `r` the fused centre's range from the receiver (m), the height
//! span the members' centre heights' spread (m) and the size spread the largest |l - l_f| +
//! |w - w_f| of a member (m), both capped at 5. [`ExistenceModel::fit`] finds `b` and `w` by
//! Newton's method on the penalised log-likelihood. Sans-IO.

use serde::{Deserialize, Serialize};
use v2x_protocol::Detection;

/// Features a group is described by.
pub const FEATURES: usize = 10;

/// The features' names, in order, as a model file lists them.
pub const FEATURE_NAMES: [&str; FEATURES] = [
    "logit_s1",
    "multi_logit_s2",
    "multi",
    "receiver",
    "ln1p_chi2",
    "range_50",
    "multi_range_50",
    "height_span",
    "size_spread",
    "multi_logit_s1",
];

/// One group's features.
pub type Features = [f64; FEATURES];

/// A logistic model of a fused box's chance of being a real object.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ExistenceModel {
    /// Intercept b.
    pub bias: f64,
    /// Weights w, in [`FEATURE_NAMES`] order.
    pub weights: Features,
}

/// Fitted on V2V4Real's `train` split (both cars' PointPillars boxes, CSBA-3D with csba-wls+'s
/// parameters and the detector's stds; a fused box is real when it takes a label at BEV IoU 0.5):
/// `v2x-sim calibrate --existence --dataset v2v4real`.
pub const DETECTOR_DEFAULT: ExistenceModel = ExistenceModel {
    bias: 1.326,
    weights: [
        2.589, 1.425, 3.118, -0.1659, -1.365, -0.5476, -1.254, -0.09518, 0.9972, -1.031,
    ],
};

fn logit(s: f64) -> f64 {
    let s = s.clamp(0.01, 0.99);
    (s / (1.0 - s)).ln()
}

fn sigmoid(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

/// A fused group as the model sees it: its members (each with whether it is the receiver's box)
/// and the fused box.
pub fn features(members: &[(&Detection, bool)], fused: &Detection) -> Features {
    let mut scores: Vec<f64> = members.iter().map(|(d, _)| d.score).collect();
    scores.sort_by(|a, b| b.total_cmp(a));
    let s1 = scores.first().map_or(0.01, |&s| logit(s));
    let multi = if members.len() >= 2 { 1.0 } else { 0.0 };
    let s2 = scores.get(1).map_or(0.0, |&s| logit(s));
    let receiver = if members.iter().any(|m| m.1) {
        1.0
    } else {
        0.0
    };
    let chi2: f64 = members
        .iter()
        .map(|(d, _)| {
            (0..2)
                .map(|a| {
                    let v = d.std.pos[a] * d.std.pos[a];
                    let e = d.center[a] - fused.center[a];
                    if v > 0.0 {
                        e * e / v
                    } else {
                        0.0
                    }
                })
                .sum::<f64>()
        })
        .sum();
    let range = fused.center[0].hypot(fused.center[1]) / 50.0;
    let (lo, hi) = members
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (d, _)| {
            (lo.min(d.center[2]), hi.max(d.center[2]))
        });
    let span = if lo <= hi { hi - lo } else { 0.0 };
    let spread = members
        .iter()
        .map(|(d, _)| (d.size[0] - fused.size[0]).abs() + (d.size[1] - fused.size[1]).abs())
        .fold(0.0, f64::max);
    let x = [
        s1,
        multi * s2,
        multi,
        receiver,
        chi2.ln_1p(),
        range,
        multi * range,
        span.min(5.0),
        spread.min(5.0),
        multi * s1,
    ];
    x.map(|v| if v.is_finite() { v } else { 0.0 })
}

/// Why a model cannot be fitted or read.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ExistenceError {
    /// The samples are all of one kind.
    #[error("the samples hold {real} real and {ghost} false boxes: a fit needs both")]
    OneSided {
        /// Samples labelled real.
        real: usize,
        /// Samples labelled false.
        ghost: usize,
    },
    /// The samples do not determine the weights (a feature that is a combination of others,
    /// with no ridge to settle it).
    #[error("the samples do not determine the weights: give a ridge (l2 > 0)")]
    Singular,
    /// Newton's method did not settle.
    #[error("the fit did not converge in {0} iterations")]
    NoConvergence(usize),
    /// The file is not a model of this kind.
    #[error("kind is {0:?}, not \"v2x-fusion existence model\"")]
    Kind(String),
    /// A model file lists other features than this build's.
    #[error("feature {index} is {found:?} in the model, {expected:?} here")]
    Features {
        /// Position in the list.
        index: usize,
        /// The model's name.
        found: String,
        /// This build's name.
        expected: &'static str,
    },
    /// A weight is not finite.
    #[error("the model's {0} is not a finite number")]
    NotFinite(String),
}

/// The form a model is written in: named features and their weights.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExistenceFile {
    /// What the model is (`"v2x-fusion existence model"`).
    pub kind: String,
    /// Intercept.
    pub bias: f64,
    /// Feature name and weight, in [`FEATURE_NAMES`] order.
    pub weights: Vec<(String, f64)>,
    /// Samples it was fitted on, real and false.
    pub samples: [usize; 2],
}

/// The `kind` of a model file.
pub const FILE_KIND: &str = "v2x-fusion existence model";

impl ExistenceModel {
    /// The chance that a group with these features is a real object.
    pub fn probability(&self, x: &Features) -> f64 {
        sigmoid(self.bias + self.weights.iter().zip(x).map(|(w, v)| w * v).sum::<f64>())
    }

    /// The maximum of the log-likelihood of `samples` (features, real) less `l2` times the
    /// weights' squared norm (the bias is not penalised).
    pub fn fit(samples: &[(Features, bool)], l2: f64) -> Result<ExistenceModel, ExistenceError> {
        const N: usize = FEATURES + 1;
        let real = samples.iter().filter(|s| s.1).count();
        let ghost = samples.len() - real;
        if real == 0 || ghost == 0 {
            return Err(ExistenceError::OneSided { real, ghost });
        }
        let mut beta = nalgebra::SVector::<f64, N>::zeros();
        beta[0] = (real as f64 / ghost as f64).ln();
        let row = |x: &Features| {
            let mut r = nalgebra::SVector::<f64, N>::zeros();
            r[0] = 1.0;
            r.fixed_rows_mut::<FEATURES>(1).copy_from_slice(x);
            r
        };
        const ITERATIONS: usize = 50;
        for _ in 0..ITERATIONS {
            let mut grad = nalgebra::SVector::<f64, N>::zeros();
            let mut hess = nalgebra::SMatrix::<f64, N, N>::zeros();
            for (x, y) in samples {
                let r = row(x);
                let p = sigmoid(beta.dot(&r));
                grad += r * (f64::from(u8::from(*y)) - p);
                hess += r * r.transpose() * (p * (1.0 - p)).max(1e-12);
            }
            for k in 1..N {
                grad[k] -= 2.0 * l2 * beta[k];
                hess[(k, k)] += 2.0 * l2;
            }
            let step = hess
                .cholesky()
                .ok_or(ExistenceError::Singular)?
                .solve(&grad);
            beta += step;
            if step.amax() < 1e-9 {
                let mut weights = [0.0; FEATURES];
                weights.copy_from_slice(beta.fixed_rows::<FEATURES>(1).as_slice());
                return Ok(ExistenceModel {
                    bias: beta[0],
                    weights,
                });
            }
        }
        Err(ExistenceError::NoConvergence(ITERATIONS))
    }

    /// The model as a file holds it.
    pub fn to_file(&self, samples: [usize; 2]) -> ExistenceFile {
        ExistenceFile {
            kind: FILE_KIND.into(),
            bias: self.bias,
            weights: FEATURE_NAMES
                .iter()
                .zip(self.weights)
                .map(|(n, w)| (n.to_string(), w))
                .collect(),
            samples,
        }
    }
}

impl TryFrom<ExistenceFile> for ExistenceModel {
    type Error = ExistenceError;

    fn try_from(f: ExistenceFile) -> Result<Self, Self::Error> {
        if f.kind != FILE_KIND {
            return Err(ExistenceError::Kind(f.kind));
        }
        if !f.bias.is_finite() {
            return Err(ExistenceError::NotFinite("bias".into()));
        }
        let mut weights = [0.0; FEATURES];
        for index in 0..FEATURES.max(f.weights.len()) {
            let expected = FEATURE_NAMES.get(index).copied().unwrap_or("(none)");
            let Some((name, w)) = f.weights.get(index) else {
                return Err(ExistenceError::Features {
                    index,
                    found: "(none)".into(),
                    expected,
                });
            };
            if name != expected {
                return Err(ExistenceError::Features {
                    index,
                    found: name.clone(),
                    expected,
                });
            }
            if !w.is_finite() {
                return Err(ExistenceError::NotFinite(name.clone()));
            }
            weights[index] = *w;
        }
        Ok(ExistenceModel {
            bias: f.bias,
            weights,
        })
    }
}

#[cfg(test)]
mod tests;
