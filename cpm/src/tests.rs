use super::*;
use crate::asn::*;
use proptest::prelude::*;
use v2x_protocol::{AgentKind, Class, Detection, Frame, Uncertainty, Velocity, NO_ID};

/// 2018-08-01T19:26:43.547590Z, a nuScenes-like capture time.
const T_US: u64 = 1_533_151_603_547_590;

fn frame(detections: Vec<Detection>) -> Frame {
    Frame {
        agent: "car1".into(),
        kind: AgentKind::Vehicle,
        seq: 7,
        capture_us: T_US,
        origin: [0.0; 3],
        detections,
    }
}

fn one_box() -> Detection {
    Detection {
        class: Class::Car,
        center: [1.234, -2.5, 0.3],
        size: [4.5, 1.9, 1.6],
        yaw: 0.5,
        score: 0.8,
        std: Uncertainty {
            pos: [0.5, 0.25, 0.1],
            size: [0.2, 0.1, 0.05],
            yaw: 0.05,
        },
        pos_cov: None,
        velocity: Some(Velocity {
            v: [3.0, -1.25],
            std: [0.4, 0.2],
        }),
        id: 42,
    }
}

fn raw(bytes: &[u8]) -> CollectivePerceptionMessage {
    rasn::uper::decode(bytes).unwrap()
}

fn objects(cpm: &CollectivePerceptionMessage) -> Vec<PerceivedObject> {
    let c = cpm
        .payload
        .cpm_containers
        .0
         .0
        .iter()
        .find(|c| c.container_id == PERCEIVED_OBJECT_CONTAINER)
        .unwrap();
    let poc: PerceivedObjectContainer = rasn::uper::decode(c.container_data.as_bytes()).unwrap();
    assert_eq!(
        poc.number_of_perceived_objects.0 as usize,
        poc.perceived_objects.0.len()
    );
    poc.perceived_objects.0
}

#[test]
fn a_box_is_coded_by_the_message_rule() {
    let bytes = encode(&frame(vec![one_box()]), &Geo::default()).unwrap();
    let cpm = raw(&bytes);
    assert_eq!(cpm.header.protocol_version.0, 2);
    assert_eq!(cpm.header.message_id.0, 14);
    assert_eq!(cpm.header.station_id.0, station_id("car1"));
    let m = &cpm.payload.management_container;
    // 1533151603547 ms Unix less the ITS epoch (1072915200000 ms).
    assert_eq!(m.reference_time.0, 460_236_403_547);
    assert_eq!(
        (
            m.reference_position.latitude.0,
            m.reference_position.longitude.0
        ),
        (0, 0)
    );
    assert_eq!(m.reference_position.altitude.altitude_value.0, 0);
    let containers: Vec<_> = cpm
        .payload
        .cpm_containers
        .0
         .0
        .iter()
        .map(|c| c.container_id.0)
        .collect();
    assert_eq!(containers, [1, 5]);
    let o = &objects(&cpm)[0];
    assert_eq!(o.object_id, Some(Identifier2B(42)));
    // Each value n with (n - 1) unit < v <= n unit; the reference altitude stands for -0.005 m.
    assert_eq!(o.position.x_coordinate.value.0, 124); // 1.234 m
    assert_eq!(o.position.y_coordinate.value.0, -250); // -2.5 m
    assert_eq!(o.position.z_coordinate.as_ref().unwrap().value.0, 31); // 0.305 m above
                                                                       // Confidences are 95 % bounds: 1.96 x 0.5 m = 0.98 m, 1.96 x 0.25 = 0.49, 1.96 x 0.1 = 0.196.
    assert_eq!(o.position.x_coordinate.confidence.0, 98);
    assert_eq!(o.position.y_coordinate.confidence.0, 49);
    assert_eq!(o.position.z_coordinate.as_ref().unwrap().confidence.0, 20);
    let dim = |d: &Option<ObjectDimension>| d.as_ref().map(|d| (d.value.0, d.confidence.0));
    assert_eq!(dim(&o.object_dimension_x), Some((45, 4))); // 4.5 m; 0.392 m
    assert_eq!(dim(&o.object_dimension_y), Some((19, 2))); // 1.9 m; 0.196 m
    assert_eq!(dim(&o.object_dimension_z), Some((16, 1))); // 1.6 m; 0.098 m
    let z = &o.angles.as_ref().unwrap().z_angle;
    assert_eq!((z.value.0, z.confidence.0), (287, 57)); // 28.648 deg; 5.615 deg
    match &o.velocity {
        Some(Velocity3dWithConfidence::cartesianVelocity(v)) => {
            assert_eq!((v.x_velocity.value.0, v.x_velocity.confidence.0), (300, 79));
            assert_eq!(
                (v.y_velocity.value.0, v.y_velocity.confidence.0),
                (-125, 40)
            );
        }
        other => panic!("{other:?}"),
    }
    let class = &o.classification.as_ref().unwrap().0[0];
    assert_eq!(
        class.object_class,
        ObjectClass::vehicleSubClass(TrafficParticipantType(5))
    );
    assert_eq!(class.confidence.0, 80);
    assert_eq!(
        o.object_perception_quality,
        Some(ObjectPerceptionQuality(12))
    );
}

