//! A received CPM, checked field by field, as boxes in the map frame: what a frame is built
//! from once the receiver adds the sender's name and a sequence number.

use crate::asn::*;
use crate::units::{std_of, value, Geo, ITS_EPOCH_UNIX_MS};
use crate::{classes, MAX_OBJECTS, MESSAGE_ID, PROTOCOL_VERSION};
use v2x_protocol::{wrap_angle, AgentKind, Detection, Frame, Uncertainty, Velocity, NO_ID};

/// A CPM read back: its sender's station id and kind, and the boxes it carries.
#[derive(Clone, Debug, PartialEq)]
pub struct Cpm {
    /// The header's station id.
    pub station_id: u32,
    /// Vehicle or roadside unit, by the originating station's container.
    pub kind: AgentKind,
    /// The reference time as Unix time (us, whole milliseconds).
    pub capture_us: u64,
    /// The reference position in the map frame (m).
    pub origin: [f64; 3],
    /// The perceived objects that have a class here.
    pub detections: Vec<Detection>,
    /// The perceived objects left out, and why.
    pub skipped: Vec<Skipped>,
}

/// A perceived object that a CPM carries and the project cannot name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Skipped {
    /// The object's index in the message.
    pub index: usize,
    /// Why it was left out.
    pub reason: &'static str,
}

impl Cpm {
    /// The frame of agent `agent` this message carries. A CPM has no sequence number: the
    /// frame's is its time in ms (the low 32 bits), so a message heard twice is a duplicate and
    /// the parts of one capture (one per tile) agree.
    pub fn into_frame(self, agent: String) -> Frame {
        Frame {
            agent,
            kind: self.kind,
            seq: (self.capture_us / 1000) as u32,
            capture_us: self.capture_us,
            origin: self.origin,
            detections: self.detections,
        }
    }
}

/// Why bytes are not a CPM the project can read.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DecodeError {
    /// The bytes are not a UPER-encoded CollectivePerceptionMessage.
    #[error("not a UPER-encoded CPM: {0}")]
    Uper(String),
    /// The header names another message or version.
    #[error("the header says message {message_id} version {version}, not a CPM version {PROTOCOL_VERSION} (message {MESSAGE_ID})")]
    Header {
        /// The header's message id.
        message_id: u8,
        /// The header's protocol version.
        version: u8,
    },
    /// A container's data is not the type its id names.
    #[error("container {id}: {message}")]
    Container {
        /// The container id.
        id: u8,
        /// What was wrong.
        message: String,
    },
    /// A field of the message is missing or not a value.
    #[error("{field}: {message}")]
    Field {
        /// The field.
        field: &'static str,
        /// What was wrong.
        message: &'static str,
    },
    /// A perceived object's field is missing or not a value.
    #[error("perceived object {index}: {field} {message}")]
    Object {
        /// The object's index in the message.
        index: usize,
        /// The field.
        field: &'static str,
        /// What was wrong.
        message: &'static str,
    },
}

