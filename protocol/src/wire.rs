//! The compact wire encoding of a [`Frame`]; `docs/wire-format.md` is its byte-level
//! specification.
//!
//! A payload is one version byte followed by postcard-encoded fields: a header, the object count,
//! then the objects. Values are quantized: positions in centimetres relative to the frame origin
//! (zig-zag varints, so nearby objects cost two bytes an axis), sizes in centimetres as the
//! difference from the class's typical size, yaw in 1/65536 turn (two fixed bytes), score in
//! 1/250 steps, velocities in 0.1 m/s (zig-zag varints, when the object has one), and standard
//! deviations on a logarithmic scale (0.2% steps). A frame carries a default uncertainty; an
//! object carries its own only when it differs. Bits of an object's tag say which optional
//! fields follow. A fused frame also says where it came from ([`Provenance`]): after the header,
//! the window's agents and whether it was complete; after each object, a bitmask of the agents
//! that contributed to it.
//!
//! One validity domain ([`crate::limits`]): [`decode`] accepts exactly the frames [`encode`] can
//! write, so a decoded frame always encodes again, and [`fit`] brings any computed frame (fused
//! output) into the domain. Decoding checks the payload size and the object count before it
//! reads a single object, validates every field, and returns a [`DecodeError`]; it never panics.

use crate::keys::{self, NameError};
use crate::limits::{
    coord_in_range, size_in_range, std_in_range, std_of_code, vel_in_range, MAX_AGENT_NAME,
    MAX_OBJECTS, MAX_PAYLOAD, MAX_WINDOW_AGENTS, STD_CODE_MAX, STD_MIN, STD_PER_UNIT, VEL_STEP,
};
use crate::{
    wrap_angle, AgentKind, AgentSet, Class, Detection, Frame, Provenance, ProvenanceError,
    Uncertainty, Velocity, NO_ID,
};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The wire format version this crate writes and reads.
pub const VERSION: u8 = 3;

const SCORE_STEPS: f64 = 250.0;
/// Kind bit 0: infrastructure (else vehicle).
const KIND_INFRA: u8 = 0x01;
/// Kind bit 1: a provenance section follows the header (a fused frame).
const KIND_PROVENANCE: u8 = 0x02;
const YAW_STEPS: f64 = 65536.0;
/// Tag bits: the low four hold the class code.
const TAG_CLASS: u8 = 0x0f;
/// Tag bit: the object carries its own std codes.
const TAG_STD: u8 = 0x10;
/// Tag bit: the object carries a velocity.
const TAG_VEL: u8 = 0x20;
/// Tag bit: an object id follows (4 bytes, little-endian); without it the object has none.
const TAG_ID: u8 = 0x40;
/// The tag bits this version defines.
const TAG_KNOWN: u8 = TAG_CLASS | TAG_STD | TAG_VEL | TAG_ID;
/// Index meaning "the frame itself" in errors.
const FRAME: usize = usize::MAX;

/// Where an error lies, as its message says it: an object by index, or the frame itself.
struct At(usize);

impl std::fmt::Display for At {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            FRAME => f.write_str("frame"),
            i => write!(f, "object {i}"),
        }
    }
}

/// Why a frame could not be encoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EncodeError {
    /// A value is NaN or infinite.
    #[error("{at}: field '{field}' is not finite", at = At(*.index))]
    NonFinite {
        /// Object index (or usize::MAX for the frame itself).
        index: usize,
        /// The field name.
        field: &'static str,
    },
    /// A value is outside what the format represents.
    #[error("{at}: field '{field}' is out of range ({value})", at = At(*.index))]
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
    /// The agent name is empty, too long or not a single key chunk.
    #[error("agent name: {0}")]
    BadAgentName(NameError),
    /// The provenance does not fit the frame (agents, source sets).
    #[error("provenance: {0}")]
    BadProvenance(ProvenanceError),
}

