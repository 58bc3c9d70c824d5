//! The property the fuzz target `cpm_decode` (`fuzz/`) checks on arbitrary bytes; it panics
//! when the property does not hold.

use crate::{decode, encode, Geo};

/// What the decoder accepts, the encoder writes back: a CPM that decodes becomes a frame that
/// encodes, to a message that decodes to the same boxes (a std may come back one step wider,
/// where its bound over 1.96 lands on a step's edge).
pub fn decode_round_trip(data: &[u8]) {
    let geo = Geo {
        lat_deg: 48.0,
        lon_deg: 11.0,
    };
    let Ok(cpm) = decode(data, &geo) else {
        return;
    };
    let frame = cpm.clone().into_frame("fuzz".into());
    let again = encode(&frame, &geo).expect("a decoded CPM encodes");
    let back = decode(&again, &geo).expect("a re-encoded CPM decodes");
    assert_eq!(back.detections.len(), cpm.detections.len());
    for (a, b) in cpm.detections.iter().zip(&back.detections) {
        assert_eq!((a.class, a.id, a.score), (b.class, b.id, b.score));
        for k in 0..3 {
            assert!((a.center[k] - b.center[k]).abs() < 1e-6, "{a:?} {b:?}");
            assert!((a.size[k] - b.size[k]).abs() < 1e-9, "{a:?} {b:?}");
        }
        assert!(
            v2x_protocol::wrap_angle(a.yaw - b.yaw).abs() < 1e-9,
            "{a:?} {b:?}"
        );
    }
}
