//! Domain types: object classes, detections with per-field uncertainty, frames.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

use crate::UnknownName;

/// One of the 10 nuScenes detection classes.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    /// Passenger car.
    Car,
    /// Truck.
    Truck,
    /// Bus (rigid or bendy).
    Bus,
    /// Trailer.
    Trailer,
    /// Construction vehicle.
    ConstructionVehicle,
    /// Pedestrian.
    Pedestrian,
    /// Motorcycle.
    Motorcycle,
    /// Bicycle.
    Bicycle,
    /// Traffic cone.
    TrafficCone,
    /// Barrier.
    Barrier,
}

impl Class {
    /// All classes, in wire-code order.
    pub const ALL: [Class; 10] = [
        Class::Car,
        Class::Truck,
        Class::Bus,
        Class::Trailer,
        Class::ConstructionVehicle,
        Class::Pedestrian,
        Class::Motorcycle,
        Class::Bicycle,
        Class::TrafficCone,
        Class::Barrier,
    ];

    /// The seven classes of the nuScenes tracking benchmark (`tracking_name`), alphabetically
    /// as its devkit lists them: no construction vehicle, traffic cone or barrier.
    pub const TRACKING: [Class; 7] = [
        Class::Bicycle,
        Class::Bus,
        Class::Car,
        Class::Motorcycle,
        Class::Pedestrian,
        Class::Trailer,
        Class::Truck,
    ];

    /// Whether the nuScenes tracking benchmark scores this class (it is a `tracking_name`).
    pub fn is_tracking(self) -> bool {
        Class::TRACKING.contains(&self)
    }

    /// The nuScenes detection name (`detection_name` in results files).
    pub fn name(self) -> &'static str {
        match self {
            Class::Car => "car",
            Class::Truck => "truck",
            Class::Bus => "bus",
            Class::Trailer => "trailer",
            Class::ConstructionVehicle => "construction_vehicle",
            Class::Pedestrian => "pedestrian",
            Class::Motorcycle => "motorcycle",
            Class::Bicycle => "bicycle",
            Class::TrafficCone => "traffic_cone",
            Class::Barrier => "barrier",
        }
    }

    /// The class of a nuScenes detection name, if it is one.
    pub fn from_name(name: &str) -> Option<Class> {
        Class::ALL.into_iter().find(|c| c.name() == name)
    }

    /// The wire code of the class (its index in [`Class::ALL`]).
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The class of a wire code, if it is one.
    pub fn from_code(code: u8) -> Option<Class> {
        Class::ALL.get(code as usize).copied()
    }

    /// The detection class of a nuScenes category name (`category.json`), as the nuScenes
    /// detection benchmark maps it; `None` for categories it ignores.
    pub fn from_category(category: &str) -> Option<Class> {
        Some(match category {
            "vehicle.car" => Class::Car,
            "vehicle.truck" => Class::Truck,
            "vehicle.bus.bendy" | "vehicle.bus.rigid" => Class::Bus,
            "vehicle.trailer" => Class::Trailer,
            "vehicle.construction" => Class::ConstructionVehicle,
            "human.pedestrian.adult"
            | "human.pedestrian.child"
            | "human.pedestrian.construction_worker"
            | "human.pedestrian.police_officer" => Class::Pedestrian,
            "vehicle.motorcycle" => Class::Motorcycle,
            "vehicle.bicycle" => Class::Bicycle,
            "movable_object.trafficcone" => Class::TrafficCone,
            "movable_object.barrier" => Class::Barrier,
            _ => return None,
        })
    }

    /// The period of the yaw angle for this class: pi for the symmetric barrier, 2 pi otherwise.
    pub fn yaw_period(self) -> f64 {
        if self == Class::Barrier {
            PI
        } else {
            2.0 * PI
        }
    }

    /// A typical size (l, w, h) in metres, the reference the wire codes sizes against.
    pub fn typical_size(self) -> [f64; 3] {
        match self {
            Class::Car => [4.6, 1.95, 1.75],
            Class::Truck => [7.0, 2.5, 3.0],
            Class::Bus => [11.0, 2.9, 3.5],
            Class::Trailer => [12.0, 2.9, 3.8],
            Class::ConstructionVehicle => [6.5, 2.8, 3.2],
            Class::Pedestrian => [0.75, 0.67, 1.75],
            Class::Motorcycle => [2.1, 0.8, 1.5],
            Class::Bicycle => [1.75, 0.6, 1.3],
            Class::TrafficCone => [0.4, 0.4, 1.0],
            Class::Barrier => [0.5, 2.5, 1.0],
        }
    }
}

