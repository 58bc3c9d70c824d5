//! DAIR-V2X cooperative data (DAIR-V2X-C and V2X-Seq-SPD): the cooperative ground truth and
//! the two real agents, the vehicle (`veh`) and the roadside unit (`inf`), each with its own
//! labels, capture times and calibration chain, all in the world frame.
//!
//! The layout and conventions are those of the official DAIR-V2X code:
//! - `cooperative/data_info.json` pairs a vehicle frame with a roadside frame. DAIR-V2X-C names
//!   them by `vehicle_pointcloud_path` and `infrastructure_pointcloud_path` and gives
//!   `cooperative_label_path` (world-frame labels); V2X-Seq-SPD names them `vehicle_frame` and
//!   `infrastructure_frame`, with `vehicle_sequence`, and keeps the cooperative labels (with
//!   `track_id`) in `cooperative/label/{vehicle_frame}.json`, in the vehicle's LiDAR frame.
//! - `vehicle-side/data_info.json` and `infrastructure-side/data_info.json` give each frame's
//!   `pointcloud_timestamp` (microseconds), its label and calibration paths and its
//!   `batch_id` (DAIR-V2X-C) or `sequence_id` (SPD), which become the scenes.
//! - A label's `3d_location` is the box centre, `3d_dimensions` are `l` (along the heading), `w`
//!   and `h`, and `rotation` is the yaw about the LiDAR's z axis. World labels give
//!   `world_8_points` in the order of [`corners`]; they are read back into a box and refused if
//!   they are not one.
//! - The vehicle's LiDAR reaches the world through `calib/lidar_to_novatel` then
//!   `calib/novatel_to_world`; the roadside's virtual LiDAR through `calib/virtuallidar_to_world`.
//! - The calibration offset of a pair (`system_error_offset`, or the roadside calibration's
//!   `relative_error`) moves the roadside by (delta_x, delta_y): in the world frame for
//!   DAIR-V2X-C and in the vehicle's LiDAR frame for V2X-Seq-SPD, as the official loaders do.
//!
//! Classes: Car and Van are `car`, Truck `truck`, Bus `bus`, Pedestrian `pedestrian`, Cyclist
//! `bicycle`, Motorcyclist and Tricyclist `motorcycle`, TrafficCone `traffic_cone`; any other
//! type is skipped and counted. Boxes with a zero size are skipped, as the official loader does.

pub mod corners;
pub mod pose;
mod read;
pub mod results;

use crate::dataset::{GroundTruth, GtFrame, GtObject, Motion, Recorded};
use crate::noise::{recorded_view, AgentNoise};
pub use corners::{corners, from_corners, CornerBox, CornerError, Corners};
pub use pose::Pose;
use serde_json::Value;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use v2x_protocol::{limits, wrap_angle, Class, Detection, NO_ID};

pub use read::class_of;
use read::*;

/// Which of the two layouts the data is in.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Layout {
    /// DAIR-V2X-C: world-frame cooperative labels, no track ids.
    Cooperative,
    /// V2X-Seq-SPD: cooperative labels in the vehicle's frame, with track ids.
    Sequential,
}

/// One cooperative frame: a vehicle frame and the roadside frame paired with it.
#[derive(Clone, Debug, PartialEq)]
pub struct DairPair {
    /// The vehicle frame's id (the sample token of the frame).
    pub veh_frame: String,
    /// The roadside frame's id.
    pub inf_frame: String,
    /// The vehicle's capture time (us).
    pub veh_us: u64,
    /// The roadside's capture time (us).
    pub inf_us: u64,
    /// Vehicle LiDAR to world.
    pub veh_to_world: Pose,
    /// Roadside virtual LiDAR to world, with the calibration offset when it is applied.
    pub inf_to_world: Pose,
    /// The pair's calibration offset (delta_x, delta_y), applied or not.
    pub offset: [f64; 2],
}

