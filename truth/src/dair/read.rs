//! Reading DAIR-V2X's JSON files: records and fields with errors naming the file, the record
//! and the field; calibration files into poses; label files into checked boxes.

use super::*;

/// A JSON file being read, for errors that name it.
pub(super) struct File {
    pub(super) path: PathBuf,
    pub(super) value: Value,
}

impl File {
    pub(super) fn read(path: PathBuf) -> Result<File, DairError> {
        let text =
            std::fs::read_to_string(&path).map_err(|e| err(&path, format!("cannot read: {e}")))?;
        let value =
            serde_json::from_str(&text).map_err(|e| err(&path, format!("not valid JSON: {e}")))?;
        Ok(File { path, value })
    }

    pub(super) fn records(&self) -> Result<&Vec<Value>, DairError> {
        self.value
            .as_array()
            .ok_or_else(|| err(&self.path, "expected a JSON array of records"))
    }

    pub(super) fn fail(
        &self,
        at: Option<usize>,
        field: &str,
        what: impl std::fmt::Display,
    ) -> DairError {
        match at {
            Some(i) => err(&self.path, format!("record {i}: field '{field}': {what}")),
            None => err(&self.path, format!("field '{field}': {what}")),
        }
    }
}

/// A number, or a string holding one (DAIR-V2X writes both).
pub(super) fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Number(n) => n.as_f64(),
        Value::String(s) => s.trim().parse().ok(),
        _ => None,
    }
    .filter(|x: &f64| x.is_finite())
}

pub(super) fn field<'a>(
    f: &File,
    rec: &'a Value,
    at: Option<usize>,
    name: &str,
) -> Result<&'a Value, DairError> {
    rec.get(name).ok_or_else(|| f.fail(at, name, "missing"))
}

pub(super) fn num(f: &File, rec: &Value, at: Option<usize>, name: &str) -> Result<f64, DairError> {
    number(field(f, rec, at, name)?).ok_or_else(|| f.fail(at, name, "expected a finite number"))
}

pub(super) fn text<'a>(
    f: &File,
    rec: &'a Value,
    at: Option<usize>,
    name: &str,
) -> Result<&'a str, DairError> {
    field(f, rec, at, name)?
        .as_str()
        .ok_or_else(|| f.fail(at, name, "expected a string"))
}

/// An id or a path's file stem (`velodyne/000123.pcd` -> `000123`); numbers are accepted.
pub(super) fn id_of(
    f: &File,
    rec: &Value,
    at: Option<usize>,
    name: &str,
) -> Result<String, DairError> {
    let v = field(f, rec, at, name)?;
    let s = match v {
        Value::String(s) => s.clone(),
        Value::Number(n) => n.to_string(),
        _ => return Err(f.fail(at, name, "expected a string")),
    };
    let stem = Path::new(&s)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("")
        .to_string();
    if stem.is_empty() {
        return Err(f.fail(at, name, "is empty"));
    }
    Ok(stem)
}

/// All numbers of a (possibly nested) array, flattened.
pub(super) fn flat(v: &Value, out: &mut Vec<f64>) -> bool {
    match v {
        Value::Array(items) => items.iter().all(|x| flat(x, out)),
        other => number(other).map(|x| out.push(x)).is_some(),
    }
}

/// A calibration file's transform: `rotation` (3x3) and `translation` (3, flat or as a column),
/// at the top level or under `key`.
pub(super) fn read_pose(path: PathBuf, key: Option<&str>) -> Result<(Pose, File), DairError> {
    let f = File::read(path)?;
    let rec = match key {
        Some(k) => field(&f, &f.value, None, k)?,
        None => &f.value,
    };
    let mut r = Vec::new();
    let mut t = Vec::new();
    if !flat(field(&f, rec, None, "rotation")?, &mut r) || r.len() != 9 {
        return Err(f.fail(None, "rotation", "expected a 3x3 matrix of numbers"));
    }
    if !flat(field(&f, rec, None, "translation")?, &mut t) || t.len() != 3 {
        return Err(f.fail(None, "translation", "expected 3 numbers"));
    }
    let pose = Pose {
        rotation: std::array::from_fn(|i| std::array::from_fn(|j| r[3 * i + j])),
        translation: [t[0], t[1], t[2]],
    };
    if pose.inverse().is_none() {
        return Err(f.fail(None, "rotation", "is singular"));
    }
    Ok((pose, f))
}

