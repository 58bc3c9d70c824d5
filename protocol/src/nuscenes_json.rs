//! nuScenes detection-results JSON files, in and out.
//!
//! The format is `{"meta": {...}, "results": {SAMPLE_TOKEN: [BOX, ...]}}` with each box holding
//! `sample_token`, `translation` [x, y, z], `size` **[w, l, h]**, `rotation` **[w, x, y, z]**,
//! `velocity`, `detection_name`, `detection_score` and `attribute_name`. v2x-fusion adds optional
//! extension fields: `translation_std` [3], `size_std` [3] (w, l, h order), `yaw_std` (rad),
//! `velocity_std` [2] (m/s; a `velocity` counts only with it),
//! `translation_cov` [9] (row-major 3x3, m^2), `instance_token` (the ground-truth object) and
//! `instance_id` (the object's id, [`stable_id`] of its token, written when no token is known,
//! e.g. by the fuser node's recorder).
//! Errors name the file, the sample token, the box index and the field.

use crate::{limits, wrap_angle, Class, Detection, Uncertainty, Velocity, NO_ID};
use serde_json::{json, Map, Value};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

mod error;
mod write;
pub use error::JsonError;
pub use write::*;

mod fields;
use fields::{class_and_score, covariance, object_id, stds, velocity};

/// The object id of an instance token, the same in every process: the 32-bit FNV-1a hash of its
/// UTF-8 bytes, with `NO_ID` (4294967295) moved to 4294967294.
pub fn stable_id(token: &str) -> u32 {
    let mut h: u32 = 0x811c_9dc5;
    for b in token.bytes() {
        h ^= b as u32;
        h = h.wrapping_mul(0x0100_0193);
    }
    if h == NO_ID {
        NO_ID - 1
    } else {
        h
    }
}

/// Maps instance tokens (strings) to the compact `u32` object ids detections carry: each token's
/// [`stable_id`], so that processes reading different files agree on every object's id.
#[derive(Debug, Clone, Default)]
pub struct TokenTable {
    ids: HashMap<String, u32>,
    names: HashMap<u32, String>,
    collisions: usize,
}

impl TokenTable {
    /// An empty table.
    pub fn new() -> Self {
        Self::default()
    }

    /// The id of a token: its [`stable_id`]. Should two tokens of one table share a hash (odds
    /// about n^2 / 2^33 for n tokens), the later one takes the next free id and the collision is
    /// counted ([`TokenTable::collisions`]): its id then depends on the order of interning.
    pub fn intern(&mut self, token: &str) -> u32 {
        if let Some(&id) = self.ids.get(token) {
            return id;
        }
        let mut id = stable_id(token);
        if self.names.contains_key(&id) {
            self.collisions += 1;
            while self.names.contains_key(&id) || id == NO_ID {
                id = id.wrapping_add(1);
            }
        }
        self.names.insert(id, token.to_string());
        self.ids.insert(token.to_string(), id);
        id
    }

    /// Tokens that did not get their own [`stable_id`] because another token had it.
    pub fn collisions(&self) -> usize {
        self.collisions
    }

    /// The id of a known token.
    pub fn get(&self, token: &str) -> Option<u32> {
        self.ids.get(token).copied()
    }

    /// The token of an id, if the id was interned.
    pub fn name(&self, id: u32) -> Option<&str> {
        self.names.get(&id).map(String::as_str)
    }

    /// Number of tokens.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True when no token was interned.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }
}

/// A parsed results file: detections grouped by sample token.
#[derive(Debug, Clone, Default)]
pub struct Results {
    /// The `meta` object, kept as it was.
    pub meta: Value,
    /// Detections per sample token, in file order within a sample.
    pub samples: BTreeMap<String, Vec<Detection>>,
    /// The sample tokens in the order the file lists them (empty for results made in memory).
    pub order: Vec<String>,
}

impl Results {
    /// Every sample with its detections, in the order the file lists them (the order in which
    /// the nuScenes devkit meets them, which breaks ties in score), then any sample the order
    /// does not name in token order.
    pub fn in_file_order(&self) -> impl Iterator<Item = (&String, &Vec<Detection>)> {
        let listed: std::collections::HashSet<&str> =
            self.order.iter().map(String::as_str).collect();
        self.order
            .iter()
            .filter_map(|k| self.samples.get_key_value(k))
            .chain(
                self.samples
                    .iter()
                    .filter(move |(k, _)| !listed.contains(k.as_str())),
            )
    }
}