/// The CPM in `bytes`, its positions brought into the map frame by `geo`.
pub fn decode(bytes: &[u8], geo: &Geo) -> Result<Cpm, DecodeError> {
    let cpm: CollectivePerceptionMessage =
        rasn::uper::decode(bytes).map_err(|e| DecodeError::Uper(e.to_string()))?;
    let h = &cpm.header;
    if h.message_id.0 != MESSAGE_ID || h.protocol_version.0 != PROTOCOL_VERSION {
        return Err(DecodeError::Header {
            message_id: h.message_id.0,
            version: h.protocol_version.0,
        });
    }
    let m = &cpm.payload.management_container;
    let capture_us = (m.reference_time.0 + ITS_EPOCH_UNIX_MS) * 1000;
    let origin = reference_point(&m.reference_position, geo)?;
    let mut kind = None;
    let mut objects = None;
    for c in &cpm.payload.cpm_containers.0 .0 {
        let id = c.container_id.0;
        let bytes = c.container_data.as_bytes();
        let found = match c.container_id {
            ORIGINATING_VEHICLE_CONTAINER => {
                inner::<OriginatingVehicleContainer>(id, bytes)?;
                Some(AgentKind::Vehicle)
            }
            ORIGINATING_RSU_CONTAINER => {
                inner::<OriginatingRsuContainer>(id, bytes)?;
                Some(AgentKind::Infrastructure)
            }
            PERCEIVED_OBJECT_CONTAINER => {
                if objects.is_some() {
                    return Err(container(id, "a second perceived-object container"));
                }
                objects = Some(inner::<PerceivedObjectContainer>(id, bytes)?);
                None
            }
            // Sensor information, perception regions and later containers: not needed here.
            _ => None,
        };
        if let Some(k) = found {
            if kind.replace(k).is_some() {
                return Err(container(id, "a second originating-station container"));
            }
        }
    }
    let kind = kind.ok_or(DecodeError::Field {
        field: "cpmContainers",
        message: "has no originating vehicle or RSU container",
    })?;
    let objects = objects.map(|c| c.perceived_objects.0).unwrap_or_default();
    if objects.len() > MAX_OBJECTS {
        return Err(DecodeError::Field {
            field: "perceivedObjects",
            message: "holds more than 255 objects (its extension)",
        });
    }
    let mut detections = Vec::new();
    let mut skipped = Vec::new();
    for (index, o) in objects.iter().enumerate() {
        match detection(index, o, origin)? {
            Ok(d) => detections.push(d),
            Err(reason) => skipped.push(Skipped { index, reason }),
        }
    }
    Ok(Cpm {
        station_id: h.station_id.0,
        kind,
        capture_us,
        origin,
        detections,
        skipped,
    })
}

/// An error about container `id`.
fn container(id: u8, message: &str) -> DecodeError {
    DecodeError::Container {
        id,
        message: message.to_string(),
    }
}

/// The container of type `T` in an open type's bytes.
fn inner<T: rasn::Decode>(id: u8, bytes: &[u8]) -> Result<T, DecodeError> {
    rasn::uper::decode(bytes).map_err(|e| container(id, &e.to_string()))
}

/// The map point a reference position stands for.
fn reference_point(p: &ReferencePosition, geo: &Geo) -> Result<[f64; 3], DecodeError> {
    let field = |field, message| DecodeError::Field { field, message };
    if p.latitude.0.abs() > 900_000_000 {
        return Err(field("referencePosition.latitude", "is unavailable"));
    }
    if p.longitude.0 <= -1_800_000_000 || p.longitude.0 > 1_800_000_000 {
        return Err(field("referencePosition.longitude", "is unavailable"));
    }
    let alt = p.altitude.altitude_value.0;
    if !(-99_999..=799_999).contains(&alt) {
        return Err(field(
            "referencePosition.altitude",
            "is unavailable or out of range",
        ));
    }
    let (x, y) = geo.to_map(p.latitude.0 as f64 / 1e7, p.longitude.0 as f64 / 1e7);
    Ok([x, y, value(alt as i64, 0.01)])
}

/// Perceived object `i` as a box, its position against map point `at`; the inner error is why a
/// well-formed object has no class here.
fn detection(
    i: usize,
    o: &PerceivedObject,
    at: [f64; 3],
) -> Result<Result<Detection, &'static str>, DecodeError> {
    let bad = |field, message| bad(i, field, message);
    let (center, pos_std) = position(i, o, at)?;
    let (size, size_std) = dimensions(i, o)?;
    let angle = &o
        .angles
        .as_ref()
        .ok_or(bad("angles", "are missing"))?
        .z_angle;
    if angle.value.0 >= 3600 {
        return Err(bad("zAngle", "is unavailable"));
    }
    let yaw = wrap_angle(value(angle.value.0 as i64, 0.1).to_radians());
    let yaw_std = std_of(angle.confidence.0 as i64, 0.1, 125, 127)
        .ok_or(bad("zAngle", "has no confidence"))?
        .to_radians();
    let velocity = match &o.velocity {
        Some(Velocity3dWithConfidence::cartesianVelocity(v)) => {
            velocity(&v.x_velocity, &v.y_velocity)
        }
        _ => None,
    };
    let (best, score) = classification(i, o)?;
    let id = o.object_id.as_ref().ok_or(bad("objectId", "is missing"))?.0;
    let Some(class) = classes::from_cpm(&best.object_class, size[0], size[1]) else {
        return Ok(Err("a class the project has no name for"));
    };
    Ok(Ok(Detection {
        class,
        center,
        size,
        yaw,
        score,
        std: Uncertainty {
            pos: pos_std,
            size: size_std,
            yaw: yaw_std,
        },
        pos_cov: None,
        velocity,
        id: if id == u16::MAX { NO_ID } else { id as u32 },
    }))
}

