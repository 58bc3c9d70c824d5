use super::*;
use crate::limits;
use proptest::prelude::*;

fn det(class: Class, center: [f64; 3], size: [f64; 3], yaw: f64, id: u32) -> Detection {
    Detection {
        class,
        center,
        size,
        yaw,
        score: 0.9,
        std: Uncertainty::uniform(0.5, 0.1, 5f64.to_radians()),
        pos_cov: None,
        velocity: None,
        id,
    }
}

fn sample_frame(n: usize) -> Frame {
    let detections = (0..n)
        .map(|i| {
            let a = i as f64 * 0.7;
            det(
                Class::ALL[i % 10],
                [
                    1000.0 + 40.0 * a.cos(),
                    -2000.0 + 40.0 * a.sin(),
                    1.0 + 0.1 * a.sin(),
                ],
                Class::ALL[i % 10].typical_size().map(|s| s * 1.07),
                wrap_angle(a * 3.1),
                i as u32,
            )
        })
        .collect();
    Frame {
        agent: "veh1".into(),
        kind: AgentKind::Vehicle,
        seq: 42,
        capture_us: 1_700_000_000_000_000,
        origin: [0.0; 3],
        detections,
    }
    .with_centroid_origin()
}

fn assert_close(a: &Frame, b: &Frame) {
    assert_eq!(a.agent, b.agent);
    assert_eq!(a.kind, b.kind);
    assert_eq!(a.seq, b.seq);
    assert_eq!(a.capture_us, b.capture_us);
    assert_eq!(a.detections.len(), b.detections.len());
    for (x, y) in a.detections.iter().zip(&b.detections) {
        assert_eq!(x.class, y.class);
        assert_eq!(x.id, y.id);
        for k in 0..3 {
            assert!(
                (x.center[k] - y.center[k]).abs() <= 0.005 + 1e-9,
                "centre {k}: {} vs {}",
                x.center[k],
                y.center[k]
            );
            assert!((x.size[k] - y.size[k]).abs() <= 0.005 + 1e-9, "size {k}");
        }
        let dyaw = wrap_angle(x.yaw - y.yaw).abs().to_degrees();
        assert!(dyaw <= 0.003, "yaw error {dyaw} deg");
        assert!((x.score - y.score).abs() <= 0.5 / 250.0 + 1e-12);
        for (s, t) in x.std.as_array().iter().zip(y.std.as_array()) {
            assert!((s - t).abs() / s <= 0.01, "std {s} vs {t}");
        }
        assert_eq!(x.velocity.is_some(), y.velocity.is_some());
        if let (Some(a), Some(b)) = (x.velocity, y.velocity) {
            for k in 0..2 {
                assert!((a.v[k] - b.v[k]).abs() <= 0.05 + 1e-9, "velocity {k}");
                assert!((a.std[k] - b.std[k]).abs() / a.std[k] <= 0.01);
            }
        }
    }
}

#[test]
fn round_trip_hand_written() {
    for n in [0, 1, 25, 75] {
        let f = sample_frame(n);
        let bytes = encode(&f).unwrap();
        assert_eq!(bytes[0], VERSION);
        assert_close(&f, &decode(&bytes).unwrap());
    }
}

#[test]
fn round_trip_edge_values() {
    let mut f = sample_frame(3);
    f.detections[0].yaw = PI;
    f.detections[1].yaw = -PI + 1e-9;
    f.detections[2].score = 1.0;
    f.detections[2].std = Uncertainty::from_array([0.01, 0.02, 0.03, 1.0, 2.0, 3.0, 1.5]);
    let g = decode(&encode(&f).unwrap()).unwrap();
    assert_close(&f, &g);
}

#[test]
fn uniform_stds_cost_nothing_per_object() {
    let f = sample_frame(75);
    let bytes = encode(&f).unwrap();
    let per_object = bytes.len() as f64 / 75.0;
    assert!(per_object <= 20.0, "{per_object} bytes per object");
    let mut g = f.clone();
    g.detections[3].std.pos[0] = 2.0;
    let b2 = encode(&g).unwrap();
    assert_eq!(
        b2.len(),
        bytes.len() + 14,
        "one override costs its 7 std codes"
    );
    assert_close(&g, &decode(&b2).unwrap());
}

