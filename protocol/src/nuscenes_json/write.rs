//! Writing nuScenes results: a box's fields, detection and tracking files, provenance and the
//! meta block, so that what [`super::parse_results`] reads is written back.

use super::*;
use smallvec::SmallVec;

/// One field of a box as it is written.
#[derive(Debug, Clone, PartialEq)]
pub enum OutField<'a> {
    /// A string.
    Str(&'a str),
    /// A class, written as its name.
    Class(Class),
    /// A number.
    Number(f64),
    /// A list of numbers.
    Numbers(SmallVec<[f64; 9]>),
    /// An object id.
    Id(u32),
}

/// Each field of one box in nuScenes results form, with the extension fields the box has,
/// given to `put` (with `sample_token` when `sample` is given): the one writer behind
/// [`box_json`] and the Python package's dicts.
pub fn box_fields<'a>(
    sample: Option<&'a str>,
    d: &Detection,
    tokens: &'a TokenTable,
    mut put: impl FnMut(&'static str, OutField<'a>),
) {
    use OutField::{Number, Numbers, Str};
    let [l, w, h] = d.size;
    let [sl, sw, sh] = d.std.size;
    if let Some(sample) = sample {
        put(Field::SampleToken.name(), Str(sample));
    }
    put(
        Field::Translation.name(),
        Numbers(SmallVec::from_slice(&d.center)),
    );
    put(
        Field::Size.name(),
        Numbers(SmallVec::from_slice(&[w, l, h])),
    );
    put(
        Field::Rotation.name(),
        Numbers(SmallVec::from_slice(&yaw_quaternion(d.yaw))),
    );
    let v = d.velocity.map_or([0.0, 0.0], |v| v.v);
    put(Field::Velocity.name(), Numbers(SmallVec::from_slice(&v)));
    put(Field::DetectionName.name(), OutField::Class(d.class));
    put(Field::DetectionScore.name(), Number(d.score));
    put("attribute_name", Str(""));
    put(
        Field::TranslationStd.name(),
        Numbers(SmallVec::from_slice(&d.std.pos)),
    );
    put(
        Field::SizeStd.name(),
        Numbers(SmallVec::from_slice(&[sw, sl, sh])),
    );
    put(Field::YawStd.name(), Number(d.std.yaw));
    if let Some(c) = d.pos_cov.as_deref() {
        put(
            Field::TranslationCov.name(),
            Numbers(SmallVec::from_slice(c.as_flattened())),
        );
    }
    if let Some(v) = d.velocity {
        put(
            Field::VelocityStd.name(),
            Numbers(SmallVec::from_slice(&v.std)),
        );
    }
    if let Some(t) = tokens.name(d.id) {
        put(Field::InstanceToken.name(), Str(t));
    } else if d.id != NO_ID {
        put(Field::InstanceId.name(), OutField::Id(d.id));
    }
}

/// One box in nuScenes results form, with the extension fields.
pub fn box_json(sample: &str, d: &Detection, tokens: &TokenTable) -> Value {
    let mut m = Map::new();
    box_fields(Some(sample), d, tokens, |k, v| {
        m.insert(
            k.into(),
            match v {
                OutField::Str(s) => json!(s),
                OutField::Class(c) => json!(c.name()),
                OutField::Number(x) => json!(x),
                OutField::Numbers(xs) => json!(xs.as_slice()),
                OutField::Id(i) => json!(i),
            },
        );
    });
    Value::Object(m)
}

/// The whole results document.
pub fn results_json(results: &Results, tokens: &TokenTable) -> Value {
    let mut map = Map::new();
    for (sample, dets) in &results.samples {
        map.insert(
            sample.clone(),
            Value::Array(dets.iter().map(|d| box_json(sample, d, tokens)).collect()),
        );
    }
    let meta = if results.meta.is_null() {
        default_meta()
    } else {
        results.meta.clone()
    };
    json!({ "meta": meta, "results": map })
}

/// A tracking results document (the nuScenes tracking format): each box also carries
/// `tracking_id` (a string, as the format has it), `tracking_name` and `tracking_score`, beside
/// the detection fields, so the same file scores as detections too. `ids[sample][k]` is the
/// track of box k of that sample.
pub fn tracking_json(
    results: &Results,
    ids: &BTreeMap<String, Vec<u32>>,
    tokens: &TokenTable,
) -> Value {
    let mut doc = results_json(results, tokens);
    let samples = doc["results"].as_object_mut().expect("built as an object");
    for (sample, boxes) in samples.iter_mut() {
        let ids = ids.get(sample).map(Vec::as_slice).unwrap_or_default();
        for (b, id) in boxes.as_array_mut().into_iter().flatten().zip(ids) {
            let m = b.as_object_mut().expect("built as an object");
            let name = m["detection_name"].clone();
            let score = m["detection_score"].clone();
            m.insert("tracking_id".into(), json!(id.to_string()));
            m.insert("tracking_name".into(), name);
            m.insert("tracking_score".into(), score);
        }
    }
    doc
}

/// A fused frame's provenance as a recording's `meta.v2x_provenance` holds it per sample:
/// `{"agents": [...], "complete": bool, "sources": [[names of box 0's agents], ...]}`.
pub fn provenance_json(p: &crate::Provenance) -> Value {
    let sources: Vec<Vec<&str>> = p.sources.iter().map(|s| p.names(s).collect()).collect();
    json!({ "agents": p.agents, "complete": p.complete, "sources": sources })
}

/// The `meta` block v2x-fusion writes when it has none to keep.
pub fn default_meta() -> Value {
    json!({
        "use_camera": false, "use_lidar": true, "use_radar": false,
        "use_map": false, "use_external": false
    })
}

/// Writes a results file.
pub fn write_results(path: &Path, results: &Results, tokens: &TokenTable) -> Result<(), JsonError> {
    let text = serde_json::to_string(&results_json(results, tokens))
        .expect("JSON values always serialize");
    std::fs::write(path, text).map_err(|e| JsonError {
        file: path.to_path_buf(),
        sample: None,
        index: None,
        field: None,
        message: format!("cannot write: {e}"),
    })
}
