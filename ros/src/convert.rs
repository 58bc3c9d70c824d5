//! A detector's ROS 2 boxes as the project's boxes in the map frame, and fused boxes as
//! `autoware_perception_msgs/DetectedObjects` for a planner.
//!
//! A box's pose is moved from the message's frame to the map frame by a static [`Transform`]
//! (a translation and a yaw, as a `tf2` static transform of a level sensor). Its stds come from
//! the pose covariance when the message gives one (x, y, z and the rotation about z on the
//! diagonal), else from the agent's default.

use crate::msg::*;
use v2x_protocol::nuscenes_json::{quaternion_yaw, yaw_quaternion};
use v2x_protocol::{wrap_angle, Class, Detection, InvalidValue, Uncertainty, Velocity, NO_ID};

/// The pose of the message's frame in the map frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Transform {
    /// Where the frame's origin lies in the map (m).
    pub translation: [f64; 3],
    /// The frame's heading in the map (rad, about +z).
    pub yaw: f64,
}

impl std::str::FromStr for Transform {
    type Err = InvalidValue;

    /// `X,Y,Z,YAW_DEG`.
    fn from_str(s: &str) -> Result<Transform, InvalidValue> {
        let bad = || InvalidValue::new("transform", "X,Y,Z,YAW_DEG (four finite numbers)", s);
        let v: Vec<f64> = s
            .split(',')
            .map(|t| t.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(bad)?;
        let [x, y, z, yaw] = v.as_slice() else {
            return Err(bad());
        };
        Ok(Transform {
            translation: [*x, *y, *z],
            yaw: yaw.to_radians(),
        })
    }
}

impl Transform {
    /// A point of the message's frame in the map.
    fn point(&self, p: &Vector3) -> [f64; 3] {
        let (s, c) = self.yaw.sin_cos();
        let t = self.translation;
        [
            t[0] + c * p.x - s * p.y,
            t[1] + s * p.x + c * p.y,
            t[2] + p.z,
        ]
    }
}

/// Boxes read from one message.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Read {
    /// The header's stamp (us since the Unix epoch).
    pub capture_us: u64,
    /// The boxes in the map frame.
    pub detections: Vec<Detection>,
    /// Boxes left out: a class the project has no name for, or a value that is not a number.
    pub skipped: usize,
}

/// Microseconds of a ROS time (0 for a time before the epoch).
pub fn time_us(t: &Time) -> u64 {
    (t.sec as i64 * 1_000_000 + t.nanosec as i64 / 1000).max(0) as u64
}

/// The ROS time of `us` microseconds.
pub fn ros_time(us: u64) -> Time {
    Time {
        sec: (us / 1_000_000).min(i32::MAX as u64) as i32,
        nanosec: (us % 1_000_000) as u32 * 1000,
    }
}

/// The class a detector's class name stands for: the nuScenes names and common others.
pub fn class_of_name(name: &str) -> Option<Class> {
    let n = name.trim().to_ascii_lowercase();
    Class::from_name(&n).or(match n.as_str() {
        "van" | "passenger_car" | "vehicle" => Some(Class::Car),
        "person" | "pedestrian" | "walker" => Some(Class::Pedestrian),
        "cyclist" | "bike" => Some(Class::Bicycle),
        "motorbike" | "motorcyclist" => Some(Class::Motorcycle),
        "cone" => Some(Class::TrafficCone),
        _ => None,
    })
}

/// The Autoware label of a class, and the class of a label.
const LABELS: [(u8, Class); 7] = [
    (1, Class::Car),
    (2, Class::Truck),
    (3, Class::Bus),
    (4, Class::Trailer),
    (5, Class::Motorcycle),
    (6, Class::Bicycle),
    (7, Class::Pedestrian),
];

/// Autoware's label of `class` (UNKNOWN, 0, for the classes it has no label for).
fn label_of(class: Class) -> u8 {
    LABELS
        .iter()
        .find(|(_, c)| *c == class)
        .map_or(0, |(l, _)| *l)
}

/// Stds from a pose covariance's diagonal, when it has one.
fn pose_stds(cov: &Covariance, default: &Uncertainty) -> Uncertainty {
    let d = |i: usize| cov.0[i * 7];
    if [0, 1, 2, 5].iter().all(|&i| d(i) > 0.0 && d(i).is_finite()) {
        Uncertainty {
            pos: [d(0).sqrt(), d(1).sqrt(), d(2).sqrt()],
            size: default.size,
            yaw: d(5).sqrt(),
        }
    } else {
        *default
    }
}

/// A box from its parts, `None` when a value is not a number or a size not positive.
fn checked(d: Detection) -> Option<Detection> {
    let finite = d.center.iter().chain(&d.size).all(|v| v.is_finite())
        && d.yaw.is_finite()
        && d.score.is_finite()
        && d.std.as_array().iter().all(|v| v.is_finite() && *v > 0.0);
    (finite && d.size.iter().all(|&s| s > 0.0)).then_some(d)
}

