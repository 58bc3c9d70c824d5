//! V2V4Real's real detections of two cars, as published in the AB3DMOT KITTI layout
//! ([`v2x_protocol::kitti`]): per-car detector output, the labels with track ids, and the
//! dataset's fused references where present. Everything is in the ego car's LiDAR frame.
//!
//! The layout below `ROOT` (an `AB3DMOT/` folder), for a split `S` (`train` or `val`, the
//! latter being V2V4Real's test split):
//! - `data/v2v4real/detection/multi_sensor_differentiable_kalman_filter_Car_S/{ego,1}/`: each
//!   car's own detections, one `NNNN.txt` per sequence;
//! - `data/v2v4real/detection/{late_fusion,cobevt}_Car_S/`: the dataset's fused references
//!   (optional: only some splits have them);
//! - `scripts/KITTI/v2v4real_S_label/` and `scripts/KITTI/v2v4real_S_evaluate_tracking.seqmap.val`:
//!   the labels and the frames of each sequence.

use crate::dataset::{GroundTruth, GtFrame, GtObject, Motion, Recorded};
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use v2x_protocol::kitti::{self, KittiError};
use v2x_protocol::nuscenes_json::Results;
use v2x_protocol::{Detection, Uncertainty, UnknownName};

/// The two cars, in input order: the ego car and the other car.
pub const CARS: [&str; 2] = ["ego", "1"];

/// The fused references the dataset publishes, by folder prefix and row name.
pub const REFERENCES: [(&str, &str); 2] = [
    ("late_fusion", "dataset late fusion"),
    ("cobevt", "CoBEVT (feature fusion)"),
];

/// One of the published splits.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Split {
    /// The training split: develop and tune here.
    #[default]
    Train,
    /// V2V4Real's test split (named `val` in the published folders).
    Val,
}

impl Split {
    /// The folder name.
    pub fn name(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Val => "val",
        }
    }
}

impl std::str::FromStr for Split {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, UnknownName> {
        match s {
            "train" => Ok(Split::Train),
            "val" | "test" => Ok(Split::Val),
            _ => Err(UnknownName::new("split", s, ["train", "val"])),
        }
    }
}

impl fmt::Display for Split {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One frame of a sequence.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct FrameRef {
    /// The sequence.
    pub seq: u32,
    /// The frame within it.
    pub frame: u32,
}

impl FrameRef {
    /// The sample token the KITTI readers give this frame.
    pub fn token(self) -> String {
        kitti::token(self.seq, self.frame)
    }

    /// The frame's capture time (us), 10 Hz within a sequence.
    pub fn capture_us(self) -> u64 {
        kitti::capture_us(self.seq, self.frame)
    }
}

/// A split loaded: every frame of the seqmap, in order, with its labels, each car's
/// detections and the references.
#[derive(Clone, Debug)]
pub struct V2v4real {
    /// The split.
    pub split: Split,
    /// Every frame scored, sequence by sequence.
    pub frames: Vec<FrameRef>,
    /// The labels of each frame (ids are the labels' track ids).
    pub gt: Vec<Vec<Detection>>,
    /// Each car's detections per frame ([`CARS`] order).
    pub cars: [Vec<Vec<Detection>>; 2],
    /// The references present, by row name, with their boxes per frame.
    pub references: Vec<(String, Vec<Vec<Detection>>)>,
}

/// Where a split's files lie below the root.
pub struct Paths {
    /// Each car's detection folder.
    pub cars: [PathBuf; 2],
    /// The label folder.
    pub labels: PathBuf,
    /// The seqmap.
    pub seqmap: PathBuf,
    /// The reference folders, present or not, as [`REFERENCES`].
    pub references: [PathBuf; 2],
}

impl Paths {
    /// The published layout of `split` below `root`.
    pub fn new(root: &Path, split: Split) -> Paths {
        let det = root.join("data/v2v4real/detection");
        let s = split.name();
        let cars_dir = det.join(format!("multi_sensor_differentiable_kalman_filter_Car_{s}"));
        let kitti = root.join("scripts/KITTI");
        Paths {
            cars: CARS.map(|c| cars_dir.join(c)),
            labels: kitti.join(format!("v2v4real_{s}_label")),
            seqmap: kitti.join(format!("v2v4real_{s}_evaluate_tracking.seqmap.val")),
            references: REFERENCES.map(|(r, _)| det.join(format!("{r}_Car_{s}"))),
        }
    }
}

/// Each frame's index by its sample token.
fn frame_index(frames: &[FrameRef]) -> BTreeMap<String, usize> {
    frames
        .iter()
        .enumerate()
        .map(|(i, f)| (f.token(), i))
        .collect()
}

/// Boxes of a results set placed on the frames (boxes of frames not listed are dropped).
fn per_frame(results: Results, index: &BTreeMap<String, usize>) -> Vec<Vec<Detection>> {
    let mut out = vec![Vec::new(); index.len()];
    for (token, dets) in results.samples {
        if let Some(&i) = index.get(&token) {
            out[i] = dets;
        }
    }
    out
}

/// Loads `split` below `root` (the `AB3DMOT/` folder), the cars' boxes with `std`.
pub fn load(root: &Path, split: Split, std: Uncertainty) -> Result<V2v4real, KittiError> {
    let p = Paths::new(root, split);
    if !p.seqmap.is_file() {
        return Err(KittiError {
            file: p.seqmap.clone(),
            line: None,
            field: None,
            message: format!(
                "no seqmap: --dataroot must be the AB3DMOT/ folder of a DMSTrack checkout \
                 (it holds data/v2v4real/ and scripts/KITTI/), with the {split} split"
            ),
        });
    }
    let seqmap = kitti::read_seqmap(&p.seqmap)?;
    let frames: Vec<FrameRef> = seqmap
        .iter()
        .flat_map(|e| (e.first..=e.last).map(move |frame| FrameRef { seq: e.seq, frame }))
        .collect();
    let index = frame_index(&frames);
    let mut gt = vec![Vec::new(); frames.len()];
    for e in &seqmap {
        let path = p.labels.join(format!("{:04}.txt", e.seq));
        for row in kitti::read_tracks(&path)? {
            if let Some(&i) = index.get(&kitti::token(e.seq, row.frame)) {
                gt[i].push(Detection {
                    id: row.id,
                    ..kitti::DetectionRow {
                        frame: row.frame,
                        class: row.class,
                        score: 1.0,
                        bbox: row.bbox,
                    }
                    .detection(Uncertainty::uniform(0.0, 0.0, 0.0))
                });
            }
        }
    }
    let read = |dir: &Path| kitti::read_detection_dir(dir, std).map(|r| per_frame(r, &index));
    let cars = [read(&p.cars[0])?, read(&p.cars[1])?];
    let mut references = Vec::new();
    for ((_, name), dir) in REFERENCES.iter().zip(&p.references) {
        if dir.is_dir() {
            references.push((name.to_string(), read(dir)?));
        }
    }
    Ok(V2v4real {
        split,
        frames,
        gt,
        cars,
        references,
    })
}

/// Time between two sequences when the split is replayed in one go (us): longer than any window
/// and than a tracker's largest gap, short enough that a replay does not wait.
pub const SEQUENCE_GAP_US: u64 = 3_000_000;

/// Both cars as recorded agents: each frame's replay time and each car's boxes.
#[derive(Debug)]
struct Recording {
    times: Vec<u64>,
    cars: [Vec<Vec<Detection>>; 2],
}

/// The agents' names in a replay: the ego car, then car 1.
pub const AGENTS: [&str; 2] = ["ego", "car1"];

impl Recorded for Recording {
    fn names(&self) -> Vec<String> {
        AGENTS.iter().map(|s| s.to_string()).collect()
    }

