//! The true-state oracle of the tracking table (`gt-state-wls tracked`): each agent's boxes
//! grouped with the likeliest true object given every object's true centre and velocity, then
//! fused by WLS-3D. Where `gt-wls` groups by the id that made each box, this groups by what the
//! boxes themselves measure, so it is the best grouping their centres and velocities allow a
//! frame at a time; the gap between the two is what no association from boxes can recover.
//!
//! Per frame and agent a, over the true objects o of the box's class:
//! d2(b, o) = (c_b - c_o)^T C_b^-1 (c_b - c_o) + sum_k (v_bk - v_ok)^2 / s_vk^2 (x, y; the
//! velocity term when both have one), inside the 99.9% chi-square gate for its degrees of
//! freedom; the largest matching of least total d2 gives each object at most one box per
//! agent. A box no object takes stays a group of its own.

use v2x_fuser::maths::association::{
    assign, mahalanobis2_plane, velocity_distance2, Edge, CHI2_2_999,
};
use v2x_fuser::maths::fusion::fuse_group;
use v2x_protocol::{Detection, Velocity};

use crate::dataset::GtObject;

/// The 99.9% quantile of the chi-square distribution with 4 degrees of freedom (centre and
/// velocity in the plane).
const CHI2_4_999: f64 = 18.467;

/// An object as an exact box: its velocity without variance, so that a distance to it weighs
/// by the other box's variance alone.
fn exact(o: &GtObject) -> Detection {
    let mut d = o.as_detection();
    d.velocity = o.velocity.map(|v| Velocity { v, std: [0.0; 2] });
    d
}

/// The squared distance of box `b` to the exact box `o` in the plane (centre, and velocity
/// when both have one) and its gate, or `None` when the centre's covariance is singular.
fn distance2(b: &Detection, o: &Detection) -> Option<(f64, f64)> {
    let c = b.position_covariance();
    let d = [b.center[0] - o.center[0], b.center[1] - o.center[1]];
    let d2 = mahalanobis2_plane(d, [[c[0][0], c[0][1]], [c[1][0], c[1][1]]])?;
    let measured = b
        .velocity
        .as_ref()
        .is_some_and(|v| v.std.iter().all(|s| *s > 0.0));
    match velocity_distance2(b, o).filter(|_| measured) {
        Some(dv2) => Some((d2 + dv2, CHI2_4_999)),
        None => Some((d2, CHI2_2_999)),
    }
}

/// The frame's fused boxes: each agent's boxes (`agents[a]`) grouped with the true objects
/// `objects` by least d2, each group fused by WLS-3D, the boxes no object took alone.
pub fn fuse_by_state(agents: &[Vec<Detection>], objects: &[GtObject]) -> Vec<Detection> {
    let mut groups: Vec<Vec<&Detection>> = vec![Vec::new(); objects.len()];
    let mut alone = Vec::new();
    let truths: Vec<Detection> = objects.iter().map(exact).collect();
    for boxes in agents {
        let mut edges = Vec::new();
        for (o, obj) in truths.iter().enumerate() {
            for (j, b) in boxes.iter().enumerate() {
                if b.class != obj.class {
                    continue;
                }
                if let Some((d2, _)) = distance2(b, obj).filter(|(d2, gate)| d2 <= gate) {
                    edges.push(Edge::new(o, j, d2));
                }
            }
        }
        let mut taken = vec![false; boxes.len()];
        for (o, j) in assign(objects.len(), boxes.len(), &edges) {
            groups[o].push(&boxes[j]);
            taken[j] = true;
        }
        alone.extend(boxes.iter().zip(taken).filter(|(_, t)| !t).map(|(b, _)| b));
    }
    groups
        .iter()
        .filter(|g| !g.is_empty())
        .map(|g| fuse_group(g))
        .chain(alone.into_iter().cloned())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::{Class, Uncertainty};

    fn object(id: u32, x: f64, vx: f64) -> GtObject {
        GtObject {
            id,
            class: Class::Pedestrian,
            center: [x, 0.0, 1.0],
            size: [0.7, 0.7, 1.8],
            yaw: 0.0,
            velocity: Some([vx, 0.0]),
        }
    }

    /// A pedestrian's box at x with 1 m of position noise, velocity vx (std 0.5), made by `id`.
    fn ped(id: u32, x: f64, vx: Option<f64>) -> Detection {
        Detection {
            class: Class::Pedestrian,
            center: [x, 0.0, 1.0],
            size: [0.7, 0.7, 1.8],
            yaw: 0.0,
            score: 0.9,
            std: Uncertainty::uniform(1.0, 0.1, 0.1),
            pos_cov: None,
            velocity: vx.map(|v| Velocity {
                v: [v, 0.0],
                std: [0.5, 0.5],
            }),
            id,
        }
    }

    #[test]
    fn velocity_tells_two_close_pedestrians_apart() {
        // A at x = 0 walking +1 m/s, B at x = 1 walking -1 m/s. Agent 1's box of A lies at
        // x = 0.8 and its box of B at 0.1: by centre alone they swap (0.04 + 0.01 against
        // 0.64 + 0.81); each velocity is 2 m/s, (2 / 0.5)^2 = 16, from the other object's,
        // so with velocities each box goes to its own object (1.45 against 32.05).
        let objects = [object(1, 0.0, 1.0), object(2, 1.0, -1.0)];
        let boxes = |v: bool| -> Vec<Vec<Detection>> {
            let (a, b) = if v {
                (Some(1.0), Some(-1.0))
            } else {
                (None, None)
            };
            vec![
                vec![ped(1, 0.8, a), ped(2, 0.1, b)],
                vec![ped(1, 0.2, a), ped(2, 0.9, b)],
            ]
        };
        let out = fuse_by_state(&boxes(true), &objects);
        assert_eq!(out.len(), 2, "{out:?}");
        // WLS of equal stds: the mean of each object's two boxes.
        for (o, vx) in out.iter().zip([1.0, -1.0]) {
            assert!((o.center[0] - 0.5).abs() < 1e-12, "{out:?}");
            assert!((o.velocity.as_ref().unwrap().v[0] - vx).abs() < 1e-12);
        }
        assert_eq!((out[0].id, out[1].id), (1, 2));
        // By centre alone: A takes agent 1's box of B (0.1) and agent 2's of A (0.2).
        let out = fuse_by_state(&boxes(false), &objects);
        assert_eq!(out.len(), 2, "{out:?}");
        assert!((out[0].center[0] - 0.15).abs() < 1e-12, "{out:?}");
        assert!((out[1].center[0] - 0.85).abs() < 1e-12, "{out:?}");
        assert_eq!((out[0].id, out[1].id), (2, 1));
    }

    #[test]
    fn a_box_beyond_every_gate_or_of_another_class_stays_alone() {
        let objects = [object(1, 0.0, 0.0)];
        let mut car = ped(9, 0.1, None);
        car.class = Class::Car;
        // 4 m from the object at 1 m std: d2 = 16 > 13.816.
        let agents = vec![vec![ped(1, 0.3, None), car], vec![ped(3, 4.0, None)]];
        let out = fuse_by_state(&agents, &objects);
        assert_eq!(out.len(), 3, "{out:?}");
        assert_eq!(out[0].center[0], 0.3);
        assert_eq!(out[1].class, Class::Car);
        assert_eq!(out[2].center[0], 4.0);
    }
}
