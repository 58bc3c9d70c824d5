//! Frames to and from wire bytes (`docs/wire-format.md`), as the JSON of a frame dict: the
//! fields `examples/python/v2x_frame.py` decodes, so the two decoders can be compared.

use crate::{DecodeError, EncodeError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use serde_json::{json, Map, Value};
use v2x_protocol::nuscenes_json::TokenTable;
use v2x_protocol::{wire, AgentKind, AgentSet, Class, Detection, Frame, Provenance, Uncertainty};
use v2x_protocol::{UnknownName, Velocity, NO_ID};

/// Decodes a payload into the JSON of its frame dict.
#[pyfunction]
pub fn decode_json(py: Python<'_>, payload: &[u8]) -> PyResult<String> {
    let (frame, provenance) = py
        .detach(|| wire::decode_with(payload))
        .map_err(|e| DecodeError::new_err(e.to_string()))?;
    Ok(frame_json(&frame, provenance.as_ref()).to_string())
}

/// Encodes the JSON of a frame dict into a payload.
#[pyfunction]
pub fn encode_json<'py>(py: Python<'py>, frame: &str) -> PyResult<Bound<'py, PyBytes>> {
    let value: Value = serde_json::from_str(frame)
        .map_err(|e| PyValueError::new_err(format!("frame: not JSON: {e}")))?;
    let (frame, provenance) = frame_of(&value).map_err(|e| EncodeError::new_err(e.to_string()))?;
    let bytes = wire::encode_with(&frame, provenance.as_ref())
        .map_err(|e| EncodeError::new_err(e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// Encodes an agent's boxes, a list of results-file dicts, into the payload of one frame (its
/// origin the boxes' centroid).
#[pyfunction]
#[pyo3(signature = (agent, kind, seq, capture_us, boxes, default_std=None))]
pub fn encode_boxes<'py>(
    py: Python<'py>,
    agent: &str,
    kind: &str,
    seq: u32,
    capture_us: u64,
    boxes: &Bound<'py, PyAny>,
    default_std: Option<&str>,
) -> PyResult<Bound<'py, PyBytes>> {
    let kind: AgentKind = kind
        .parse()
        .map_err(|e: v2x_protocol::UnknownName| PyValueError::new_err(e.to_string()))?;
    let missing = crate::options::missing_std(default_std)?;
    let detections = crate::boxdict::read_boxes("boxes", boxes, &mut TokenTable::new(), missing)?;
    let frame = Frame {
        agent: agent.to_owned(),
        kind,
        seq,
        capture_us,
        origin: [0.0; 3],
        detections,
    }
    .with_centroid_origin();
    let bytes = wire::encode(&frame).map_err(|e| EncodeError::new_err(e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// A frame (and a fused frame's provenance) as its dict's JSON.
fn frame_json(frame: &Frame, provenance: Option<&Provenance>) -> Value {
    let objects: Vec<Value> = frame
        .detections
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let mut o = object_json(d);
            if let Some(p) = provenance {
                o["sources"] = json!(p.names(&p.sources[i]).collect::<Vec<_>>());
            }
            o
        })
        .collect();
    let mut f = json!({
        "agent": frame.agent,
        "kind": match frame.kind {
            AgentKind::Vehicle => "vehicle",
            AgentKind::Infrastructure => "infrastructure",
        },
        "seq": frame.seq,
        "capture_us": frame.capture_us,
        "origin": frame.origin,
        "objects": objects,
    });
    if let Some(p) = provenance {
        f["agents"] = json!(p.agents);
        f["complete"] = json!(p.complete);
    }
    f
}

/// One object of a frame dict.
fn object_json(d: &Detection) -> Value {
    let mut o = json!({
        "class": d.class.name(),
        "center": d.center,
        "size": d.size,
        "yaw": d.yaw,
        "score": d.score,
        "id": (d.id != NO_ID).then_some(d.id),
        "std": d.std.as_array(),
    });
    if let Some(v) = d.velocity {
        o["velocity"] = json!(v.v);
        o["velocity_std"] = json!(v.std);
    }
    o
}

/// A frame dict's value that is missing or of the wrong kind.
#[derive(Debug, Clone, PartialEq)]
struct DictError {
    /// Where it sits: `objects[3].center`.
    path: String,
    /// What it should have been.
    expected: String,
}

impl std::fmt::Display for DictError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path, self.expected)
    }
}

/// Where a value sits in a frame dict, for errors: `objects[3].`.
struct At<'a>(&'a str);

