//! DAIR-V2X detection results as an agent's input, so that a detector trained with the official
//! code plugs in: per frame, `boxes_3d` (each box as its eight corners in mmdetection3d's order,
//! in the side's own LiDAR frame), `labels_3d` (0 pedestrian, 1 cyclist, 2 car; others are
//! skipped) and `scores_3d`, as the official inference returns them, saved as JSON: a folder of
//! `{frame_id}.json` files, or one file mapping each frame id to its results.
//!
//! mmdetection3d's corners of a box of length l, width w and height h are, in its own frame:
//! (-l/2, -w/2, 0), (-l/2, -w/2, h), (-l/2, +w/2, h), (-l/2, +w/2, 0), then the same four at
//! +l/2; the box is read back from them whatever the library's yaw convention: centre = their
//! mean, sizes = the mean length of each group of parallel edges, heading = the direction of the
//! edges from the back face (the first four) to the front face.

use super::corners::{box_of, CornerBox, CornerError, Corners, EdgeGroups};
use super::{err, number, DairError};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use v2x_protocol::{limits, Class};

/// One detected box in its side's LiDAR frame.
#[derive(Clone, Debug, PartialEq)]
pub struct LocalBox {
    /// The detection class.
    pub class: Class,
    /// Centre (m).
    pub center: [f64; 3],
    /// Length, width, height (m).
    pub size: [f64; 3],
    /// Heading about the LiDAR's z axis (rad).
    pub yaw: f64,
    /// Confidence.
    pub score: f64,
}

/// The class of an official label id.
fn class_of_id(id: i64) -> Option<Class> {
    match id {
        0 => Some(Class::Pedestrian),
        1 => Some(Class::Bicycle),
        2 => Some(Class::Car),
        _ => None,
    }
}

/// The edges of mmdetection3d's corner order: length (back face to front face), width, height.
const MMDET_EDGES: EdgeGroups = [
    [(4, 0), (5, 1), (6, 2), (7, 3)],
    [(3, 0), (2, 1), (6, 5), (7, 4)],
    [(1, 0), (2, 3), (5, 4), (6, 7)],
];

/// A box from mmdetection3d's corners, or why they are not one.
pub fn from_mmdet_corners(c: &Corners) -> Result<CornerBox, CornerError> {
    box_of(c, &MMDET_EDGES)
}

/// One frame's results object.
fn frame_boxes(path: &Path, frame: &str, v: &Value) -> Result<Vec<LocalBox>, DairError> {
    let fail =
        |field: &str, what: String| err(path, format!("frame {frame}: field '{field}': {what}"));
    let list = |field: &str| -> Result<&Vec<Value>, DairError> {
        v.get(field)
            .and_then(Value::as_array)
            .ok_or_else(|| fail(field, "expected an array".into()))
    };
    let (boxes, labels, scores) = (list("boxes_3d")?, list("labels_3d")?, list("scores_3d")?);
    if labels.len() != boxes.len() || scores.len() != boxes.len() {
        return Err(fail(
            "labels_3d",
            format!(
                "{} boxes, {} labels and {} scores: expected one of each per box",
                boxes.len(),
                labels.len(),
                scores.len()
            ),
        ));
    }
    let mut out = Vec::new();
    for (i, b) in boxes.iter().enumerate() {
        let label = number(&labels[i]).filter(|x| x.fract() == 0.0);
        let Some(label) = label else {
            return Err(fail("labels_3d", format!("box {i}: expected an integer")));
        };
        let score = number(&scores[i])
            .ok_or_else(|| fail("scores_3d", format!("box {i}: expected a number")))?;
        // The official pipeline pads a frame without boxes with one of score -2333 and label -1.
        let Some(class) = class_of_id(label as i64) else {
            continue;
        };
        if !(0.0..=1.0).contains(&score) {
            return Err(fail(
                "scores_3d",
                format!("box {i}: {score} is not in [0, 1]"),
            ));
        }
        let mut v = Vec::new();
        if !super::flat(b, &mut v) || v.len() != 24 {
            return Err(fail(
                "boxes_3d",
                format!("box {i}: expected 8 corners of 3 numbers"),
            ));
        }
        let c: Corners = std::array::from_fn(|p| [v[3 * p], v[3 * p + 1], v[3 * p + 2]]);
        let CornerBox { center, size, yaw } = from_mmdet_corners(&c).map_err(|e| {
            fail(
                "boxes_3d",
                format!("box {i}: {e} (in mmdetection3d's corner order)"),
            )
        })?;
        if size.iter().any(|s| !limits::size_in_range(*s)) {
            return Err(fail(
                "boxes_3d",
                format!("box {i}: sizes {size:?} out of range"),
            ));
        }
        out.push(LocalBox {
            class,
            center,
            size,
            yaw,
            score,
        });
    }
    Ok(out)
}

