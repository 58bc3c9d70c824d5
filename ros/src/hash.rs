//! Type hashes of ROS 2 messages (RIHS01, REP 2011), which rmw_zenoh puts in every key: the
//! SHA-256 of the type's description and those it refers to, as canonical JSON, computed from
//! the field lists in `ros/msg/`.

use sha2::{Digest, Sha256};
use std::collections::BTreeMap;

/// Every message type the project knows, by its full name, with its fields as in its `.msg`.
const DEFINITIONS: [(&str, &str); 27] = [
    (
        "autoware_perception_msgs/msg/DetectedObject",
        include_str!("../msg/autoware_perception_msgs.DetectedObject.msg"),
    ),
    (
        "autoware_perception_msgs/msg/DetectedObjectKinematics",
        include_str!("../msg/autoware_perception_msgs.DetectedObjectKinematics.msg"),
    ),
    (
        "autoware_perception_msgs/msg/DetectedObjects",
        include_str!("../msg/autoware_perception_msgs.DetectedObjects.msg"),
    ),
    (
        "autoware_perception_msgs/msg/ObjectClassification",
        include_str!("../msg/autoware_perception_msgs.ObjectClassification.msg"),
    ),
    (
        "autoware_perception_msgs/msg/Shape",
        include_str!("../msg/autoware_perception_msgs.Shape.msg"),
    ),
    (
        "autoware_perception_msgs/msg/TrackedObject",
        include_str!("../msg/autoware_perception_msgs.TrackedObject.msg"),
    ),
    (
        "autoware_perception_msgs/msg/TrackedObjectKinematics",
        include_str!("../msg/autoware_perception_msgs.TrackedObjectKinematics.msg"),
    ),
    (
        "autoware_perception_msgs/msg/TrackedObjects",
        include_str!("../msg/autoware_perception_msgs.TrackedObjects.msg"),
    ),
    (
        "builtin_interfaces/msg/Time",
        include_str!("../msg/builtin_interfaces.Time.msg"),
    ),
    (
        "geometry_msgs/msg/Accel",
        include_str!("../msg/geometry_msgs.Accel.msg"),
    ),
    (
        "geometry_msgs/msg/AccelWithCovariance",
        include_str!("../msg/geometry_msgs.AccelWithCovariance.msg"),
    ),
    (
        "geometry_msgs/msg/Point",
        include_str!("../msg/geometry_msgs.Point.msg"),
    ),
    (
        "geometry_msgs/msg/Point32",
        include_str!("../msg/geometry_msgs.Point32.msg"),
    ),
    (
        "geometry_msgs/msg/Polygon",
        include_str!("../msg/geometry_msgs.Polygon.msg"),
    ),
    (
        "geometry_msgs/msg/Pose",
        include_str!("../msg/geometry_msgs.Pose.msg"),
    ),
    (
        "geometry_msgs/msg/PoseWithCovariance",
        include_str!("../msg/geometry_msgs.PoseWithCovariance.msg"),
    ),
    (
        "geometry_msgs/msg/Quaternion",
        include_str!("../msg/geometry_msgs.Quaternion.msg"),
    ),
    (
        "geometry_msgs/msg/Twist",
        include_str!("../msg/geometry_msgs.Twist.msg"),
    ),
    (
        "geometry_msgs/msg/TwistWithCovariance",
        include_str!("../msg/geometry_msgs.TwistWithCovariance.msg"),
    ),
    (
        "geometry_msgs/msg/Vector3",
        include_str!("../msg/geometry_msgs.Vector3.msg"),
    ),
    (
        "std_msgs/msg/Header",
        include_str!("../msg/std_msgs.Header.msg"),
    ),
    (
        "unique_identifier_msgs/msg/UUID",
        include_str!("../msg/unique_identifier_msgs.UUID.msg"),
    ),
    (
        "vision_msgs/msg/BoundingBox3D",
        include_str!("../msg/vision_msgs.BoundingBox3D.msg"),
    ),
    (
        "vision_msgs/msg/Detection3D",
        include_str!("../msg/vision_msgs.Detection3D.msg"),
    ),
    (
        "vision_msgs/msg/Detection3DArray",
        include_str!("../msg/vision_msgs.Detection3DArray.msg"),
    ),
    (
        "vision_msgs/msg/ObjectHypothesis",
        include_str!("../msg/vision_msgs.ObjectHypothesis.msg"),
    ),
    (
        "vision_msgs/msg/ObjectHypothesisWithPose",
        include_str!("../msg/vision_msgs.ObjectHypothesisWithPose.msg"),
    ),
];

