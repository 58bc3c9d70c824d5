//! The KITTI tracking text layouts as AB3DMOT reads and writes them, in which V2V4Real's
//! detections, fused references and tracking labels are published: one `NNNN.txt` per
//! sequence, one row per box.
//!
//! - A detection row (AB3DMOT's input) has 15 comma-separated fields:
//!   `frame,type,x1,y1,x2,y2,score,h,w,l,x,y,z,ry,alpha`, `type` 1 pedestrian, 2 car, 3 cyclist;
//!   the 2D box and `alpha` are unused (written as 0).
//! - A label or tracking row has 17 space-separated fields, `frame id type truncated occluded
//!   alpha x1 y1 x2 y2 h w l x y z ry`, and a tracker's output an 18th, the score; `type` is a
//!   name (`Car`, `Van`, `Pedestrian`, ...), and `DontCare` rows (id -1) are skipped.
//! - The seqmap lists each sequence scored: `NNNN empty FIRST LAST` (frames, inclusive).
//!
//! Box convention, as V2V4Real's exporter writes it: `h w l` are the height, width and length,
//! `x` is the LiDAR's x, `y` the LiDAR's z of the box centre and `z` the LiDAR's y (y and z
//! swapped), and `ry` the yaw about the LiDAR's z axis, 0 along +x with the length along the
//! heading. Every box is in the ego car's LiDAR frame; frames are 10 Hz apart.
//!
//! Read into results ([`read_detection_dir`]), frame `f` of sequence `NNNN` is the sample
//! [`token`]`(NNNN, f)` captured at [`capture_us`]`(NNNN, f)`: sequences lie 1,000 s apart, so
//! no fusion window or track spans two of them.

use crate::nuscenes_json::{default_meta, Results};
use crate::{limits, wrap_angle, Class, Detection, Uncertainty, NO_ID};
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

mod write;
pub use write::{write_detection_dir, write_track_dir};

/// Time between frames (us): 10 Hz.
pub const FRAME_US: u64 = 100_000;
/// Time between the starts of two sequences (us): 1,000 s, 10,000 frames.
pub const SEQUENCE_US: u64 = 1_000_000_000;

/// A problem with a KITTI-layout file, located by file, line and field.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiError {
    /// The file or folder.
    pub file: PathBuf,
    /// The line (from 1), if any.
    pub line: Option<usize>,
    /// The field, if any.
    pub field: Option<&'static str>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for KittiError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ", line {l}")?;
        }
        if let Some(field) = self.field {
            write!(f, ", field '{field}'")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for KittiError {}

/// A row's problem before it is placed in a file: the field and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct RowError {
    /// The field, if one is at fault.
    pub field: Option<&'static str>,
    /// What is wrong.
    pub message: String,
}

impl RowError {
    fn at(self, file: &Path, line: usize) -> KittiError {
        KittiError {
            file: file.to_path_buf(),
            line: Some(line),
            field: self.field,
            message: self.message,
        }
    }
}

fn field_err(field: &'static str, message: impl Into<String>) -> RowError {
    RowError {
        field: Some(field),
        message: message.into(),
    }
}

/// The sample token of frame `frame` of sequence `seq`: `SSSS_FFFFFF`.
pub fn token(seq: u32, frame: u32) -> String {
    format!("{seq:04}_{frame:06}")
}

/// The sequence and frame a [`token`] names.
pub fn parse_token(token: &str) -> Option<(u32, u32)> {
    let (s, f) = token.split_once('_')?;
    let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    (digits(s) && digits(f)).then_some((s.parse().ok()?, f.parse().ok()?))
}

/// The capture time of frame `frame` of sequence `seq` (us).
pub fn capture_us(seq: u32, frame: u32) -> u64 {
    seq as u64 * SEQUENCE_US + frame as u64 * FRAME_US
}

/// AB3DMOT's type index of a detection row.
fn class_of_index(i: u32) -> Option<Class> {
    match i {
        1 => Some(Class::Pedestrian),
        2 => Some(Class::Car),
        3 => Some(Class::Bicycle),
        _ => None,
    }
}

