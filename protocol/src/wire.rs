//! The compact wire encoding of a [`Frame`] (DESIGN §8).
//!
//! A payload is one version byte followed by a postcard body. Values are quantized:
//! positions in centimetres relative to the frame origin (zig-zag varints, so nearby objects
//! cost two bytes an axis), sizes in centimetres as the difference from the class's typical size,
//! yaw in 1/65536 turn (two fixed bytes), score in 1/250 steps, and standard deviations on a
//! logarithmic scale (0.2% steps, so within 0.1% relative). A frame carries a default
//! uncertainty; an object carries its own only when it differs, so uniform stds cost nothing per
//! object. Decoding validates every field and returns a [`DecodeError`]; it never panics.

use crate::{wrap_angle, AgentKind, Class, Detection, Frame, Uncertainty};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The wire format version this crate writes and reads.
pub const VERSION: u8 = 1;
/// The most objects a frame may carry.
pub const MAX_OBJECTS: usize = 4096;
/// The longest agent name, in bytes.
pub const MAX_AGENT_NAME: usize = 64;

const SCORE_STEPS: f64 = 250.0;
const YAW_STEPS: f64 = 65536.0;
/// Log-scale std code: std = STD_MIN * exp((code - 1) / STD_PER_UNIT); code 0 is invalid.
const STD_MIN: f64 = 1e-4;
const STD_PER_UNIT: f64 = 500.0;
/// Largest |relative position| in cm that encodes (about 21 km).
const MAX_REL_CM: f64 = i32::MAX as f64;

/// Why a frame could not be encoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EncodeError {
    /// A value is NaN or infinite.
    #[error("object {index}: field '{field}' is not finite")]
    NonFinite {
        /// Object index (or usize::MAX for the frame itself).
        index: usize,
        /// The field name.
        field: &'static str,
    },
    /// A value is outside what the format represents.
    #[error("object {index}: field '{field}' is out of range ({value})")]
    OutOfRange {
        /// Object index (or usize::MAX for the frame itself).
        index: usize,
        /// The field name.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
    /// More objects than [`MAX_OBJECTS`].
    #[error("frame has {0} objects, more than the limit {MAX_OBJECTS}")]
    TooManyObjects(usize),
    /// The agent name is too long.
    #[error("agent name is {0} bytes, more than the limit {MAX_AGENT_NAME}")]
    AgentNameTooLong(usize),
}

/// Why a payload could not be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// The payload is empty.
    #[error("empty payload")]
    Empty,
    /// The version byte is not one this build reads.
    #[error("unknown wire version {0} (this build reads version {VERSION})")]
    UnknownVersion(u8),
    /// The payload ended early.
    #[error("payload truncated")]
    Truncated,
    /// The body is not a valid encoding.
    #[error("malformed payload: {0}")]
    Malformed(String),
    /// Bytes follow a complete frame.
    #[error("{0} trailing bytes after the frame")]
    TrailingBytes(usize),
    /// More objects than the limit.
    #[error("frame has {0} objects, more than the limit {MAX_OBJECTS}")]
    TooManyObjects(usize),
    /// A decoded value is not finite.
    #[error("object {index}: field '{field}' is not finite")]
    NonFinite {
        /// Object index (usize::MAX for the frame).
        index: usize,
        /// The field name.
        field: &'static str,
    },
    /// A decoded size is zero or negative.
    #[error("object {index}: size '{field}' is not positive")]
    NonPositiveSize {
        /// Object index.
        index: usize,
        /// The field name.
        field: &'static str,
    },
    /// A decoded standard deviation is zero (code 0).
    #[error("object {index}: std '{field}' is not positive")]
    NonPositiveStd {
        /// Object index (usize::MAX for the frame default).
        index: usize,
        /// The field name.
        field: &'static str,
    },
    /// A code is outside its range (class, kind, score, agent name).
    #[error("object {index}: field '{field}' is out of range ({value})")]
    OutOfRange {
        /// Object index (usize::MAX for the frame).
        index: usize,
        /// The field name.
        field: &'static str,
        /// The offending code.
        value: i64,
    },
}