#[test]
fn velocities_round_trip_and_cost_about_two_bytes() {
    let f = sample_frame(75);
    let base = encode(&f).unwrap().len();
    let mut g = f.clone();
    for (i, d) in g.detections.iter_mut().enumerate() {
        // a mix: static, walking, driving along x, driving diagonally
        let v = [[0.0, 0.0], [1.2, -0.4], [11.3, 0.2], [-7.9, 7.9]][i % 4];
        d.velocity = Some(Velocity { v, std: [0.3, 0.3] });
    }
    let bytes = encode(&g).unwrap();
    let extra = (bytes.len() - base) as f64 / 75.0;
    // 0.1 m/s steps: 1 byte per axis below 6.4 m/s, 2 above; stds ride in the frame default
    assert!((2.0..=3.0).contains(&extra), "{extra} bytes per object");
    let h = decode(&bytes).unwrap();
    assert_close(&g, &h);
    assert_eq!(h.detections[2].velocity.unwrap().v, [11.3, 0.2]);
    // one object with its own velocity std carries 2 codes more than its 7
    g.detections[5].velocity.as_mut().unwrap().std = [1.0, 1.0];
    assert_eq!(encode(&g).unwrap().len(), bytes.len() + 14 + 4);
    let mut bad = g.clone();
    bad.detections[0].velocity.as_mut().unwrap().v[1] = 150.0;
    assert!(matches!(
        encode(&bad),
        Err(EncodeError::OutOfRange {
            field: "velocity.y",
            ..
        })
    ));
}

#[test]
fn encode_rejects_bad_values() {
    let mut f = sample_frame(2);
    f.detections[1].center[0] = f64::NAN;
    assert_eq!(
        encode(&f),
        Err(EncodeError::NonFinite {
            index: 1,
            field: "center.x"
        })
    );
    let mut f = sample_frame(2);
    f.detections[0].size[2] = 0.0;
    assert!(matches!(
        encode(&f),
        Err(EncodeError::OutOfRange {
            field: "size.h",
            ..
        })
    ));
    let mut f = sample_frame(2);
    f.detections[0].score = 1.5;
    assert!(matches!(
        encode(&f),
        Err(EncodeError::OutOfRange { field: "score", .. })
    ));
    let mut f = sample_frame(1);
    f.detections[0].std.yaw = -1.0;
    assert!(matches!(
        encode(&f),
        Err(EncodeError::OutOfRange {
            field: "std.yaw",
            ..
        })
    ));
    let f = Frame {
        detections: vec![sample_frame(1).detections[0].clone(); MAX_OBJECTS + 1],
        ..sample_frame(0)
    };
    assert_eq!(
        encode(&f),
        Err(EncodeError::TooManyObjects(MAX_OBJECTS + 1))
    );
}

fn parts(f: &Frame) -> (Header, Vec<Object>) {
    let bytes = encode(f).unwrap();
    let mut h = read_header(&bytes).unwrap();
    let objects = (0..h.count)
        .map(|_| Object::read(&mut h.rest).unwrap())
        .collect();
    (h.header, objects)
}

fn valid() -> (Header, Vec<Object>) {
    parts(&sample_frame(2))
}