/// The sample tokens of a results document's `results` object in the order the text lists them
/// (a JSON object read into a map loses it).
fn sample_order(text: &str) -> Vec<String> {
    use serde::de::{Deserializer, IgnoredAny, MapAccess, Visitor};
    struct Keys;
    impl<'de> Visitor<'de> for Keys {
        type Value = Vec<String>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("an object")
        }
        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Vec<String>, A::Error> {
            let mut keys = Vec::new();
            while let Some(k) = map.next_key::<String>()? {
                map.next_value::<IgnoredAny>()?;
                keys.push(k);
            }
            Ok(keys)
        }
    }
    #[derive(serde::Deserialize)]
    struct Doc {
        #[serde(default, deserialize_with = "keys")]
        results: Vec<String>,
    }
    fn keys<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
        d.deserialize_map(Keys)
    }
    let mut seen = std::collections::HashSet::new();
    serde_json::from_str::<Doc>(text)
        .map(|d| d.results)
        .unwrap_or_default()
        .into_iter()
        .filter(|k| seen.insert(k.clone()))
        .collect()
}

/// How to fill in stds a box does not give.
#[derive(Debug, Clone, Copy)]
pub enum MissingStd {
    /// A missing std field is an error.
    Error,
    /// Missing std fields take these values.
    Default(Uncertainty),
}

struct Ctx<'a> {
    file: &'a Path,
    sample: Option<&'a str>,
    index: Option<usize>,
}

impl<'a> Ctx<'a> {
    /// The whole file, before any sample or box.
    fn file(file: &'a Path) -> Self {
        Ctx {
            file,
            sample: None,
            index: None,
        }
    }

    fn err(&self, field: Option<&str>, message: impl Into<String>) -> JsonError {
        JsonError {
            file: self.file.to_path_buf(),
            sample: self.sample.map(str::to_string),
            index: self.index,
            field: field.map(str::to_string),
            message: message.into(),
        }
    }

    fn numbers<const N: usize>(
        &self,
        obj: &(impl BoxFields + ?Sized),
        f: Field,
    ) -> Result<Option<[f64; N]>, JsonError> {
        let field = f.name();
        let out = match obj.numbers::<N>(f) {
            None => return Ok(None),
            Some(Numbers::List(out)) => out,
            Some(Numbers::Len(n)) => {
                return Err(self.err(Some(field), format!("expected {N} numbers, found {n}")))
            }
            Some(Numbers::Other) => {
                return Err(self.err(Some(field), format!("expected an array of {N} numbers")))
            }
        };
        if let Some(k) = out.iter().position(|x| !x.is_finite()) {
            return Err(self.err(Some(field), format!("element {k} is not a finite number")));
        }
        Ok(Some(out))
    }

    fn required<const N: usize>(
        &self,
        obj: &(impl BoxFields + ?Sized),
        f: Field,
    ) -> Result<[f64; N], JsonError> {
        self.numbers(obj, f)?
            .ok_or_else(|| self.err(Some(f.name()), "missing"))
    }
}

/// One field of a box as its source holds it.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldValue<'a> {
    /// `null` (`None`).
    Null,
    /// A number, with the integer it is when it was written as one (for ids).
    Number(f64, Option<u64>),
    /// A string.
    Str(std::borrow::Cow<'a, str>),
    /// A list: each element's number, NaN where an element is not a number.
    List(smallvec::SmallVec<[f64; 4]>),
    /// Anything else (a boolean, an object, a type the source does not know).
    Other,
}