#[test]
fn a_box_comes_back_at_the_middle_of_its_steps() {
    let bytes = encode(&frame(vec![one_box()]), &Geo::default()).unwrap();
    let cpm = decode(&bytes, &Geo::default()).unwrap();
    assert_eq!(cpm.station_id, station_id("car1"));
    assert_eq!(cpm.kind, AgentKind::Vehicle);
    assert_eq!(cpm.capture_us, 1_533_151_603_547_000);
    assert!(cpm.skipped.is_empty());
    let d = &cpm.detections[0];
    let near = |a: f64, b: f64| (a - b).abs() < 1e-9;
    assert!(
        near(d.center[0], 1.235) && near(d.center[1], -2.505) && near(d.center[2], 0.3),
        "{:?}",
        d.center
    );
    assert!(near(d.size[0], 4.45) && near(d.size[1], 1.85) && near(d.size[2], 1.55));
    assert!(near(d.yaw, 28.65_f64.to_radians()));
    assert!(near(d.std.pos[0], 0.98 / 1.959_963_984_540_054));
    assert!(near(d.std.size[0], 0.4 / 1.959_963_984_540_054));
    let v = d.velocity.unwrap();
    assert!(near(v.v[0], 2.995) && near(v.v[1], -1.255));
    assert_eq!((d.class, d.score, d.id), (Class::Car, 0.8, 42));
    let f = cpm.into_frame("car1".into());
    assert_eq!(
        (f.agent.as_str(), f.seq),
        ("car1", 1_533_151_603_547_u64 as u32)
    );
}

#[test]
fn a_roadside_unit_sends_the_rsu_container() {
    let mut f = frame(vec![]);
    f.kind = AgentKind::Infrastructure;
    let bytes = encode(&f, &Geo::default()).unwrap();
    let ids: Vec<_> = raw(&bytes)
        .payload
        .cpm_containers
        .0
         .0
        .iter()
        .map(|c| c.container_id.0)
        .collect();
    assert_eq!(ids, [2, 5]);
    let cpm = decode(&bytes, &Geo::default()).unwrap();
    assert_eq!(
        (cpm.kind, cpm.detections.len()),
        (AgentKind::Infrastructure, 0)
    );
}

#[test]
fn what_a_cpm_cannot_state_is_refused_by_name() {
    let geo = Geo::default();
    let mut f = frame(vec![one_box(); 256]);
    assert_eq!(encode(&f, &geo), Err(EncodeError::TooManyObjects(256)));
    f.detections.truncate(255);
    assert!(encode(&f, &geo).is_ok());
    let mut early = frame(vec![]);
    early.capture_us = 1_000_000;
    assert_eq!(
        encode(&early, &geo),
        Err(EncodeError::BeforeItsEpoch(1_000_000))
    );
    let mut far = one_box();
    far.center[1] = 1400.0;
    assert!(matches!(
        encode(&frame(vec![one_box(), far]), &geo),
        Err(EncodeError::Object {
            index: 1,
            field: "y",
            ..
        })
    ));
    let mut long = one_box();
    long.size[0] = 26.0;
    assert!(matches!(
        encode(&frame(vec![long]), &geo),
        Err(EncodeError::Object {
            index: 0,
            field: "length",
            ..
        })
    ));
    let mut high = frame(vec![]);
    high.origin[2] = 9000.0;
    assert!(matches!(
        encode(&high, &geo),
        Err(EncodeError::Origin {
            field: "altitude",
            ..
        })
    ));
}