#[test]
fn decode_reports_each_invalid_field() {
    assert_eq!(decode(&[]), Err(DecodeError::Empty));
    assert_eq!(decode(&[7, 1, 2]), Err(DecodeError::UnknownVersion(7)));
    assert_eq!(
        decode(&vec![VERSION; MAX_PAYLOAD + 1]),
        Err(DecodeError::TooLarge(MAX_PAYLOAD + 1))
    );

    let (h, o) = valid();
    let mut b = assemble(&h, None, &o);
    b.push(0);
    assert_eq!(decode(&b), Err(DecodeError::TrailingBytes(1)));

    let (mut h, o) = valid();
    h.kind = 5;
    assert!(matches!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::OutOfRange { field: "kind", .. })
    ));

    let (h, mut o) = valid();
    o[1].tag = 12;
    assert_eq!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::OutOfRange {
            index: 1,
            field: "class",
            value: 12
        })
    );

    let (h, mut o) = valid();
    o[0].tag |= 0x80; // a bit this version does not define
    assert!(matches!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::OutOfRange { field: "tag", .. })
    ));

    let (h, mut o) = valid();
    o[0].size_delta_cm[1] = -10_000;
    assert_eq!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::SizeOutOfRange {
            index: 0,
            field: "size.w",
            cm: (Class::Car.typical_size()[1] * 100.0).round() as i64 - 10_000
        })
    );

    // A size above 1 km decodes nowhere: the encoder could not write it back.
    let (h, mut o) = valid();
    o[0].size_delta_cm[0] = 100_000;
    assert!(matches!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::SizeOutOfRange {
            field: "size.l",
            ..
        })
    ));

    let (h, mut o) = valid();
    o[1].tag |= TAG_VEL;
    o[1].vel = Some([0, 1001]); // 100.1 m/s
    assert!(matches!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::OutOfRange {
            index: 1,
            field: "velocity.y",
            ..
        })
    ));

    let (h, mut o) = valid();
    o[1].score = 251;
    assert!(matches!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::OutOfRange { field: "score", .. })
    ));

    let (mut h, o) = valid();
    h.default_std[6] = 0;
    assert_eq!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::BadStdCode {
            index: usize::MAX,
            field: "std.yaw",
            code: 0
        })
    );

    let (h, mut o) = valid();
    o[0].tag |= TAG_STD;
    o[0].std = Some([5, 5, STD_CODE_MAX + 1, 5, 5, 5, 5]);
    assert_eq!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::BadStdCode {
            index: 0,
            field: "std.z",
            code: STD_CODE_MAX + 1
        })
    );

    for name in ["", "a/b", "x*", &"n".repeat(MAX_AGENT_NAME + 1)] {
        let (mut h, o) = valid();
        h.agent = name.into();
        assert!(
            matches!(
                decode(&assemble(&h, None, &o)),
                Err(DecodeError::BadAgentName(_))
            ),
            "{name}"
        );
    }

    let (mut h, o) = valid();
    h.origin_cm[0] = i64::MAX;
    assert!(matches!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::OutOfRange {
            field: "origin",
            ..
        })
    ));

    // An origin at the edge of the domain with an object pushed beyond it.
    let (mut h, mut o) = valid();
    h.origin_cm[1] = (limits::COORD_MAX * 100.0) as i64;
    o[1].pos_cm[1] = 1;
    assert!(matches!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::OutOfRange {
            index: 1,
            field: "center.y",
            ..
        })
    ));
}

#[test]
fn the_object_count_is_checked_before_any_object_is_read() {
    let (h, _) = valid();
    // Claims 5,000 objects and carries none: refused as too many, not read as truncated.
    let mut w = Writer(vec![VERSION]);
    w.put(&h);
    w.put(&5_000u64);
    assert_eq!(decode(&w.0), Err(DecodeError::TooManyObjects(5_000)));
    assert_eq!(peek(&w.0), Err(DecodeError::TooManyObjects(5_000)));
    let (h, o) = valid();
    assert_eq!(peek(&assemble(&h, None, &o)), Ok(("veh1".to_string(), 2)));
}

#[test]
fn encode_rejects_what_decode_rejects() {
    let mut f = sample_frame(1);
    f.agent = String::new();
    assert!(matches!(encode(&f), Err(EncodeError::BadAgentName(_))));
    let mut f = sample_frame(1);
    f.detections[0].size[0] = 1000.5;
    assert!(matches!(
        encode(&f),
        Err(EncodeError::OutOfRange {
            field: "size.l",
            ..
        })
    ));
    let mut f = sample_frame(1);
    f.detections[0].std.pos[0] = limits::STD_MIN / 2.0;
    assert!(matches!(
        encode(&f),
        Err(EncodeError::OutOfRange { field: "std.x", .. })
    ));
    let mut f = sample_frame(1);
    f.origin[2] = 2e9;
    assert!(matches!(
        encode(&f),
        Err(EncodeError::OutOfRange {
            field: "origin",
            ..
        })
    ));
}

