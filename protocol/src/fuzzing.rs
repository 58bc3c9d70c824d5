//! Properties checked on arbitrary input, shared by the fuzz targets (`fuzz/`) and by the
//! regression tests that replay their corpus and every input that once failed. Each function
//! panics when its property does not hold.

use crate::nuscenes_json::{parse_results, results_json, MissingStd, TokenTable};
use crate::{wire, wrap_angle, Uncertainty};
use std::path::Path;

/// The wire's one-domain property: whatever decodes (with its provenance, when a fused frame)
/// encodes again, to a payload that decodes to the same frame and provenance; [`wire::peek`]
/// agrees with [`wire::decode`] on the header.
pub fn wire_round_trip(data: &[u8]) {
    let peeked = wire::peek(data);
    match wire::decode_with(data) {
        Ok((f, p)) => {
            assert_eq!(peeked, Ok((f.agent.clone(), f.detections.len())));
            assert_eq!(wire::decode(data).as_ref(), Ok(&f));
            let again = wire::encode_with(&f, p.as_ref()).expect("a decoded frame encodes");
            let back = wire::decode_with(&again).expect("a re-encoded frame decodes");
            assert_eq!(back, (f, p));
        }
        Err(_) => {
            // A header that peeks fine may still hold a bad object; the reverse never happens.
            if let Err(e) = peeked {
                assert_eq!(wire::decode(data), Err(e));
            }
        }
    }
}

/// Results files: parsing never panics, and whatever parses is written back to a document that
/// parses to the same boxes.
pub fn results_round_trip(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz.json");
    let missing = MissingStd::Default(Uncertainty::uniform(1.0, 1.0, 1.0));
    let mut tokens = TokenTable::new();
    let Ok(r) = parse_results(path, text, &mut tokens, missing) else {
        return;
    };
    let written = results_json(&r, &tokens).to_string();
    let mut tokens2 = TokenTable::new();
    let r2 = parse_results(path, &written, &mut tokens2, missing)
        .unwrap_or_else(|e| panic!("written results do not parse: {e}"));
    assert_eq!(r.samples.len(), r2.samples.len());
    for ((s1, d1), (s2, d2)) in r.samples.iter().zip(&r2.samples) {
        assert_eq!(s1, s2);
        assert_eq!(d1.len(), d2.len());
        for (a, b) in d1.iter().zip(d2) {
            assert_eq!((a.class, a.center, a.size), (b.class, b.center, b.size));
            assert_eq!((a.score, a.std, &a.pos_cov), (b.score, b.std, &b.pos_cov));
            assert!(
                wrap_angle(a.yaw - b.yaw).abs() < 1e-9,
                "{} {}",
                a.yaw,
                b.yaw
            );
            match tokens.name(a.id) {
                Some(t) => assert_eq!(Some(t), tokens2.name(b.id)),
                None => assert_eq!(a.id, b.id),
            }
        }
    }
}