impl fmt::Display for Class {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Class {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Class::from_name(s)
            .ok_or_else(|| UnknownName::new("class", s, Class::ALL.iter().map(|c| c.name())))
    }
}

/// Per-field standard deviations of a detection (metres and radians).
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Uncertainty {
    /// Centre std along x, y, z (m).
    pub pos: [f64; 3],
    /// Size std along l, w, h (m).
    pub size: [f64; 3],
    /// Yaw std (rad).
    pub yaw: f64,
}

impl Uncertainty {
    /// The same std on every position axis, every size axis, and for yaw.
    pub fn uniform(pos: f64, size: f64, yaw: f64) -> Self {
        Uncertainty {
            pos: [pos; 3],
            size: [size; 3],
            yaw,
        }
    }

    /// All seven stds in the order x, y, z, l, w, h, yaw.
    pub fn as_array(&self) -> [f64; 7] {
        let [x, y, z] = self.pos;
        let [l, w, h] = self.size;
        [x, y, z, l, w, h, self.yaw]
    }

    /// The stds from an array in the order x, y, z, l, w, h, yaw.
    pub fn from_array(a: [f64; 7]) -> Self {
        Uncertainty {
            pos: [a[0], a[1], a[2]],
            size: [a[3], a[4], a[5]],
            yaw: a[6],
        }
    }

    /// True when every std lies in the wire's range ([`crate::limits::STD_MIN`] to about 10^4).
    pub fn is_valid(&self) -> bool {
        self.as_array()
            .iter()
            .all(|s| crate::limits::std_in_range(*s))
    }
}

/// The noise profiles of the paper's simulation (`docs/method.md` §5).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseProfile {
    /// 0.5 m, 5 deg, 0.1 m.
    Mild,
    /// 1.5 m, 20 deg, 0.5 m.
    Moderate,
    /// 3.0 m, 60 deg, 1.0 m.
    Large,
}

impl NoiseProfile {
    /// All profiles, mildest first.
    pub const ALL: [NoiseProfile; 3] = [
        NoiseProfile::Mild,
        NoiseProfile::Moderate,
        NoiseProfile::Large,
    ];

    /// The profile's standard deviations.
    pub fn std(self) -> Uncertainty {
        let (pos, yaw_deg, size) = match self {
            NoiseProfile::Mild => (0.5, 5.0, 0.1),
            NoiseProfile::Moderate => (1.5, 20.0, 0.5),
            NoiseProfile::Large => (3.0, 60.0, 1.0),
        };
        Uncertainty::uniform(pos, size, f64::to_radians(yaw_deg))
    }

    /// The profile's velocity std (m/s per axis): 0.25, 0.5 and 1.0, the velocity errors
    /// (mAVE) of lidar detectors, of good camera detectors and of monocular camera detectors on
    /// the nuScenes benchmark, matching the profiles' grades of position error.
    pub fn velocity_std(self) -> f64 {
        match self {
            NoiseProfile::Mild => 0.25,
            NoiseProfile::Moderate => 0.5,
            NoiseProfile::Large => 1.0,
        }
    }

    /// The profile's base confidence (0.9, 0.7, 0.5).
    pub fn base_confidence(self) -> f64 {
        match self {
            NoiseProfile::Mild => 0.9,
            NoiseProfile::Moderate => 0.7,
            NoiseProfile::Large => 0.5,
        }
    }

    /// The profile's name.
    pub fn name(self) -> &'static str {
        match self {
            NoiseProfile::Mild => "mild",
            NoiseProfile::Moderate => "moderate",
            NoiseProfile::Large => "large",
        }
    }
}

