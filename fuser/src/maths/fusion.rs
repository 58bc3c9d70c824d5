//! WLS-3D: weighted-least-squares fusion of a group of associated detections (paper §3.3,
//! `docs/method.md` §2).
//!
//! z = (sum R_n^-1)^-1 sum R_n^-1 y_n and P = (sum R_n^-1)^-1 over the M members, R_n being the
//! member's covariance: a full 3x3 block for the centre when the member carries one, diagonal
//! otherwise, and diagonal for size and yaw. Yaw is circular: each member's yaw is unwrapped
//! against the member with the smallest yaw std before the weighted sum, and the result is
//! wrapped. A member more than pi/2 and more than 4 combined stds from that reference (a heading
//! turned by pi, not noise) is turned back by pi: for the symmetric barrier (yaw period pi) that
//! is the same box; for the other classes a detector flipped its heading, and the fused yaw
//! variance grows by q pi^2, q being the flipped members' share of the yaw weight.
//! Velocities are fused the same way over the members that have one. The fused detection carries
//! P's stds, the highest member score, and the id of the most certain member (smallest sum of
//! variances; ties go to the earliest member).

use nalgebra::{Matrix3, Vector3};
use v2x_protocol::{wrap_angle, AgentSet, Detection, Uncertainty, Velocity};

/// A fused box and the agents (indices into the method's input lists) whose boxes went into it.
#[derive(Clone, Debug, PartialEq)]
pub struct Sourced {
    /// The fused box.
    pub det: Detection,
    /// The contributing agents.
    pub sources: AgentSet,
}

/// Weighted mean and fused variance of scalars y_n with variances r_n:
/// z = (sum 1/r_n)^-1 sum y_n / r_n, P = (sum 1/r_n)^-1.
pub fn wls_scalar(values: impl Iterator<Item = (f64, f64)>) -> (f64, f64) {
    let (mut info, mut eta) = (0.0, 0.0);
    for (y, r) in values {
        info += 1.0 / r;
        eta += y / r;
    }
    (eta / info, 1.0 / info)
}

/// Index of the most certain member: smallest sum of variances, the earliest on ties.
pub fn most_certain(members: &[&Detection]) -> usize {
    let mut best = 0;
    for (i, m) in members.iter().enumerate().skip(1) {
        if m.total_variance() < members[best].total_variance() {
            best = i;
        }
    }
    best
}

/// How many combined stds apart two headings must be (beyond pi/2) to be taken as a flip.
pub const FLIP_SIGMAS: f64 = 4.0;

/// WLS of the members' yaws (`docs/method.md` §2), unwrapped against the member with the
/// smallest yaw std; members more than pi/2 from it and beyond [`FLIP_SIGMAS`] of their combined
/// std (so not explained by noise) are turned by pi. With yaw period pi that costs nothing; with
/// 2 pi (a flipped heading) the fused variance is P + q pi^2 for the share q of yaw weight that
/// was flipped. Returns (yaw, variance).
pub fn fuse_yaw(members: &[&Detection], period: f64) -> (f64, f64) {
    use std::f64::consts::{FRAC_PI_2, PI};
    let reference = members
        .iter()
        .enumerate()
        .min_by(|(i, a), (j, b)| a.std.yaw.total_cmp(&b.std.yaw).then(i.cmp(j)))
        .map(|(_, m)| *m)
        .expect("non-empty group");
    let ref_var = reference.std.yaw * reference.std.yaw;
    let reference = reference.yaw;
    let (mut flipped, mut total) = (0.0, 0.0);
    let (yaw, var) = wls_scalar(members.iter().map(|m| {
        let r = m.std.yaw * m.std.yaw;
        let mut d = wrap_angle(m.yaw - reference);
        total += 1.0 / r;
        if d.abs() > FRAC_PI_2 && d * d > FLIP_SIGMAS.powi(2) * (r + ref_var) {
            d = wrap_angle(d + PI);
            if period > PI {
                flipped += 1.0 / r;
            }
        }
        (reference + d, r)
    }));
    let q = if total > 0.0 { flipped / total } else { 0.0 };
    (wrap_angle(yaw), var + q * PI * PI)
}

