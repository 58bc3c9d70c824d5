//! One track's filter (`docs/method.md` §8): two constant-velocity models on (x, y, vx, vy)
//! mixed as an interacting multiple model, each updated by a box with the Kalman gain; the
//! size, height and yaw by WLS. Sans-IO: a track and a box in, the track updated.

use super::{Track, TrackMotion};
use crate::maths::fusion::FLIP_SIGMAS;
use nalgebra::{Const, DimMin, Matrix2, Matrix2x4, Matrix4, SMatrix, SVector, Vector2, Vector4};
use v2x_protocol::{wrap_angle, Class, Detection, Uncertainty, Velocity};

/// A tentative track from a box.
pub(super) fn birth(id: u32, b: &Detection, p: &TrackMotion) -> Track {
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
pub(super) fn predict(t: &mut Track, dt: f64, p: &TrackMotion) {
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
pub(super) fn may_pass(t: &Track, b: &Detection, [vx, vy]: [f64; 2], gate: f64) -> bool {
    let dx = b.center[0] - t.x[0];
    let dy = b.center[1] - t.x[1];
    dx * dx <= gate * (t.p[(0, 0)] + vx) && dy * dy <= gate * (t.p[(1, 1)] + vy)
}

/// The squared Mahalanobis distance d^2 = y^T S^-1 y of a box from a track's state, and ln det S
/// (`None` when S is singular).
pub(super) fn distance(t: &Track, b: &Detection) -> Option<(f64, f64)> {
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
pub(super) fn update(t: &mut Track, b: &Detection, dt: f64, p: &TrackMotion) {
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
pub(super) fn estimate(t: &Track) -> Detection {
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