/// A loaded DAIR-V2X data set.
#[derive(Clone, Debug)]
pub struct Dair {
    /// Which layout it was read from.
    pub layout: Layout,
    /// The cooperative labels in the world frame, one frame per pair at the vehicle's capture
    /// time, keyed by the vehicle frame id; its `recorded` agents are [`Dair::rec`].
    pub gt: GroundTruth,
    /// The two agents as recorded.
    pub rec: Arc<Recording>,
    /// A detector's results in place of an agent's labels (vehicle, roadside), per pair in the
    /// world frame ([`Dair::use_results`]).
    pub results: [Option<Vec<Vec<Detection>>>; 2],
    /// World labels whose `3d_location` or `3d_dimensions` lie more than 10 cm from their
    /// `world_8_points` (the corners are used).
    pub corner_mismatches: usize,
}

/// The two agents of DAIR-V2X data as recorded, pair by pair (parallel to the ground truth's
/// frames).
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// The pairs.
    pub pairs: Vec<DairPair>,
    /// The vehicle's own labels per pair, in the world frame.
    pub veh: Vec<Vec<GtObject>>,
    /// The roadside's own labels per pair, in the world frame.
    pub inf: Vec<Vec<GtObject>>,
}

impl Recorded for Recording {
    fn names(&self) -> Vec<String> {
        AGENTS.iter().map(|s| s.to_string()).collect()
    }

    fn capture_us(&self, agent: usize, frame: usize) -> u64 {
        let p = &self.pairs[frame];
        if agent == 0 {
            p.veh_us
        } else {
            p.inf_us
        }
    }

    fn position(&self, agent: usize, frame: usize) -> [f64; 3] {
        let p = &self.pairs[frame];
        if agent == 0 {
            p.veh_to_world.translation
        } else {
            p.inf_to_world.translation
        }
    }

    fn labels(&self, agent: usize, frame: usize) -> &[GtObject] {
        if agent == 0 {
            &self.veh[frame]
        } else {
            &self.inf[frame]
        }
    }
}

/// The two agents of the data, in the order `v2x-sim gen` writes them (agent1, agent2).
pub const AGENTS: [&str; 2] = ["veh", "inf"];

impl Dair {
    /// An agent's (0 vehicle, 1 roadside) detections at pair `i`: its labels as `noise` sees
    /// them ([`AgentNoise::labels`]: exactly, stating 0.5 m; another profile: with its noise
    /// drawn on top, seeded by `seed`), within `range` m of its sensor when given.
    pub fn detections(
        &self,
        agent: usize,
        i: usize,
        noise: &AgentNoise,
        seed: u64,
        range: Option<f64>,
    ) -> Vec<Detection> {
        if let Some(r) = &self.results[agent] {
            let p = self.rec.position(agent, i);
            return r[i]
                .iter()
                .filter(|d| {
                    range.is_none_or(|m| (d.center[0] - p[0]).hypot(d.center[1] - p[1]) <= m)
                })
                .cloned()
                .collect();
        }
        recorded_view(&self.gt, self.rec.as_ref(), agent, i, noise, seed, range)
    }

    /// Takes a detector's results (by the side's frame id, in its LiDAR frame) as agent
    /// `agent`'s boxes instead of its labels, stating [`AgentNoise::labels`]' stds. Returns
    /// how many pairs the results have no frame for (those pairs get no boxes).
    pub fn use_results(
        &mut self,
        agent: usize,
        results: &BTreeMap<String, Vec<results::LocalBox>>,
    ) -> usize {
        let std = AgentNoise::labels().std;
        let mut missing = 0;
        let per_pair = self
            .rec
            .pairs
            .iter()
            .map(|p| {
                let (frame, pose) = if agent == 0 {
                    (&p.veh_frame, &p.veh_to_world)
                } else {
                    (&p.inf_frame, &p.inf_to_world)
                };
                let Some(boxes) = results.get(frame) else {
                    missing += 1;
                    return Vec::new();
                };
                boxes
                    .iter()
                    .map(|b| Detection {
                        class: b.class,
                        center: pose.apply(b.center),
                        size: b.size,
                        yaw: wrap_angle(pose.yaw(b.yaw)),
                        score: b.score,
                        std,
                        pos_cov: None,
                        velocity: None,
                        id: NO_ID,
                    })
                    .collect()
            })
            .collect();
        self.results[agent] = Some(per_pair);
        missing
    }

    /// An agent's capture time of pair `i` (us).
    pub fn capture_us(&self, agent: usize, i: usize) -> u64 {
        self.rec.capture_us(agent, i)
    }
}