/// The boxes of a `vision_msgs/Detection3DArray`: each detection's best hypothesis gives its
/// class and score, its box the pose and size (x length, y width, z height).
pub fn from_detection3d_array(m: &Detection3DArray, tf: &Transform, default: &Uncertainty) -> Read {
    let mut read = Read {
        capture_us: time_us(&m.header.stamp),
        ..Default::default()
    };
    for det in &m.detections {
        let best = det
            .results
            .iter()
            .max_by(|a, b| a.hypothesis.score.total_cmp(&b.hypothesis.score));
        let class = best.and_then(|h| class_of_name(&h.hypothesis.class_id));
        let (Some(h), Some(class)) = (best, class) else {
            read.skipped += 1;
            continue;
        };
        let b = &det.bbox;
        let size = [b.size.x, b.size.y, b.size.z];
        let o = b.center.orientation;
        let d = Detection {
            class,
            center: tf.point(&b.center.position),
            size,
            yaw: wrap_angle(quaternion_yaw([o.w, o.x, o.y, o.z]) + tf.yaw),
            score: h.hypothesis.score.clamp(0.0, 1.0),
            std: pose_stds(&h.pose.covariance, default),
            pos_cov: None,
            velocity: None,
            id: det
                .id
                .trim()
                .parse()
                .ok()
                .filter(|&i| i != NO_ID)
                .unwrap_or(NO_ID),
        };
        match checked(d) {
            Some(d) => read.detections.push(d),
            None => read.skipped += 1,
        }
    }
    read
}

/// The boxes of an `autoware_perception_msgs/DetectedObjects`: the most probable label, the
/// existence probability as the score, a box or cylinder's dimensions, and a velocity when the
/// twist and its covariance are given.
pub fn from_detected_objects(m: &DetectedObjects, tf: &Transform, default: &Uncertainty) -> Read {
    let mut read = Read {
        capture_us: time_us(&m.header.stamp),
        ..Default::default()
    };
    for o in &m.objects {
        let label = o
            .classification
            .iter()
            .max_by(|a, b| a.probability.total_cmp(&b.probability))
            .map(|c| c.label);
        let class = label.and_then(|l| LABELS.iter().find(|(x, _)| *x == l).map(|(_, c)| *c));
        let (Some(class), 0 | 1) = (class, o.shape.kind) else {
            read.skipped += 1;
            continue;
        };
        let k = &o.kinematics;
        let p = &k.pose_with_covariance;
        let dims = o.shape.dimensions;
        let size = [dims.x, dims.y, dims.z];
        let q = p.pose.orientation;
        let yaw = wrap_angle(quaternion_yaw([q.w, q.x, q.y, q.z]) + tf.yaw);
        let std = if k.has_position_covariance {
            pose_stds(&p.covariance, default)
        } else {
            *default
        };
        let t = &k.twist_with_covariance;
        let velocity = (k.has_twist && k.has_twist_covariance).then(|| {
            // The twist is in the object's frame: turned by its heading into the map's.
            let (s, c) = yaw.sin_cos();
            let (vx, vy) = (t.twist.linear.x, t.twist.linear.y);
            let (sx, sy) = (t.covariance.0[0].sqrt(), t.covariance.0[7].sqrt());
            Velocity {
                v: [c * vx - s * vy, s * vx + c * vy],
                std: [sx.max(sy), sx.max(sy)],
            }
        });
        let d = Detection {
            class,
            center: tf.point(&p.pose.position),
            size,
            yaw,
            score: (o.existence_probability as f64).clamp(0.0, 1.0),
            std,
            pos_cov: None,
            velocity: velocity.filter(|v| {
                v.v.iter().chain(&v.std).all(|x| x.is_finite()) && v.std.iter().all(|s| *s > 0.0)
            }),
            id: NO_ID,
        };
        match checked(d) {
            Some(d) => read.detections.push(d),
            None => read.skipped += 1,
        }
    }
    read
}