#[test]
fn the_map_lies_on_the_tangent_plane_of_its_origin() {
    // One degree is 110.574 km of latitude and 111.320 km of longitude at the equator.
    let geo = Geo::default();
    let (lat, lon) = geo.to_wgs84(111_320.0, 110_574.0);
    assert!(
        (lat - 1.0).abs() < 1e-4 && (lon - 1.0).abs() < 1e-4,
        "{lat} {lon}"
    );
    let boston = Geo {
        lat_deg: 42.336,
        lon_deg: -71.057,
    };
    let (lat, lon) = boston.to_wgs84(1234.5, -678.9);
    let (x, y) = boston.to_map(lat, lon);
    assert!((x - 1234.5).abs() < 1e-6 && (y + 678.9).abs() < 1e-6);
}

#[test]
fn a_map_origin_is_read_as_lat_lon() {
    let g: Geo = "42.336,-71.057".parse().unwrap();
    assert_eq!((g.lat_deg, g.lon_deg), (42.336, -71.057));
    let e = "91,0".parse::<Geo>().unwrap_err();
    assert_eq!((e.field.as_str(), e.got.as_str()), ("latitude", "91"));
    let e = "0,x".parse::<Geo>().unwrap_err();
    assert_eq!((e.field.as_str(), e.got.as_str()), ("longitude", "x"));
    assert_eq!(
        "1".parse::<Geo>().unwrap_err().to_string(),
        "map origin must be LAT,LON in degrees (got 1)"
    );
}

#[test]
fn station_ids_are_fnv1a_of_the_name() {
    assert_eq!(station_id(""), 0x811c_9dc5);
    assert_eq!(station_id("a"), 0xe40c_292c);
    assert_eq!(station_id("foobar"), 0xbf9c_f968);
}

#[test]
fn cones_and_barriers_share_a_class_and_come_back_by_footprint() {
    let mut cone = one_box();
    cone.class = Class::TrafficCone;
    cone.size = Class::TrafficCone.typical_size();
    let mut barrier = one_box();
    barrier.class = Class::Barrier;
    barrier.size = Class::Barrier.typical_size();
    let bytes = encode(&frame(vec![cone, barrier]), &Geo::default()).unwrap();
    let classes: Vec<_> = objects(&raw(&bytes))
        .iter()
        .map(|o| o.classification.clone().unwrap().0[0].object_class.clone())
        .collect();
    assert_eq!(classes[0], classes[1]);
    let back = decode(&bytes, &Geo::default()).unwrap();
    let classes: Vec<_> = back.detections.iter().map(|d| d.class).collect();
    assert_eq!(classes, [Class::TrafficCone, Class::Barrier]);
}

/// The message re-encoded after `change` to its first object.
fn altered(change: impl FnOnce(&mut PerceivedObject)) -> Vec<u8> {
    let mut cpm = raw(&encode(&frame(vec![one_box(), one_box()]), &Geo::default()).unwrap());
    let mut objs = objects(&cpm);
    change(&mut objs[0]);
    let poc = PerceivedObjectContainer {
        number_of_perceived_objects: CardinalNumber1B(objs.len() as u8),
        perceived_objects: PerceivedObjects(objs),
    };
    let containers = &mut cpm.payload.cpm_containers.0 .0;
    containers[1].container_data = rasn::types::Any::new(rasn::uper::encode(&poc).unwrap());
    rasn::uper::encode(&cpm).unwrap()
}