#[test]
fn fit_makes_any_fused_frame_encodable() {
    // Two agents at the format's minimum std: WLS halves the variance, below the floor.
    let mut f = sample_frame(3);
    for d in &mut f.detections {
        d.std = Uncertainty::uniform(limits::STD_MIN / 2f64.sqrt(), 0.1, 0.1);
    }
    assert!(encode(&f).is_err());
    let report = fit(&mut f);
    assert_eq!(report.stds_clamped, 9);
    assert!(encode(&f).is_ok());

    // Too many objects: the lowest scores go.
    let mut f = sample_frame(MAX_OBJECTS + 10);
    for (i, d) in f.detections.iter_mut().enumerate() {
        d.score = if i < 10 { 0.01 } else { 0.9 };
    }
    let report = fit(&mut f);
    assert_eq!(report.objects_capped, 10);
    assert_eq!(f.detections.len(), MAX_OBJECTS);
    assert!(f.detections.iter().all(|d| d.score == 0.9));
    assert!(encode(&f).is_ok());

    // One object 1e8 m away cannot take the others out of reach: it alone is dropped.
    let mut f = sample_frame(5);
    f.detections[2].center = [1e8, 1e8, 0.0];
    f.detections[3].center[0] = f64::NAN;
    let report = fit(&mut f);
    assert_eq!(report.objects_invalid, 2);
    assert_eq!(f.detections.len(), 3);
    assert!(encode(&f).is_ok());
    assert!(fit(&mut f).is_clean());
}

#[test]
fn fit_drops_a_dropped_objects_source_set() {
    let (mut f, mut p) = fused_frame(5);
    f.detections[2].center = [1e8, 1e8, 0.0];
    f.detections[3].center[0] = f64::NAN;
    let kept = [
        p.sources[0].clone(),
        p.sources[1].clone(),
        p.sources[4].clone(),
    ];
    let report = fit_with(&mut f, Some(&mut p));
    assert_eq!(report.objects_invalid, 2);
    assert_eq!(p.sources, kept);
    let (_, q) = decode_with(&encode_with(&f, Some(&p)).unwrap()).unwrap();
    assert_eq!(q, Some(p));
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = encode(&sample_frame(25)).unwrap();
    for n in 0..bytes.len() {
        let r = decode(&bytes[..n]);
        assert!(r.is_err(), "prefix of {n} bytes decoded");
        if n > 1 {
            assert!(
                matches!(
                    r,
                    Err(DecodeError::Truncated) | Err(DecodeError::Malformed(_))
                ),
                "prefix {n}: {r:?}"
            );
        }
    }
}

/// The one-domain property: whatever decodes encodes again, to a payload that decodes to the
/// same frame.
pub(crate) fn assert_decoded_reencodes(bytes: &[u8]) {
    if let Ok((f, p)) = decode_with(bytes) {
        let again = encode_with(&f, p.as_ref())
            .unwrap_or_else(|e| panic!("decoded frame does not encode: {e}"));
        assert_eq!(decode_with(&again).unwrap(), (f, p));
    }
}

/// A fused frame of `n` boxes over three agents, box i from the agents of the bits of i % 7 + 1.
fn fused_frame(n: usize) -> (Frame, Provenance) {
    let mut f = sample_frame(n);
    f.agent = "fuser".into();
    f.kind = AgentKind::Infrastructure;
    let p = Provenance {
        agents: vec!["veh1".into(), "rsu1".into(), "veh2".into()],
        complete: false,
        sources: (0..n)
            .map(|i| (0..3).filter(|k| (i % 7 + 1) & (1 << k) != 0).collect())
            .collect(),
    };
    (f, p)
}