/// Why a payload could not be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// The payload is empty.
    #[error("empty payload")]
    Empty,
    /// The payload is larger than any valid frame.
    #[error("payload of {0} bytes, more than the limit {MAX_PAYLOAD}")]
    TooLarge(usize),
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
    TooManyObjects(u64),
    /// The agent name is empty, too long or not a single key chunk.
    #[error("agent name: {0}")]
    BadAgentName(NameError),
    /// The provenance section is invalid (agents, completeness, source masks).
    #[error("provenance: {0}")]
    BadProvenance(ProvenanceError),
    /// A decoded size is outside the domain.
    #[error("object {index}: size '{field}' is out of range ({cm} cm)")]
    SizeOutOfRange {
        /// Object index.
        index: usize,
        /// The field name.
        field: &'static str,
        /// The decoded size in centimetres.
        cm: i64,
    },
    /// A std code is zero or above the largest.
    #[error("{at}: std '{field}' has invalid code {code}", at = At(*.index))]
    BadStdCode {
        /// Object index (usize::MAX for the frame default).
        index: usize,
        /// The field name.
        field: &'static str,
        /// The code.
        code: u16,
    },
    /// A code is outside its range (class, kind, tag, score, coordinates).
    #[error("{at}: field '{field}' is out of range ({value})", at = At(*.index))]
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
const VEL_FIELDS: [&str; 2] = ["velocity.x", "velocity.y"];
const VEL_STD_FIELDS: [&str; 2] = ["std.vx", "std.vy"];
const SIZE_FIELDS: [&str; 3] = ["size.l", "size.w", "size.h"];
const CENTER_FIELDS: [&str; 3] = ["center.x", "center.y", "center.z"];

/// The fields of a frame before its objects, in wire order.
#[derive(Serialize, Deserialize, Debug, PartialEq, Clone)]
struct Header {
    agent: String,
    kind: u8,
    seq: u32,
    capture_us: u64,
    origin_cm: [i64; 3],
    default_std: [u16; 7],
    default_vel_std: [u16; 2],
}

/// One object as the wire holds it.
#[derive(Debug, PartialEq, Clone)]
struct Object {
    tag: u8,
    pos_cm: [i32; 3],
    size_delta_cm: [i32; 3],
    yaw: [u8; 2],
    score: u8,
    /// Little-endian id; present exactly when `tag & TAG_ID`.
    id: Option<[u8; 4]>,
    /// Present exactly when `tag & TAG_STD`.
    std: Option<[u16; 7]>,
    /// Velocity in [`VEL_STEP`] units; present exactly when `tag & TAG_VEL`.
    vel: Option<[i32; 2]>,
    /// Velocity std codes; present exactly when both `TAG_STD` and `TAG_VEL`.
    vel_std: Option<[u16; 2]>,
}

/// Appends postcard encodings of values to a buffer.
struct Writer(Vec<u8>);

impl Writer {
    fn put<T: Serialize + ?Sized>(&mut self, v: &T) {
        self.0 = postcard::to_extend(v, std::mem::take(&mut self.0))
            .expect("postcard serialization into a Vec cannot fail");
    }
}

/// Reads postcard encodings of values off a byte slice.
struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    /// Reads one value, which must be in its shortest encoding (no padded varint): what the
    /// decoder accepts, the encoder writes back byte for byte.
    fn take<T: DeserializeOwned + Serialize>(&mut self) -> Result<T, DecodeError> {
        let (v, rest) = postcard::take_from_bytes(self.0).map_err(|e| match e {
            postcard::Error::DeserializeUnexpectedEnd => DecodeError::Truncated,
            other => DecodeError::Malformed(other.to_string()),
        })?;
        let used = self.0.len() - rest.len();
        // Written back, the value takes as many bytes as it was read from (counted, not written).
        let size = postcard::serialize_with_flavor(&v, postcard::ser_flavors::Size::default());
        if size.ok() != Some(used) {
            return Err(DecodeError::Malformed(
                "a number is not in its shortest encoding (padded varint)".into(),
            ));
        }
        self.0 = rest;
        Ok(v)
    }

    fn take_bytes(&mut self, n: usize) -> Result<&[u8], DecodeError> {
        if self.0.len() < n {
            return Err(DecodeError::Truncated);
        }
        let (b, rest) = self.0.split_at(n);
        self.0 = rest;
        Ok(b)
    }
}

