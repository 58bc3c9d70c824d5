//! Boxes and classes the workspace's tests, benches and examples build scenes from (feature
//! `fixtures`; not part of the formats).

use crate::{Class, Detection, Uncertainty, NO_ID};

/// A nuScenes-like urban mix in ten draws (four cars, two pedestrians, a barrier, a cone, a
/// truck, a bicycle).
pub const URBAN_MIX: [Class; 10] = [
    Class::Car,
    Class::Car,
    Class::Car,
    Class::Car,
    Class::Pedestrian,
    Class::Pedestrian,
    Class::Barrier,
    Class::TrafficCone,
    Class::Truck,
    Class::Bicycle,
];

/// A car of typical size (4.5 x 1.9 x 1.6 m) centred at (x, y, 0) and heading along x, with
/// `pos_std` m of position std and 0.1 of size and yaw std, score 0.8, no velocity, no id.
pub fn car(x: f64, y: f64, pos_std: f64) -> Detection {
    Detection {
        class: Class::Car,
        center: [x, y, 0.0],
        size: [4.5, 1.9, 1.6],
        yaw: 0.0,
        score: 0.8,
        std: Uncertainty::uniform(pos_std, 0.1, 0.1),
        pos_cov: None,
        velocity: None,
        id: NO_ID,
    }
}