impl<'a> FieldValue<'a> {
    /// A JSON value as a field.
    pub fn of_json(v: &'a Value) -> FieldValue<'a> {
        match v {
            Value::Null => FieldValue::Null,
            Value::Number(n) => FieldValue::Number(n.as_f64().unwrap_or(f64::NAN), n.as_u64()),
            Value::String(s) => FieldValue::Str(s.as_str().into()),
            Value::Array(a) => {
                FieldValue::List(a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
            }
            Value::Bool(_) | Value::Object(_) => FieldValue::Other,
        }
    }

    /// The same field, owning its text.
    pub fn into_owned(self) -> FieldValue<'static> {
        match self {
            FieldValue::Null => FieldValue::Null,
            FieldValue::Number(x, i) => FieldValue::Number(x, i),
            FieldValue::Str(s) => FieldValue::Str(std::borrow::Cow::Owned(s.into_owned())),
            FieldValue::List(l) => FieldValue::List(l),
            FieldValue::Other => FieldValue::Other,
        }
    }

    fn as_f64(&self) -> Option<f64> {
        match self {
            FieldValue::Number(x, _) => Some(*x),
            _ => None,
        }
    }

    fn as_str(&self) -> Option<&str> {
        match self {
            FieldValue::Str(s) => Some(s),
            _ => None,
        }
    }
}

/// A field a box is read from (what [`BoxFields::field`] is asked for).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Field {
    /// `sample_token`.
    SampleToken,
    /// `translation`.
    Translation,
    /// `size`.
    Size,
    /// `rotation`.
    Rotation,
    /// `velocity`.
    Velocity,
    /// `detection_name`.
    DetectionName,
    /// `detection_score`.
    DetectionScore,
    /// `translation_std`.
    TranslationStd,
    /// `size_std`.
    SizeStd,
    /// `yaw_std`.
    YawStd,
    /// `translation_cov`.
    TranslationCov,
    /// `velocity_std`.
    VelocityStd,
    /// `instance_token`.
    InstanceToken,
    /// `instance_id`.
    InstanceId,
}

impl Field {
    /// Every field, each at its own place (`f as usize`).
    pub const ALL: [Field; 14] = [
        Field::SampleToken,
        Field::Translation,
        Field::Size,
        Field::Rotation,
        Field::Velocity,
        Field::DetectionName,
        Field::DetectionScore,
        Field::TranslationStd,
        Field::SizeStd,
        Field::YawStd,
        Field::TranslationCov,
        Field::VelocityStd,
        Field::InstanceToken,
        Field::InstanceId,
    ];

    /// The field's key in a results file.
    pub const fn name(self) -> &'static str {
        match self {
            Field::SampleToken => "sample_token",
            Field::Translation => "translation",
            Field::Size => "size",
            Field::Rotation => "rotation",
            Field::Velocity => "velocity",
            Field::DetectionName => "detection_name",
            Field::DetectionScore => "detection_score",
            Field::TranslationStd => "translation_std",
            Field::SizeStd => "size_std",
            Field::YawStd => "yaw_std",
            Field::TranslationCov => "translation_cov",
            Field::VelocityStd => "velocity_std",
            Field::InstanceToken => "instance_token",
            Field::InstanceId => "instance_id",
        }
    }
}

/// Where a box's fields are read from: a results file's JSON object, or (in the Python package)
/// a dict read key by key. Every source reaches the same checks.
pub trait BoxFields {
    /// The field `f`, `None` when the box has no such field.
    fn field(&self, f: Field) -> Option<FieldValue<'_>>;

    /// The field `f` as a list of `N` numbers ([`Numbers::of`] of [`BoxFields::field`]; a
    /// source may read it more directly, to the same result).
    fn numbers<const N: usize>(&self, f: Field) -> Option<Numbers<N>> {
        self.field(f).map(Numbers::of)
    }
}

/// A field read as a list of `N` numbers.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Numbers<const N: usize> {
    /// A list of `N` elements: each one's number, NaN where an element is not a number.
    List([f64; N]),
    /// A list of another length.
    Len(usize),
    /// Not a list.
    Other,
}

impl<const N: usize> Numbers<N> {
    /// A field as a list of `N` numbers.
    pub fn of(v: FieldValue<'_>) -> Numbers<N> {
        match v {
            FieldValue::List(xs) if xs.len() == N => Numbers::List(std::array::from_fn(|k| xs[k])),
            FieldValue::List(xs) => Numbers::Len(xs.len()),
            _ => Numbers::Other,
        }
    }
}

impl BoxFields for Map<String, Value> {
    fn field(&self, f: Field) -> Option<FieldValue<'_>> {
        self.get(f.name()).map(FieldValue::of_json)
    }
}