#[test]
fn objects_of_other_classes_are_skipped_and_reported() {
    let bytes = altered(|o| {
        o.classification.as_mut().unwrap().0[0].object_class = ObjectClass::vruSubClass(
            VruProfileAndSubprofile::animal(VruSubProfileAnimal::wild_animal),
        );
    });
    let cpm = decode(&bytes, &Geo::default()).unwrap();
    assert_eq!(cpm.detections.len(), 1);
    assert_eq!(
        cpm.skipped,
        [Skipped {
            index: 0,
            reason: "a class the project has no name for"
        }]
    );
}

#[test]
fn a_malformed_object_is_refused_by_index_and_field() {
    let no_z = altered(|o| o.position.z_coordinate = None);
    assert_eq!(
        decode(&no_z, &Geo::default()),
        Err(DecodeError::Object {
            index: 0,
            field: "zCoordinate",
            message: "is missing"
        })
    );
    let no_conf = altered(|o| o.position.x_coordinate.confidence = CoordinateConfidence(4096));
    assert!(matches!(
        decode(&no_conf, &Geo::default()),
        Err(DecodeError::Object {
            index: 0,
            field: "xCoordinate",
            ..
        })
    ));
    let wide = altered(|o| {
        o.object_dimension_y = Some(ObjectDimension {
            value: ObjectDimensionValue(256),
            confidence: ObjectDimensionConfidence(3),
        })
    });
    assert!(matches!(
        decode(&wide, &Geo::default()),
        Err(DecodeError::Object {
            index: 0,
            field: "objectDimensionY",
            ..
        })
    ));
}

#[test]
fn another_message_is_refused_by_its_header() {
    let mut cpm = raw(&encode(&frame(vec![]), &Geo::default()).unwrap());
    cpm.header.message_id = MessageId(2);
    let bytes = rasn::uper::encode(&cpm).unwrap();
    assert_eq!(
        decode(&bytes, &Geo::default()),
        Err(DecodeError::Header {
            message_id: 2,
            version: 2
        })
    );
}

#[test]
fn truncated_messages_are_errors() {
    let bytes = encode(&frame(vec![one_box(); 3]), &Geo::default()).unwrap();
    for n in 0..bytes.len() {
        assert!(decode(&bytes[..n], &Geo::default()).is_err(), "{n} bytes");
    }
}

#[test]
fn a_large_frame_is_several_messages_and_the_clock_does_not_count() {
    let b = |n: usize, t: u64| {
        let mut f = frame(
            (0..n)
                .map(|i| v2x_protocol::fixtures::car(i as f64 * 3.0, (i % 7) as f64, 0.3))
                .collect(),
        );
        f.capture_us = t;
        message_bytes(&f)
    };
    // 300 boxes: a message of 255 and one of 45, each with its own header.
    assert!(b(255, T_US) > 0 && b(45, T_US) > 0);
    assert_eq!(b(300, T_US), b(255, T_US) + b(45, T_US));
    // A CPM's fields are of fixed width: a synthetic clock from 0 costs the same.
    assert_eq!(b(24, 0), b(24, T_US));
    assert_eq!(
        b(0, T_US),
        encode(&frame(vec![]), &Geo::default()).unwrap().len()
    );
    // A box that no CPM can state: nothing to count.
    let mut f = frame(vec![one_box()]);
    f.detections[0].size[0] = 30.0;
    assert_eq!(message_bytes(&f), 0);
}