impl Object {
    fn write(&self, w: &mut Writer) {
        // A tuple encodes as its fields one after another: one call for the fixed part.
        w.put(&(
            self.tag,
            self.pos_cm,
            self.size_delta_cm,
            self.yaw,
            self.score,
        ));
        if let Some(id) = &self.id {
            w.put(id);
        }
        if let Some(v) = &self.vel {
            w.put(v);
        }
        if let Some(s) = &self.std {
            w.put(s);
        }
        if let Some(s) = &self.vel_std {
            w.put(s);
        }
    }

    fn read(r: &mut Reader) -> Result<Object, DecodeError> {
        let tag: u8 = r.take()?;
        let (has_std, has_vel) = (tag & TAG_STD != 0, tag & TAG_VEL != 0);
        Ok(Object {
            tag,
            pos_cm: r.take()?,
            size_delta_cm: r.take()?,
            yaw: r.take()?,
            score: r.take()?,
            id: if tag & TAG_ID != 0 {
                Some(r.take()?)
            } else {
                None
            },
            vel: if has_vel { Some(r.take()?) } else { None },
            std: if has_std { Some(r.take()?) } else { None },
            vel_std: if has_std && has_vel {
                Some(r.take()?)
            } else {
                None
            },
        })
    }
}

/// Writes a header, the provenance section when there is one, and the objects (each followed by
/// its source mask in fused frames) as a payload.
fn assemble(header: &Header, provenance: Option<&Provenance>, objects: &[Object]) -> Vec<u8> {
    let mut w = Writer(vec![VERSION]);
    w.put(header);
    if let Some(p) = provenance {
        w.put(&u8::from(p.complete));
        w.put(&p.agents);
    }
    w.put(&(objects.len() as u64));
    for (i, o) in objects.iter().enumerate() {
        o.write(&mut w);
        if let Some(p) = provenance {
            w.0.extend(p.sources[i].to_bytes(p.agents.len()));
        }
    }
    w.0
}

fn quantize_std(s: f64) -> u16 {
    let code = ((s / STD_MIN).ln() * STD_PER_UNIT).round() + 1.0;
    code.clamp(1.0, STD_CODE_MAX as f64) as u16
}

fn check_stds(u: &Uncertainty, index: usize) -> Result<[u16; 7], EncodeError> {
    let a = u.as_array();
    for (k, s) in a.into_iter().enumerate() {
        if !s.is_finite() {
            return Err(EncodeError::NonFinite {
                index,
                field: STD_FIELDS[k],
            });
        }
        if !std_in_range(s) {
            return Err(EncodeError::OutOfRange {
                index,
                field: STD_FIELDS[k],
                value: s,
            });
        }
    }
    Ok(a.map(quantize_std))
}

/// Checks an agent name the way both directions do: non-empty, at most [`MAX_AGENT_NAME`]
/// bytes, one key chunk without wildcards.
pub fn check_agent_name(name: &str) -> Result<(), NameError> {
    if name.len() > MAX_AGENT_NAME {
        return Err(NameError::TooLong {
            len: name.len(),
            max: MAX_AGENT_NAME,
        });
    }
    keys::validate_chunk("agent name", name)
}

/// Encodes a frame into a payload. The frame-level default uncertainty is the most common one
/// among the objects. Fails, naming the object and field, on any value outside the domain.
pub fn encode(frame: &Frame) -> Result<Vec<u8>, EncodeError> {
    encode_with(frame, None)
}