/// The detection class of a DAIR-V2X object type, if it is scored.
pub fn class_of(kind: &str) -> Option<Class> {
    Some(match kind.to_ascii_lowercase().as_str() {
        "car" | "van" => Class::Car,
        "truck" => Class::Truck,
        "bus" => Class::Bus,
        "pedestrian" => Class::Pedestrian,
        "cyclist" => Class::Bicycle,
        "motorcyclist" | "tricyclist" => Class::Motorcycle,
        "trafficcone" => Class::TrafficCone,
        _ => return None,
    })
}

/// One label of a label file.
pub(super) struct Label {
    pub(super) class: Class,
    pub(super) center: [f64; 3],
    pub(super) size: [f64; 3],
    pub(super) yaw: f64,
    pub(super) track: Option<String>,
}

/// The labels of one file, in its frame; `world` reads `world_8_points` when a record has them,
/// and counts in `mismatched` the records whose `3d_location` and `3d_dimensions` disagree with
/// their corners by more than 10 cm (the corners are used, as the official evaluation does).
pub(super) fn read_labels(
    path: PathBuf,
    world: bool,
    skipped: &mut BTreeMap<String, usize>,
    mismatched: &mut usize,
) -> Result<Vec<Label>, DairError> {
    let f = File::read(path)?;
    let mut out = Vec::new();
    for (i, rec) in f.records()?.iter().enumerate() {
        let at = Some(i);
        let kind = text(&f, rec, at, "type")?;
        let Some(class) = class_of(kind) else {
            *skipped.entry(kind.to_string()).or_default() += 1;
            continue;
        };
        let track = match rec.get("track_id") {
            Some(Value::String(s)) => Some(s.clone()),
            Some(Value::Number(n)) => Some(n.to_string()),
            _ => None,
        };
        let corners = match (world, rec.get("world_8_points")) {
            (true, Some(points)) => {
                let mut v = Vec::new();
                if !flat(points, &mut v) || v.len() != 24 {
                    return Err(f.fail(at, "world_8_points", "expected 8 points of 3 numbers"));
                }
                let c: Corners = std::array::from_fn(|p| [v[3 * p], v[3 * p + 1], v[3 * p + 2]]);
                Some(from_corners(&c).map_err(|e| f.fail(at, "world_8_points", e))?)
            }
            _ => None,
        };
        let described = ["3d_location", "3d_dimensions", "rotation"]
            .iter()
            .all(|k| rec.get(*k).is_some());
        let fields = if corners.is_none() || described {
            Some(label_fields(&f, rec, at)?)
        } else {
            None
        };
        let b = match (corners, fields) {
            (Some(b), Some(g)) => {
                let off = (0..3)
                    .map(|k| (b.center[k] - g.center[k]).abs())
                    .fold(0.0, f64::max);
                let size = (0..3)
                    .map(|k| (b.size[k] - g.size[k]).abs())
                    .fold(0.0, f64::max);
                if off > 0.1 || size > 0.1 {
                    *mismatched += 1;
                }
                b
            }
            (Some(b), None) | (None, Some(b)) => b,
            (None, None) => unreachable!("one of the two is read"),
        };
        if b.size.contains(&0.0) {
            continue;
        }
        check_box(&f, at, b.center, b.size)?;
        out.push(Label {
            class,
            center: b.center,
            size: b.size,
            yaw: b.yaw,
            track,
        });
    }
    Ok(out)
}

/// A record's box from `3d_location` (the centre), `3d_dimensions` and `rotation`.
pub(super) fn label_fields(
    f: &File,
    rec: &Value,
    at: Option<usize>,
) -> Result<CornerBox, DairError> {
    let dims = field(f, rec, at, "3d_dimensions")?;
    let loc = field(f, rec, at, "3d_location")?;
    Ok(CornerBox {
        size: [
            num(f, dims, at, "l")?,
            num(f, dims, at, "w")?,
            num(f, dims, at, "h")?,
        ],
        center: [
            num(f, loc, at, "x")?,
            num(f, loc, at, "y")?,
            num(f, loc, at, "z")?,
        ],
        yaw: num(f, rec, at, "rotation")?,
    })
}

pub(super) fn check_box(
    f: &File,
    at: Option<usize>,
    center: [f64; 3],
    size: [f64; 3],
) -> Result<(), DairError> {
    if size.iter().any(|s| !limits::size_in_range(*s)) {
        return Err(f.fail(
            at,
            "3d_dimensions",
            format!(
                "sizes must lie between {} and {} m, got {size:?}",
                limits::SIZE_MIN,
                limits::SIZE_MAX
            ),
        ));
    }
    if center.iter().any(|c| c.abs() > limits::COORD_MAX) {
        return Err(f.fail(at, "3d_location", "coordinates must lie within 1e9 m"));
    }
    Ok(())
}