/// Fuses a non-empty group of detections of one object with WLS-3D.
pub fn fuse_group(members: &[&Detection]) -> Detection {
    assert!(!members.is_empty(), "a group has at least one member");
    if members.len() == 1 {
        return members[0].clone();
    }
    let best = most_certain(members);

    // Centre: information form, full 3x3 when any member has a full covariance.
    let (center, pos_cov) = if members.iter().all(|m| m.pos_cov.is_none()) {
        let mut c = [0.0; 3];
        let mut var = [0.0; 3];
        for k in 0..3 {
            (c[k], var[k]) = wls_scalar(
                members
                    .iter()
                    .map(|m| (m.center[k], m.std.pos[k] * m.std.pos[k])),
            );
        }
        (c, var.map(f64::sqrt))
    } else {
        let mut info = Matrix3::zeros();
        let mut eta = Vector3::zeros();
        for m in members {
            let cov = m.position_covariance();
            let r = Matrix3::from_fn(|i, j| cov[i][j]);
            let r_inv = r
                .try_inverse()
                .unwrap_or_else(|| Matrix3::from_diagonal(&r.diagonal().map(|v| 1.0 / v)));
            info += r_inv;
            eta += r_inv * Vector3::from(m.center);
        }
        let p = info
            .try_inverse()
            .unwrap_or_else(|| Matrix3::from_diagonal(&info.diagonal().map(|v| 1.0 / v)));
        let z = p * eta;
        let full: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| p[(i, j)]));
        return finish(members, best, [z[0], z[1], z[2]], Some(full));
    };
    let mut d = finish(members, best, center, None);
    d.std.pos = pos_cov;
    d
}

fn finish(
    members: &[&Detection],
    best: usize,
    center: [f64; 3],
    full: Option<[[f64; 3]; 3]>,
) -> Detection {
    let mut size = [0.0; 3];
    let mut size_std = [0.0; 3];
    for k in 0..3 {
        let (z, p) = wls_scalar(
            members
                .iter()
                .map(|m| (m.size[k], m.std.size[k] * m.std.size[k])),
        );
        size[k] = z;
        size_std[k] = p.sqrt();
    }
    let (yaw, yaw_var) = fuse_yaw(members, members[best].class.yaw_period());
    let pos = match full {
        Some(p) => [p[0][0].sqrt(), p[1][1].sqrt(), p[2][2].sqrt()],
        None => [0.0; 3],
    };
    // Velocity: WLS over the members that measured one.
    let moving = || members.iter().filter_map(|m| m.velocity.as_ref());
    let velocity = moving().next().is_some().then(|| {
        let mut v = Velocity {
            v: [0.0; 2],
            std: [0.0; 2],
        };
        for k in 0..2 {
            let (z, p) = wls_scalar(moving().map(|m| (m.v[k], m.std[k] * m.std[k])));
            v.v[k] = z;
            v.std[k] = p.sqrt();
        }
        v
    });
    Detection {
        class: members[best].class,
        center,
        size,
        yaw,
        score: members.iter().map(|m| m.score).fold(f64::MIN, f64::max),
        std: Uncertainty {
            pos,
            size: size_std,
            yaw: yaw_var.sqrt(),
        },
        pos_cov: full.map(Box::new),
        velocity,
        id: members[best].id,
    }
}

/// The centre's sums: per axis with diagonal covariances, in information form once any member
/// has a full one.
#[derive(Clone, Debug)]
enum CentreSum {
    Axes([(f64, f64); 3]),
    Full(Matrix3<f64>, Vector3<f64>),
}

/// The yaw's sums against its reference member (the smallest yaw std, the earliest on ties).
#[derive(Clone, Debug)]
struct YawSum {
    reference: usize,
    /// The yaw period of the most certain member's class, as the sums have it.
    period: f64,
    info: f64,
    eta: f64,
    flipped: f64,
    total: f64,
}