/// Encodes a frame with its provenance (a fused frame) or without (an agent's frame).
pub fn encode_with(frame: &Frame, provenance: Option<&Provenance>) -> Result<Vec<u8>, EncodeError> {
    if let Some(p) = provenance {
        p.check(frame.detections.len())
            .map_err(EncodeError::BadProvenance)?;
    }
    if frame.detections.len() > MAX_OBJECTS {
        return Err(EncodeError::TooManyObjects(frame.detections.len()));
    }
    check_agent_name(&frame.agent).map_err(EncodeError::BadAgentName)?;
    let origin_cm = origin_code(frame.origin)?;
    let mut codes = Vec::with_capacity(frame.detections.len());
    let mut vel_codes = Vec::new();
    // A std equal to the last box's has its codes (boxes often share their stds).
    let mut last: Option<(&Uncertainty, [u16; 7])> = None;
    for (i, d) in frame.detections.iter().enumerate() {
        let c = match last {
            Some((u, c)) if *u == d.std => c,
            _ => check_stds(&d.std, i)?,
        };
        last = Some((&d.std, c));
        let v = match &d.velocity {
            Some(v) => Some(check_velocity(v, i)?),
            None => None,
        };
        codes.push((c, v));
        vel_codes.extend(v.map(|(_, s)| s));
    }
    let default_std = most_common(&codes.iter().map(|c| c.0).collect::<Vec<_>>()).unwrap_or([1; 7]);
    let default_vel_std = most_common(&vel_codes).unwrap_or([1; 2]);

    let objects = frame
        .detections
        .iter()
        .zip(&codes)
        .enumerate()
        .map(|(i, (d, c))| object(i, d, origin_cm, *c, (default_std, default_vel_std)))
        .collect::<Result<Vec<_>, _>>()?;
    let header = Header {
        agent: frame.agent.clone(),
        kind: match frame.kind {
            AgentKind::Vehicle => 0,
            AgentKind::Infrastructure => KIND_INFRA,
        } | if provenance.is_some() {
            KIND_PROVENANCE
        } else {
            0
        },
        seq: frame.seq,
        capture_us: frame.capture_us,
        origin_cm,
        default_std,
        default_vel_std,
    };
    Ok(assemble(&header, provenance, &objects))
}

/// An object's std codes, and its velocity in steps with the velocity's std codes.
type ObjectCodes = ([u16; 7], Option<([i32; 2], [u16; 2])>);

/// The frame's origin in centimetres, checked.
fn origin_code(origin: [f64; 3]) -> Result<[i64; 3], EncodeError> {
    let mut origin_cm = [0i64; 3];
    for k in 0..3 {
        let o = origin[k];
        if !o.is_finite() {
            return Err(EncodeError::NonFinite {
                index: FRAME,
                field: "origin",
            });
        }
        if !coord_in_range(o) {
            return Err(EncodeError::OutOfRange {
                index: FRAME,
                field: "origin",
                value: o,
            });
        }
        origin_cm[k] = (o * 100.0).round() as i64;
    }
    Ok(origin_cm)
}