    fn capture_us(&self, _agent: usize, frame: usize) -> u64 {
        self.times[frame]
    }

    /// Both cars' boxes are in the ego car's frame, whose origin is the ego car's sensor.
    fn position(&self, _agent: usize, _frame: usize) -> [f64; 3] {
        [0.0; 3]
    }

    fn labels(&self, _agent: usize, _frame: usize) -> &[GtObject] {
        &[]
    }

    fn detections(&self, agent: usize, frame: usize) -> Option<&[Detection]> {
        Some(&self.cars[agent][frame])
    }
}

impl V2v4real {
    /// Each frame's time when the split is replayed: from 1 s, 100 ms apart within a sequence
    /// and [`SEQUENCE_GAP_US`] from one sequence to the next.
    pub fn replay_times(&self) -> Vec<u64> {
        let mut times = Vec::with_capacity(self.frames.len());
        let mut t = 1_000_000;
        for (i, f) in self.frames.iter().enumerate() {
            if i > 0 {
                t += if self.frames[i - 1].seq == f.seq {
                    kitti::FRAME_US
                } else {
                    SEQUENCE_GAP_US
                };
            }
            times.push(t);
        }
        times
    }

    /// The split as ground truth for a run over Zenoh: a scene per sequence, each frame at its
    /// [`V2v4real::replay_times`], the labels its objects (one id per sequence and track id),
    /// and the two cars as recorded agents sending their own boxes as they are (give them
    /// their stds first).
    pub fn ground_truth(&self) -> GroundTruth {
        let times = self.replay_times();
        let mut gt = GroundTruth {
            motion: Motion::Frames,
            ..Default::default()
        };
        for (i, f) in self.frames.iter().enumerate() {
            if i == 0 || self.frames[i - 1].seq != f.seq {
                gt.scenes.push(format!("{:04}", f.seq));
            }
            let objects = self.gt[i]
                .iter()
                .map(|d| GtObject {
                    id: gt.tokens.intern(&format!("{:04}_{}", f.seq, d.id)),
                    class: d.class,
                    center: d.center,
                    size: d.size,
                    yaw: d.yaw,
                    velocity: None,
                })
                .collect();
            gt.frames.push(GtFrame {
                sample_token: f.token(),
                scene: gt.scenes.len() - 1,
                timestamp_us: times[i],
                ego: Some([0.0; 3]),
                objects,
            });
        }
        gt.recorded = Some(std::sync::Arc::new(Recording {
            times,
            cars: self.cars.clone(),
        }));
        gt
    }

    /// Adds a folder of KITTI detection rows (a fusion's output, say) as a reference named
    /// `name`; boxes of frames the split does not score are left out.
    pub fn add_reference(&mut self, name: String, dir: &Path) -> Result<(), KittiError> {
        let rows = self.read_rows(dir)?;
        self.references.push((name, rows));
        Ok(())
    }

    /// A folder of KITTI detection rows placed on the split's frames (boxes of frames the split
    /// does not score are left out).
    pub fn read_rows(&self, dir: &Path) -> Result<Vec<Vec<Detection>>, KittiError> {
        let rows = kitti::read_detection_dir(dir, Uncertainty::uniform(0.5, 0.1, 0.1))?;
        Ok(per_frame(rows, &frame_index(&self.frames)))
    }

    /// Label boxes over every frame.
    pub fn boxes(&self) -> usize {
        self.gt.iter().map(Vec::len).sum()
    }
}

#[cfg(test)]
mod tests;