#[test]
fn provenance_round_trips_and_costs_a_byte_per_box() {
    for n in [0, 1, 30] {
        let (f, p) = fused_frame(n);
        let plain = encode(&f).unwrap();
        let bytes = encode_with(&f, Some(&p)).unwrap();
        // complete (1) + count (1) + three names with their lengths (15), one mask byte a box.
        assert_eq!(bytes.len(), plain.len() + 1 + 1 + 15 + n, "{n} boxes");
        assert_eq!(bytes[0], VERSION);
        let (g, q) = decode_with(&bytes).unwrap();
        assert_close(&f, &g);
        assert_eq!(q.as_ref(), Some(&p));
        // A plain decode reads the same frame and leaves the provenance out.
        assert_eq!(decode(&bytes).unwrap(), g);
        assert_eq!(peek(&bytes), Ok(("fuser".to_string(), n)));
        // An agent's frame has none.
        assert_eq!(decode_with(&plain).unwrap().1, None);
    }
    // Nine agents take two mask bytes a box.
    let (f, mut p) = fused_frame(4);
    p.agents = (0..9).map(|k| format!("a{k}")).collect();
    p.sources[3] = AgentSet::single(8);
    let bytes = encode_with(&f, Some(&p)).unwrap();
    assert_eq!(decode_with(&bytes).unwrap().1, Some(p.clone()));
    assert_eq!(&bytes[bytes.len() - 2..], &[0, 1]);
}

#[test]
fn provenance_errors_name_the_problem() {
    let (f, p) = fused_frame(3);
    let mut q = p.clone();
    q.sources.pop();
    assert!(matches!(
        encode_with(&f, Some(&q)),
        Err(EncodeError::BadProvenance(ProvenanceError::Sources {
            sets: 2,
            boxes: 3
        }))
    ));
    let mut q = p.clone();
    q.sources[1] = AgentSet::single(3);
    assert!(matches!(
        encode_with(&f, Some(&q)),
        Err(EncodeError::BadProvenance(_))
    ));

    let bytes = encode_with(&f, Some(&p)).unwrap();
    let (h, _) = parts(&f);
    // The completeness byte sits right after the header.
    let at = {
        let mut w = Writer(vec![VERSION]);
        w.put(&Header {
            kind: h.kind | KIND_PROVENANCE,
            ..h.clone()
        });
        w.0.len()
    };
    let mut b = bytes.clone();
    b[at] = 2;
    assert_eq!(
        decode(&b),
        Err(DecodeError::BadProvenance(ProvenanceError::BadComplete(2)))
    );
    // A mask bit beyond the three agents.
    let mut b = bytes.clone();
    *b.last_mut().unwrap() = 0b1000;
    let mask = ProvenanceError::BadMask {
        object: 2,
        listed: 3,
    };
    assert_eq!(decode(&b), Err(DecodeError::BadProvenance(mask.clone())));
    *b.last_mut().unwrap() = 0;
    assert_eq!(decode(&b), Err(DecodeError::BadProvenance(mask)));
    // Without its last mask the frame is truncated; an unknown kind bit is refused.
    assert_eq!(
        decode(&bytes[..bytes.len() - 1]),
        Err(DecodeError::Truncated)
    );
    // The kind byte follows the version and the name "fuser" with its length.
    let kind_at = 1 + 1 + "fuser".len();
    let mut b2 = bytes.clone();
    b2[kind_at] |= 0x04;
    assert!(matches!(
        decode(&b2),
        Err(DecodeError::OutOfRange { field: "kind", .. })
    ));
    // Duplicate agents are refused on both sides.
    let mut q = p.clone();
    q.agents[2] = "veh1".into();
    assert!(encode_with(&f, Some(&q)).is_err());
    let mut w = Writer(vec![VERSION]);
    w.put(&Header {
        kind: h.kind | KIND_PROVENANCE,
        ..h.clone()
    });
    w.put(&1u8);
    w.put(&vec!["a".to_string(), "a".to_string()]);
    w.put(&0u64);
    assert!(matches!(
        decode(&w.0),
        Err(DecodeError::BadProvenance(ProvenanceError::Twice {
            index: 1,
            ..
        }))
    ));
    // Too many agents are refused before any name is read.
    let mut w = Writer(vec![VERSION]);
    w.put(&Header {
        kind: h.kind | KIND_PROVENANCE,
        ..h
    });
    w.put(&1u8);
    w.put(&5_000u64);
    assert_eq!(
        decode(&w.0),
        Err(DecodeError::BadProvenance(ProvenanceError::TooManyAgents(
            5000
        )))
    );
}