/// Tracks as a `TrackedObjects` in frame `frame_id`, stamped `capture_us`: each box's id (its
/// tracking id) as the first four bytes (little-endian) of its UUID, the rest zero; pose,
/// twist, class and shape as [`to_detected_objects`] gives them.
pub fn to_tracked_objects(tracks: &[Detection], capture_us: u64, frame_id: &str) -> TrackedObjects {
    let detected = to_detected_objects(tracks, capture_us, frame_id);
    let objects = detected
        .objects
        .into_iter()
        .zip(tracks)
        .map(|(o, d)| {
            let mut uuid = [0u8; 16];
            uuid[..4].copy_from_slice(&d.id.to_le_bytes());
            let k = o.kinematics;
            TrackedObject {
                object_id: Uuid { uuid },
                existence_probability: o.existence_probability,
                classification: o.classification,
                kinematics: TrackedObjectKinematics {
                    pose_with_covariance: k.pose_with_covariance,
                    twist_with_covariance: k.twist_with_covariance,
                    acceleration_with_covariance: AccelWithCovariance::default(),
                    orientation_availability: k.orientation_availability,
                    is_stationary: d.velocity.is_some_and(|v| v.v[0].hypot(v.v[1]) < 0.1),
                },
                shape: o.shape,
            }
        })
        .collect();
    TrackedObjects {
        header: detected.header,
        objects,
    }
}

