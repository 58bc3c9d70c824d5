//! The messages' fields as CDR carries them, in the order of `ros/msg/` (serde with
//! cdr-encoding, behind the 4-byte encapsulation header).

use serde::de::{Error as _, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// `builtin_interfaces/msg/Time`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

/// `std_msgs/msg/Header`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was captured.
    pub stamp: Time,
    /// The coordinate frame the data is in.
    pub frame_id: String,
}

/// `geometry_msgs/msg/Point` and `Vector3`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

/// A 6 x 6 covariance, row-major (x, y, z, rotation about x, y, z), as a fixed array of 36.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Covariance([0.0; 36])
    }
}

impl Serialize for Covariance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("36 float64")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (i, v) in c.iter_mut().enumerate() {
                    *v = seq
                        .next_element()?
                        .ok_or_else(|| A::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, V)
    }
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `geometry_msgs/msg/Twist`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity.
    pub linear: Vector3,
    /// Angular velocity.
    pub angular: Vector3,
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `geometry_msgs/msg/Point32`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point32 {
    /// x.
    pub x: f32,
    /// y.
    pub y: f32,
    /// z.
    pub z: f32,
}

/// `geometry_msgs/msg/Polygon`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Polygon {
    /// Its corners.
    pub points: Vec<Point32>,
}

/// `vision_msgs/msg/ObjectHypothesis`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ObjectHypothesis {
    /// The class, as the detector names it.
    pub class_id: String,
    /// Its score.
    pub score: f64,
}

/// `vision_msgs/msg/ObjectHypothesisWithPose`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ObjectHypothesisWithPose {
    /// Class and score.
    pub hypothesis: ObjectHypothesis,
    /// The pose with its covariance.
    pub pose: PoseWithCovariance,
}

/// `vision_msgs/msg/BoundingBox3D`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BoundingBox3D {
    /// The box's centre and orientation.
    pub center: Pose,
    /// Its size along its own x (length), y (width), z (height).
    pub size: Vector3,
}

/// `vision_msgs/msg/Detection3D`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Detection3D {
    /// Its own header.
    pub header: Header,
    /// Class hypotheses.
    pub results: Vec<ObjectHypothesisWithPose>,
    /// The box.
    pub bbox: BoundingBox3D,
    /// A tracking id, if any.
    pub id: String,
}

/// `vision_msgs/msg/Detection3DArray`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Detection3DArray {
    /// Stamp and frame of every detection.
    pub header: Header,
    /// The detections.
    pub detections: Vec<Detection3D>,
}

/// `autoware_perception_msgs/msg/ObjectClassification`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ObjectClassification {
    /// UNKNOWN 0, CAR 1, TRUCK 2, BUS 3, TRAILER 4, MOTORCYCLE 5, BICYCLE 6, PEDESTRIAN 7, ...
    pub label: u8,
    /// Its probability.
    pub probability: f32,
}

/// `autoware_perception_msgs/msg/Shape`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Shape {
    /// BOUNDING_BOX 0, CYLINDER 1, POLYGON 2.
    #[serde(rename = "type")]
    pub kind: u8,
    /// The footprint, for a polygon.
    pub footprint: Polygon,
    /// For a box: x length, y width, z height.
    pub dimensions: Vector3,
}

/// `autoware_perception_msgs/msg/DetectedObjectKinematics`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DetectedObjectKinematics {
    /// The pose with its covariance.
    pub pose_with_covariance: PoseWithCovariance,
    /// Whether the covariance is given.
    pub has_position_covariance: bool,
    /// UNAVAILABLE 0, SIGN_UNKNOWN 1, AVAILABLE 2.
    pub orientation_availability: u8,
    /// Velocity in the object's frame, with its covariance.
    pub twist_with_covariance: TwistWithCovariance,
    /// Whether the twist is given.
    pub has_twist: bool,
    /// Whether its covariance is given.
    pub has_twist_covariance: bool,
}

/// `autoware_perception_msgs/msg/DetectedObject`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DetectedObject {
    /// How likely the object exists.
    pub existence_probability: f32,
    /// Class probabilities.
    pub classification: Vec<ObjectClassification>,
    /// Pose and velocity.
    pub kinematics: DetectedObjectKinematics,
    /// Its shape.
    pub shape: Shape,
}

/// `autoware_perception_msgs/msg/DetectedObjects`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DetectedObjects {
    /// Stamp and frame of every object.
    pub header: Header,
    /// The objects.
    pub objects: Vec<DetectedObject>,
}

/// `unique_identifier_msgs/msg/UUID`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Uuid {
    /// The 16 bytes.
    pub uuid: [u8; 16],
}

/// `geometry_msgs/msg/Accel`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Accel {
    /// Linear acceleration.
    pub linear: Vector3,
    /// Angular acceleration.
    pub angular: Vector3,
}

/// `geometry_msgs/msg/AccelWithCovariance`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AccelWithCovariance {
    /// The acceleration.
    pub accel: Accel,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `autoware_perception_msgs/msg/TrackedObjectKinematics`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackedObjectKinematics {
    /// The pose with its covariance.
    pub pose_with_covariance: PoseWithCovariance,
    /// Velocity in the object's frame, with its covariance.
    pub twist_with_covariance: TwistWithCovariance,
    /// Acceleration, with its covariance.
    pub acceleration_with_covariance: AccelWithCovariance,
    /// UNAVAILABLE 0, SIGN_UNKNOWN 1, AVAILABLE 2.
    pub orientation_availability: u8,
    /// Whether the object stands still.
    pub is_stationary: bool,
}

/// `autoware_perception_msgs/msg/TrackedObject`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackedObject {
    /// The track's id.
    pub object_id: Uuid,
    /// How likely the object exists.
    pub existence_probability: f32,
    /// Class probabilities.
    pub classification: Vec<ObjectClassification>,
    /// Pose, velocity and acceleration.
    pub kinematics: TrackedObjectKinematics,
    /// Its shape.
    pub shape: Shape,
}

/// `autoware_perception_msgs/msg/TrackedObjects`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackedObjects {
    /// Stamp and frame of every object.
    pub header: Header,
    /// The tracks.
    pub objects: Vec<TrackedObject>,
}

/// A message type the project reads or writes.
pub trait Message: Serialize + for<'de> Deserialize<'de> {
    /// Its full name, `pkg/msg/Name`.
    const NAME: &'static str;
}

impl Message for Detection3DArray {
    const NAME: &'static str = "vision_msgs/msg/Detection3DArray";
}

impl Message for DetectedObjects {
    const NAME: &'static str = "autoware_perception_msgs/msg/DetectedObjects";
}

impl Message for TrackedObjects {
    const NAME: &'static str = "autoware_perception_msgs/msg/TrackedObjects";
}
