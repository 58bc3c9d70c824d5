//! Rigid transforms between the DAIR-V2X frames (LiDAR, NovAtel, world), as the official code
//! composes them: `p_to = R p_from + t`, inverses by the matrix inverse of `R`.

/// A transform from one frame to another: `p' = rotation * p + translation`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Pose {
    /// The 3x3 rotation, row-major.
    pub rotation: [[f64; 3]; 3],
    /// The translation (m).
    pub translation: [f64; 3],
}

impl Pose {
    /// The identity.
    pub const IDENTITY: Pose = Pose {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0, 0.0, 0.0],
    };

    /// A rotation by `yaw` about z followed by a translation.
    pub fn planar(yaw: f64, translation: [f64; 3]) -> Pose {
        let (s, c) = yaw.sin_cos();
        Pose {
            rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
            translation,
        }
    }

    /// The image of a point.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        std::array::from_fn(|i| {
            r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + self.translation[i]
        })
    }

    /// The image of a direction (rotation only).
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        std::array::from_fn(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2])
    }

    /// This transform followed by `next`.
    pub fn then(&self, next: &Pose) -> Pose {
        let (a, b) = (&self.rotation, &next.rotation);
        let rotation = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| b[i][k] * a[k][j]).sum())
        });
        Pose {
            rotation,
            translation: next.apply(self.translation),
        }
    }

    /// The inverse transform, or `None` when the rotation is singular.
    pub fn inverse(&self) -> Option<Pose> {
        let m = &self.rotation;
        let cof = |i: usize, j: usize| {
            let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
            let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
            m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
        };
        let det = m[0][0] * cof(0, 0) + m[0][1] * cof(0, 1) + m[0][2] * cof(0, 2);
        if !det.is_finite() || det.abs() < 1e-12 {
            return None;
        }
        let inv: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| cof(j, i) / det));
        let back = Pose {
            rotation: inv,
            translation: [0.0; 3],
        };
        let t = back.apply(self.translation);
        Some(Pose {
            rotation: inv,
            translation: [-t[0], -t[1], -t[2]],
        })
    }

    /// The yaw in the target frame of a heading `yaw` about the source frame's z axis: the
    /// direction of the rotated heading vector in the target's x-y plane.
    pub fn yaw(&self, yaw: f64) -> f64 {
        let d = self.rotate([yaw.cos(), yaw.sin(), 0.0]);
        d[1].atan2(d[0])
    }

    /// Moves the target frame's origin: the same transform, then a shift by `d`.
    pub fn shifted(&self, d: [f64; 3]) -> Pose {
        Pose {
            rotation: self.rotation,
            translation: std::array::from_fn(|i| self.translation[i] + d[i]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
    }

    #[test]
    fn composition_and_inverse_by_hand() {
        // A quarter turn then (10, 0, 1): (1, 0, 0) -> (0, 1, 0) -> (10, 1, 1).
        let a = Pose::planar(std::f64::consts::FRAC_PI_2, [10.0, 0.0, 1.0]);
        assert!(close(a.apply([1.0, 0.0, 0.0]), [10.0, 1.0, 1.0]));
        let back = a.inverse().unwrap();
        assert!(close(back.apply([10.0, 1.0, 1.0]), [1.0, 0.0, 0.0]));
        // then: a shift by (0, 0, 2) after a.
        let b = a.then(&Pose::planar(0.0, [0.0, 0.0, 2.0]));
        assert!(close(b.apply([1.0, 0.0, 0.0]), [10.0, 1.0, 3.0]));
        assert!((a.yaw(0.1) - (0.1 + std::f64::consts::FRAC_PI_2)).abs() < 1e-12);
        let singular = Pose {
            rotation: [[0.0; 3]; 3],
            translation: [0.0; 3],
        };
        assert_eq!(singular.inverse(), None);
    }
}