/// The class of a label's type name (`None`: not an object class, such as `DontCare`).
pub fn class_of_name(name: &str) -> Option<Class> {
    match name {
        "Car" | "Van" => Some(Class::Car),
        "Truck" => Some(Class::Truck),
        "Pedestrian" | "Person_sitting" => Some(Class::Pedestrian),
        "Cyclist" => Some(Class::Bicycle),
        _ => None,
    }
}

/// The type index and name a class is written with (`None`: the layout has no such type).
pub fn kitti_type(class: Class) -> Option<(u32, &'static str)> {
    match class {
        Class::Car => Some((2, "Car")),
        Class::Pedestrian => Some((1, "Pedestrian")),
        Class::Bicycle => Some((3, "Cyclist")),
        _ => None,
    }
}

/// A box of a row: where it is, how large, which way it faces (LiDAR frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KittiBox {
    /// Centre x, y, z in the ego car's LiDAR frame (m).
    pub center: [f64; 3],
    /// Length, width, height (m).
    pub size: [f64; 3],
    /// Yaw about +z (rad), wrapped to (-pi, pi].
    pub yaw: f64,
}

impl KittiBox {
    /// The seven columns `h w l x y z ry` of the layout.
    pub fn columns(&self) -> [f64; 7] {
        let [x, y, z] = self.center;
        let [l, w, h] = self.size;
        [h, w, l, x, z, y, self.yaw]
    }

    /// The box of the seven columns `h w l x y z ry`, validated.
    fn from_columns(c: &[f64; 7]) -> Result<KittiBox, RowError> {
        let [h, w, l, x, y, z, ry] = *c;
        for (name, v) in [("h", h), ("w", w), ("l", l)] {
            if !limits::size_in_range(v) {
                return Err(field_err(
                    name,
                    format!(
                        "size {v} m is outside {}..{} m",
                        limits::SIZE_MIN,
                        limits::SIZE_MAX
                    ),
                ));
            }
        }
        for (name, v) in [("x", x), ("y", y), ("z", z)] {
            if !limits::coord_in_range(v) {
                return Err(field_err(
                    name,
                    format!("coordinate {v} is not finite or too large"),
                ));
            }
        }
        if !ry.is_finite() {
            return Err(field_err("ry", format!("yaw {ry} is not finite")));
        }
        Ok(KittiBox {
            center: [x, z, y],
            size: [l, w, h],
            yaw: wrap_angle(ry),
        })
    }
}

fn number<T: std::str::FromStr>(text: &str, field: &'static str) -> Result<T, RowError> {
    text.trim()
        .parse()
        .map_err(|_| field_err(field, format!("'{text}' is not a number of the right kind")))
}

fn columns(fields: &[&str], names: &[&'static str; 7]) -> Result<[f64; 7], RowError> {
    let mut c = [0.0; 7];
    for (k, (t, name)) in fields.iter().zip(names).enumerate() {
        c[k] = number(t, name)?;
    }
    Ok(c)
}

const BOX_FIELDS: [&str; 7] = ["h", "w", "l", "x", "y", "z", "ry"];

fn score_of(text: &str) -> Result<f64, RowError> {
    let s: f64 = number(text, "score")?;
    if !(0.0..=1.0).contains(&s) {
        return Err(field_err("score", format!("score {s} is outside 0..1")));
    }
    Ok(s)
}

/// One detection row.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectionRow {
    /// The frame within its sequence.
    pub frame: u32,
    /// The class.
    pub class: Class,
    /// The confidence in 0..1.
    pub score: f64,
    /// The box.
    pub bbox: KittiBox,
}

