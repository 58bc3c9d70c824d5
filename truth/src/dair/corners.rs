//! DAIR-V2X box corners: the eight points of a box in the order the official code writes and
//! reads them (`get_3d_8points`, the cooperative labels' `world_8_points`), and the box they
//! describe.
//!
//! For a box of length `l` (along its heading), width `w` and height `h` centred at the origin
//! with yaw 0, the corners are, bottom first: `(+l/2, +w/2)`, `(+l/2, -w/2)`, `(-l/2, -w/2)`,
//! `(-l/2, +w/2)` at `z = -h/2`, then the same four at `z = +h/2`.

/// Eight corners, bottom four then top four.
pub type Corners = [[f64; 3]; 8];

/// The corners of a box (`size` l, w, h; `center` its centre; `yaw` about z).
pub fn corners(center: [f64; 3], size: [f64; 3], yaw: f64) -> Corners {
    let [l, w, h] = size;
    let (s, c) = yaw.sin_cos();
    const SIGNS: [(f64, f64); 4] = [(1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0)];
    std::array::from_fn(|i| {
        let (sx, sy) = SIGNS[i % 4];
        let (x, y) = (sx * l / 2.0, sy * w / 2.0);
        let z = if i < 4 { -h / 2.0 } else { h / 2.0 };
        [
            center[0] + c * x - s * y,
            center[1] + s * x + c * y,
            center[2] + z,
        ]
    })
}

/// A box read back from its corners: centre, size (l, w, h) and yaw.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct CornerBox {
    /// The mean of the corners.
    pub center: [f64; 3],
    /// Length, width, height: the mean length of each group of four parallel edges.
    pub size: [f64; 3],
    /// The direction of the mean back-to-front edge in the x-y plane.
    pub yaw: f64,
}

/// For length (back to front), width and height, the four edges of each as (to, from) corners.
pub type EdgeGroups = [[(usize, usize); 4]; 3];

/// The edges of [`corners`]' order.
const EDGES: EdgeGroups = [
    [(0, 3), (1, 2), (4, 7), (5, 6)],
    [(0, 1), (3, 2), (4, 5), (7, 6)],
    [(4, 0), (5, 1), (6, 2), (7, 3)],
];

/// Why eight corners are not a box's.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CornerError {
    /// A coordinate is NaN or infinite.
    #[error("a corner is not a finite number")]
    NotFinite,
    /// The four parallel edges of one dimension disagree in length.
    #[error("the corners are not a box: its {dimension} edges measure {lengths:.3?} m")]
    Edges {
        /// `length`, `width` or `height`.
        dimension: &'static str,
        /// The four edges' lengths (m).
        lengths: Vec<f64>,
    },
    /// Length and width are not square.
    #[error("the corners are not a box: its length and width edges are not square")]
    NotSquare,
}

/// The box of eight corners whose edges are `groups`: every group of four parallel edges must
/// agree in length within 5 cm + 5%, and length must stand square to width within about 3
/// degrees.
pub fn box_of(c: &Corners, groups: &EdgeGroups) -> Result<CornerBox, CornerError> {
    if c.iter().flatten().any(|v| !v.is_finite()) {
        return Err(CornerError::NotFinite);
    }
    let sub = |a: usize, b: usize| -> [f64; 3] { std::array::from_fn(|k| c[a][k] - c[b][k]) };
    let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let mut size = [0.0; 3];
    let mut mean_edge = [[0.0; 3]; 3];
    for (g, edges) in groups.iter().enumerate() {
        let lengths: Vec<f64> = edges.iter().map(|&(a, b)| norm(sub(a, b))).collect();
        let mean = lengths.iter().sum::<f64>() / 4.0;
        if lengths
            .iter()
            .any(|l| (l - mean).abs() > 0.05 + 0.05 * mean)
        {
            return Err(CornerError::Edges {
                dimension: ["length", "width", "height"][g],
                lengths,
            });
        }
        size[g] = mean;
        for &(a, b) in edges {
            let d = sub(a, b);
            for k in 0..3 {
                mean_edge[g][k] += d[k] / 4.0;
            }
        }
    }
    let (l, w) = (mean_edge[0], mean_edge[1]);
    let dot = l.iter().zip(w).map(|(a, b)| a * b).sum::<f64>();
    if size[0] > 0.0 && size[1] > 0.0 && (dot / (size[0] * size[1])).abs() > 0.05 {
        return Err(CornerError::NotSquare);
    }
    let center = std::array::from_fn(|k| c.iter().map(|p| p[k]).sum::<f64>() / 8.0);
    Ok(CornerBox {
        center,
        size,
        yaw: l[1].atan2(l[0]),
    })
}

/// The box whose corners, in [`corners`]' order, these are, or why they are not a box's.
pub fn from_corners(c: &Corners) -> Result<CornerBox, CornerError> {
    box_of(c, &EDGES)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_of_a_box_by_hand() {
        // A 4 x 2 x 1.5 box at (10, 20, 1) facing +y: the front-left corner (+l/2, +w/2) lies at
        // (10 - 1, 20 + 2) on the bottom, z = 0.25.
        let c = corners(
            [10.0, 20.0, 1.0],
            [4.0, 2.0, 1.5],
            std::f64::consts::FRAC_PI_2,
        );
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        assert!(close(c[0], [9.0, 22.0, 0.25]));
        assert!(close(c[1], [11.0, 22.0, 0.25]));
        assert!(close(c[2], [11.0, 18.0, 0.25]));
        assert!(close(c[3], [9.0, 18.0, 0.25]));
        assert!(close(c[6], [11.0, 18.0, 1.75]));
        let b = from_corners(&c).unwrap();
        assert!(close(b.center, [10.0, 20.0, 1.0]));
        assert!(close(b.size, [4.0, 2.0, 1.5]));
        assert!((b.yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn corners_that_are_no_box_are_refused() {
        let mut c = corners([0.0; 3], [4.0, 2.0, 1.5], 0.3);
        c[5][0] += 1.0;
        let e = from_corners(&c).unwrap_err();
        assert!(
            matches!(
                e,
                CornerError::Edges {
                    dimension: "length",
                    ..
                }
            ),
            "{e}"
        );
        c = corners([0.0; 3], [4.0, 2.0, 1.5], 0.3);
        c[2][1] = f64::NAN;
        assert_eq!(from_corners(&c), Err(CornerError::NotFinite));
    }
}