/// What is wrong with a field of object `index`.
fn bad(index: usize, field: &'static str, message: &'static str) -> DecodeError {
    DecodeError::Object {
        index,
        field,
        message,
    }
}

/// Object `i`'s centre in the map (the message's reference position `at` added) and its stds.
fn position(
    i: usize,
    o: &PerceivedObject,
    at: [f64; 3],
) -> Result<([f64; 3], [f64; 3]), DecodeError> {
    let p = &o.position;
    let z = p
        .z_coordinate
        .as_ref()
        .ok_or(bad(i, "zCoordinate", "is missing"))?;
    let mut center = [0.0; 3];
    let mut pos_std = [0.0; 3];
    for (k, (c, field)) in [
        (&p.x_coordinate, "xCoordinate"),
        (&p.y_coordinate, "yCoordinate"),
        (z, "zCoordinate"),
    ]
    .into_iter()
    .enumerate()
    {
        if !(-131_071..=131_070).contains(&c.value.0) {
            return Err(bad(i, field, "is out of range"));
        }
        center[k] = at[k] + value(c.value.0 as i64, 0.01);
        pos_std[k] = std_of(c.confidence.0 as i64, 0.01, 4094, 4096).ok_or(bad(
            i,
            field,
            "has no confidence",
        ))?;
    }
    Ok((center, pos_std))
}

/// Object `i`'s length, width and height and their stds.
fn dimensions(i: usize, o: &PerceivedObject) -> Result<([f64; 3], [f64; 3]), DecodeError> {
    let dims = [
        (&o.object_dimension_x, "objectDimensionX"),
        (&o.object_dimension_y, "objectDimensionY"),
        (&o.object_dimension_z, "objectDimensionZ"),
    ];
    let mut size = [0.0; 3];
    let mut size_std = [0.0; 3];
    for (k, (d, field)) in dims.into_iter().enumerate() {
        let d = d.as_ref().ok_or(bad(i, field, "is missing"))?;
        if !(1..=254).contains(&d.value.0) {
            return Err(bad(i, field, "is unavailable or out of range"));
        }
        size[k] = value(d.value.0 as i64, 0.1);
        size_std[k] =
            std_of(d.confidence.0 as i64, 0.1, 30, 32).ok_or(bad(i, field, "has no confidence"))?;
    }
    Ok((size, size_std))
}

/// Object `i`'s most confident class and its score (the perception quality's when the class
/// has no confidence).
fn classification(
    i: usize,
    o: &PerceivedObject,
) -> Result<(&ObjectClassWithConfidence, f64), DecodeError> {
    let classes = o
        .classification
        .as_ref()
        .ok_or(bad(i, "classification", "is missing"))?;
    let best = classes
        .0
        .iter()
        .max_by_key(|c| {
            if c.confidence.0 <= 100 {
                c.confidence.0
            } else {
                0
            }
        })
        .ok_or(bad(i, "classification", "is empty"))?;
    let score = if best.confidence.0 <= 100 {
        best.confidence.0 as f64 / 100.0
    } else if let Some(q) = &o.object_perception_quality {
        q.0 as f64 / 15.0
    } else {
        return Err(bad(
            i,
            "classification",
            "has no confidence and no perception quality",
        ));
    };
    Ok((best, score))
}

/// A velocity from its two components; `None` when either is unavailable or out of range.
fn velocity(x: &VelocityComponent, y: &VelocityComponent) -> Option<Velocity> {
    let mut v = [0.0; 2];
    let mut std = [0.0; 2];
    for (k, c) in [x, y].into_iter().enumerate() {
        if !(-16_382..=16_381).contains(&c.value.0) {
            return None;
        }
        v[k] = value(c.value.0 as i64, 0.01);
        std[k] = std_of(c.confidence.0 as i64, 0.01, 125, 127)?;
    }
    Some(Velocity { v, std })
}
