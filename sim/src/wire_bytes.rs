//! What a frame costs on the air, in the project's own encoding and as the standard message
//! (ETSI CPM, UPER) of the same boxes, so that benches report the two side by side.

use std::ops::AddAssign;
use v2x_protocol::{wire, AgentKind, Detection, Frame};

/// Bytes of frames in each encoding.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Bytes {
    /// The project's frames (docs/wire-format.md).
    pub frame: usize,
    /// ETSI CPMs of the same boxes (docs/cpm.md): one per 255 boxes.
    pub cpm: usize,
}

impl AddAssign for Bytes {
    fn add_assign(&mut self, o: Bytes) {
        self.frame += o.frame;
        self.cpm += o.cpm;
    }
}

/// What a frame of `dets` from `agent` costs (bytes), encoded as agents send it; 0 in an
/// encoding that cannot carry it.
pub fn frame_bytes(agent: &str, kind: AgentKind, capture_us: u64, dets: &[Detection]) -> Bytes {
    let frame = Frame {
        agent: agent.to_string(),
        kind,
        seq: 0,
        capture_us,
        origin: [0.0; 3],
        detections: dets.to_vec(),
    }
    .with_centroid_origin();
    Bytes {
        frame: wire::encode(&frame).map_or(0, |b| b.len()),
        cpm: v2x_cpm::message_bytes(&frame),
    }
}
