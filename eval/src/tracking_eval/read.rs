//! Reading a nuScenes tracking results file into the evaluation's boxes; errors name the
//! file, sample, box and field.

use super::*;

/// Reads a nuScenes tracking results file: per sample token, each box's `tracking_id` (a string
/// or an integer), `tracking_name`, `tracking_score` and `translation`. Errors name the file, sample, box and field.
pub fn read_tracking(path: &Path) -> Result<BTreeMap<String, Vec<TrackBox>>, JsonError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| JsonError::file(path, format!("cannot read: {e}")))?;
    parse_tracking(path, &text)
}

/// Parses a nuScenes tracking results document as [`read_tracking`] reads a file; `path` only
/// names the source in errors.
pub fn parse_tracking(
    path: &Path,
    text: &str,
) -> Result<BTreeMap<String, Vec<TrackBox>>, JsonError> {
    let doc: serde_json::Value =
        serde_json::from_str(text).map_err(|e| JsonError::file(path, format!("not JSON: {e}")))?;
    let results = doc
        .get("results")
        .and_then(|r| r.as_object())
        .ok_or_else(|| JsonError::file(path, "no \"results\" object"))?;
    let mut out = BTreeMap::new();
    for (sample, boxes) in results {
        let boxes = boxes.as_array().ok_or_else(|| JsonError {
            sample: Some(sample.clone()),
            ..JsonError::file(path, "expected an array of boxes")
        })?;
        let list = boxes
            .iter()
            .enumerate()
            .map(|(k, b)| {
                track_box(b, |field, what| {
                    JsonError::field(path, sample, k, field, what)
                })
            })
            .collect::<Result<_, _>>()?;
        out.insert(sample.clone(), list);
    }
    Ok(out)
}

/// One box of a tracking results file; `at` locates a problem with one of its fields.
fn track_box(
    b: &serde_json::Value,
    at: impl Fn(&str, &str) -> JsonError,
) -> Result<TrackBox, JsonError> {
    let track = match b.get("tracking_id") {
        Some(serde_json::Value::String(s)) => s.clone(),
        Some(serde_json::Value::Number(n)) => n.to_string(),
        Some(_) => return Err(at("tracking_id", "expected a string")),
        None => {
            return Err(at(
                "tracking_id",
                "missing (is this a tracking results file?)",
            ))
        }
    };
    let name = b
        .get("tracking_name")
        .and_then(|v| v.as_str())
        .ok_or_else(|| at("tracking_name", "missing or not a string"))?;
    let class: Class = name
        .parse()
        .map_err(|e: UnknownName| at("tracking_name", &e.to_string()))?;
    let t = b
        .get("translation")
        .and_then(|v| v.as_array())
        .filter(|a| a.len() == 3)
        .ok_or_else(|| at("translation", "expected 3 numbers"))?;
    let xy: Vec<f64> = t[..2]
        .iter()
        .filter_map(|v| v.as_f64())
        .filter(|v| v.is_finite())
        .collect();
    if xy.len() != 2 {
        return Err(at("translation", "expected finite numbers"));
    }
    let score = b
        .get("tracking_score")
        .and_then(|v| v.as_f64())
        .filter(|v| v.is_finite())
        .ok_or_else(|| at("tracking_score", "expected a finite number"))?;
    Ok(TrackBox {
        track,
        class,
        center: [xy[0], xy[1]],
        score,
    })
}