/// WLS-3D of a group built one member at a time: [`fuse_group`] of the members in the order
/// added, bit for bit, at the cost of the new member alone (the yaw's sums are redone when a
/// new member becomes the yaw reference, the centre's when the first full covariance joins).
/// CSBA-3D over many agents adds one member per agent to a group.
#[derive(Clone, Debug)]
pub struct GroupSum<'a> {
    members: smallvec::SmallVec<[&'a Detection; 4]>,
    best: usize,
    /// The best member's total variance.
    best_variance: f64,
    centre: CentreSum,
    size: [(f64, f64); 3],
    yaw: YawSum,
    velocity: Option<[(f64, f64); 2]>,
    score: f64,
}

/// Adds y with variance r to a scalar's (information, information-weighted sum).
fn add_scalar((info, eta): &mut (f64, f64), y: f64, r: f64) {
    *info += 1.0 / r;
    *eta += y / r;
}

impl<'a> GroupSum<'a> {
    /// The sums of `members`, in order (at least one).
    pub fn of(members: &[&'a Detection]) -> Self {
        let first = members[0];
        let mut g = GroupSum {
            members: smallvec::smallvec![first],
            best: 0,
            best_variance: first.total_variance(),
            centre: CentreSum::Axes([(0.0, 0.0); 3]),
            size: [(0.0, 0.0); 3],
            yaw: YawSum {
                reference: 0,
                period: first.class.yaw_period(),
                info: 0.0,
                eta: 0.0,
                flipped: 0.0,
                total: 0.0,
            },
            velocity: None,
            score: f64::MIN,
        };
        g.add_centre(first);
        g.add_rest(first);
        g.add_yaw(first);
        for m in &members[1..] {
            g.add(m);
        }
        g
    }

    /// Adds a member.
    pub fn add(&mut self, m: &'a Detection) {
        self.members.push(m);
        let (i, variance) = (self.members.len() - 1, m.total_variance());
        if variance < self.best_variance {
            (self.best, self.best_variance) = (i, variance);
        }
        match (&self.centre, &m.pos_cov) {
            (CentreSum::Axes(_), Some(_)) => self.redo_centre(),
            _ => self.add_centre(m),
        }
        self.add_rest(m);
        let reference = self.members[self.yaw.reference];
        let period = self.members[self.best].class.yaw_period();
        if m.std.yaw.total_cmp(&reference.std.yaw).is_lt() || period != self.yaw.period {
            self.redo_yaw();
        } else {
            self.add_yaw(m);
        }
    }

    fn add_centre(&mut self, m: &Detection) {
        match &mut self.centre {
            CentreSum::Axes(axes) if m.pos_cov.is_none() => {
                for (k, a) in axes.iter_mut().enumerate() {
                    add_scalar(a, m.center[k], m.std.pos[k] * m.std.pos[k]);
                }
            }
            CentreSum::Axes(_) => self.redo_centre(),
            CentreSum::Full(info, eta) => {
                let cov = m.position_covariance();
                let r = Matrix3::from_fn(|i, j| cov[i][j]);
                let r_inv = r
                    .try_inverse()
                    .unwrap_or_else(|| Matrix3::from_diagonal(&r.diagonal().map(|v| 1.0 / v)));
                *info += r_inv;
                *eta += r_inv * Vector3::from(m.center);
            }
        }
    }

    /// The centre's sums from every member, in information form.
    fn redo_centre(&mut self) {
        self.centre = CentreSum::Full(Matrix3::zeros(), Vector3::zeros());
        for m in self.members.clone() {
            self.add_centre(m);
        }
    }

    /// Size, velocity and score.
    fn add_rest(&mut self, m: &Detection) {
        for (k, s) in self.size.iter_mut().enumerate() {
            add_scalar(s, m.size[k], m.std.size[k] * m.std.size[k]);
        }
        if let Some(v) = &m.velocity {
            let sums = self.velocity.get_or_insert([(0.0, 0.0); 2]);
            for (k, a) in sums.iter_mut().enumerate() {
                add_scalar(a, v.v[k], v.std[k] * v.std[k]);
            }
        }
        self.score = self.score.max(m.score);
    }

    fn add_yaw(&mut self, m: &Detection) {
        use std::f64::consts::{FRAC_PI_2, PI};
        let reference = self.members[self.yaw.reference];
        let ref_var = reference.std.yaw * reference.std.yaw;
        let y = &mut self.yaw;
        let period = y.period;
        let r = m.std.yaw * m.std.yaw;
        let mut d = wrap_angle(m.yaw - reference.yaw);
        y.total += 1.0 / r;
        if d.abs() > FRAC_PI_2 && d * d > FLIP_SIGMAS.powi(2) * (r + ref_var) {
            d = wrap_angle(d + PI);
            if period > PI {
                y.flipped += 1.0 / r;
            }
        }
        let mut sums = (y.info, y.eta);
        add_scalar(&mut sums, reference.yaw + d, r);
        (y.info, y.eta) = sums;
    }

    /// The yaw's sums from every member against the new reference.
    fn redo_yaw(&mut self) {
        let reference = (0..self.members.len())
            .min_by(|&i, &j| {
                let (a, b) = (self.members[i].std.yaw, self.members[j].std.yaw);
                a.total_cmp(&b).then(i.cmp(&j))
            })
            .expect("non-empty group");
        self.yaw = YawSum {
            reference,
            period: self.members[self.best].class.yaw_period(),
            info: 0.0,
            eta: 0.0,
            flipped: 0.0,
            total: 0.0,
        };
        for m in self.members.clone() {
            self.add_yaw(m);
        }
    }

    /// The fused box: [`fuse_group`] of the members added.
    pub fn fused(&self) -> Detection {
        use std::f64::consts::PI;
        if self.members.len() == 1 {
            return self.members[0].clone();
        }
        let best = self.members[self.best];
        let (center, pos, full) = match &self.centre {
            CentreSum::Axes(axes) => (
                axes.map(|(info, eta)| eta / info),
                axes.map(|(info, _)| (1.0 / info).sqrt()),
                None,
            ),
            CentreSum::Full(info, eta) => {
                let p = info
                    .try_inverse()
                    .unwrap_or_else(|| Matrix3::from_diagonal(&info.diagonal().map(|v| 1.0 / v)));
                let z = p * eta;
                let full: [[f64; 3]; 3] =
                    std::array::from_fn(|i| std::array::from_fn(|j| p[(i, j)]));
                (
                    [z[0], z[1], z[2]],
                    [full[0][0].sqrt(), full[1][1].sqrt(), full[2][2].sqrt()],
                    Some(full),
                )
            }
        };
        let y = &self.yaw;
        let q = if y.total > 0.0 {
            y.flipped / y.total
        } else {
            0.0
        };
        let yaw_var = 1.0 / y.info + q * PI * PI;
        Detection {
            class: best.class,
            center,
            size: self.size.map(|(info, eta)| eta / info),
            yaw: wrap_angle(y.eta / y.info),
            score: self.score,
            std: Uncertainty {
                pos,
                size: self.size.map(|(info, _)| (1.0 / info).sqrt()),
                yaw: yaw_var.sqrt(),
            },
            pos_cov: full.map(Box::new),
            velocity: self.velocity.map(|v| Velocity {
                v: v.map(|(info, eta)| eta / info),
                std: v.map(|(info, _)| (1.0 / info).sqrt()),
            }),
            id: best.id,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;
    use v2x_protocol::Class;

    fn det(center: [f64; 3], yaw: f64, pos_std: f64, yaw_std: f64, id: u32) -> Detection {
        Detection {
            class: Class::Car,
            center,
            size: [4.0, 2.0, 1.5],
            yaw,
            score: 0.5,
            std: Uncertainty {
                pos: [pos_std; 3],
                size: [0.1; 3],
                yaw: yaw_std,
            },
            pos_cov: None,
            velocity: None,
            id,
        }
    }

    #[test]
    fn two_boxes_hand_computed() {
        // sigma 1 and 2: weights 1 and 1/4 -> z = (0*1 + 5*0.25)/1.25 = 1, P = 1/1.25 = 0.8
        let a = det([0.0, 0.0, 0.0], 0.1, 1.0, 0.1, 7);
        let mut b = det([5.0, 10.0, 2.5], 0.3, 2.0, 0.2, 9);
        b.score = 0.9;
        let f = fuse_group(&[&a, &b]);
        assert!((f.center[0] - 1.0).abs() < 1e-12);
        assert!((f.center[1] - 2.0).abs() < 1e-12);
        assert!((f.center[2] - 0.5).abs() < 1e-12);
        assert!((f.std.pos[0] - 0.8f64.sqrt()).abs() < 1e-12);
        // yaw: (0.1/0.01 + 0.3/0.04) / (1/0.01 + 1/0.04) = (10 + 7.5)/125 = 0.14
        assert!((f.yaw - 0.14).abs() < 1e-12);
        assert_eq!(f.score, 0.9);
        assert_eq!(f.id, 7, "id of the most certain member");
        assert!(f.pos_cov.is_none());
    }

    #[test]
    fn yaws_across_pi() {
        // 179 deg and -179 deg, equal weights: the mean is 180 deg, not 0.
        let a = det([0.0; 3], 179f64.to_radians(), 1.0, 0.1, 1);
        let b = det([0.0; 3], -179f64.to_radians(), 1.0, 0.1, 2);
        let f = fuse_group(&[&a, &b]);
        assert!((f.yaw.abs() - PI).abs() < 1e-9, "{}", f.yaw);
        // 170 and -176 (= 184) with weights 1 : 3 -> 170*0.25 + 184*0.75 = 180.5 -> -179.5
        let a = det([0.0; 3], 170f64.to_radians(), 1.0, 0.2, 1);
        let b = det([0.0; 3], -176f64.to_radians(), 1.0, 0.2 / 3f64.sqrt(), 2);
        let f = fuse_group(&[&a, &b]);
        assert!(
            (f.yaw.to_degrees() + 179.5).abs() < 1e-9,
            "{}",
            f.yaw.to_degrees()
        );
    }

    #[test]
    fn barriers_have_period_pi() {
        // 0.05 and pi - 0.05: the same barrier orientation (symmetric), not 90 degrees.
        let mut a = det([0.0; 3], 0.05, 1.0, 0.1, 1);
        let mut b = det([0.0; 3], PI - 0.05, 1.0, 0.1, 2);
        a.class = Class::Barrier;
        b.class = Class::Barrier;
        let f = fuse_group(&[&a, &b]);
        assert!(f.yaw.abs() < 1e-12, "{}", f.yaw);
        assert!(
            (f.std.yaw - 0.1 / 2f64.sqrt()).abs() < 1e-12,
            "no flip for a barrier"
        );
        // A car at the same two yaws is one flipped heading: it keeps the first (most certain
        // on ties) member's direction.
        a.class = Class::Car;
        b.class = Class::Car;
        let f = fuse_group(&[&a, &b]);
        assert!(f.yaw.abs() < 1e-12, "{}", f.yaw);
    }

    #[test]
    fn a_flipped_heading_is_aligned_and_widens_the_std() {
        // 0.3 rad with std 0.05, and the same car seen at 0.3 + pi with std 0.1.
        let a = det([0.0; 3], 0.3, 1.0, 0.05, 1);
        let b = det([0.0; 3], wrap_angle(0.3 + PI), 1.0, 0.1, 2);
        for f in [fuse_group(&[&a, &b]), fuse_group(&[&b, &a])] {
            assert!((f.yaw - 0.3).abs() < 1e-12, "{}", f.yaw);
            // P = 1 / (400 + 100) = 0.002; q = 100 / 500 = 0.2: var = 0.002 + 0.2 pi^2.
            let want = (0.002 + 0.2 * PI * PI).sqrt();
            assert!((f.std.yaw - want).abs() < 1e-12, "{}", f.std.yaw);
        }
        // Members within pi/2 are not flipped: 0 and 1.5 rad, equal stds, average to 0.75.
        let c = det([0.0; 3], 0.0, 1.0, 0.1, 1);
        let d = det([0.0; 3], 1.5, 1.0, 0.1, 2);
        assert!((fuse_group(&[&c, &d]).yaw - 0.75).abs() < 1e-12);
        // Nor beyond pi/2 when the stds explain it: 0 and 2 rad at 60 degrees each (4 combined
        // stds are 5.9 rad) average to 1, with the plain WLS std.
        let c = det([0.0; 3], 0.0, 1.0, 60f64.to_radians(), 1);
        let d = det([0.0; 3], 2.0, 1.0, 60f64.to_radians(), 2);
        let f = fuse_group(&[&c, &d]);
        assert!((f.yaw - 1.0).abs() < 1e-12);
        assert!((f.std.yaw - 60f64.to_radians() / 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn fusing_a_box_with_itself_halves_variance() {
        let a = det([3.0, 4.0, 5.0], 1.0, 1.5, 0.3, 1);
        let f = fuse_group(&[&a, &a]);
        for k in 0..3 {
            assert!((f.center[k] - a.center[k]).abs() < 1e-12);
        }
        for (s, t) in a.std.as_array().iter().zip(f.std.as_array()) {
            assert!((t * t - s * s / 2.0).abs() < 1e-12);
        }
    }

    proptest::proptest! {
        #[test]
        fn any_box_fused_with_itself_keeps_its_values_and_halves_its_variance(
            c in proptest::array::uniform3(-1e3f64..1e3),
            yaw in -3.1f64..3.1,
            s in proptest::array::uniform7(0.01f64..10.0),
        ) {
            let mut a = det(c, yaw, 1.0, 1.0, 5);
            a.std = Uncertainty::from_array(s);
            let f = fuse_group(&[&a, &a]);
            for k in 0..3 {
                proptest::prop_assert!((f.center[k] - a.center[k]).abs() < 1e-9);
                proptest::prop_assert!((f.size[k] - a.size[k]).abs() < 1e-9);
            }
            proptest::prop_assert!(wrap_angle(f.yaw - a.yaw).abs() < 1e-9);
            for (x, y) in a.std.as_array().iter().zip(f.std.as_array()) {
                proptest::prop_assert!((y * y - x * x / 2.0).abs() < 1e-9 * x * x);
            }
            proptest::prop_assert_eq!(f.id, 5);
        }
    }

    #[test]
    fn ties_go_to_the_earliest_member() {
        let a = det([0.0; 3], 0.0, 1.0, 0.1, 11);
        let b = det([1.0; 3], 0.0, 1.0, 0.1, 22);
        assert_eq!(fuse_group(&[&a, &b]).id, 11);
        assert_eq!(fuse_group(&[&b, &a]).id, 22);
    }

    #[test]
    fn full_covariance() {
        // a: cov diag(1, 1, 1); b: cov [[2, 1, 0], [1, 2, 0], [0, 0, 1]] at (3, 0, 0).
        // info = I + inv(b) with inv(b) = [[2/3, -1/3, 0], [-1/3, 2/3, 0], [0, 0, 1]]
        // P = inv([[5/3, -1/3, 0], [-1/3, 5/3, 0], [0, 0, 2]]) = [[5/8, 1/8, 0], [1/8, 5/8, 0], [0,0,1/2]]
        // eta = inv(b) (3,0,0) = (2, -1, 0); z = P eta = (10/8 - 1/8, 2/8 - 5/8, 0) = (9/8, -3/8, 0)
        let a = det([0.0; 3], 0.0, 1.0, 0.1, 1);
        let mut b = det([3.0, 0.0, 0.0], 0.0, 1.0, 0.1, 2);
        b.pos_cov = Some(Box::new([
            [2.0, 1.0, 0.0],
            [1.0, 2.0, 0.0],
            [0.0, 0.0, 1.0],
        ]));
        let f = fuse_group(&[&a, &b]);
        assert!((f.center[0] - 9.0 / 8.0).abs() < 1e-12);
        assert!((f.center[1] + 3.0 / 8.0).abs() < 1e-12);
        let p = f.pos_cov.unwrap();
        assert!((p[0][1] - 1.0 / 8.0).abs() < 1e-12);
        assert!((f.std.pos[0] - (5.0f64 / 8.0).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn velocities_fuse_over_the_members_that_have_one() {
        let mut a = det([0.0; 3], 0.0, 1.0, 0.1, 1);
        a.velocity = Some(Velocity {
            v: [10.0, 0.0],
            std: [1.0, 1.0],
        });
        let mut b = det([0.0; 3], 0.0, 1.0, 0.1, 2);
        b.velocity = Some(Velocity {
            v: [13.0, 3.0],
            std: [2.0, 2.0],
        });
        let c = det([0.0; 3], 0.0, 1.0, 0.1, 3); // no velocity: no say in it
        let f = fuse_group(&[&a, &b, &c]);
        let v = f.velocity.unwrap();
        // weights 1 and 1/4: (10 + 13/4) / 1.25 = 10.6; (0 + 3/4) / 1.25 = 0.6; var 0.8
        assert!((v.v[0] - 10.6).abs() < 1e-12 && (v.v[1] - 0.6).abs() < 1e-12);
        assert!((v.std[0] - 0.8f64.sqrt()).abs() < 1e-12);
        assert_eq!(fuse_group(&[&c, &c]).velocity, None);
    }

    #[test]
    fn three_members() {
        let a = det([0.0; 3], 0.0, 1.0, 0.1, 1);
        let b = det([3.0; 3], 0.0, 1.0, 0.1, 2);
        let c = det([6.0; 3], 0.0, 1.0, 0.1, 3);
        let f = fuse_group(&[&a, &b, &c]);
        assert!((f.center[0] - 3.0).abs() < 1e-12);
        assert!((f.std.pos[0] - (1.0f64 / 3.0).sqrt()).abs() < 1e-12);
    }

    proptest::proptest! {
        /// Built one member at a time, a group fuses to fuse_group's box bit for bit: flips,
        /// full covariances joining late, velocities on some members, barriers and cars.
        #[test]
        fn a_group_built_member_by_member_fuses_as_fuse_group(
            members in proptest::collection::vec(
                (
                    -5.0f64..5.0,
                    -3.2f64..3.2,
                    0.05f64..2.0,
                    0.01f64..0.8,
                    0.05f64..0.5,
                    0u8..4,
                    0.0f64..1.0,
                ),
                1..12,
            ),
            barrier in proptest::bool::ANY,
        ) {
            let dets: Vec<Detection> = members
                .iter()
                .enumerate()
                .map(|(i, &(x, yaw, pos, yaw_std, size_std, extra, score))| {
                    let mut d = det([x, 2.0 * x, 0.5], yaw, pos, yaw_std, i as u32);
                    d.class = if barrier { Class::Barrier } else { Class::Car };
                    d.std.size = [size_std, 0.1, 0.2];
                    d.size = [4.0 + x / 10.0, 2.0, 1.5];
                    d.score = score;
                    if extra & 1 == 1 {
                        d.velocity = Some(Velocity { v: [x, -x], std: [pos, 2.0 * pos] });
                    }
                    if extra == 2 {
                        let v = pos * pos;
                        d.pos_cov = Some(Box::new([[v, 0.3 * v, 0.0], [0.3 * v, v, 0.0], [0.0, 0.0, v]]));
                    }
                    d
                })
                .collect();
            let refs: Vec<&Detection> = dets.iter().collect();
            let mut sum = GroupSum::of(&refs[..1]);
            proptest::prop_assert_eq!(sum.fused(), fuse_group(&refs[..1]));
            for k in 1..refs.len() {
                sum.add(refs[k]);
                proptest::prop_assert_eq!(sum.fused(), fuse_group(&refs[..=k]));
            }
            proptest::prop_assert_eq!(GroupSum::of(&refs).fused(), fuse_group(&refs));
        }
    }
}