/// One field: its name and type as the description states them.
struct Field {
    name: String,
    type_id: u8,
    capacity: u64,
    nested: String,
}

/// REP 2011's field type ids of the primitive types the definitions use.
fn primitive_id(t: &str) -> Option<u8> {
    Some(match t {
        "uint8" | "byte" => 3,
        "int32" => 6,
        "uint32" => 7,
        "float32" => 10,
        "float64" => 11,
        "bool" => 15,
        "string" => 17,
        _ => return None,
    })
}

/// The full name of type `t` met in package `pkg`'s definition (`Name`, `pkg/Name`,
/// `pkg/msg/Name`).
fn full_name(pkg: &str, t: &str) -> String {
    match t.split('/').collect::<Vec<_>>().as_slice() {
        [name] => format!("{pkg}/msg/{name}"),
        [p, name] => format!("{p}/msg/{name}"),
        _ => t.to_string(),
    }
}

/// The fields of type `name`; panics on a type the table lacks (the table is the project's own).
fn fields(name: &str) -> Vec<Field> {
    let (_, text) = DEFINITIONS
        .iter()
        .find(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("no definition of {name}"));
    let pkg = name.split('/').next().unwrap_or_default();
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#') && !l.contains('='))
        .map(|l| {
            let mut words = l.split_whitespace();
            let (t, field) = (words.next().unwrap_or(""), words.next().unwrap_or(""));
            let (base, array) = match t.split_once('[') {
                Some((b, rest)) => (b, Some(rest.trim_end_matches(']'))),
                None => (t, None),
            };
            let (mut type_id, nested) = match primitive_id(base) {
                Some(id) => (id, String::new()),
                None => (1, full_name(pkg, base)),
            };
            let mut capacity = 0;
            match array {
                None => {}
                Some("") => type_id += 144,
                Some(n) => {
                    type_id += 48;
                    capacity = n.parse().unwrap_or(0);
                }
            }
            Field {
                name: field.to_string(),
                type_id,
                capacity,
                nested,
            }
        })
        .collect()
}

/// One type's description as canonical JSON.
fn description_json(name: &str, fields: &[Field]) -> String {
    let fields: Vec<String> = fields
        .iter()
        .map(|f| {
            format!(
                "{{\"name\": \"{}\", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": 0, \"nested_type_name\": \"{}\"}}}}",
                f.name, f.type_id, f.capacity, f.nested
            )
        })
        .collect();
    format!(
        "{{\"type_name\": \"{name}\", \"fields\": [{}]}}",
        fields.join(", ")
    )
}

/// The RIHS01 hash of message type `name` (`pkg/msg/Name`), as `RIHS01_<64 hex digits>`.
pub fn type_hash(name: &str) -> String {
    let mut referenced: BTreeMap<String, Vec<Field>> = BTreeMap::new();
    let mut todo: Vec<String> = fields(name).into_iter().map(|f| f.nested).collect();
    while let Some(n) = todo.pop() {
        if n.is_empty() || referenced.contains_key(&n) {
            continue;
        }
        let f = fields(&n);
        todo.extend(f.iter().map(|x| x.nested.clone()));
        referenced.insert(n, f);
    }
    let refs: Vec<String> = referenced
        .iter()
        .map(|(n, f)| description_json(n, f))
        .collect();
    let json = format!(
        "{{\"type_description\": {}, \"referenced_type_descriptions\": [{}]}}",
        description_json(name, &fields(name)),
        refs.join(", ")
    );
    let digest = Sha256::digest(json.as_bytes());
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    format!("RIHS01_{hex}")
}

/// The full names of every type the project knows.
pub fn known_types() -> impl Iterator<Item = &'static str> {
    DEFINITIONS.iter().map(|(n, _)| *n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hashes_are_those_ros_computes() {
        // As ROS 2 (Iron and later) states them for these types.
        assert_eq!(
            type_hash("std_msgs/msg/Header"),
            "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01"
        );
        assert_eq!(
            type_hash("geometry_msgs/msg/PoseWithCovariance"),
            "RIHS01_9a7c0fd234b7f45c6098745ecccd773ca1085670e64107135397aee31c02e1bb"
        );
    }

    #[test]
    fn every_type_refers_only_to_known_types() {
        for name in known_types() {
            assert!(type_hash(name).starts_with("RIHS01_"));
        }
    }
}