impl fmt::Display for NoiseProfile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for NoiseProfile {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        NoiseProfile::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                UnknownName::new(
                    "noise profile",
                    s,
                    NoiseProfile::ALL.map(NoiseProfile::name),
                )
            })
    }
}

/// Why a std setting cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StdSettingError {
    /// Neither a profile nor three numbers.
    #[error("invalid std '{0}': expected mild, moderate, large or three numbers POS,SIZE,YAW_DEG")]
    Form(String),
    /// Three numbers, one outside the wire's domain.
    #[error(
        "invalid std '{0}': each value must lie in [{min}, {max:.0}] (metres, metres, degrees)",
        min = crate::limits::STD_MIN,
        max = crate::limits::std_max()
    )]
    OutOfRange(String),
}

/// Parses a std setting: a profile name, or `POS,SIZE,YAW_DEG` in metres and degrees.
pub fn parse_std(s: &str) -> Result<Uncertainty, StdSettingError> {
    if let Ok(p) = s.parse::<NoiseProfile>() {
        return Ok(p.std());
    }
    let form = || StdSettingError::Form(s.to_string());
    let parts: Vec<f64> = s
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| form())?;
    let [pos, size, yaw] = parts[..] else {
        return Err(form());
    };
    let u = Uncertainty::uniform(pos, size, yaw.to_radians());
    if u.is_valid() {
        Ok(u)
    } else {
        Err(StdSettingError::OutOfRange(s.to_string()))
    }
}

/// Identifier of no object: a detection that carries no object id.
pub const NO_ID: u32 = u32::MAX;

/// One detected 3D box in the shared map frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Object class.
    pub class: Class,
    /// Centre x, y, z in the map frame (m).
    pub center: [f64; 3],
    /// Size l, w, h (m).
    pub size: [f64; 3],
    /// Yaw about +z (rad, 0 along +x), wrapped to (-pi, pi].
    pub yaw: f64,
    /// Confidence in [0, 1].
    pub score: f64,
    /// Per-field standard deviations.
    pub std: Uncertainty,
    /// Full 3x3 centre covariance (row-major, m^2) when the source gives one; it overrides
    /// `std.pos` in association and fusion. Boxed: most boxes have none, and the 72 bytes
    /// inline would make every detection a third larger.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pos_cov: Option<Box<[[f64; 3]; 3]>>,
    /// Velocity in the map's x-y plane with its stds, when the source measures it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<Velocity>,
    /// Agent-local object id (in simulation the ground-truth instance), or [`NO_ID`].
    pub id: u32,
}

impl Detection {
    /// The centre covariance: the full one when present, else diagonal from `std.pos`.
    pub fn position_covariance(&self) -> [[f64; 3]; 3] {
        self.pos_cov.as_deref().copied().unwrap_or_else(|| {
            let [x, y, z] = self.std.pos;
            [[x * x, 0.0, 0.0], [0.0, y * y, 0.0], [0.0, 0.0, z * z]]
        })
    }

    /// Sum of the seven variances: how uncertain the detection is overall (smaller is surer).
    pub fn total_variance(&self) -> f64 {
        let cov = self.position_covariance();
        let pos = cov[0][0] + cov[1][1] + cov[2][2];
        pos + self.std.size.iter().map(|s| s * s).sum::<f64>() + self.std.yaw * self.std.yaw
    }

    /// Bird's-eye-view footprint corners (x, y), counter-clockwise.
    pub fn bev_corners(&self) -> [[f64; 2]; 4] {
        let (s, c) = self.yaw.sin_cos();
        let (hl, hw) = (self.size[0] / 2.0, self.size[1] / 2.0);
        let [x, y, _] = self.center;
        let pts = [(hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw)];
        pts.map(|(dx, dy)| [x + c * dx - s * dy, y + s * dx + c * dy])
    }
}

/// A velocity over ground (m/s) with its per-axis standard deviations.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Velocity {
    /// vx, vy in the map frame (m/s).
    pub v: [f64; 2],
    /// Std of vx and vy (m/s).
    pub std: [f64; 2],
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    if a > -PI && a <= PI {
        return a;
    }
    let two_pi = 2.0 * PI;
    let r = (a + PI).rem_euclid(two_pi) - PI;
    if r <= -PI {
        r + two_pi
    } else {
        r
    }
}

