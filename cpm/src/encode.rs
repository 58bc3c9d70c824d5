//! A frame as one CPM: the header, the management container with the reference time and
//! position, the originating station's container, and a perceived object per box.

use crate::asn::*;
use crate::units::{code, confidence, station_id, value, Geo, ITS_EPOCH_UNIX_MS};
use crate::{classes, MAX_OBJECTS, MESSAGE_ID, PROTOCOL_VERSION};
use rasn::types::Any;
use v2x_protocol::{AgentKind, Detection, Frame, NO_ID};

/// Why a frame cannot be one CPM.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EncodeError {
    /// More boxes than one message carries.
    #[error("{0} boxes: one CPM carries at most {MAX_OBJECTS}")]
    TooManyObjects(usize),
    /// The capture time lies before the ITS epoch.
    #[error("capture time {0} us lies before 2004-01-01, the start of ITS time")]
    BeforeItsEpoch(u64),
    /// The frame's origin is off the earth or outside the altitudes a CPM states.
    #[error("the frame's origin {field} is {value}, outside what a CPM states ({range})")]
    Origin {
        /// `latitude`, `longitude` or `altitude`.
        field: &'static str,
        /// The value (degrees or metres).
        value: f64,
        /// What the message allows.
        range: &'static str,
    },
    /// A box's value lies outside what the message states.
    #[error("box {index}: {field} {value} lies outside what a CPM states ({range})")]
    Object {
        /// The box's index in the frame.
        index: usize,
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What the message allows.
        range: &'static str,
    },
    /// The ASN.1 encoder refused a value (a bug: every value is checked before).
    #[error("UPER encoding failed: {0}")]
    Uper(String),
}

/// The frame as one UPER-encoded CPM, its positions placed on the earth by `geo`.
pub fn encode(frame: &Frame, geo: &Geo) -> Result<Vec<u8>, EncodeError> {
    let n = frame.detections.len();
    if n > MAX_OBJECTS {
        return Err(EncodeError::TooManyObjects(n));
    }
    let ms = frame.capture_us / 1000;
    if ms < ITS_EPOCH_UNIX_MS {
        return Err(EncodeError::BeforeItsEpoch(frame.capture_us));
    }
    let (reference, at) = reference_position(frame.origin, geo)?;
    let objects = frame
        .detections
        .iter()
        .enumerate()
        .map(|(i, d)| perceived_object(i, d, at))
        .collect::<Result<Vec<_>, _>>()?;
    let station = match frame.kind {
        AgentKind::Vehicle => wrapped(
            ORIGINATING_VEHICLE_CONTAINER,
            &OriginatingVehicleContainer {
                orientation_angle: Wgs84Angle {
                    value: Wgs84AngleValue(3601),
                    confidence: Wgs84AngleConfidence(127),
                },
                pitch_angle: None,
                roll_angle: None,
                trailer_data_set: None,
            },
        )?,
        AgentKind::Infrastructure => wrapped(
            ORIGINATING_RSU_CONTAINER,
            &OriginatingRsuContainer {
                map_reference: None,
            },
        )?,
    };
    let perceived = wrapped(
        PERCEIVED_OBJECT_CONTAINER,
        &PerceivedObjectContainer {
            number_of_perceived_objects: CardinalNumber1B(n as u8),
            perceived_objects: PerceivedObjects(objects),
        },
    )?;
    let cpm = CollectivePerceptionMessage {
        header: ItsPduHeader {
            protocol_version: OrdinalNumber1B(PROTOCOL_VERSION),
            message_id: MessageId(MESSAGE_ID),
            station_id: StationId(station_id(&frame.agent)),
        },
        payload: CpmPayload {
            management_container: ManagementContainer {
                reference_time: TimestampIts(ms - ITS_EPOCH_UNIX_MS),
                reference_position: reference,
                segmentation_info: None,
                message_rate_range: None,
            },
            cpm_containers: ConstraintWrappedCpmContainers(WrappedCpmContainers(vec![
                station, perceived,
            ])),
        },
    };
    rasn::uper::encode(&cpm).map_err(|e| EncodeError::Uper(e.to_string()))
}

/// A container wrapped as the open type it travels in.
fn wrapped<T: rasn::Encode>(
    id: CpmContainerId,
    container: &T,
) -> Result<WrappedCpmContainer, EncodeError> {
    let bytes = rasn::uper::encode(container).map_err(|e| EncodeError::Uper(e.to_string()))?;
    Ok(WrappedCpmContainer {
        container_id: id,
        container_data: Any::new(bytes),
    })
}

/// The CPM reference position of map point `origin`, and the map point the message will be read
/// as standing for (boxes are coded against it, so only their own steps are lost).
fn reference_position(
    origin: [f64; 3],
    geo: &Geo,
) -> Result<(ReferencePosition, [f64; 3]), EncodeError> {
    let (lat, lon) = geo.to_wgs84(origin[0], origin[1]);
    let lat_code = (lat * 1e7).round();
    let lon_code = (lon * 1e7).round();
    if !(lat_code.abs() <= 900_000_000.0) {
        return Err(EncodeError::Origin {
            field: "latitude",
            value: lat,
            range: "-90..90 degrees",
        });
    }
    if !(lon_code > -1_800_000_000.0 && lon_code <= 1_800_000_000.0) {
        return Err(EncodeError::Origin {
            field: "longitude",
            value: lon,
            range: "-180..180 degrees",
        });
    }
    let alt = code(origin[2], 0.01);
    if !(-99_999..=799_999).contains(&alt) {
        return Err(EncodeError::Origin {
            field: "altitude",
            value: origin[2],
            range: "-1000..8000 m",
        });
    }
    let (x, y) = geo.to_map(lat_code / 1e7, lon_code / 1e7);
    let position = ReferencePosition {
        latitude: Latitude(lat_code as i32),
        longitude: Longitude(lon_code as i32),
        position_confidence_ellipse: PosConfidenceEllipse {
            semi_major_confidence: SemiAxisLength(4095),
            semi_minor_confidence: SemiAxisLength(4095),
            semi_major_orientation: HeadingValue(3601),
        },
        altitude: Altitude {
            altitude_value: AltitudeValue(alt as i32),
            altitude_confidence: AltitudeConfidence::unavailable,
        },
    };
    Ok((position, [x, y, value(alt, 0.01)]))
}