impl DetectionRow {
    /// Parses one comma-separated detection row.
    pub fn parse(line: &str) -> Result<DetectionRow, RowError> {
        let f: Vec<&str> = line.trim().split(',').collect();
        if f.len() != 15 {
            return Err(RowError {
                field: None,
                message: format!(
                    "a detection row has 15 comma-separated fields \
                     (frame,type,x1,y1,x2,y2,score,h,w,l,x,y,z,ry,alpha), this one {}",
                    f.len()
                ),
            });
        }
        let frame = number(f[0], "frame")?;
        let ty: u32 = number(f[1], "type")?;
        let class = class_of_index(ty).ok_or_else(|| {
            field_err(
                "type",
                format!("type {ty} is not 1 (pedestrian), 2 (car) or 3 (cyclist)"),
            )
        })?;
        let score = score_of(f[6])?;
        let c = columns(&f[7..14], &BOX_FIELDS)?;
        Ok(DetectionRow {
            frame,
            class,
            score,
            bbox: KittiBox::from_columns(&c)?,
        })
    }

    /// The row as the layout writes it.
    pub fn write(&self) -> String {
        let ty = kitti_type(self.class).map_or(2, |t| t.0);
        let c = self.bbox.columns().map(|v| v.to_string()).join(",");
        format!("{},{ty},0,0,0,0,{},{c},0", self.frame, self.score)
    }

    /// The row as a detection with the given stds (the layout states none).
    pub fn detection(&self, std: Uncertainty) -> Detection {
        Detection {
            class: self.class,
            center: self.bbox.center,
            size: self.bbox.size,
            yaw: self.bbox.yaw,
            score: self.score,
            std,
            pos_cov: None,
            velocity: None,
            id: NO_ID,
        }
    }
}

/// One label or tracking row.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackRow {
    /// The frame within its sequence.
    pub frame: u32,
    /// The track id.
    pub id: u32,
    /// The class.
    pub class: Class,
    /// The box.
    pub bbox: KittiBox,
    /// The score, for a tracker's output (labels have none).
    pub score: Option<f64>,
}

impl TrackRow {
    /// Parses one space-separated label or tracking row; `None` for a row that is no object
    /// (`DontCare`, or a type the layout scores as none).
    pub fn parse(line: &str) -> Result<Option<TrackRow>, RowError> {
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() != 17 && f.len() != 18 {
            return Err(RowError {
                field: None,
                message: format!(
                    "a label row has 17 space-separated fields (frame id type truncated \
                     occluded alpha x1 y1 x2 y2 h w l x y z ry), a tracking row 18 (then score), \
                     this one {}",
                    f.len()
                ),
            });
        }
        let frame = number(f[0], "frame")?;
        let Some(class) = class_of_name(f[2]) else {
            return Ok(None);
        };
        let id: i64 = number(f[1], "id")?;
        let id = u32::try_from(id)
            .ok()
            .filter(|&i| i != NO_ID)
            .ok_or_else(|| field_err("id", format!("track id {id} is not in 0..{NO_ID}")))?;
        let c = columns(&f[10..17], &BOX_FIELDS)?;
        let score = f.get(17).map(|s| score_of(s)).transpose()?;
        Ok(Some(TrackRow {
            frame,
            id,
            class,
            bbox: KittiBox::from_columns(&c)?,
            score,
        }))
    }

    /// The row as the layout writes it (with the score when there is one).
    pub fn write(&self) -> String {
        let name = kitti_type(self.class).map_or("Car", |t| t.1);
        let c = self.bbox.columns().map(|v| v.to_string()).join(" ");
        let mut row = format!("{} {} {name} 0 0 0 0 0 0 0 {c}", self.frame, self.id);
        if let Some(s) = self.score {
            row.push_str(&format!(" {s}"));
        }
        row
    }
}

/// Parses every non-empty line of a file with `parse`, placing errors at their line.
fn rows<T>(
    path: &Path,
    text: &str,
    parse: impl Fn(&str) -> Result<Option<T>, RowError>,
) -> Result<Vec<T>, KittiError> {
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        if let Some(r) = parse(line).map_err(|e| e.at(path, k + 1))? {
            out.push(r);
        }
    }
    Ok(out)
}