fn arb_detection() -> impl Strategy<Value = Detection> {
    (
        0usize..10,
        prop::array::uniform3(-500.0f64..500.0),
        prop::array::uniform3(0.05f64..20.0),
        -10.0f64..10.0,
        0.0f64..=1.0,
        prop::array::uniform7(0.001f64..50.0),
        any::<u32>(),
        prop::option::of((
            prop::array::uniform2(-99.0f64..99.0),
            prop::array::uniform2(0.01f64..10.0),
        )),
    )
        .prop_map(|(c, center, size, yaw, score, std, id, vel)| Detection {
            class: Class::ALL[c],
            center,
            size,
            yaw: wrap_angle(yaw),
            score,
            std: Uncertainty::from_array(std),
            pos_cov: None,
            velocity: vel.map(|(v, std)| Velocity { v, std }),
            id,
        })
}

proptest! {
    #[test]
    fn round_trip_property(
        dets in prop::collection::vec(arb_detection(), 0..40),
        seq in any::<u32>(),
        t in any::<u64>(),
        origin in prop::array::uniform3(-1e5f64..1e5),
        infra in any::<bool>(),
        uniform in any::<bool>(),
    ) {
        let mut dets = dets;
        if uniform {
            for d in &mut dets { d.std = Uncertainty::uniform(1.5, 0.5, 0.35); }
        }
        let f = Frame {
            agent: "rsu-7".into(),
            kind: if infra { AgentKind::Infrastructure } else { AgentKind::Vehicle },
            seq,
            capture_us: t,
            origin,
            detections: dets.into_iter().map(|mut d| {
                for k in 0..3 { d.center[k] += origin[k]; }
                d
            }).collect(),
        };
        let g = decode(&encode(&f).unwrap()).unwrap();
        assert_close(&f, &g);
    }

    #[test]
    fn provenance_round_trip_property(
        n in 0usize..20,
        agents in 1usize..40,
        complete in any::<bool>(),
        seeds in prop::collection::vec(any::<u64>(), 20),
    ) {
        let (f, _) = fused_frame(n);
        let p = Provenance {
            agents: (0..agents).map(|k| format!("agent-{k}")).collect(),
            complete,
            sources: (0..n)
                .map(|i| {
                    let s = seeds[i];
                    let mut set: AgentSet = (0..agents).filter(|k| s >> (k % 64) & 1 == 1).collect();
                    set.insert((s % agents as u64) as usize);
                    set
                })
                .collect(),
        };
        let bytes = encode_with(&f, Some(&p)).unwrap();
        let (g, q) = decode_with(&bytes).unwrap();
        assert_close(&f, &g);
        prop_assert_eq!(q, Some(p));
    }

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        assert_decoded_reencodes(&bytes);
        let mut v = vec![VERSION];
        v.extend(&bytes);
        assert_decoded_reencodes(&v);
    }

    #[test]
    fn corrupted_frames_never_panic_and_reencode(pos in 0usize..400, val in any::<u8>()) {
        let mut bytes = encode(&sample_frame(20)).unwrap();
        let p = pos % bytes.len();
        bytes[p] = val;
        assert_decoded_reencodes(&bytes);
        let (f, prov) = fused_frame(20);
        let mut bytes = encode_with(&f, Some(&prov)).unwrap();
        let p = pos % bytes.len();
        bytes[p] = val;
        assert_decoded_reencodes(&bytes);
    }
}

#[test]
fn ids_take_four_bytes_and_none_takes_none() {
    let mut f = sample_frame(3);
    f.detections[0].id = 7;
    f.detections[1].id = 0xdead_beef;
    f.detections[2].id = NO_ID;
    let bytes = encode(&f).unwrap();
    let g = decode(&bytes).unwrap();
    let ids: Vec<u32> = g.detections.iter().map(|d| d.id).collect();
    assert_eq!(ids, vec![7, 0xdead_beef, NO_ID]);
    let (_, objects) = parts(&f);
    assert_eq!(objects[0].tag & TAG_ID, TAG_ID);
    assert_eq!(objects[1].id, Some([0xef, 0xbe, 0xad, 0xde]));
    assert_eq!((objects[2].tag & TAG_ID, objects[2].id), (0, None));
    // Every id costs the same four bytes; leaving it out saves them.
    let mut small = f.clone();
    small.detections[1].id = 1;
    assert_eq!(encode(&small).unwrap().len(), bytes.len());
    let mut none = f.clone();
    none.detections[0].id = NO_ID;
    assert_eq!(encode(&none).unwrap().len(), bytes.len() - 4);
    // "No id" written as an id is refused: the decoder accepts one spelling of each frame.
    let (h, mut o) = parts(&f);
    o[0].id = Some(NO_ID.to_le_bytes());
    assert!(matches!(
        decode(&assemble(&h, None, &o)),
        Err(DecodeError::OutOfRange {
            index: 0,
            field: "id",
            ..
        })
    ));
}