const STD_FIELDS: [&str; 7] = [
    "std.x", "std.y", "std.z", "std.l", "std.w", "std.h", "std.yaw",
];
const SIZE_FIELDS: [&str; 3] = ["size.l", "size.w", "size.h"];

#[derive(Serialize, Deserialize, Debug, PartialEq)]
struct WireFrame {
    agent: String,
    kind: u8,
    seq: u32,
    capture_us: u64,
    origin_cm: [i64; 3],
    default_std: [u16; 7],
    objects: Vec<WireObject>,
}

#[derive(Serialize, Deserialize, Debug, PartialEq)]
struct WireObject {
    /// Low 4 bits: class code; bit 4: a std override follows.
    tag: u8,
    pos_cm: [i32; 3],
    size_delta_cm: [i32; 3],
    yaw: [u8; 2],
    score: u8,
    id: u32,
    std: Option<[u16; 7]>,
}

fn quantize_std(s: f64) -> u16 {
    let code = ((s / STD_MIN).ln() * STD_PER_UNIT).round() + 1.0;
    code.clamp(1.0, u16::MAX as f64) as u16
}

fn dequantize_std(code: u16) -> f64 {
    STD_MIN * ((code as f64 - 1.0) / STD_PER_UNIT).exp()
}

fn quantize_stds(u: &Uncertainty) -> [u16; 7] {
    u.as_array().map(quantize_std)
}

fn check_stds(u: &Uncertainty, index: usize) -> Result<(), EncodeError> {
    for (k, s) in u.as_array().into_iter().enumerate() {
        if !s.is_finite() {
            return Err(EncodeError::NonFinite {
                index,
                field: STD_FIELDS[k],
            });
        }
        if !(STD_MIN..=1e6).contains(&s) {
            return Err(EncodeError::OutOfRange {
                index,
                field: STD_FIELDS[k],
                value: s,
            });
        }
    }
    Ok(())
}

/// Encodes a frame into a payload (version byte + postcard body). The frame-level default
/// uncertainty is the most common one among the objects.
pub fn encode(frame: &Frame) -> Result<Vec<u8>, EncodeError> {
    const FRAME: usize = usize::MAX;
    if frame.detections.len() > MAX_OBJECTS {
        return Err(EncodeError::TooManyObjects(frame.detections.len()));
    }
    if frame.agent.len() > MAX_AGENT_NAME {
        return Err(EncodeError::AgentNameTooLong(frame.agent.len()));
    }
    let mut origin_cm = [0i64; 3];
    for k in 0..3 {
        let o = frame.origin[k];
        if !o.is_finite() {
            return Err(EncodeError::NonFinite {
                index: FRAME,
                field: "origin",
            });
        }
        if o.abs() > 1e12 {
            return Err(EncodeError::OutOfRange {
                index: FRAME,
                field: "origin",
                value: o,
            });
        }
        origin_cm[k] = (o * 100.0).round() as i64;
    }
    // The default uncertainty: the most frequent quantized one (first seen wins ties).
    let mut codes = Vec::with_capacity(frame.detections.len());
    for (i, d) in frame.detections.iter().enumerate() {
        check_stds(&d.std, i)?;
        codes.push(quantize_stds(&d.std));
    }
    let default_std = most_common(&codes).unwrap_or([1; 7]);

    let mut objects = Vec::with_capacity(frame.detections.len());
    for (i, d) in frame.detections.iter().enumerate() {
        let mut pos_cm = [0i32; 3];
        for k in 0..3 {
            let c = d.center[k];
            if !c.is_finite() {
                return Err(EncodeError::NonFinite {
                    index: i,
                    field: ["center.x", "center.y", "center.z"][k],
                });
            }
            let rel = (c * 100.0 - origin_cm[k] as f64).round();
            if rel.abs() > MAX_REL_CM {
                return Err(EncodeError::OutOfRange {
                    index: i,
                    field: ["center.x", "center.y", "center.z"][k],
                    value: c,
                });
            }
            pos_cm[k] = rel as i32;
        }
        let typical = d.class.typical_size();
        let mut size_delta_cm = [0i32; 3];
        for k in 0..3 {
            let s = d.size[k];
            if !s.is_finite() {
                return Err(EncodeError::NonFinite {
                    index: i,
                    field: SIZE_FIELDS[k],
                });
            }
            let cm = (s * 100.0).round();
            if !(1.0..=100_000.0).contains(&cm) {
                return Err(EncodeError::OutOfRange {
                    index: i,
                    field: SIZE_FIELDS[k],
                    value: s,
                });
            }
            size_delta_cm[k] = cm as i32 - (typical[k] * 100.0).round() as i32;
        }
        if !d.yaw.is_finite() {
            return Err(EncodeError::NonFinite {
                index: i,
                field: "yaw",
            });
        }
        let turn = wrap_angle(d.yaw).rem_euclid(2.0 * PI) / (2.0 * PI);
        let yaw = ((turn * YAW_STEPS).round() as u32 % 65536) as u16;
        if !d.score.is_finite() {
            return Err(EncodeError::NonFinite {
                index: i,
                field: "score",
            });
        }
        if !(0.0..=1.0).contains(&d.score) {
            return Err(EncodeError::OutOfRange {
                index: i,
                field: "score",
                value: d.score,
            });
        }
        let std = (codes[i] != default_std).then_some(codes[i]);
        objects.push(WireObject {
            tag: d.class.code() | if std.is_some() { 0x10 } else { 0 },
            pos_cm,
            size_delta_cm,
            yaw: yaw.to_le_bytes(),
            score: (d.score * SCORE_STEPS).round() as u8,
            id: d.id,
            std,
        });
    }
    let wf = WireFrame {
        agent: frame.agent.clone(),
        kind: match frame.kind {
            AgentKind::Vehicle => 0,
            AgentKind::Infrastructure => 1,
        },
        seq: frame.seq,
        capture_us: frame.capture_us,
        origin_cm,
        default_std,
        objects,
    };
    let mut out = vec![VERSION];
    out.extend(postcard::to_stdvec(&wf).expect("postcard serialization into a Vec cannot fail"));
    Ok(out)
}