/// Why a DAIR-V2X data root could not be read: the file and what is wrong with it.
#[derive(Debug, thiserror::Error)]
#[error("{}: {what}", path.display())]
pub struct DairError {
    /// The file or directory.
    pub path: PathBuf,
    /// What is wrong, naming the record and field.
    pub what: String,
}

fn err(path: &Path, what: impl Into<String>) -> DairError {
    DairError {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

/// A label moved into the world by `pose`, as a ground-truth object with id `id`.
fn to_world(l: &Label, pose: &Pose, id: u32) -> GtObject {
    GtObject {
        id,
        class: l.class,
        center: pose.apply(l.center),
        size: l.size,
        yaw: wrap_angle(pose.yaw(l.yaw)),
        velocity: None,
    }
}

/// One side's `data_info.json`, by frame id.
struct SideInfo {
    dir: PathBuf,
    records: HashMap<String, (usize, Value)>,
    file: File,
}

impl SideInfo {
    fn read(root: &Path, side: &str) -> Result<SideInfo, DairError> {
        let dir = root.join(side);
        let file = File::read(dir.join("data_info.json"))?;
        let mut records = HashMap::new();
        for (i, rec) in file.records()?.iter().enumerate() {
            let id = if rec.get("frame_id").is_some() {
                id_of(&file, rec, Some(i), "frame_id")?
            } else {
                id_of(&file, rec, Some(i), "pointcloud_path")?
            };
            records.insert(id, (i, rec.clone()));
        }
        Ok(SideInfo { dir, records, file })
    }

    fn get(
        &self,
        id: &str,
        pairs: &File,
        at: usize,
        name: &str,
    ) -> Result<(usize, &Value), DairError> {
        self.records.get(id).map(|(i, r)| (*i, r)).ok_or_else(|| {
            pairs.fail(
                Some(at),
                name,
                format!("frame {id} is not in {}", self.file.path.display()),
            )
        })
    }

    /// A path the record names under one of `keys`, else `default` (relative to the side).
    fn path(&self, rec: &Value, keys: &[&str], default: String) -> PathBuf {
        let named = keys
            .iter()
            .find_map(|k| rec.get(*k).and_then(Value::as_str))
            .filter(|s| !s.is_empty());
        self.dir.join(named.map(str::to_string).unwrap_or(default))
    }

    fn timestamp(&self, rec: &Value, at: usize) -> Result<u64, DairError> {
        let t = num(&self.file, rec, Some(at), "pointcloud_timestamp")?;
        if !(0.0..=1e17).contains(&t) {
            return Err(self.file.fail(
                Some(at),
                "pointcloud_timestamp",
                "expected microseconds since the epoch",
            ));
        }
        Ok(t as u64)
    }
}

/// A calibration offset object (`delta_x`, `delta_y`; empty strings are 0).
fn offset_of(v: Option<&Value>) -> [f64; 2] {
    let get = |k: &str| v.and_then(|o| o.get(k)).and_then(number).unwrap_or(0.0);
    [get("delta_x"), get("delta_y")]
}

/// Loads a DAIR-V2X-C or V2X-Seq-SPD root (the folder holding `cooperative/`, `vehicle-side/`
/// and `infrastructure-side/`), with the calibration offset applied when `offset` is true.
pub fn load_dair(root: &Path, offset: bool) -> Result<Dair, DairError> {
    for sub in ["cooperative", "vehicle-side", "infrastructure-side"] {
        if !root.join(sub).is_dir() {
            return Err(err(
                &root.join(sub),
                "no such directory (give --dataroot the folder holding cooperative/, vehicle-side/ and infrastructure-side/)",
            ));
        }
    }
    let pairs_file = File::read(root.join("cooperative/data_info.json"))?;
    let veh_info = SideInfo::read(root, "vehicle-side")?;
    let inf_info = SideInfo::read(root, "infrastructure-side")?;
    let records = pairs_file.records()?;
    let layout = match records.first() {
        Some(r) if r.get("vehicle_frame").is_some() => Layout::Sequential,
        _ => Layout::Cooperative,
    };
    let mut gt = GroundTruth {
        motion: Motion::Frames,
        ..Default::default()
    };
    let src = Sources {
        root,
        pairs: &pairs_file,
        layout,
        veh_info: &veh_info,
        inf_info: &inf_info,
        apply_offset: offset,
    };
    let mut rows = Vec::new();
    for (i, rec) in records.iter().enumerate() {
        rows.push(read_pair(&src, i, rec, &mut gt)?);
    }
    sort_by_scene(&mut rows);
    let mut rec = Recording::default();
    let mut corner_mismatches = 0;
    let mut seen = std::collections::HashSet::new();
    for r in rows {
        if !seen.insert(r.pair.veh_frame.clone()) {
            return Err(err(
                &pairs_file.path,
                format!("vehicle frame {} is paired twice", r.pair.veh_frame),
            ));
        }
        if gt.scenes.last() != Some(&r.scene) {
            gt.scenes.push(r.scene.clone());
        }
        gt.frames.push(GtFrame {
            sample_token: r.pair.veh_frame.clone(),
            scene: gt.scenes.len() - 1,
            timestamp_us: r.pair.veh_us,
            ego: Some(r.pair.veh_to_world.translation),
            objects: r.objects,
        });
        corner_mismatches += r.mismatched;
        rec.pairs.push(r.pair);
        rec.veh.push(r.veh);
        rec.inf.push(r.inf);
    }
    let rec = Arc::new(rec);
    gt.recorded = Some(rec.clone());
    Ok(Dair {
        layout,
        gt,
        rec,
        results: [None, None],
        corner_mismatches,
    })
}

/// Orders the pairs' rows by scene (in order of first capture), then time.
fn sort_by_scene(rows: &mut [Row]) {
    let mut first: HashMap<String, u64> = HashMap::new();
    for r in rows.iter() {
        let e = first.entry(r.scene.clone()).or_insert(r.pair.veh_us);
        *e = (*e).min(r.pair.veh_us);
    }
    rows.sort_by(|a, b| {
        (first[&a.scene], &a.scene, a.pair.veh_us, &a.pair.veh_frame).cmp(&(
            first[&b.scene],
            &b.scene,
            b.pair.veh_us,
            &b.pair.veh_frame,
        ))
    });
}

/// One side's own labels in the world (types the ground truth does not score are left out).
fn side_boxes(path: PathBuf, pose: &Pose) -> Result<Vec<GtObject>, DairError> {
    let labels = read_labels(path, false, &mut BTreeMap::new(), &mut 0)?;
    Ok(labels.iter().map(|l| to_world(l, pose, NO_ID)).collect())
}

/// One pair as read, before ordering.
struct Row {
    scene: String,
    mismatched: usize,
    pair: DairPair,
    objects: Vec<GtObject>,
    veh: Vec<GtObject>,
    inf: Vec<GtObject>,
}

/// What every pair is read against.
struct Sources<'a> {
    root: &'a Path,
    pairs: &'a File,
    layout: Layout,
    veh_info: &'a SideInfo,
    inf_info: &'a SideInfo,
    apply_offset: bool,
}

/// Pair `i` of `cooperative/data_info.json`: its frames, poses and labels.
fn read_pair(src: &Sources, i: usize, rec: &Value, gt: &mut GroundTruth) -> Result<Row, DairError> {
    let (veh_key, inf_key) = match src.layout {
        Layout::Sequential => ("vehicle_frame", "infrastructure_frame"),
        Layout::Cooperative => ("vehicle_pointcloud_path", "infrastructure_pointcloud_path"),
    };
    let veh_frame = id_of(src.pairs, rec, Some(i), veh_key)?;
    let inf_frame = id_of(src.pairs, rec, Some(i), inf_key)?;
    let (vi, veh) = src.veh_info.get(&veh_frame, src.pairs, i, veh_key)?;
    let (ii, inf) = src.inf_info.get(&inf_frame, src.pairs, i, inf_key)?;
    let pair = pair_poses(src, rec, (&veh_frame, veh), (&inf_frame, inf))?;
    let pair = DairPair {
        veh_us: src.veh_info.timestamp(veh, vi)?,
        inf_us: src.inf_info.timestamp(inf, ii)?,
        ..pair
    };
    let scene = match src.layout {
        Layout::Sequential => rec
            .get("vehicle_sequence")
            .or_else(|| veh.get("sequence_id")),
        Layout::Cooperative => veh.get("batch_id"),
    }
    .and_then(|v| {
        v.as_str()
            .map(str::to_string)
            .or_else(|| number(v).map(|n| n.to_string()))
    })
    .unwrap_or_else(|| "dair".to_string());
    let mut mismatched = 0;
    let objects = cooperative_labels(src, rec, &pair, gt, &mut mismatched)?;
    let veh_labels = src.veh_info.path(
        veh,
        &["label_lidar_std_path", "label_lidar_path"],
        format!("label/lidar/{veh_frame}.json"),
    );
    let inf_labels = src.inf_info.path(
        inf,
        &[
            "label_lidar_std_path",
            "label_virtuallidar_path",
            "label_lidar_path",
        ],
        format!("label/virtuallidar/{inf_frame}.json"),
    );
    Ok(Row {
        scene,
        mismatched,
        objects,
        veh: side_boxes(veh_labels, &pair.veh_to_world)?,
        inf: side_boxes(inf_labels, &pair.inf_to_world)?,
        pair,
    })
}

/// A pair's frames and poses (capture times still 0): the vehicle's chain, the roadside's
/// calibration and the offset, applied as the layout's official loader does when asked.
fn pair_poses(
    src: &Sources,
    rec: &Value,
    (veh_frame, veh): (&str, &Value),
    (inf_frame, inf): (&str, &Value),
) -> Result<DairPair, DairError> {
    let calib = |info: &SideInfo, r: &Value, key: &str, default: String, under: Option<&str>| {
        read_pose(info.path(r, &[key], default), under)
    };
    let (lidar_to_novatel, _) = calib(
        src.veh_info,
        veh,
        "calib_lidar_to_novatel_path",
        format!("calib/lidar_to_novatel/{veh_frame}.json"),
        Some("transform"),
    )?;
    let (novatel_to_world, _) = calib(
        src.veh_info,
        veh,
        "calib_novatel_to_world_path",
        format!("calib/novatel_to_world/{veh_frame}.json"),
        None,
    )?;
    let veh_to_world = lidar_to_novatel.then(&novatel_to_world);
    let (inf_calib, inf_file) = calib(
        src.inf_info,
        inf,
        "calib_virtuallidar_to_world_path",
        format!("calib/virtuallidar_to_world/{inf_frame}.json"),
        None,
    )?;
    let (offset, shift) = match src.layout {
        Layout::Cooperative => {
            let o = offset_of(
                inf_file
                    .value
                    .get("relative_error")
                    .or_else(|| rec.get("system_error_offset")),
            );
            (o, [o[0], o[1], 0.0])
        }
        Layout::Sequential => {
            let o = offset_of(rec.get("system_error_offset"));
            (o, veh_to_world.rotate([o[0], o[1], 0.0]))
        }
    };
    Ok(DairPair {
        veh_frame: veh_frame.to_string(),
        inf_frame: inf_frame.to_string(),
        veh_us: 0,
        inf_us: 0,
        veh_to_world,
        inf_to_world: if src.apply_offset {
            inf_calib.shifted(shift)
        } else {
            inf_calib
        },
        offset,
    })
}

/// A pair's cooperative labels in the world, each with its id: its track's (SPD) or its own.
fn cooperative_labels(
    src: &Sources,
    rec: &Value,
    pair: &DairPair,
    gt: &mut GroundTruth,
    mismatched: &mut usize,
) -> Result<Vec<GtObject>, DairError> {
    let frame = &pair.veh_frame;
    let (path, world, pose) = match src.layout {
        Layout::Cooperative => (
            match rec.get("cooperative_label_path").and_then(Value::as_str) {
                Some(p) => src.root.join(p),
                None => src
                    .root
                    .join(format!("cooperative/label_world/{frame}.json")),
            },
            true,
            Pose::IDENTITY,
        ),
        Layout::Sequential => (
            src.root.join(format!("cooperative/label/{frame}.json")),
            false,
            pair.veh_to_world,
        ),
    };
    let labels = read_labels(path, world, &mut gt.skipped, mismatched)?;
    Ok(labels
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let token = match &l.track {
                Some(t) => format!("track {t}"),
                None => format!("{frame}#{k}"),
            };
            to_world(l, &pose, gt.tokens.intern(&token))
        })
        .collect())
}

#[cfg(test)]
mod tests;