fn read_text(path: &Path) -> Result<String, KittiError> {
    std::fs::read_to_string(path).map_err(|e| KittiError {
        file: path.to_path_buf(),
        line: None,
        field: None,
        message: format!("cannot read: {e}"),
    })
}

/// The detection rows of one sequence file.
pub fn parse_detections(path: &Path, text: &str) -> Result<Vec<DetectionRow>, KittiError> {
    rows(path, text, |l| DetectionRow::parse(l).map(Some))
}

/// The object rows of one label or tracking file.
pub fn parse_tracks(path: &Path, text: &str) -> Result<Vec<TrackRow>, KittiError> {
    rows(path, text, TrackRow::parse)
}

/// The object rows of one label or tracking file on disk.
pub fn read_tracks(path: &Path) -> Result<Vec<TrackRow>, KittiError> {
    parse_tracks(path, &read_text(path)?)
}

/// One sequence of a seqmap: its name (`NNNN`) and its first and last frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SeqmapEntry {
    /// The sequence number.
    pub seq: u32,
    /// The first frame.
    pub first: u32,
    /// The last frame (inclusive).
    pub last: u32,
}

/// Parses a seqmap: `NNNN empty FIRST LAST` per line.
pub fn parse_seqmap(path: &Path, text: &str) -> Result<Vec<SeqmapEntry>, KittiError> {
    rows(path, text, |line| {
        let f: Vec<&str> = line.split_whitespace().collect();
        if f.len() != 4 {
            return Err(RowError {
                field: None,
                message: format!(
                    "a seqmap row has 4 fields (NNNN empty FIRST LAST), this one {}",
                    f.len()
                ),
            });
        }
        let e = SeqmapEntry {
            seq: number(f[0], "sequence")?,
            first: number(f[2], "first")?,
            last: number(f[3], "last")?,
        };
        if e.last < e.first {
            return Err(field_err("last", "the last frame is before the first"));
        }
        Ok(Some(e))
    })
}

/// Reads a seqmap file.
pub fn read_seqmap(path: &Path) -> Result<Vec<SeqmapEntry>, KittiError> {
    parse_seqmap(path, &read_text(path)?)
}

/// The sequence files of a folder (`NNNN.txt`), by sequence number; other files are ignored.
pub fn sequence_files(dir: &Path) -> Result<BTreeMap<u32, PathBuf>, KittiError> {
    let err = |message: String| KittiError {
        file: dir.to_path_buf(),
        line: None,
        field: None,
        message,
    };
    let entries = std::fs::read_dir(dir).map_err(|e| err(format!("cannot list: {e}")))?;
    let mut out = BTreeMap::new();
    for e in entries {
        let path = e.map_err(|e| err(format!("cannot list: {e}")))?.path();
        let seq = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_suffix(".txt"))
            .filter(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|s| s.parse::<u32>().ok());
        if let Some(seq) = seq {
            out.insert(seq, path);
        }
    }
    if out.is_empty() {
        return Err(err(
            "holds no sequence files (NNNN.txt, one row per box)".into()
        ));
    }
    Ok(out)
}

/// A folder of detection files as results: each frame with a box is a sample ([`token`]), with
/// its capture time in `meta.v2x_timestamps`; every box takes `std`.
pub fn read_detection_dir(dir: &Path, std: Uncertainty) -> Result<Results, KittiError> {
    let mut results = Results {
        meta: default_meta(),
        ..Default::default()
    };
    let mut times = serde_json::Map::new();
    for (seq, path) in sequence_files(dir)? {
        for r in parse_detections(&path, &read_text(&path)?)? {
            let t = token(seq, r.frame);
            if !results.samples.contains_key(&t) {
                times.insert(t.clone(), capture_us(seq, r.frame).into());
                results.order.push(t.clone());
            }
            results.samples.entry(t).or_default().push(r.detection(std));
        }
    }
    results.meta["v2x_timestamps"] = serde_json::Value::Object(times);
    Ok(results)
}

#[cfg(test)]
mod tests;