/// One object of the frame, checked and quantized: `codes` are its std and velocity codes,
/// `defaults` the frame's default std and velocity std codes (an object with others carries its
/// own).
fn object(
    i: usize,
    d: &Detection,
    origin_cm: [i64; 3],
    codes: ObjectCodes,
    (default_std, default_vel_std): ([u16; 7], [u16; 2]),
) -> Result<Object, EncodeError> {
    let mut pos_cm = [0i32; 3];
    for k in 0..3 {
        let c = d.center[k];
        if !c.is_finite() {
            return Err(EncodeError::NonFinite {
                index: i,
                field: CENTER_FIELDS[k],
            });
        }
        let rel = (c * 100.0).round() - origin_cm[k] as f64;
        if !coord_in_range(c) || !(i32::MIN as f64..=i32::MAX as f64).contains(&rel) {
            return Err(EncodeError::OutOfRange {
                index: i,
                field: CENTER_FIELDS[k],
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
        if !size_in_range(s) {
            return Err(EncodeError::OutOfRange {
                index: i,
                field: SIZE_FIELDS[k],
                value: s,
            });
        }
        size_delta_cm[k] = (s * 100.0).round() as i32 - (typical[k] * 100.0).round() as i32;
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
    let (std_codes, vel) = codes;
    let own = std_codes != default_std || vel.is_some_and(|(_, s)| s != default_vel_std);
    let mut tag = d.class.code();
    if own {
        tag |= TAG_STD;
    }
    if vel.is_some() {
        tag |= TAG_VEL;
    }
    if d.id != NO_ID {
        tag |= TAG_ID;
    }
    Ok(Object {
        tag,
        pos_cm,
        size_delta_cm,
        yaw: yaw.to_le_bytes(),
        score: (d.score * SCORE_STEPS).round() as u8,
        id: (d.id != NO_ID).then(|| d.id.to_le_bytes()),
        vel: vel.map(|(v, _)| v),
        std: own.then_some(std_codes),
        vel_std: if own { vel.map(|(_, s)| s) } else { None },
    })
}

/// Checks a velocity and quantizes it: (velocity in steps, std codes).
fn check_velocity(v: &Velocity, index: usize) -> Result<([i32; 2], [u16; 2]), EncodeError> {
    let mut q = [0i32; 2];
    let mut c = [0u16; 2];
    for k in 0..2 {
        if !v.v[k].is_finite() {
            return Err(EncodeError::NonFinite {
                index,
                field: VEL_FIELDS[k],
            });
        }
        if !vel_in_range(v.v[k]) {
            return Err(EncodeError::OutOfRange {
                index,
                field: VEL_FIELDS[k],
                value: v.v[k],
            });
        }
        q[k] = (v.v[k] / VEL_STEP).round() as i32;
        let s = v.std[k];
        if !s.is_finite() {
            return Err(EncodeError::NonFinite {
                index,
                field: VEL_STD_FIELDS[k],
            });
        }
        if !std_in_range(s) {
            return Err(EncodeError::OutOfRange {
                index,
                field: VEL_STD_FIELDS[k],
                value: s,
            });
        }
        c[k] = quantize_std(s);
    }
    Ok((q, c))
}

fn most_common<const N: usize>(codes: &[[u16; N]]) -> Option<[u16; N]> {
    let mut best: Option<([u16; N], usize)> = None;
    let mut counts: Vec<([u16; N], usize)> = Vec::new();
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
    if let Some(k) = codes.iter().position(|&c| c == 0 || c > STD_CODE_MAX) {
        return Err(DecodeError::BadStdCode {
            index,
            field: STD_FIELDS[k],
            code: codes[k],
        });
    }
    Ok(Uncertainty::from_array(codes.map(std_of_code)))
}

fn decode_vel_stds(codes: [u16; 2], index: usize) -> Result<[f64; 2], DecodeError> {
    if let Some(k) = codes.iter().position(|&c| c == 0 || c > STD_CODE_MAX) {
        return Err(DecodeError::BadStdCode {
            index,
            field: VEL_STD_FIELDS[k],
            code: codes[k],
        });
    }
    Ok(codes.map(std_of_code))
}

fn cm_in_range(cm: i64, index: usize, field: &'static str) -> Result<(), DecodeError> {
    if coord_in_range(cm as f64 / 100.0) {
        Ok(())
    } else {
        Err(DecodeError::OutOfRange {
            index,
            field,
            value: cm,
        })
    }
}

/// A provenance section before its per-object masks are read.
struct ProvenanceHead {
    agents: Vec<String>,
    complete: bool,
}

/// Reads and checks a provenance section: the completeness byte and the agent list.
fn read_provenance(r: &mut Reader) -> Result<ProvenanceHead, DecodeError> {
    let bad = DecodeError::BadProvenance;
    let complete = match r.take::<u8>()? {
        0 => false,
        1 => true,
        c => return Err(bad(ProvenanceError::BadComplete(c))),
    };
    let n: u64 = r.take()?;
    if n > MAX_WINDOW_AGENTS as u64 {
        return Err(bad(ProvenanceError::TooManyAgents(
            usize::try_from(n).unwrap_or(usize::MAX),
        )));
    }
    let mut agents = Vec::with_capacity(n as usize);
    for _ in 0..n {
        agents.push(r.take::<String>()?);
    }
    let head = Provenance {
        agents,
        complete,
        sources: Vec::new(),
    };
    head.check(0).map_err(bad)?;
    Ok(ProvenanceHead {
        agents: head.agents,
        complete,
    })
}

/// Everything before the first object, checked.
struct Head<'a> {
    header: Header,
    provenance: Option<ProvenanceHead>,
    count: usize,
    /// The bytes from the first object on.
    rest: Reader<'a>,
}

/// Reads and checks the header, the provenance section if any and the object count, without
/// reading any object.
fn read_header(bytes: &[u8]) -> Result<Head<'_>, DecodeError> {
    if bytes.len() > MAX_PAYLOAD {
        return Err(DecodeError::TooLarge(bytes.len()));
    }
    let (&version, body) = bytes.split_first().ok_or(DecodeError::Empty)?;
    if version != VERSION {
        return Err(DecodeError::UnknownVersion(version));
    }
    let mut r = Reader(body);
    let header: Header = r.take()?;
    check_agent_name(&header.agent).map_err(DecodeError::BadAgentName)?;
    if header.kind & !(KIND_INFRA | KIND_PROVENANCE) != 0 {
        return Err(DecodeError::OutOfRange {
            index: FRAME,
            field: "kind",
            value: header.kind as i64,
        });
    }
    for o in header.origin_cm {
        cm_in_range(o, FRAME, "origin")?;
    }
    decode_stds(header.default_std, FRAME)?;
    decode_vel_stds(header.default_vel_std, FRAME)?;
    let provenance = if header.kind & KIND_PROVENANCE != 0 {
        Some(read_provenance(&mut r)?)
    } else {
        None
    };
    let count: u64 = r.take()?;
    if count > MAX_OBJECTS as u64 {
        return Err(DecodeError::TooManyObjects(count));
    }
    Ok(Head {
        header,
        provenance,
        count: count as usize,
        rest: r,
    })
}

/// Reads a payload's agent name and object count without decoding the objects (cheap checks
/// before the full [`decode`]).
pub fn peek(bytes: &[u8]) -> Result<(String, usize), DecodeError> {
    let h = read_header(bytes)?;
    Ok((h.header.agent, h.count))
}

/// Decodes and validates a payload; a fused frame's provenance is checked and left out.
pub fn decode(bytes: &[u8]) -> Result<Frame, DecodeError> {
    decode_with(bytes).map(|(f, _)| f)
}

/// Decodes and validates a payload, with its provenance when it is a fused frame.
pub fn decode_with(bytes: &[u8]) -> Result<(Frame, Option<Provenance>), DecodeError> {
    let Head {
        header,
        provenance: head,
        count,
        rest: mut r,
    } = read_header(bytes)?;
    let mask_len = head.as_ref().map(|h| h.agents.len().div_ceil(8));
    let mut sources = Vec::new();
    let default_std = decode_stds(header.default_std, FRAME)?;
    let default_vel_std = decode_vel_stds(header.default_vel_std, FRAME)?;
    let mut detections = Vec::with_capacity(count);
    for i in 0..count {
        let o = Object::read(&mut r)?;
        detections.push(decode_object(
            i,
            &o,
            header.origin_cm,
            default_std,
            default_vel_std,
        )?);
        if let (Some(len), Some(h)) = (mask_len, &head) {
            let set = AgentSet::from_bytes(r.take_bytes(len)?);
            if set.is_empty() || set.bound() > h.agents.len() {
                return Err(DecodeError::BadProvenance(ProvenanceError::BadMask {
                    object: i,
                    listed: h.agents.len(),
                }));
            }
            sources.push(set);
        }
    }
    if !r.0.is_empty() {
        return Err(DecodeError::TrailingBytes(r.0.len()));
    }
    let frame = Frame {
        agent: header.agent,
        kind: if header.kind & KIND_INFRA == 0 {
            AgentKind::Vehicle
        } else {
            AgentKind::Infrastructure
        },
        seq: header.seq,
        capture_us: header.capture_us,
        origin: header.origin_cm.map(|c| c as f64 / 100.0),
        detections,
    };
    let provenance = head.map(|h| Provenance {
        agents: h.agents,
        complete: h.complete,
        sources,
    });
    Ok((frame, provenance))
}

/// Object `i` of a frame whose origin is `origin_cm`, checked and brought back to metres and
/// radians; objects without stds of their own take the frame's defaults.
fn decode_object(
    i: usize,
    o: &Object,
    origin_cm: [i64; 3],
    default_std: Uncertainty,
    default_vel_std: [f64; 2],
) -> Result<Detection, DecodeError> {
    let class = Class::from_code(o.tag & TAG_CLASS).ok_or(DecodeError::OutOfRange {
        index: i,
        field: "class",
        value: (o.tag & TAG_CLASS) as i64,
    })?;
    if o.id == Some(NO_ID.to_le_bytes()) {
        // "No id" is said by leaving the id out.
        return Err(DecodeError::OutOfRange {
            index: i,
            field: "id",
            value: NO_ID as i64,
        });
    }
    if o.tag & !TAG_KNOWN != 0 {
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
        if !size_in_range(cm as f64 / 100.0) {
            return Err(DecodeError::SizeOutOfRange {
                index: i,
                field: SIZE_FIELDS[k],
                cm,
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
    let mut center = [0.0; 3];
    for k in 0..3 {
        let cm = origin_cm[k] + o.pos_cm[k] as i64;
        cm_in_range(cm, i, CENTER_FIELDS[k])?;
        center[k] = cm as f64 / 100.0;
    }
    let velocity = match o.vel {
        None => None,
        Some(q) => {
            let v = q.map(|x| x as f64 * VEL_STEP);
            if let Some(k) = (0..2).find(|&k| !vel_in_range(v[k])) {
                return Err(DecodeError::OutOfRange {
                    index: i,
                    field: VEL_FIELDS[k],
                    value: q[k] as i64,
                });
            }
            let std = match o.vel_std {
                Some(c) => decode_vel_stds(c, i)?,
                None => default_vel_std,
            };
            Some(Velocity { v, std })
        }
    };
    let turn = u16::from_le_bytes(o.yaw) as f64 / YAW_STEPS;
    Ok(Detection {
        class,
        center,
        size,
        yaw: wrap_angle(turn * 2.0 * PI),
        score: o.score as f64 / SCORE_STEPS,
        std,
        pos_cov: None,
        velocity,
        id: o.id.map_or(NO_ID, u32::from_le_bytes),
    })
}

/// What [`fit`] changed to bring a frame into the wire's domain.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Fit {
    /// Standard deviations raised to the floor or lowered to the ceiling of the std code.
    pub stds_clamped: usize,
    /// Sizes clamped into the size range.
    pub sizes_clamped: usize,
    /// Scores clamped into [0, 1].
    pub scores_clamped: usize,
    /// Velocity components clamped into the velocity range.
    pub velocities_clamped: usize,
    /// Objects dropped because a value was not finite or lay too far from the others.
    pub objects_invalid: usize,
    /// Objects dropped to stay within [`MAX_OBJECTS`] (the lowest scores, shared fairly between
    /// the agents of a fused frame).
    pub objects_capped: usize,
}

impl Fit {
    /// True when nothing changed.
    pub fn is_clean(&self) -> bool {
        *self == Fit::default()
    }
}

/// Brings a computed frame (such as fused output) into the wire's domain so that [`encode`]
/// succeeds: clamps stds, sizes and scores, sets the origin to the component-wise median of the
/// centres, drops objects with non-finite values or out of reach of the origin, and keeps the
/// [`MAX_OBJECTS`] highest-scoring objects ([`fit_with`] shares them fairly between the
/// agents of a fused frame). The agent name must already be valid.
pub fn fit(frame: &mut Frame) -> Fit {
    fit_with(frame, None)
}

/// Keeps the objects (and their source sets, when given) whose `keep` entry is true.
fn retain_objects(frame: &mut Frame, sources: Option<&mut Vec<AgentSet>>, keep: &[bool]) {
    let mut i = 0;
    frame.detections.retain(|_| {
        i += 1;
        keep[i - 1]
    });
    if let Some(s) = sources {
        let mut i = 0;
        s.retain(|_| {
            i += 1;
            keep.get(i - 1).copied().unwrap_or(false)
        });
    }
}

/// Which of `dets` to keep so that at most `cap` remain, shared fairly between the agents that
/// contributed them: each object ranks by its best place in the score order of one of its
/// source agents' objects, and the lowest ranks stay (then the highest scores). So every agent
/// keeps its best `cap / agents` objects at least, however many another agent sends. Without
/// source sets (one per object), the highest-scoring objects stay.
fn fair_share(dets: &[Detection], sources: Option<&[AgentSet]>, cap: usize) -> Vec<bool> {
    let mut by_score: Vec<usize> = (0..dets.len()).collect();
    by_score.sort_by(|&a, &b| dets[b].score.total_cmp(&dets[a].score).then(a.cmp(&b)));
    let mut rank = vec![0usize; dets.len()];
    if let Some(sources) = sources.filter(|s| s.len() == dets.len()) {
        let mut seen: Vec<usize> = Vec::new();
        for &i in &by_score {
            rank[i] = usize::MAX;
            for k in sources[i].iter() {
                if seen.len() <= k {
                    seen.resize(k + 1, 0);
                }
                rank[i] = rank[i].min(seen[k]);
                seen[k] += 1;
            }
        }
    }
    // A stable sort keeps the score order within a rank.
    by_score.sort_by_key(|&i| rank[i]);
    let mut keep = vec![false; dets.len()];
    for &i in by_score.iter().take(cap) {
        keep[i] = true;
    }
    keep
}

/// [`fit`] for a fused frame: a dropped object's source set is dropped with it, so the
/// provenance still has one set per object.
pub fn fit_with(frame: &mut Frame, mut provenance: Option<&mut Provenance>) -> Fit {
    let mut fit = Fit::default();
    let before = frame.detections.len();
    let keep: Vec<bool> = frame
        .detections
        .iter()
        .map(|d| {
            d.center.iter().all(|c| coord_in_range(*c))
                && d.size.iter().all(|s| s.is_finite())
                && d.yaw.is_finite()
                && d.score.is_finite()
                && d.std.as_array().iter().all(|s| s.is_finite())
                && d.velocity
                    .is_none_or(|v| v.v.iter().chain(&v.std).all(|x| x.is_finite()))
        })
        .collect();
    retain_objects(frame, provenance.as_mut().map(|p| &mut p.sources), &keep);
    fit.objects_invalid = before - frame.detections.len();
    for d in &mut frame.detections {
        let mut a = d.std.as_array();
        for s in &mut a {
            if !std_in_range(*s) {
                *s = crate::limits::clamp_std(*s);
                fit.stds_clamped += 1;
            }
        }
        d.std = Uncertainty::from_array(a);
        for s in &mut d.size {
            if !size_in_range(*s) {
                *s = s.clamp(crate::limits::SIZE_MIN, crate::limits::SIZE_MAX);
                fit.sizes_clamped += 1;
            }
        }
        if !(0.0..=1.0).contains(&d.score) {
            d.score = d.score.clamp(0.0, 1.0);
            fit.scores_clamped += 1;
        }
        if let Some(v) = &mut d.velocity {
            for k in 0..2 {
                if !vel_in_range(v.v[k]) {
                    v.v[k] = v.v[k].clamp(-crate::limits::VEL_MAX, crate::limits::VEL_MAX);
                    fit.velocities_clamped += 1;
                }
                if !std_in_range(v.std[k]) {
                    v.std[k] = crate::limits::clamp_std(v.std[k]);
                    fit.stds_clamped += 1;
                }
            }
        }
    }
    if frame.detections.len() > MAX_OBJECTS {
        let sources = provenance.as_ref().map(|p| p.sources.as_slice());
        let keep = fair_share(&frame.detections, sources, MAX_OBJECTS);
        retain_objects(frame, provenance.as_mut().map(|p| &mut p.sources), &keep);
        fit.objects_capped = keep.iter().filter(|k| !**k).count();
    }
    // Origin: the median centre, so that one far-away object cannot push the others out of reach.
    if !frame.detections.is_empty() {
        for k in 0..3 {
            let mut v: Vec<f64> = frame.detections.iter().map(|d| d.center[k]).collect();
            v.sort_by(f64::total_cmp);
            frame.origin[k] = (v[v.len() / 2] * 100.0).round() / 100.0;
        }
    }
    if !frame.origin.iter().all(|o| coord_in_range(*o)) {
        frame.origin = [0.0; 3];
    }
    let before = frame.detections.len();
    let origin = frame.origin;
    let keep: Vec<bool> = frame
        .detections
        .iter()
        .map(|d| {
            (0..3).all(|k| {
                let rel = (d.center[k] * 100.0).round() - (origin[k] * 100.0).round();
                (i32::MIN as f64..=i32::MAX as f64).contains(&rel)
            })
        })
        .collect();
    retain_objects(frame, provenance.as_mut().map(|p| &mut p.sources), &keep);
    fit.objects_invalid += before - frame.detections.len();
    fit
}

#[cfg(test)]
mod tests;