fn arb_box() -> impl Strategy<Value = Detection> {
    let class = prop::sample::select(Class::ALL.to_vec());
    (
        class,
        prop::array::uniform3(-1300.0..1300.0f64),
        prop::array::uniform3(0.05..25.4f64),
        -3.2..3.2f64,
        0.0..=1.0f64,
        (
            prop::array::uniform3(0.001..20.0f64),
            prop::array::uniform3(0.001..1.5f64),
            0.0001..0.1f64,
        ),
        prop::option::of((
            prop::array::uniform2(-150.0..150.0f64),
            prop::array::uniform2(0.001..0.6f64),
        )),
        prop::option::of(0u32..65535),
    )
        .prop_map(|(class, center, size, yaw, score, (pos, sz, y), vel, id)| {
            // Cones and barriers come back by footprint: give them their typical one.
            let size = match class {
                Class::TrafficCone | Class::Barrier => class.typical_size(),
                _ => size,
            };
            let std = Uncertainty {
                pos,
                size: sz,
                yaw: y,
            };
            let velocity = vel.map(|(v, std)| Velocity { v, std });
            Detection {
                id: id.unwrap_or(NO_ID),
                class,
                score,
                center,
                size,
                yaw,
                std,
                velocity,
                pos_cov: None,
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A round trip loses no more than the message's steps: half a step of each value (a
    /// centimetre of position, 0.1 m of size, 0.1 degree of yaw, 1 cm/s, 1 % of score) and a
    /// step of each std (its 95 % bound rounded up).
    #[test]
    fn round_trips_lose_only_the_messages_steps(
        boxes in prop::collection::vec(arb_box(), 0..20),
        lat in -60.0..60.0f64,
        lon in -179.0..179.0f64,
        origin in (-2000.0..2000.0f64, -2000.0..2000.0f64, -500.0..500.0f64),
    ) {
        let geo = Geo { lat_deg: lat, lon_deg: lon };
        let origin = [origin.0, origin.1, origin.2];
        let boxes: Vec<Detection> = boxes.into_iter().map(|mut d| {
            for k in 0..3 { d.center[k] += origin[k]; }
            d
        }).collect();
        let mut f = frame(boxes.clone());
        f.origin = origin;
        let back = decode(&encode(&f, &geo).unwrap(), &geo).unwrap();
        prop_assert_eq!(back.detections.len(), boxes.len());
        let z = 1.959_963_984_540_054;
        for (a, b) in boxes.iter().zip(&back.detections) {
            prop_assert_eq!(a.class, b.class);
            prop_assert_eq!(a.id, b.id);
            for k in 0..3 {
                prop_assert!((a.center[k] - b.center[k]).abs() <= 0.005 + 1e-6, "centre {} {:?} {:?}", k, a.center, b.center);
                prop_assert!((a.size[k] - b.size[k]).abs() <= 0.05 + 1e-9);
                prop_assert!(b.std.pos[k] >= a.std.pos[k] - 1e-12 && b.std.pos[k] <= (a.std.pos[k] + 0.01 / z).max(0.01 / z) + 1e-12);
                let sat = 3.0 / z;
                prop_assert!(b.std.size[k] >= a.std.size[k].min(sat) - 1e-12 && b.std.size[k] <= a.std.size[k].min(sat) + 0.1 / z + 1e-12);
            }
            let dyaw = v2x_protocol::wrap_angle(a.yaw - b.yaw).abs();
            prop_assert!(dyaw <= 0.05_f64.to_radians() + 1e-9, "yaw {} {}", a.yaw, b.yaw);
            prop_assert!((a.score.max(0.01) - b.score).abs() <= 0.005 + 1e-9);
            prop_assert_eq!(a.velocity.is_some(), b.velocity.is_some());
            if let (Some(u), Some(w)) = (a.velocity, b.velocity) {
                for k in 0..2 {
                    prop_assert!((u.v[k] - w.v[k]).abs() <= 0.005 + 1e-9);
                    prop_assert!(w.std[k] >= u.std[k] - 1e-12);
                }
            }
        }
    }

    /// Whatever the bytes, decoding answers without panicking, and what decodes encodes again.
    #[test]
    fn any_bytes_decode_or_fail_cleanly(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        crate::fuzzing::decode_round_trip(&bytes);
    }

    /// A real message with bytes changed decodes to boxes that encode again, or fails cleanly.
    #[test]
    fn changed_messages_round_trip_or_fail(flips in prop::collection::vec((0usize..1000, any::<u8>()), 1..6)) {
        let mut bytes = encode(&frame(vec![one_box(); 4]), &Geo { lat_deg: 48.0, lon_deg: 11.0 }).unwrap();
        for (at, x) in flips {
            let n = bytes.len();
            bytes[at % n] ^= x;
        }
        crate::fuzzing::decode_round_trip(&bytes);
    }
}