impl Default for Detection {
    /// A car at the origin with its class's typical size, score 0.5, stds of 1 (m, m, rad) and
    /// no id: a starting point for building detections field by field.
    fn default() -> Self {
        Detection {
            class: Class::Car,
            center: [0.0; 3],
            size: Class::Car.typical_size(),
            yaw: 0.0,
            score: 0.5,
            std: Uncertainty::uniform(1.0, 1.0, 1.0),
            pos_cov: None,
            velocity: None,
            id: NO_ID,
        }
    }
}

/// What kind of agent produced a frame.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum AgentKind {
    /// A connected vehicle.
    #[default]
    Vehicle,
    /// A roadside (infrastructure) unit.
    Infrastructure,
}

impl FromStr for AgentKind {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "vehicle" => Ok(AgentKind::Vehicle),
            "infrastructure" | "infra" | "rsu" => Ok(AgentKind::Infrastructure),
            _ => Err(UnknownName::new(
                "agent kind",
                s,
                ["vehicle", "infrastructure"],
            )),
        }
    }
}

/// One agent's detections at one capture time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// The sending agent's name (the last segment of its key expression).
    pub agent: String,
    /// Vehicle or infrastructure.
    pub kind: AgentKind,
    /// Sequence number, increasing by one per frame sent.
    pub seq: u32,
    /// Capture time on the sensor clock (microseconds).
    pub capture_us: u64,
    /// Reference point of the frame in the map frame (m); the wire codes positions against it.
    pub origin: [f64; 3],
    /// The detected boxes.
    pub detections: Vec<Detection>,
}

impl Frame {
    /// Sets `origin` to the centroid of the detections (or keeps it when there are none).
    pub fn with_centroid_origin(mut self) -> Self {
        if !self.detections.is_empty() {
            let n = self.detections.len() as f64;
            let mut o = [0.0; 3];
            for d in &self.detections {
                for (k, v) in o.iter_mut().enumerate() {
                    *v += d.center[k] / n;
                }
            }
            self.origin = o;
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fusion of large scenes is bound by memory traffic: a detection must not grow unnoticed.
    #[test]
    #[cfg(target_pointer_width = "64")]
    fn a_detection_takes_176_bytes() {
        assert_eq!(std::mem::size_of::<Detection>(), 176);
    }

    #[test]
    fn wrap_angle_is_half_open() {
        assert_eq!(wrap_angle(PI), PI);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.5 + 4.0 * PI) - 0.5).abs() < 1e-12);
        assert!((wrap_angle(-0.5 - 2.0 * PI) + 0.5).abs() < 1e-12);
    }

    #[test]
    fn class_names_and_categories() {
        for c in Class::ALL {
            assert_eq!(Class::from_name(c.name()), Some(c));
            assert_eq!(Class::from_code(c.code()), Some(c));
        }
        assert_eq!(Class::from_category("vehicle.bus.rigid"), Some(Class::Bus));
        assert_eq!(
            Class::from_category("human.pedestrian.child"),
            Some(Class::Pedestrian)
        );
        assert_eq!(Class::from_category("human.pedestrian.stroller"), None);
        assert_eq!(Class::from_code(10), None);
        assert!("lorry"
            .parse::<Class>()
            .unwrap_err()
            .expected
            .contains(&"car"));
    }

    #[test]
    fn bev_corners_of_rotated_box() {
        let d = Detection {
            class: Class::Car,
            center: [1.0, 2.0, 0.0],
            size: [4.0, 2.0, 1.5],
            yaw: PI / 2.0,
            score: 1.0,
            std: Uncertainty::uniform(1.0, 1.0, 1.0),
            pos_cov: None,
            velocity: None,
            id: 0,
        };
        let c = d.bev_corners();
        assert!((c[0][0] - 0.0).abs() < 1e-12 && (c[0][1] - 4.0).abs() < 1e-12);
    }
}