fn most_common(codes: &[[u16; 7]]) -> Option<[u16; 7]> {
    let mut best: Option<([u16; 7], usize)> = None;
    let mut counts: Vec<([u16; 7], usize)> = Vec::new();
    for c in codes {
        match counts.iter_mut().find(|(k, _)| k == c) {
            Some((_, n)) => *n += 1,
            None => counts.push((*c, 1)),
        }
        if counts.len() > 64 {
            break; // heterogeneous stds: any default will do
        }
    }
    for (k, n) in counts {
        if best.is_none_or(|(_, bn)| n > bn) {
            best = Some((k, n));
        }
    }
    best.map(|(k, _)| k)
}

fn decode_stds(codes: [u16; 7], index: usize) -> Result<Uncertainty, DecodeError> {
    if let Some(k) = codes.iter().position(|&c| c == 0) {
        return Err(DecodeError::NonPositiveStd {
            index,
            field: STD_FIELDS[k],
        });
    }
    Ok(Uncertainty::from_array(codes.map(dequantize_std)))
}

/// Decodes and validates a payload produced by [`encode`].
pub fn decode(bytes: &[u8]) -> Result<Frame, DecodeError> {
    const FRAME: usize = usize::MAX;
    let (&version, body) = bytes.split_first().ok_or(DecodeError::Empty)?;
    if version != VERSION {
        return Err(DecodeError::UnknownVersion(version));
    }
    let (wf, rest): (WireFrame, &[u8]) = postcard::take_from_bytes(body).map_err(|e| match e {
        postcard::Error::DeserializeUnexpectedEnd => DecodeError::Truncated,
        other => DecodeError::Malformed(other.to_string()),
    })?;
    if !rest.is_empty() {
        return Err(DecodeError::TrailingBytes(rest.len()));
    }
    if wf.objects.len() > MAX_OBJECTS {
        return Err(DecodeError::TooManyObjects(wf.objects.len()));
    }
    if wf.agent.is_empty() || wf.agent.len() > MAX_AGENT_NAME {
        return Err(DecodeError::OutOfRange {
            index: FRAME,
            field: "agent",
            value: wf.agent.len() as i64,
        });
    }
    let kind = match wf.kind {
        0 => AgentKind::Vehicle,
        1 => AgentKind::Infrastructure,
        k => {
            return Err(DecodeError::OutOfRange {
                index: FRAME,
                field: "kind",
                value: k as i64,
            })
        }
    };
    let default_std = decode_stds(wf.default_std, FRAME)?;
    let origin = wf.origin_cm.map(|c| c as f64 / 100.0);
    if origin.iter().any(|o| !o.is_finite() || o.abs() > 1e12) {
        return Err(DecodeError::NonFinite {
            index: FRAME,
            field: "origin",
        });
    }
    let mut detections = Vec::with_capacity(wf.objects.len());
    for (i, o) in wf.objects.into_iter().enumerate() {
        let class = Class::from_code(o.tag & 0x0f).ok_or(DecodeError::OutOfRange {
            index: i,
            field: "class",
            value: (o.tag & 0x0f) as i64,
        })?;
        let has_std = o.tag & 0x10 != 0;
        if o.tag & !0x1f != 0 || has_std != o.std.is_some() {
            return Err(DecodeError::OutOfRange {
                index: i,
                field: "tag",
                value: o.tag as i64,
            });
        }
        let typical = class.typical_size();
        let mut size = [0.0; 3];
        for k in 0..3 {
            let cm = (typical[k] * 100.0).round() as i64 + o.size_delta_cm[k] as i64;
            if cm <= 0 {
                return Err(DecodeError::NonPositiveSize {
                    index: i,
                    field: SIZE_FIELDS[k],
                });
            }
            size[k] = cm as f64 / 100.0;
        }
        if o.score as f64 > SCORE_STEPS {
            return Err(DecodeError::OutOfRange {
                index: i,
                field: "score",
                value: o.score as i64,
            });
        }
        let std = match o.std {
            Some(codes) => decode_stds(codes, i)?,
            None => default_std,
        };
        let center: [f64; 3] =
            std::array::from_fn(|k| (wf.origin_cm[k] + o.pos_cm[k] as i64) as f64 / 100.0);
        let turn = u16::from_le_bytes(o.yaw) as f64 / YAW_STEPS;
        detections.push(Detection {
            class,
            center,
            size,
            yaw: wrap_angle(turn * 2.0 * PI),
            score: o.score as f64 / SCORE_STEPS,
            std,
            pos_cov: None,
            id: o.id,
        });
    }
    Ok(Frame {
        agent: wf.agent,
        kind,
        seq: wf.seq,
        capture_us: wf.capture_us,
        origin,
        detections,
    })
}