/// Box `i` as a perceived object, its centre against map point `at`.
fn perceived_object(i: usize, d: &Detection, at: [f64; 3]) -> Result<PerceivedObject, EncodeError> {
    let out = |field, value, range| EncodeError::Object {
        index: i,
        field,
        value,
        range,
    };
    let axis = |k: usize, field| {
        let n = code(d.center[k] - at[k], 0.01);
        if !(-131_071..=131_070).contains(&n) {
            return Err(out(
                field,
                d.center[k],
                "within 1310.7 m of the frame's origin",
            ));
        }
        Ok(CartesianCoordinateWithConfidence {
            value: CartesianCoordinateLarge(n as i32),
            confidence: CoordinateConfidence(confidence(d.std.pos[k], 0.01, 4094, 4095) as u16),
        })
    };
    let dimension = |k: usize, field| {
        let n = code(d.size[k], 0.1);
        if !(1..=254).contains(&n) {
            return Err(out(field, d.size[k], "0..25.4 m"));
        }
        Ok(ObjectDimension {
            value: ObjectDimensionValue(n as u16),
            confidence: ObjectDimensionConfidence(confidence(d.std.size[k], 0.1, 30, 31) as u8),
        })
    };
    let velocity = d.velocity.map(|v| velocity(i, &v)).transpose()?;
    let degrees = d.yaw.to_degrees().rem_euclid(360.0);
    let yaw = code(degrees, 0.1) % 3600;
    let score = (d.score * 100.0).round().clamp(1.0, 100.0) as u8;
    Ok(PerceivedObject {
        object_id: Some(Identifier2B(if d.id == NO_ID {
            u16::MAX
        } else {
            d.id as u16
        })),
        measurement_delta_time: DeltaTimeMilliSecondSigned(0),
        position: CartesianPosition3dWithConfidence {
            x_coordinate: axis(0, "x")?,
            y_coordinate: axis(1, "y")?,
            z_coordinate: Some(axis(2, "z")?),
        },
        velocity,
        acceleration: None,
        angles: Some(EulerAnglesWithConfidence {
            z_angle: CartesianAngle {
                value: CartesianAngleValue(yaw as u16),
                confidence: AngleConfidence(confidence(d.std.yaw.to_degrees(), 0.1, 125, 126) as u8),
            },
            y_angle: None,
            x_angle: None,
        }),
        z_angular_velocity: None,
        lower_triangular_correlation_matrices: None,
        object_dimension_z: Some(dimension(2, "height")?),
        object_dimension_y: Some(dimension(1, "width")?),
        object_dimension_x: Some(dimension(0, "length")?),
        object_age: None,
        object_perception_quality: Some(ObjectPerceptionQuality((d.score * 15.0).round() as u8)),
        sensor_id_list: None,
        classification: Some(ObjectClassDescription(vec![ObjectClassWithConfidence {
            object_class: classes::to_cpm(d.class),
            confidence: ConfidenceLevel(score),
        }])),
        map_position: None,
    })
}

/// Box `i`'s velocity, its components within the message's range.
fn velocity(i: usize, v: &v2x_protocol::Velocity) -> Result<Velocity3dWithConfidence, EncodeError> {
    let component = |k: usize, field| {
        let n = code(v.v[k], 0.01);
        if !(-16_382..=16_381).contains(&n) {
            return Err(EncodeError::Object {
                index: i,
                field,
                value: v.v[k],
                range: "-163.82..163.81 m/s",
            });
        }
        Ok(VelocityComponent {
            value: VelocityComponentValue(n as i16),
            confidence: SpeedConfidence(confidence(v.std[k], 0.01, 125, 126) as u8),
        })
    };
    Ok(Velocity3dWithConfidence::cartesianVelocity(
        VelocityCartesian {
            x_velocity: component(0, "vx")?,
            y_velocity: component(1, "vy")?,
            z_velocity: None,
        },
    ))
}

/// Bytes of the CPMs that carry a frame's boxes: one message per [`MAX_OBJECTS`] boxes (one for
/// a frame without boxes); 0 when a box cannot be stated. A CPM's fields have fixed widths, so
/// its size does not depend on the time: a clock before the ITS epoch is counted as if at it.
pub fn message_bytes(frame: &Frame) -> usize {
    let at = Frame {
        capture_us: frame.capture_us.max(ITS_EPOCH_UNIX_MS * 1000),
        detections: Vec::new(),
        ..frame.clone()
    };
    let mut parts: Vec<&[Detection]> = frame.detections.chunks(MAX_OBJECTS).collect();
    if parts.is_empty() {
        parts.push(&[]);
    }
    let mut total = 0;
    for part in parts {
        let message = Frame {
            detections: part.to_vec(),
            ..at.clone()
        };
        match encode(&message, &Geo::default()) {
            Ok(b) => total += b.len(),
            Err(_) => return 0,
        }
    }
    total
}
