use super::*;
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

fn body(wf: &WireFrame) -> Vec<u8> {
    let mut v = vec![VERSION];
    v.extend(postcard::to_stdvec(wf).unwrap());
    v
}

fn valid_wire() -> WireFrame {
    let bytes = encode(&sample_frame(2)).unwrap();
    postcard::from_bytes(&bytes[1..]).unwrap()
}

#[test]
fn decode_reports_each_invalid_field() {
    assert_eq!(decode(&[]), Err(DecodeError::Empty));
    assert_eq!(decode(&[7, 1, 2]), Err(DecodeError::UnknownVersion(7)));

    let mut b = body(&valid_wire());
    b.push(0);
    assert_eq!(decode(&b), Err(DecodeError::TrailingBytes(1)));

    let mut wf = valid_wire();
    wf.kind = 5;
    assert!(matches!(
        decode(&body(&wf)),
        Err(DecodeError::OutOfRange { field: "kind", .. })
    ));

    let mut wf = valid_wire();
    wf.objects[1].tag = 12;
    assert_eq!(
        decode(&body(&wf)),
        Err(DecodeError::OutOfRange {
            index: 1,
            field: "class",
            value: 12
        })
    );

    let mut wf = valid_wire();
    wf.objects[0].tag |= 0x10; // says an override follows, but none does
    assert!(matches!(
        decode(&body(&wf)),
        Err(DecodeError::OutOfRange { field: "tag", .. })
    ));

    let mut wf = valid_wire();
    wf.objects[0].size_delta_cm[1] = -10_000;
    assert_eq!(
        decode(&body(&wf)),
        Err(DecodeError::NonPositiveSize {
            index: 0,
            field: "size.w"
        })
    );

    let mut wf = valid_wire();
    wf.objects[1].score = 251;
    assert!(matches!(
        decode(&body(&wf)),
        Err(DecodeError::OutOfRange { field: "score", .. })
    ));

    let mut wf = valid_wire();
    wf.default_std[6] = 0;
    assert_eq!(
        decode(&body(&wf)),
        Err(DecodeError::NonPositiveStd {
            index: usize::MAX,
            field: "std.yaw"
        })
    );

    let mut wf = valid_wire();
    wf.objects[0].tag |= 0x10;
    wf.objects[0].std = Some([5, 5, 0, 5, 5, 5, 5]);
    assert_eq!(
        decode(&body(&wf)),
        Err(DecodeError::NonPositiveStd {
            index: 0,
            field: "std.z"
        })
    );

    let mut wf = valid_wire();
    wf.agent = String::new();
    assert!(matches!(
        decode(&body(&wf)),
        Err(DecodeError::OutOfRange { field: "agent", .. })
    ));

    let mut wf = valid_wire();
    let o = wf.objects.pop().unwrap();
    wf.objects = (0..MAX_OBJECTS + 1)
        .map(|_| WireObject {
            std: None,
            tag: o.tag & 0x0f,
            ..o
        })
        .collect();
    assert_eq!(
        decode(&body(&wf)),
        Err(DecodeError::TooManyObjects(MAX_OBJECTS + 1))
    );

    let mut wf = valid_wire();
    wf.origin_cm[0] = i64::MAX;
    assert!(matches!(
        decode(&body(&wf)),
        Err(DecodeError::NonFinite {
            field: "origin",
            ..
        })
    ));
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

fn arb_detection() -> impl Strategy<Value = Detection> {
    (
        0usize..10,
        prop::array::uniform3(-500.0f64..500.0),
        prop::array::uniform3(0.05f64..20.0),
        -10.0f64..10.0,
        0.0f64..=1.0,
        prop::array::uniform7(0.001f64..50.0),
        any::<u32>(),
    )
        .prop_map(|(c, center, size, yaw, score, std, id)| Detection {
            class: Class::ALL[c],
            center,
            size,
            yaw: wrap_angle(yaw),
            score,
            std: Uncertainty::from_array(std),
            pos_cov: None,
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
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let _ = decode(&bytes);
        let mut v = vec![VERSION];
        v.extend(&bytes);
        let _ = decode(&v);
    }

    #[test]
    fn corrupted_frames_never_panic(pos in 0usize..400, val in any::<u8>()) {
        let mut bytes = encode(&sample_frame(20)).unwrap();
        let p = pos % bytes.len();
        bytes[p] = val;
        let _ = decode(&bytes);
    }
}