impl At<'_> {
    fn err(&self, name: &str, expected: impl Into<String>) -> DictError {
        DictError {
            path: format!("{}{name}", self.0),
            expected: expected.into(),
        }
    }

    fn field<'v>(&self, obj: &'v Map<String, Value>, name: &str) -> Result<&'v Value, DictError> {
        obj.get(name).ok_or_else(|| self.err(name, "missing"))
    }

    fn int(&self, obj: &Map<String, Value>, name: &str, max: u64) -> Result<u64, DictError> {
        self.field(obj, name)?
            .as_u64()
            .filter(|v| *v <= max)
            .ok_or_else(|| self.err(name, format!("expected an integer from 0 to {max}")))
    }

    fn number(&self, obj: &Map<String, Value>, name: &str) -> Result<f64, DictError> {
        self.field(obj, name)?
            .as_f64()
            .ok_or_else(|| self.err(name, "expected a number"))
    }

    fn numbers<const N: usize>(
        &self,
        obj: &Map<String, Value>,
        name: &str,
    ) -> Result<[f64; N], DictError> {
        let bad = || self.err(name, format!("expected {N} numbers"));
        let arr = self.field(obj, name)?.as_array().ok_or_else(bad)?;
        if arr.len() != N {
            return Err(bad());
        }
        let mut out = [0.0; N];
        for (o, v) in out.iter_mut().zip(arr) {
            *o = v.as_f64().ok_or_else(bad)?;
        }
        Ok(out)
    }

    fn string<'v>(&self, obj: &'v Map<String, Value>, name: &str) -> Result<&'v str, DictError> {
        self.field(obj, name)?
            .as_str()
            .ok_or_else(|| self.err(name, "expected a string"))
    }

    /// A name of a closed set (a class, a kind).
    fn name<T: std::str::FromStr<Err = UnknownName>>(
        &self,
        obj: &Map<String, Value>,
        name: &str,
    ) -> Result<T, DictError> {
        self.string(obj, name)?
            .parse()
            .map_err(|e: UnknownName| self.err(name, e.to_string()))
    }
}

/// A frame dict (and a fused frame's provenance when it lists `agents`) from its JSON; the values
/// are checked by the encoder.
fn frame_of(v: &Value) -> Result<(Frame, Option<Provenance>), DictError> {
    let at = At("");
    let f = v
        .as_object()
        .ok_or_else(|| at.err("frame", "expected a dict"))?;
    let kind: AgentKind = at.name(f, "kind")?;
    let agents: Option<Vec<String>> = match f.get("agents") {
        None | Some(Value::Null) => None,
        Some(a) => Some(
            serde_json::from_value(a.clone())
                .map_err(|_| at.err("agents", "expected a list of names"))?,
        ),
    };
    let objects = at
        .field(f, "objects")?
        .as_array()
        .ok_or_else(|| at.err("objects", "expected a list"))?;
    let mut detections = Vec::with_capacity(objects.len());
    let mut sources = Vec::new();
    for (i, o) in objects.iter().enumerate() {
        let prefix = format!("objects[{i}].");
        let at = At(&prefix);
        let o = o
            .as_object()
            .ok_or_else(|| At("").err(&format!("objects[{i}]"), "expected a dict"))?;
        detections.push(object_of(&at, o)?);
        if let Some(agents) = &agents {
            sources.push(sources_of(&at, o, agents)?);
        }
    }
    let frame = Frame {
        agent: at.string(f, "agent")?.to_owned(),
        kind,
        seq: at.int(f, "seq", u32::MAX as u64)? as u32,
        capture_us: at.int(f, "capture_us", u64::MAX)?,
        origin: match f.get("origin") {
            None | Some(Value::Null) => [0.0; 3],
            Some(_) => at.numbers(f, "origin")?,
        },
        detections,
    };
    let provenance = match agents {
        None => None,
        Some(agents) => Some(Provenance {
            agents,
            complete: f
                .get("complete")
                .map_or(Some(true), Value::as_bool)
                .ok_or_else(|| at.err("complete", "expected true or false"))?,
            sources,
        }),
    };
    Ok((frame, provenance))
}

/// One object of a frame dict.
fn object_of(at: &At, o: &Map<String, Value>) -> Result<Detection, DictError> {
    let class: Class = at.name(o, "class")?;
    let id = match o.get("id") {
        None | Some(Value::Null) => NO_ID,
        Some(_) => at.int(o, "id", (NO_ID - 1) as u64)? as u32,
    };
    let velocity = match o.get("velocity") {
        None | Some(Value::Null) => None,
        Some(_) => Some(Velocity {
            v: at.numbers(o, "velocity")?,
            std: match o.get("velocity_std") {
                None | Some(Value::Null) => [1.0; 2],
                Some(_) => at.numbers(o, "velocity_std")?,
            },
        }),
    };
    Ok(Detection {
        class,
        center: at.numbers(o, "center")?,
        size: at.numbers(o, "size")?,
        yaw: at.number(o, "yaw")?,
        score: at.number(o, "score")?,
        std: Uncertainty::from_array(at.numbers(o, "std")?),
        pos_cov: None,
        velocity,
        id,
    })
}

/// The source set of one object of a fused frame dict: its `sources`, names among `agents`.
fn sources_of(at: &At, o: &Map<String, Value>, agents: &[String]) -> Result<AgentSet, DictError> {
    let names = at
        .field(o, "sources")?
        .as_array()
        .ok_or_else(|| at.err("sources", "expected a list of agent names"))?;
    let mut set = AgentSet::new();
    for n in names {
        let k = n
            .as_str()
            .and_then(|n| agents.iter().position(|a| a == n))
            .ok_or_else(|| at.err("sources", format!("{n} is not one of the frame's agents")))?;
        set.insert(k);
    }
    Ok(set)
}