/// Encodes a frame as postcard of plain `f32` fields (no quantization), for size comparisons.
pub fn encode_plain_f32(frame: &Frame) -> Vec<u8> {
    #[derive(Serialize)]
    struct PlainObject {
        class: u8,
        center: [f32; 3],
        size: [f32; 3],
        yaw: f32,
        score: f32,
        std: [f32; 7],
        id: u32,
    }
    #[derive(Serialize)]
    struct PlainFrame<'a> {
        agent: &'a str,
        kind: u8,
        seq: u32,
        capture_us: u64,
        origin: [f32; 3],
        objects: Vec<PlainObject>,
    }
    let pf = PlainFrame {
        agent: &frame.agent,
        kind: frame.kind as u8,
        seq: frame.seq,
        capture_us: frame.capture_us,
        origin: frame.origin.map(|v| v as f32),
        objects: frame
            .detections
            .iter()
            .map(|d| PlainObject {
                class: d.class.code(),
                center: d.center.map(|v| v as f32),
                size: d.size.map(|v| v as f32),
                yaw: d.yaw as f32,
                score: d.score as f32,
                std: d.std.as_array().map(|v| v as f32),
                id: d.id,
            })
            .collect(),
    };
    postcard::to_stdvec(&pf).expect("postcard serialization into a Vec cannot fail")
}

/// Encodes a frame as JSON (serde's natural form), for size comparisons.
pub fn encode_json(frame: &Frame) -> Vec<u8> {
    serde_json::to_vec(frame).expect("a frame always serializes to JSON")
}

#[cfg(test)]
mod tests;