#[test]
fn a_padded_varint_is_refused() {
    // 0 as one byte reads; the same 0 padded to three bytes (80 80 00) does not.
    assert_eq!(Reader(&[0x00]).take::<u32>(), Ok(0));
    assert_eq!(Reader(&[0x81, 0x01]).take::<u32>(), Ok(129));
    for padded in [&[0x80, 0x80, 0x00][..], &[0x80, 0x00], &[0x81, 0x81, 0x00]] {
        assert!(
            matches!(Reader(padded).take::<u32>(), Err(DecodeError::Malformed(ref m)) if m.contains("shortest")),
            "{padded:02x?}"
        );
    }
    // In a whole payload: a frame of no objects ends with its object count, 00.
    let mut f = sample_frame(0);
    f.detections.clear();
    let mut bytes = encode(&f).unwrap();
    assert_eq!(bytes.last(), Some(&0x00));
    assert_eq!(decode(&bytes).unwrap().detections.len(), 0);
    bytes.pop();
    bytes.extend([0x80, 0x80, 0x00]);
    assert!(matches!(decode(&bytes), Err(DecodeError::Malformed(_))));
}

#[test]
fn a_bad_frame_field_is_named_as_the_frames() {
    let (mut h, o) = valid();
    h.kind = 5;
    let e = decode(&assemble(&h, None, &o)).unwrap_err();
    assert_eq!(e.to_string(), "frame: field 'kind' is out of range (5)");
    let (h, mut o) = valid();
    o[1].tag = 12;
    assert!(decode(&assemble(&h, None, &o))
        .unwrap_err()
        .to_string()
        .starts_with("object 1: field"));
}

#[test]
fn the_output_cap_is_shared_fairly_between_agents() {
    // Agent 0 sends MAX_OBJECTS boxes of score 1.0; agents 1 and 2 send 24 boxes each of score
    // 0.5, and 8 boxes are fused from agents 1 and 2 together.
    let n0 = MAX_OBJECTS;
    let (mut f, mut p) = fused_frame(n0 + 56);
    let mut sources = Vec::new();
    for (i, d) in f.detections.iter_mut().enumerate() {
        let s: AgentSet = if i < n0 {
            d.score = 1.0;
            AgentSet::single(0)
        } else if i < n0 + 24 {
            d.score = 0.5;
            AgentSet::single(1)
        } else if i < n0 + 48 {
            d.score = 0.5;
            AgentSet::single(2)
        } else {
            d.score = 0.4;
            [1, 2].into_iter().collect()
        };
        sources.push(s);
    }
    p.sources = sources;
    let report = fit_with(&mut f, Some(&mut p));
    assert_eq!(report.objects_capped, 56);
    assert_eq!(f.detections.len(), MAX_OBJECTS);
    // Every box of agents 1 and 2 stays; agent 0 keeps its MAX_OBJECTS - 56 best.
    let of = |k: usize| p.sources.iter().filter(|s| s.contains(k)).count();
    assert_eq!((of(0), of(1), of(2)), (MAX_OBJECTS - 56, 32, 32));
    assert!(encode_with(&f, Some(&p)).is_ok());
    // Without provenance the cap is by score alone: agent 0's boxes take every place.
    let (mut f, _) = fused_frame(n0 + 56);
    for (i, d) in f.detections.iter_mut().enumerate() {
        d.score = if i < n0 { 1.0 } else { 0.5 };
    }
    fit(&mut f);
    assert!(f.detections.iter().all(|d| d.score == 1.0));
}
