//! `docs/wire-format.md` matches the code: the document's example bytes decode to the frame it
//! describes, and that frame encodes to exactly those bytes.

use v2x_protocol::{
    wire, AgentKind, AgentSet, Class, Detection, Frame, Provenance, Uncertainty, Velocity, NO_ID,
};

/// The example frame of the document, field by field.
fn documented_frame() -> Frame {
    Frame {
        agent: "rsu1".into(),
        kind: AgentKind::Infrastructure,
        seq: 7,
        capture_us: 1_700_000_000_000_000,
        origin: [100.0, -50.0, 1.0],
        detections: vec![
            Detection {
                class: Class::Car,
                center: [102.5, -48.0, 1.8],
                size: [4.6, 1.95, 1.75],
                yaw: std::f64::consts::FRAC_PI_2,
                score: 0.9,
                std: Uncertainty::uniform(0.5, 0.1, 5f64.to_radians()),
                pos_cov: None,
                velocity: Some(Velocity {
                    v: [5.0, -0.3],
                    std: [0.25, 0.25],
                }),
                id: 12,
            },
            Detection {
                class: Class::Pedestrian,
                center: [95.0, -50.0, 0.9],
                size: [0.8, 0.6, 1.7],
                yaw: 0.0,
                score: 0.5,
                std: Uncertainty::uniform(0.3, 0.1, 5f64.to_radians()),
                pos_cov: None,
                velocity: None,
                id: NO_ID,
            },
        ],
    }
}

/// The fused example: the same boxes published by the fuser from a complete window of `rsu1` and
/// `veh1`, the car seen by both, the pedestrian by `rsu1` alone.
fn documented_fused() -> (Frame, Provenance) {
    let mut f = documented_frame();
    f.agent = "fuser".into();
    let p = Provenance {
        agents: vec!["rsu1".into(), "veh1".into()],
        complete: true,
        sources: vec![[0, 1].into_iter().collect(), AgentSet::single(0)],
    };
    (f, p)
}

/// With `PRINT_WIRE_EXAMPLE` set, prints the bytes the encoder writes (to update the document).
fn print_if_asked(encoded: &[u8]) {
    if std::env::var_os("PRINT_WIRE_EXAMPLE").is_some() {
        for b in encoded {
            print!("{b:02x} ");
        }
        println!();
    }
}

/// The hex bytes of a document's example block (between the `NAME` markers).
fn documented_bytes(name: &str) -> Vec<u8> {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../docs/wire-format.md"
    ))
    .expect("docs/wire-format.md is in the repository");
    let start = doc.find(&format!("<!-- {name} -->")).expect("start marker");
    let end = doc.find(&format!("<!-- /{name} -->")).expect("end marker");
    let mut bytes = Vec::new();
    for line in doc[start..end].lines() {
        // each line: hex bytes, then `|` and a comment
        let hex = line.split('|').next().unwrap_or("");
        for tok in hex.split_whitespace() {
            if tok.len() == 2 && tok.chars().all(|c| c.is_ascii_hexdigit()) {
                bytes.push(u8::from_str_radix(tok, 16).unwrap());
            }
        }
    }
    bytes
}

#[test]
fn the_documented_bytes_are_the_documented_frame() {
    let bytes = documented_bytes("example-bytes");
    let frame = documented_frame();
    let encoded = wire::encode(&frame).unwrap();
    print_if_asked(&encoded);
    assert_eq!(
        encoded, bytes,
        "encode(documented frame) differs from the document's bytes"
    );
    let decoded = wire::decode(&bytes).unwrap();
    assert_eq!(decoded.agent, "rsu1");
    assert_eq!(decoded.kind, AgentKind::Infrastructure);
    assert_eq!(
        (decoded.seq, decoded.capture_us),
        (7, 1_700_000_000_000_000)
    );
    assert_eq!(decoded.origin, [100.0, -50.0, 1.0]);
    let (car, walker) = (&decoded.detections[0], &decoded.detections[1]);
    assert_eq!(
        (car.class, car.id, walker.class, walker.id),
        (Class::Car, 12, Class::Pedestrian, NO_ID)
    );
    assert_eq!(car.center, [102.5, -48.0, 1.8]);
    assert_eq!(car.size, [4.6, 1.95, 1.75]);
    assert!((car.yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert_eq!((car.score, walker.score), (0.9, 0.5));
    let v = car.velocity.unwrap();
    assert_eq!(v.v, [5.0, -0.30000000000000004]);
    assert!((v.std[0] - 0.25).abs() < 0.25 * 1e-3);
    assert!((walker.std.pos[0] - 0.3).abs() < 0.3 * 1e-3);
    assert!((car.std.pos[0] - 0.5).abs() < 0.5 * 1e-3);
    assert_eq!(walker.size, [0.8, 0.6, 1.7]);
    assert_eq!(walker.velocity, None);
}

#[test]
fn the_documented_fused_bytes_are_the_documented_fused_frame() {
    let bytes = documented_bytes("fused-example-bytes");
    let (frame, provenance) = documented_fused();
    let encoded = wire::encode_with(&frame, Some(&provenance)).unwrap();
    print_if_asked(&encoded);
    assert_eq!(
        encoded, bytes,
        "encode(documented fused frame) differs from the document's bytes"
    );
    let (decoded, p) = wire::decode_with(&bytes).unwrap();
    let p = p.expect("a fused frame carries its provenance");
    assert_eq!(p, provenance);
    assert_eq!(p.names(&p.sources[0]).collect::<Vec<_>>(), ["rsu1", "veh1"]);
    assert_eq!(
        decoded,
        wire::decode(&documented_bytes("example-bytes"))
            .map(|mut f| {
                f.agent = "fuser".into();
                f
            })
            .unwrap()
    );
}