/// Reads detection results: a folder of `{frame_id}.json`, or one JSON object by frame id.
pub fn read_results(path: &Path) -> Result<BTreeMap<String, Vec<LocalBox>>, DairError> {
    let mut out = BTreeMap::new();
    if path.is_dir() {
        let entries =
            std::fs::read_dir(path).map_err(|e| err(path, format!("cannot list: {e}")))?;
        for e in entries {
            let p = e
                .map_err(|e| err(path, format!("cannot list: {e}")))?
                .path();
            if p.extension().and_then(|x| x.to_str()) != Some("json") {
                continue;
            }
            let frame = p
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("")
                .to_string();
            let f = super::File::read(p.clone())?;
            out.insert(frame.clone(), frame_boxes(&p, &frame, &f.value)?);
        }
        return Ok(out);
    }
    let f = super::File::read(path.to_path_buf())?;
    let Some(frames) = f.value.as_object() else {
        return Err(err(path, "expected an object mapping each frame id to its results, or a folder of {frame_id}.json"));
    };
    for (frame, v) in frames {
        out.insert(frame.clone(), frame_boxes(path, frame, v)?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// mmdetection3d's corners of a box, written out by hand for yaw 0 and turned by `yaw`.
    fn mmdet(center: [f64; 3], [l, w, h]: [f64; 3], yaw: f64) -> Corners {
        let local = [
            [-l / 2.0, -w / 2.0, 0.0],
            [-l / 2.0, -w / 2.0, h],
            [-l / 2.0, w / 2.0, h],
            [-l / 2.0, w / 2.0, 0.0],
            [l / 2.0, -w / 2.0, 0.0],
            [l / 2.0, -w / 2.0, h],
            [l / 2.0, w / 2.0, h],
            [l / 2.0, w / 2.0, 0.0],
        ];
        let (s, c) = yaw.sin_cos();
        local.map(|[x, y, z]| {
            [
                center[0] + c * x - s * y,
                center[1] + s * x + c * y,
                center[2] - h / 2.0 + z,
            ]
        })
    }

    #[test]
    fn a_box_comes_back_from_its_mmdetection3d_corners() {
        let CornerBox { center, size, yaw } =
            from_mmdet_corners(&mmdet([5.0, -2.0, -1.0], [4.2, 1.8, 1.5], 0.4)).unwrap();
        assert!(center
            .iter()
            .zip([5.0, -2.0, -1.0])
            .all(|(a, b)| (a - b).abs() < 1e-12));
        assert!(size
            .iter()
            .zip([4.2, 1.8, 1.5])
            .all(|(a, b)| (a - b).abs() < 1e-12));
        assert!((yaw - 0.4).abs() < 1e-12);
        let mut bad = mmdet([0.0; 3], [4.0, 2.0, 1.5], 0.0);
        bad[6][0] += 2.0;
        assert!(from_mmdet_corners(&bad).is_err());
    }

    #[test]
    fn results_files_are_read_by_frame_and_checked() {
        let dir = std::env::temp_dir().join(format!("dair-results-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let pad = [[0.0f64; 3]; 8];
        let frame = serde_json::json!({
            "boxes_3d": [mmdet([10.0, 0.0, -1.0], [4.5, 1.9, 1.6], 0.0), pad],
            "labels_3d": [2, -1],
            "scores_3d": [0.8, -2333],
        });
        std::fs::write(dir.join("000010.json"), frame.to_string()).unwrap();
        let r = read_results(&dir).unwrap();
        assert_eq!(
            r["000010"].len(),
            1,
            "the official empty-frame pad is skipped"
        );
        assert_eq!(r["000010"][0].class, Class::Car);
        assert_eq!(r["000010"][0].score, 0.8);
        let one = dir.join("all.json");
        let mut bad = frame.clone();
        bad["scores_3d"] = serde_json::json!([0.8]);
        std::fs::write(&one, serde_json::json!({ "000011": bad }).to_string()).unwrap();
        let e = read_results(&one).unwrap_err().to_string();
        assert!(
            e.contains("all.json") && e.contains("frame 000011") && e.contains("labels_3d"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