/// Fused boxes as a `DetectedObjects` in frame `frame_id` (the map's), stamped `capture_us`:
/// each a bounding box with its pose covariance from its stds and, when it has a velocity, its
/// twist in its own frame. Cones and barriers, which Autoware has no label for, are UNKNOWN.
pub fn to_detected_objects(dets: &[Detection], capture_us: u64, frame_id: &str) -> DetectedObjects {
    let objects = dets
        .iter()
        .map(|d| {
            let mut cov = Covariance::default();
            for (i, s) in [
                d.std.pos[0],
                d.std.pos[1],
                d.std.pos[2],
                0.0,
                0.0,
                d.std.yaw,
            ]
            .into_iter()
            .enumerate()
            {
                cov.0[i * 7] = s * s;
            }
            let [w, x, y, z] = yaw_quaternion(d.yaw);
            let mut twist = TwistWithCovariance::default();
            if let Some(v) = d.velocity {
                let (s, c) = d.yaw.sin_cos();
                twist.twist.linear = Vector3 {
                    x: c * v.v[0] + s * v.v[1],
                    y: -s * v.v[0] + c * v.v[1],
                    z: 0.0,
                };
                let var = v.std[0].max(v.std[1]).powi(2);
                twist.covariance.0[0] = var;
                twist.covariance.0[7] = var;
            }
            DetectedObject {
                existence_probability: d.score as f32,
                classification: vec![ObjectClassification {
                    label: label_of(d.class),
                    probability: 1.0,
                }],
                kinematics: DetectedObjectKinematics {
                    pose_with_covariance: PoseWithCovariance {
                        pose: Pose {
                            position: Vector3 {
                                x: d.center[0],
                                y: d.center[1],
                                z: d.center[2],
                            },
                            orientation: Quaternion { x, y, z, w },
                        },
                        covariance: cov,
                    },
                    has_position_covariance: true,
                    orientation_availability: 2,
                    twist_with_covariance: twist,
                    has_twist: d.velocity.is_some(),
                    has_twist_covariance: d.velocity.is_some(),
                },
                shape: Shape {
                    kind: 0,
                    footprint: Polygon::default(),
                    dimensions: Vector3 {
                        x: d.size[0],
                        y: d.size[1],
                        z: d.size[2],
                    },
                },
            }
        })
        .collect();
    DetectedObjects {
        header: Header {
            stamp: ros_time(capture_us),
            frame_id: frame_id.to_string(),
        },
        objects,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cdr::{from_bytes, to_bytes, CdrError};

    fn array() -> Detection3DArray {
        let mut cov = Covariance::default();
        for (i, v) in [0.25, 0.16, 0.09, 0.0, 0.0, 0.01].into_iter().enumerate() {
            cov.0[i * 7] = v;
        }
        let det = |x: f64, class: &str| Detection3D {
            header: Header::default(),
            results: vec![ObjectHypothesisWithPose {
                hypothesis: ObjectHypothesis {
                    class_id: class.into(),
                    score: 0.9,
                },
                pose: PoseWithCovariance {
                    covariance: cov,
                    ..Default::default()
                },
            }],
            bbox: BoundingBox3D {
                center: Pose {
                    position: Vector3 { x, y: 0.0, z: 0.5 },
                    orientation: Quaternion::default(),
                },
                size: Vector3 {
                    x: 4.5,
                    y: 1.9,
                    z: 1.6,
                },
            },
            id: "17".into(),
        };
        Detection3DArray {
            header: Header {
                stamp: Time {
                    sec: 1_700_000_000,
                    nanosec: 250_000_000,
                },
                frame_id: "lidar".into(),
            },
            detections: vec![det(1.0, "Car"), det(2.0, "ghost"), det(f64::NAN, "car")],
        }
    }

    #[test]
    fn a_transform_moves_boxes_into_the_map() {
        let tf: Transform = "10,5,0,90".parse().unwrap();
        let read = from_detection3d_array(&array(), &tf, &Uncertainty::uniform(1.0, 1.0, 1.0));
        assert_eq!(read.capture_us, 1_700_000_000_250_000);
        // The unnamed class and the box at NaN are left out.
        assert_eq!((read.detections.len(), read.skipped), (1, 2));
        let d = &read.detections[0];
        assert_eq!(d.class, Class::Car);
        assert!((d.center[0] - 10.0).abs() < 1e-12 && (d.center[1] - 6.0).abs() < 1e-12);
        assert!((d.yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!((d.size, d.score, d.id), ([4.5, 1.9, 1.6], 0.9, 17));
        assert!((d.std.pos[0] - 0.5).abs() < 1e-12 && (d.std.pos[2] - 0.3).abs() < 1e-12);
        assert!((d.std.yaw - 0.1).abs() < 1e-12 && d.std.size == [1.0; 3]);
        assert!("1,2,3".parse::<Transform>().is_err() && "1,2,x,4".parse::<Transform>().is_err());
    }

    #[test]
    fn fused_boxes_come_back_from_their_detected_objects() {
        let mut car = v2x_protocol::fixtures::car(3.0, -4.0, 0.4);
        car.yaw = 2.5;
        car.velocity = Some(Velocity {
            v: [1.5, -2.0],
            std: [0.3, 0.3],
        });
        let mut walker = v2x_protocol::fixtures::car(-1.0, 2.0, 0.2);
        walker.class = Class::Pedestrian;
        let mut cone = walker.clone();
        cone.class = Class::TrafficCone;
        let msg = to_detected_objects(&[car.clone(), walker.clone(), cone], 1_234_567_000, "map");
        assert_eq!(
            msg.header.stamp,
            Time {
                sec: 1234,
                nanosec: 567_000_000
            }
        );
        let labels: Vec<u8> = msg
            .objects
            .iter()
            .map(|o| o.classification[0].label)
            .collect();
        assert_eq!(labels, [1, 7, 0]);
        let back: DetectedObjects = from_bytes(&to_bytes(&msg)).unwrap();
        assert_eq!(back, msg);
        let read = from_detected_objects(
            &back,
            &Transform::default(),
            &Uncertainty::uniform(9.0, 9.0, 9.0),
        );
        assert_eq!(
            (read.detections.len(), read.skipped, read.capture_us),
            (2, 1, 1_234_567_000)
        );
        for (a, b) in [car, walker].iter().zip(&read.detections) {
            assert_eq!(a.class, b.class);
            for k in 0..3 {
                assert!(
                    (a.center[k] - b.center[k]).abs() < 1e-9
                        && (a.size[k] - b.size[k]).abs() < 1e-9
                );
                assert!((a.std.pos[k] - b.std.pos[k]).abs() < 1e-9);
            }
            assert!(wrap_angle(a.yaw - b.yaw).abs() < 1e-9 && (a.std.yaw - b.std.yaw).abs() < 1e-9);
            assert!((a.score - b.score).abs() < 1e-6);
            match (a.velocity, b.velocity) {
                (Some(u), Some(w)) => {
                    assert!((u.v[0] - w.v[0]).abs() < 1e-9 && (u.v[1] - w.v[1]).abs() < 1e-9);
                    assert!((u.std[0] - w.std[0]).abs() < 1e-9);
                }
                (None, None) => {}
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn tracks_keep_their_ids_in_their_uuids() {
        let mut a = v2x_protocol::fixtures::car(1.0, 2.0, 0.3);
        a.id = 0x0102_0304;
        let mut b = a.clone();
        b.id = 7;
        let m = to_tracked_objects(&[a, b], 5_000_000, "map");
        let back: TrackedObjects = from_bytes(&to_bytes(&m)).unwrap();
        assert_eq!(back, m);
        assert_eq!(m.objects[0].object_id.uuid[..5], [4, 3, 2, 1, 0]);
        assert_eq!(m.objects[1].object_id.uuid[0], 7);
        assert_eq!(
            m.objects[0].kinematics.pose_with_covariance.pose.position.x,
            1.0
        );
    }

    #[test]
    fn cdr_payloads_round_trip_and_bad_ones_are_errors() {
        let m = array();
        let bytes = to_bytes(&m);
        assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
        let back: Detection3DArray = from_bytes(&bytes).unwrap();
        assert_eq!(back.detections.len(), 3);
        assert_eq!(back.detections[0], m.detections[0]);
        assert_eq!(
            from_bytes::<Detection3DArray>(&bytes[..3]),
            Err(CdrError::Short(3))
        );
        let mut other = bytes.clone();
        other[1] = 7;
        assert!(matches!(
            from_bytes::<Detection3DArray>(&other),
            Err(CdrError::Representation(7))
        ));
        for n in 4..bytes.len() {
            assert!(
                from_bytes::<Detection3DArray>(&bytes[..n]).is_err(),
                "{n} bytes"
            );
        }
    }
}