/// Yaw (rad) of a nuScenes quaternion [w, x, y, z].
pub fn quaternion_yaw(q: [f64; 4]) -> f64 {
    let [w, x, y, z] = q;
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

/// The nuScenes quaternion [w, x, y, z] of a rotation by `yaw` about +z.
pub fn yaw_quaternion(yaw: f64) -> [f64; 4] {
    let (s, c) = (yaw / 2.0).sin_cos();
    [c, 0.0, 0.0, s]
}

/// Reads a results file from disk.
pub fn read_results(
    path: &Path,
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> Result<Results, JsonError> {
    let ctx = Ctx::file(path);
    let text =
        std::fs::read_to_string(path).map_err(|e| ctx.err(None, format!("cannot read: {e}")))?;
    parse_results(path, &text, tokens, missing)
}

/// Parses results JSON text; `path` only names the source in errors.
pub fn parse_results(
    path: &Path,
    text: &str,
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> Result<Results, JsonError> {
    let ctx = Ctx::file(path);
    let root: Value =
        serde_json::from_str(text).map_err(|e| ctx.err(None, format!("not valid JSON: {e}")))?;
    let root = root
        .as_object()
        .ok_or_else(|| ctx.err(None, "expected a JSON object with 'meta' and 'results'"))?;
    let meta = root.get("meta").cloned().unwrap_or(Value::Null);
    let results = root
        .get("results")
        .ok_or_else(|| ctx.err(Some("results"), "missing"))?
        .as_object()
        .ok_or_else(|| ctx.err(Some("results"), "expected an object keyed by sample token"))?;
    let mut samples = BTreeMap::new();
    for (token, boxes) in results {
        let sctx = Ctx {
            file: path,
            sample: Some(token),
            index: None,
        };
        let boxes = boxes
            .as_array()
            .ok_or_else(|| sctx.err(None, "expected an array of boxes"))?;
        let mut dets = Vec::with_capacity(boxes.len());
        for (i, b) in boxes.iter().enumerate() {
            let bctx = Ctx {
                file: path,
                sample: Some(token),
                index: Some(i),
            };
            dets.push(parse_box(&bctx, b, tokens, missing)?);
        }
        samples.insert(token.clone(), dets);
    }
    Ok(Results {
        meta,
        samples,
        order: sample_order(text),
    })
}

/// Parses a JSON array of boxes in results form that belong to no sample in particular (their
/// `sample_token`, if any, is not checked); `path` only names the source in errors.
pub fn parse_boxes(
    path: &Path,
    boxes: &Value,
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> Result<Vec<Detection>, JsonError> {
    let ctx = Ctx::file(path);
    let boxes = boxes
        .as_array()
        .ok_or_else(|| ctx.err(None, "expected a list of boxes"))?;
    boxes
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let bctx = Ctx {
                index: Some(i),
                ..ctx
            };
            parse_box(&bctx, b, tokens, missing)
        })
        .collect()
}

fn parse_box(
    ctx: &Ctx,
    b: &Value,
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> Result<Detection, JsonError> {
    let obj = b
        .as_object()
        .ok_or_else(|| ctx.err(None, "expected a box object"))?;
    parse_fields(ctx, obj, tokens, missing)
}

/// Parses and checks box `index` of the list `source` names (in errors) from its fields, as a
/// results file's box is: the same checks whatever holds the fields.
pub fn parse_box_fields(
    source: &Path,
    index: usize,
    fields: &(impl BoxFields + ?Sized),
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> Result<Detection, JsonError> {
    let ctx = Ctx {
        index: Some(index),
        ..Ctx::file(source)
    };
    parse_fields(&ctx, fields, tokens, missing)
}

fn parse_fields(
    ctx: &Ctx,
    obj: &(impl BoxFields + ?Sized),
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> Result<Detection, JsonError> {
    if let (Some(st), Some(sample)) = (obj.field(Field::SampleToken), ctx.sample) {
        if st.as_str() != Some(sample) {
            return Err(ctx.err(
                Some("sample_token"),
                "does not match the sample it is listed under",
            ));
        }
    }
    let center = ctx.required::<3>(obj, Field::Translation)?;
    if !center.iter().all(|c| limits::coord_in_range(*c)) {
        return Err(ctx.err(
            Some("translation"),
            format!(
                "coordinates must lie within {:e} m of the map origin",
                limits::COORD_MAX
            ),
        ));
    }
    let [w, l, h] = ctx.required::<3>(obj, Field::Size)?;
    if [w, l, h].iter().any(|s| !limits::size_in_range(*s)) {
        return Err(ctx.err(
            Some("size"),
            format!(
                "sizes must be positive, between {} and {} m",
                limits::SIZE_MIN,
                limits::SIZE_MAX
            ),
        ));
    }
    let q = ctx.required::<4>(obj, Field::Rotation)?;
    if q.iter().map(|v| v * v).sum::<f64>() < 1e-12 {
        return Err(ctx.err(Some("rotation"), "zero quaternion"));
    }
    let (class, score) = class_and_score(ctx, obj)?;
    let std = stds(ctx, obj, missing)?;
    let pos_cov = match ctx.numbers::<9>(obj, Field::TranslationCov)? {
        None => None,
        Some(c) => Some(covariance(ctx, c)?),
    };
    let id = object_id(ctx, obj, tokens)?;
    let velocity = velocity(ctx, obj)?;
    Ok(Detection {
        class,
        center,
        size: [l, w, h],
        yaw: wrap_angle(quaternion_yaw(q)),
        score,
        std,
        pos_cov: pos_cov.map(Box::new),
        velocity,
        id,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("agent1.json")
    }

    const GOOD: &str = r#"{"meta": {"use_lidar": true}, "results": {
        "s1": [{"sample_token": "s1", "translation": [10.0, 20.0, 1.0], "size": [2.0, 4.5, 1.6],
                "rotation": [0.7071067811865476, 0.0, 0.0, 0.7071067811865476], "velocity": [0, 0],
                "detection_name": "car", "detection_score": 0.8, "attribute_name": "",
                "translation_std": [0.5, 0.6, 0.7], "size_std": [0.1, 0.2, 0.3], "yaw_std": 0.05,
                "instance_token": "abc"}],
        "s2": []}}"#;

    #[test]
    fn samples_keep_the_files_order() {
        let text = r#"{"results": {"zz": [], "aa": [], "mm": []}}"#;
        let r = parse_results(p(), text, &mut TokenTable::new(), MissingStd::Error).unwrap();
        let order: Vec<&str> = r.in_file_order().map(|(k, _)| k.as_str()).collect();
        assert_eq!(order, ["zz", "aa", "mm"]);
        // made in memory: token order
        let mut made = r.clone();
        made.order.clear();
        let order: Vec<&str> = made.in_file_order().map(|(k, _)| k.as_str()).collect();
        assert_eq!(order, ["aa", "mm", "zz"]);
    }

    /// A box held by something other than a JSON object: a list of fields.
    struct Fields<'a>(Vec<(&'a str, FieldValue<'a>)>);

    impl BoxFields for Fields<'_> {
        fn field(&self, f: Field) -> Option<FieldValue<'_>> {
            self.0
                .iter()
                .find(|(k, _)| *k == f.name())
                .map(|(_, v)| v.clone())
        }
    }

    impl<'a> Fields<'a> {
        fn with(mut self, name: &'a str, v: FieldValue<'a>) -> Self {
            self.0.retain(|(k, _)| *k != name);
            self.0.push((name, v));
            self
        }
    }

    #[test]
    fn each_field_has_its_own_key_and_its_place_in_all() {
        for (i, f) in Field::ALL.iter().enumerate() {
            assert_eq!(*f as usize, i, "{f:?}");
            assert_eq!(
                Field::ALL.iter().filter(|g| g.name() == f.name()).count(),
                1
            );
        }
        let b: Map<String, Value> = serde_json::from_str(r#"{"size_std": [1, 2, 3]}"#).unwrap();
        assert_eq!(
            b.field(Field::SizeStd),
            Some(FieldValue::List([1.0, 2.0, 3.0].into_iter().collect()))
        );
        assert_eq!(b.field(Field::Size), None);
    }

    #[test]
    fn any_source_of_fields_meets_the_same_checks() {
        let doc: Value = serde_json::from_str(GOOD).unwrap();
        let b = doc["results"]["s1"][0].as_object().unwrap();
        let fields = || {
            Fields(
                b.iter()
                    .map(|(k, v)| (k.as_str(), FieldValue::of_json(v)))
                    .collect(),
            )
        };
        let mut tokens = TokenTable::new();
        let parse = |f: &Fields, tokens: &mut TokenTable| {
            parse_box_fields(p(), 3, f, tokens, MissingStd::Error)
        };
        let whole = parse_results(p(), GOOD, &mut TokenTable::new(), MissingStd::Error).unwrap();
        assert_eq!(
            parse(&fields(), &mut tokens).unwrap(),
            whole.samples["s1"][0]
        );
        // An id is an integer written as one: 7 is, 7.0 is not.
        let f = fields()
            .with("instance_token", FieldValue::Null)
            .with("instance_id", FieldValue::Number(7.0, Some(7)));
        assert_eq!(parse(&f, &mut tokens).unwrap().id, 7);
        let f = f.with("instance_id", FieldValue::Number(7.0, None));
        assert_eq!(
            parse(&f, &mut tokens).unwrap_err().to_string(),
            "agent1.json, box 3, field 'instance_id': expected an integer below 4294967295"
        );
        let f = fields().with(
            "translation",
            FieldValue::List([1.0, f64::NAN, 2.0].into_iter().collect()),
        );
        assert_eq!(
            parse(&f, &mut tokens).unwrap_err().to_string(),
            "agent1.json, box 3, field 'translation': element 1 is not a finite number"
        );
        let f = fields().with("detection_score", FieldValue::Other);
        assert_eq!(
            parse(&f, &mut tokens).unwrap_err().to_string(),
            "agent1.json, box 3, field 'detection_score': expected a number in [0, 1]"
        );
    }

    #[test]
    fn a_list_of_boxes_belongs_to_no_sample() {
        let doc: Value = serde_json::from_str(GOOD).unwrap();
        let mut tokens = TokenTable::new();
        let dets = parse_boxes(p(), &doc["results"]["s1"], &mut tokens, MissingStd::Error).unwrap();
        let whole = parse_results(p(), GOOD, &mut TokenTable::new(), MissingStd::Error).unwrap();
        assert_eq!(dets, whole.samples["s1"]);
        assert_eq!(tokens.name(dets[0].id), Some("abc"));
        let mut bad = doc["results"]["s1"].clone();
        bad[0]["detection_score"] = json!(2.0);
        let e = parse_boxes(
            p(),
            &json!([doc["results"]["s1"][0], bad[0]]),
            &mut tokens,
            MissingStd::Error,
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "agent1.json, box 1, field 'detection_score': expected a number in [0, 1]"
        );
        let e = parse_boxes(p(), &json!({}), &mut tokens, MissingStd::Error).unwrap_err();
        assert_eq!(e.to_string(), "agent1.json: expected a list of boxes");
    }

    #[test]
    fn parses_conventions() {
        let mut t = TokenTable::new();
        let r = parse_results(p(), GOOD, &mut t, MissingStd::Error).unwrap();
        let d = &r.samples["s1"][0];
        assert_eq!(d.size, [4.5, 2.0, 1.6]);
        assert!((d.yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(d.std.size, [0.2, 0.1, 0.3]);
        assert_eq!(d.std.pos, [0.5, 0.6, 0.7]);
        assert_eq!(t.name(d.id), Some("abc"));
        assert!(r.samples["s2"].is_empty());
    }

    #[test]
    fn round_trip() {
        let mut t = TokenTable::new();
        let r = parse_results(p(), GOOD, &mut t, MissingStd::Error).unwrap();
        let text = results_json(&r, &t).to_string();
        let mut t2 = TokenTable::new();
        let r2 = parse_results(p(), &text, &mut t2, MissingStd::Error).unwrap();
        assert_eq!(r.samples.len(), r2.samples.len());
        let (a, b) = (&r.samples["s1"][0], &r2.samples["s1"][0]);
        assert_eq!(a.class, b.class);
        assert_eq!(a.center, b.center);
        assert_eq!(a.size, b.size);
        assert!((a.yaw - b.yaw).abs() < 1e-12);
        assert_eq!(a.std, b.std);
        assert_eq!(t2.name(b.id), Some("abc"));
        assert_eq!(r2.meta, r.meta);
    }

    #[test]
    fn yaw_of_quaternion_matches_design() {
        for yaw in [-3.0, -1.0, 0.0, 0.4, 3.1] {
            assert!((quaternion_yaw(yaw_quaternion(yaw)) - yaw).abs() < 1e-12);
        }
    }

    fn err_of(text: &str, missing: MissingStd) -> JsonError {
        parse_results(p(), text, &mut TokenTable::new(), missing).unwrap_err()
    }

    fn replaced(from: &str, to: &str) -> String {
        assert!(GOOD.contains(from), "{from}");
        GOOD.replace(from, to)
    }

    #[test]
    fn malformed_cases_name_file_sample_and_field() {
        let cases: Vec<(String, Option<&str>, &str)> = vec![
            (
                replaced(
                    r#""translation": [10.0, 20.0, 1.0]"#,
                    r#""translation": [10.0, 20.0]"#,
                ),
                Some("translation"),
                "expected 3 numbers",
            ),
            (
                replaced(r#""translation": [10.0, 20.0, 1.0], "#, ""),
                Some("translation"),
                "missing",
            ),
            (
                replaced(r#""size": [2.0, 4.5, 1.6]"#, r#""size": [2.0, -4.5, 1.6]"#),
                Some("size"),
                "positive",
            ),
            (
                replaced(r#""size": [2.0, 4.5, 1.6]"#, r#""size": [2.0, "x", 1.6]"#),
                Some("size"),
                "element 1",
            ),
            (
                replaced(r#""detection_name": "car""#, r#""detection_name": "lorry""#),
                Some("detection_name"),
                "unknown class 'lorry'",
            ),
            (
                replaced(r#""detection_score": 0.8"#, r#""detection_score": 1.8"#),
                Some("detection_score"),
                "[0, 1]",
            ),
            (
                replaced(
                    r#""rotation": [0.7071067811865476, 0.0, 0.0, 0.7071067811865476]"#,
                    r#""rotation": [0, 0, 0, 0]"#,
                ),
                Some("rotation"),
                "zero",
            ),
            (
                replaced(r#""yaw_std": 0.05"#, r#""yaw_std": -1"#),
                Some("yaw_std"),
                "must lie in",
            ),
            (
                // so small that its inverse overflows: the assignment would see infinite costs
                replaced(r#""yaw_std": 0.05"#, r#""yaw_std": 1e-200"#),
                Some("yaw_std"),
                "must lie in",
            ),
            (
                replaced(
                    r#""translation_std": [0.5, 0.6, 0.7]"#,
                    r#""translation_std": [0.5, 1e9, 0.7]"#,
                ),
                Some("translation_std"),
                "must lie in",
            ),
            (
                replaced(
                    r#""size": [2.0, 4.5, 1.6]"#,
                    r#""size": [2.0, 4500.0, 1.6]"#,
                ),
                Some("size"),
                "between",
            ),
            (
                replaced(
                    r#""translation": [10.0, 20.0, 1.0]"#,
                    r#""translation": [10.0, 2e12, 1.0]"#,
                ),
                Some("translation"),
                "within",
            ),
            (
                // symmetric with a positive diagonal, but not positive definite (eigenvalue -1)
                replaced(
                    r#""yaw_std": 0.05,"#,
                    r#""yaw_std": 0.05, "translation_cov": [1, 2, 0, 2, 1, 0, 0, 0, 1],"#,
                ),
                Some("translation_cov"),
                "positive-definite",
            ),
            (
                replaced(
                    r#""yaw_std": 0.05,"#,
                    r#""yaw_std": 0.05, "translation_cov": [1, 0.5, 0, 0, 1, 0, 0, 0, 1],"#,
                ),
                Some("translation_cov"),
                "symmetric",
            ),
            (
                replaced(r#""sample_token": "s1""#, r#""sample_token": "s9""#),
                Some("sample_token"),
                "does not match",
            ),
            (
                replaced(r#""instance_token": "abc""#, r#""instance_token": 5"#),
                Some("instance_token"),
                "string",
            ),
        ];
        for (text, field, msg) in cases {
            let e = err_of(&text, MissingStd::Error);
            assert_eq!(e.field.as_deref(), field, "{e}");
            assert_eq!(e.sample.as_deref(), Some("s1"), "{e}");
            assert_eq!(e.index, Some(0));
            let shown = e.to_string();
            assert!(shown.contains(msg), "{shown}");
            assert!(
                shown.starts_with("agent1.json: sample 's1', box 0"),
                "{shown}"
            );
        }
    }

    #[test]
    fn velocities_count_with_their_std() {
        let mut t = TokenTable::new();
        let r = parse_results(p(), GOOD, &mut t, MissingStd::Error).unwrap();
        assert_eq!(
            r.samples["s1"][0].velocity, None,
            "velocity without velocity_std"
        );
        let text = replaced(
            r#""velocity": [0, 0]"#,
            r#""velocity": [3.5, -1.25], "velocity_std": [0.3, 0.4]"#,
        );
        let r = parse_results(p(), &text, &mut t, MissingStd::Error).unwrap();
        let v = r.samples["s1"][0].velocity.unwrap();
        assert_eq!((v.v, v.std), ([3.5, -1.25], [0.3, 0.4]));
        let back = results_json(&r, &t).to_string();
        let r2 = parse_results(p(), &back, &mut t, MissingStd::Error).unwrap();
        assert_eq!(r2.samples["s1"][0].velocity, Some(v));
        for (from, to, field) in [
            (
                r#""velocity": [0, 0]"#,
                r#""velocity_std": [0.3, 0.4]"#,
                "velocity",
            ),
            (
                r#""velocity": [0, 0]"#,
                r#""velocity": [300, 0], "velocity_std": [0.3, 0.4]"#,
                "velocity",
            ),
            (
                r#""velocity": [0, 0]"#,
                r#""velocity": [3, 0], "velocity_std": [0, 0.4]"#,
                "velocity_std",
            ),
        ] {
            let e = err_of(&replaced(from, to), MissingStd::Error);
            assert_eq!(e.field.as_deref(), Some(field), "{e}");
        }
    }

    #[test]
    fn a_positive_definite_covariance_is_kept() {
        let text = replaced(
            r#""yaw_std": 0.05,"#,
            r#""yaw_std": 0.05, "translation_cov": [2, 1, 0, 1, 2, 0, 0, 0, 1],"#,
        );
        let r = parse_results(p(), &text, &mut TokenTable::new(), MissingStd::Error).unwrap();
        assert_eq!(
            r.samples["s1"][0].pos_cov,
            Some(Box::new([
                [2.0, 1.0, 0.0],
                [1.0, 2.0, 0.0],
                [0.0, 0.0, 1.0]
            ]))
        );
    }

    #[test]
    fn ids_are_hashes_of_tokens_whatever_the_order() {
        // FNV-1a 32 of "" and "a".
        assert_eq!(stable_id(""), 0x811c_9dc5);
        assert_eq!(stable_id("a"), 0xe40c_292c);
        let tokens = ["4a1d", "b2c3", "ffee01", "a"];
        let mut one = TokenTable::new();
        let mut other = TokenTable::new();
        for t in tokens {
            one.intern(t);
        }
        for t in tokens.iter().rev().take(2) {
            other.intern(t);
        }
        for t in ["a", "ffee01"] {
            assert_eq!(one.get(t), other.get(t), "{t}");
            assert_eq!(one.get(t), Some(stable_id(t)));
            assert_eq!(one.name(stable_id(t)), Some(t));
        }
        // "1aa9" and "25054" share a hash: the second one interned moves on, counted.
        assert_eq!(stable_id("1aa9"), stable_id("25054"));
        let mut t = TokenTable::new();
        assert_eq!(t.intern("1aa9"), 0x0bcd_d871);
        assert_eq!(t.intern("25054"), 0x0bcd_d872);
        assert_eq!(t.intern("1aa9"), 0x0bcd_d871);
        assert_eq!((t.collisions(), t.len()), (1, 2));
        assert_eq!(t.name(0x0bcd_d872), Some("25054"));
    }

    #[test]
    fn instance_ids_without_tokens() {
        let text = replaced(r#""instance_token": "abc""#, r#""instance_id": 42"#);
        let r = parse_results(p(), &text, &mut TokenTable::new(), MissingStd::Error).unwrap();
        assert_eq!(r.samples["s1"][0].id, 42);
        let out = results_json(&r, &TokenTable::new()).to_string();
        assert!(out.contains(r#""instance_id":42"#), "{out}");
        let bad = replaced(r#""instance_token": "abc""#, r#""instance_id": -1"#);
        assert_eq!(
            err_of(&bad, MissingStd::Error).field.as_deref(),
            Some("instance_id")
        );
    }

    #[test]
    fn missing_stds_need_a_default() {
        let text = replaced(r#""yaw_std": 0.05,"#, "");
        let e = err_of(&text, MissingStd::Error);
        assert_eq!(e.field.as_deref(), Some("yaw_std"));
        assert!(e.to_string().contains("--default-std"));
        let r = parse_results(
            p(),
            &text,
            &mut TokenTable::new(),
            MissingStd::Default(Uncertainty::uniform(1.0, 2.0, 3.0)),
        )
        .unwrap();
        assert_eq!(r.samples["s1"][0].std.yaw, 3.0);
        assert_eq!(r.samples["s1"][0].std.pos, [0.5, 0.6, 0.7]);
    }

    #[test]
    fn document_level_errors() {
        assert!(err_of("{", MissingStd::Error)
            .message
            .contains("not valid JSON"));
        assert_eq!(
            err_of(r#"{"meta": {}}"#, MissingStd::Error)
                .field
                .as_deref(),
            Some("results")
        );
        assert!(err_of(r#"{"results": {"s": 3}}"#, MissingStd::Error)
            .message
            .contains("array of boxes"));
        let e = read_results(
            Path::new("/nonexistent/x.json"),
            &mut TokenTable::new(),
            MissingStd::Error,
        )
        .unwrap_err();
        assert!(e
            .to_string()
            .starts_with("/nonexistent/x.json: cannot read"));
    }
}
