//! Ground truth: time-ordered frames of objects with stable ids, from nuScenes tables on disk or
//! from the synthetic town ([`crate::town`]).
//!
//! The loader reads `scene`, `sample`, `sample_annotation`, `instance` and `category`, plus
//! `ego_pose` through `sample_data` when both are present; categories map to the 10 detection
//! classes and the others are skipped and counted. Errors name the directory, table, record and
//! field.

use serde_json::Value;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use v2x_protocol::nuscenes_json::{quaternion_yaw, TokenTable};
use v2x_protocol::{wrap_angle, Class};

mod nuscenes;
pub use nuscenes::{load_nuscenes, LoadError};

/// One ground-truth object in one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct GtObject {
    /// Stable object id (index in the dataset's token table).
    pub id: u32,
    /// Detection class.
    pub class: Class,
    /// Centre in the map frame (m).
    pub center: [f64; 3],
    /// Size l, w, h (m).
    pub size: [f64; 3],
    /// Yaw (rad).
    pub yaw: f64,
    /// Velocity over ground (m/s), when it can be known (the town's motion; nuScenes tables:
    /// from the neighbouring annotations, as the nuScenes devkit computes it).
    pub velocity: Option<[f64; 2]>,
}

impl GtObject {
    /// The object as an exact detection (for drawing): no noise, tiny stds, score 1.
    pub fn as_detection(&self) -> v2x_protocol::Detection {
        v2x_protocol::Detection {
            class: self.class,
            center: self.center,
            size: self.size,
            yaw: self.yaw,
            score: 1.0,
            std: v2x_protocol::Uncertainty::uniform(0.01, 0.01, 0.001),
            pos_cov: None,
            velocity: self.velocity.map(|v| v2x_protocol::Velocity {
                v,
                std: [0.01, 0.01],
            }),
            id: self.id,
        }
    }
}

/// One annotation of an object's track.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackPoint {
    /// Annotation time (us).
    pub t_us: u64,
    /// The annotated box (with its devkit velocity).
    pub object: GtObject,
}

/// How objects move between the annotated frames.
#[derive(Clone, Debug, Default)]
pub enum Motion {
    /// Nothing is known between frames: a time gets its nearest frame.
    #[default]
    Frames,
    /// Annotated tracks per scene (by object id), interpolated between annotations: linear
    /// position and size, shortest-arc yaw, velocity linear between the annotations'. An object
    /// exists only between its first and last annotation.
    Tracks(Vec<BTreeMap<u32, Vec<TrackPoint>>>),
    /// Per scene, objects that move continuously (the synthetic town's actors).
    Continuous(Vec<std::sync::Arc<dyn Continuous>>),
}

/// A scene whose objects are known at any time, not only at its frames.
pub trait Continuous: std::fmt::Debug + Send + Sync {
    /// Every object of the scene at `t_us`, with its velocity.
    fn objects_at(&self, t_us: u64) -> Vec<GtObject>;
}

/// All objects at one time step.
#[derive(Clone, Debug, PartialEq)]
pub struct GtFrame {
    /// The nuScenes sample token.
    pub sample_token: String,
    /// Index of the scene in [`GroundTruth::scenes`].
    pub scene: usize,
    /// Timestamp (microseconds).
    pub timestamp_us: u64,
    /// Ego position when known (m).
    pub ego: Option<[f64; 3]>,
    /// The objects, in the order of the source (for nuScenes tables, `sample_annotation.json`
    /// order, as the devkit lists them).
    pub objects: Vec<GtObject>,
}

/// A whole ground-truth data set.
#[derive(Clone, Debug, Default)]
pub struct GroundTruth {
    /// Scene names, in order.
    pub scenes: Vec<String>,
    /// Frames ordered by scene, then time.
    pub frames: Vec<GtFrame>,
    /// Instance tokens of the object ids.
    pub tokens: TokenTable,
    /// Annotations skipped per category name (not one of the 10 classes).
    pub skipped: BTreeMap<String, usize>,
    /// How objects move between frames (continuous-time ground truth).
    pub motion: Motion,
    /// Agents recorded with the data, when it has them (DAIR-V2X's vehicle and roadside unit).
    pub recorded: Option<std::sync::Arc<dyn Recorded>>,
}

/// Agents recorded with the data: at each frame, each agent's own capture time, sensor position
/// and labels (its view of the objects).
pub trait Recorded: std::fmt::Debug + Send + Sync {
    /// The agents' names, in order.
    fn names(&self) -> Vec<String>;
    /// Agent `agent`'s capture time at frame `frame` (us).
    fn capture_us(&self, agent: usize, frame: usize) -> u64;
    /// Where agent `agent`'s sensor stands at frame `frame`.
    fn position(&self, agent: usize, frame: usize) -> [f64; 3];
    /// Agent `agent`'s own labels at frame `frame`.
    fn labels(&self, agent: usize, frame: usize) -> &[GtObject];
    /// Agent `agent`'s own detections at frame `frame`, when the data holds a detector's boxes
    /// (replayed as they are, no noise drawn); `None`: the agent sees its labels.
    fn detections(&self, _agent: usize, _frame: usize) -> Option<&[v2x_protocol::Detection]> {
        None
    }
}

impl GroundTruth {
    /// Part `k` of `n` (from 0) of every scene, cut by frame count in time order, as a data set
    /// of its own (the scenes' names and motion kept); `None` for data with recorded agents,
    /// whose frames cannot be cut, or when `k >= n`.
    pub fn part(&self, k: usize, n: usize) -> Option<GroundTruth> {
        if self.recorded.is_some() || k >= n {
            return None;
        }
        let mut count = vec![0usize; self.scenes.len().max(1)];
        for f in &self.frames {
            if let Some(c) = count.get_mut(f.scene) {
                *c += 1;
            }
        }
        let mut seen = vec![0usize; count.len()];
        let mut frames = Vec::new();
        for f in &self.frames {
            let Some(i) = seen.get_mut(f.scene) else {
                continue;
            };
            if *i * n / count[f.scene] == k {
                frames.push(f.clone());
            }
            *i += 1;
        }
        Some(GroundTruth {
            frames,
            ..self.clone()
        })
    }

    /// Number of annotated boxes over all frames.
    pub fn boxes(&self) -> usize {
        self.frames.iter().map(|f| f.objects.len()).sum()
    }

    /// The frame of a sample token.
    pub fn frame_index(&self) -> HashMap<&str, usize> {
        self.frames
            .iter()
            .enumerate()
            .map(|(i, f)| (f.sample_token.as_str(), i))
            .collect()
    }

    /// The first and last frame time of a scene (us).
    pub fn scene_span(&self, scene: usize) -> Option<(u64, u64)> {
        let mut times = self
            .frames
            .iter()
            .filter(|f| f.scene == scene)
            .map(|f| f.timestamp_us);
        let first = times.next()?;
        Some(times.fold((first, first), |(a, b), t| (a.min(t), b.max(t))))
    }

    /// The scene a time belongs to: the one whose span holds it, else the one that ends last
    /// before it (or the first).
    pub fn scene_at(&self, t_us: u64) -> usize {
        let mut best = 0;
        for sc in 0..self.scenes.len().max(1) {
            match self.scene_span(sc) {
                Some((a, b)) if a <= t_us && t_us <= b => return sc,
                Some((a, _)) if a <= t_us => best = sc,
                _ => {}
            }
        }
        best
    }

    /// The index of the frame of `scene` nearest to `t_us`.
    pub fn nearest_frame(&self, scene: usize, t_us: u64) -> Option<usize> {
        self.frames
            .iter()
            .enumerate()
            .filter(|(_, f)| f.scene == scene)
            .min_by_key(|(_, f)| f.timestamp_us.abs_diff(t_us))
            .map(|(i, _)| i)
    }

    /// The objects of `scene` at `t_us`: exactly a frame's when `t_us` is a frame time,
    /// otherwise from the motion model.
    pub fn objects_at(&self, scene: usize, t_us: u64) -> Vec<GtObject> {
        if let Some(i) = self.nearest_frame(scene, t_us) {
            if self.frames[i].timestamp_us == t_us {
                return self.frames[i].objects.clone();
            }
        }
        match &self.motion {
            Motion::Continuous(scenes) => scenes
                .get(scene)
                .map_or_else(Vec::new, |s| s.objects_at(t_us)),
            Motion::Tracks(scenes) => scenes.get(scene).map_or_else(Vec::new, |tracks| {
                tracks
                    .values()
                    .filter_map(|track| interpolate(track, t_us))
                    .collect()
            }),
            Motion::Frames => self
                .nearest_frame(scene, t_us)
                .map_or_else(Vec::new, |i| self.frames[i].objects.clone()),
        }
    }

    /// Whether any object is known between frames: the town's actors, or an object annotated
    /// in more than one frame (in most vehicle-infrastructure data sets each annotation is its
    /// own instance, and nothing can be interpolated).
    pub fn tracked_across_frames(&self) -> bool {
        match &self.motion {
            Motion::Frames => false,
            Motion::Continuous(_) => true,
            Motion::Tracks(scenes) => scenes.iter().flat_map(|s| s.values()).any(|t| t.len() > 1),
        }
    }

    /// A frame's objects in the order the simulation draws their noise in (one draw after
    /// another): by id for nuScenes tables, as seeded runs have always drawn them, whatever the
    /// order of `sample_annotation.json`; as they are for the town.
    pub fn in_draw_order(&self, mut objects: Vec<GtObject>) -> Vec<GtObject> {
        if matches!(self.motion, Motion::Tracks(_)) {
            objects.sort_by_key(|o| o.id);
        }
        objects
    }

    /// Frames per second of the data (median spacing of the first scene).
    pub fn hz(&self) -> f64 {
        let mut dts: Vec<u64> = self
            .frames
            .windows(2)
            .filter(|w| w[0].scene == w[1].scene && w[1].timestamp_us > w[0].timestamp_us)
            .map(|w| w[1].timestamp_us - w[0].timestamp_us)
            .take(101)
            .collect();
        dts.sort_unstable();
        dts.get(dts.len() / 2).map_or(10.0, |&d| 1e6 / d as f64)
    }
}

/// An object's box at `t_us` from its track, if the track spans that time.
pub fn interpolate(track: &[TrackPoint], t_us: u64) -> Option<GtObject> {
    let (first, last) = (track.first()?, track.last()?);
    if t_us < first.t_us || t_us > last.t_us {
        return None;
    }
    let k = track.partition_point(|p| p.t_us <= t_us);
    if k == 0 {
        return Some(first.object.clone());
    }
    let a = &track[k - 1];
    if a.t_us == t_us || k == track.len() {
        return Some(a.object.clone());
    }
    let b = &track[k];
    let w = (t_us - a.t_us) as f64 / (b.t_us - a.t_us) as f64;
    let lerp = |x: f64, y: f64| x + w * (y - x);
    let (oa, ob) = (&a.object, &b.object);
    Some(GtObject {
        id: oa.id,
        class: oa.class,
        center: std::array::from_fn(|i| lerp(oa.center[i], ob.center[i])),
        size: std::array::from_fn(|i| lerp(oa.size[i], ob.size[i])),
        yaw: wrap_angle(oa.yaw + w * wrap_angle(ob.yaw - oa.yaw)),
        velocity: match (oa.velocity, ob.velocity) {
            (Some(u), Some(v)) => Some([lerp(u[0], v[0]), lerp(u[1], v[1])]),
            (u, v) => u.or(v),
        },
    })
}

/// The velocity of annotation `i` of a time-sorted track, as the nuScenes devkit's
/// `box_velocity` computes it: the position difference of the previous and next annotations
/// (or the annotation itself at either end) over their time difference, unknown for a single
/// annotation or when that difference exceeds 1.5 s (3 s with both neighbours).
pub fn devkit_velocity(track: &[(u64, [f64; 3])], i: usize) -> Option<[f64; 2]> {
    let has_prev = i > 0;
    let has_next = i + 1 < track.len();
    let first = if has_prev { i - 1 } else { i };
    let last = if has_next { i + 1 } else { i };
    if first == last {
        return None;
    }
    let dt = (track[last].0 as f64 - track[first].0 as f64) / 1e6;
    let max_dt = if has_prev && has_next { 3.0 } else { 1.5 };
    if !(dt > 0.0) || dt > max_dt {
        return None;
    }
    let (p, q) = (track[first].1, track[last].1);
    Some([(q[0] - p[0]) / dt, (q[1] - p[1]) / dt])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/nuscenes-mini")
    }

    fn point(t_us: u64, center: [f64; 3], size: [f64; 3], yaw: f64, v: [f64; 2]) -> TrackPoint {
        TrackPoint {
            t_us,
            object: GtObject {
                id: 4,
                class: Class::Car,
                center,
                size,
                yaw,
                velocity: Some(v),
            },
        }
    }

    #[test]
    fn interpolation_between_annotations_by_hand() {
        // 0.5 s apart; the yaw crosses +-pi: from 170 to -170 degrees is +20, not -340
        let track = vec![
            point(
                1_000_000,
                [0.0, 0.0, 1.0],
                [4.0, 2.0, 1.5],
                170f64.to_radians(),
                [8.0, 0.0],
            ),
            point(
                1_500_000,
                [4.0, 2.0, 1.2],
                [4.4, 2.0, 1.5],
                -170f64.to_radians(),
                [8.0, 4.0],
            ),
        ];
        // a quarter of the way: 1.125 s
        let o = interpolate(&track, 1_125_000).unwrap();
        assert_eq!(o.id, 4);
        assert!((o.center[0] - 1.0).abs() < 1e-12 && (o.center[1] - 0.5).abs() < 1e-12);
        assert!((o.center[2] - 1.05).abs() < 1e-12);
        assert!((o.size[0] - 4.1).abs() < 1e-12);
        assert!(
            (o.yaw - 175f64.to_radians()).abs() < 1e-12,
            "{}",
            o.yaw.to_degrees()
        );
        let v = o.velocity.unwrap();
        assert!((v[0] - 8.0).abs() < 1e-12 && (v[1] - 1.0).abs() < 1e-12);
        // three quarters: -175 degrees, across pi
        let o = interpolate(&track, 1_375_000).unwrap();
        assert!(
            (o.yaw + 175f64.to_radians()).abs() < 1e-12,
            "{}",
            o.yaw.to_degrees()
        );
        // on an annotation: exactly it; outside the track: no object
        assert_eq!(interpolate(&track, 1_500_000).unwrap(), track[1].object);
        assert_eq!(interpolate(&track, 999_999), None);
        assert_eq!(interpolate(&track, 1_500_001), None);
    }

    #[test]
    fn velocities_as_the_devkit_computes_them() {
        let track = [
            (0, [0.0, 0.0, 0.0]),
            (500_000, [5.0, 1.0, 0.0]),
            (1_000_000, [12.0, 2.0, 0.0]),
            (3_000_000, [20.0, 2.0, 0.0]),
        ];
        // inside: previous to next, (12 - 0) / 1 s
        assert_eq!(devkit_velocity(&track, 1), Some([12.0, 2.0]));
        // at the start: itself to the next, 5 / 0.5 s
        assert_eq!(devkit_velocity(&track, 0), Some([10.0, 2.0]));
        // neighbours 2.5 s apart: still within the devkit's 3 s
        assert_eq!(devkit_velocity(&track, 2), Some([6.0, 0.4]));
        // at the end 2 s from its previous: beyond the devkit's 1.5 s, unknown
        assert_eq!(devkit_velocity(&track, 3), None);
        assert_eq!(devkit_velocity(&track[..1], 0), None);
    }

    #[test]
    fn loads_the_fixture() {
        let gt = load_nuscenes(&fixture(), "v1.0-fixture").unwrap();
        assert_eq!(gt.scenes, vec!["scene-a", "scene-b"]);
        assert_eq!(gt.frames.len(), 3);
        // frames in scene then time order
        assert_eq!(gt.frames[0].sample_token, "s1");
        assert_eq!(gt.frames[1].sample_token, "s2");
        assert_eq!(gt.frames[2].sample_token, "s3");
        assert_eq!(gt.frames[0].ego, Some([100.0, 200.0, 0.0]));
        assert_eq!(gt.frames[2].ego, None);
        // s1: a car (size [w,l,h] = [2,4.5,1.6], yaw 90 deg) and a pedestrian; the animal skipped
        let f = &gt.frames[0];
        assert_eq!(f.objects.len(), 2);
        let car = f.objects.iter().find(|o| o.class == Class::Car).unwrap();
        assert_eq!(car.size, [4.5, 2.0, 1.6]);
        assert!((car.yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert_eq!(gt.tokens.name(car.id), Some("inst-car"));
        // the car keeps its id across frames
        assert!(gt.frames[1].objects.iter().any(|o| o.id == car.id));
        assert_eq!(gt.skipped.get("animal"), Some(&1));
        assert_eq!(gt.boxes(), 4);
        assert!((gt.hz() - 2.0).abs() < 1e-9);
    }

    #[test]
    fn objects_keep_the_annotation_order() {
        // as the devkit lists a sample's boxes: sample_annotation.json order, either way round
        let tmp = tmpdir("annotation-order");
        let dir = copy_fixture(&tmp);
        let names = |gt: &GroundTruth| -> Vec<String> {
            gt.frames[0]
                .objects
                .iter()
                .map(|o| gt.tokens.name(o.id).unwrap().to_string())
                .collect()
        };
        let gt = load_nuscenes(&tmp, "v1.0-fixture").unwrap();
        assert_eq!(names(&gt), ["inst-car", "inst-ped"]);
        let path = dir.join("sample_annotation.json");
        let mut anns: Vec<Value> =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        anns.reverse();
        std::fs::write(&path, serde_json::to_string(&anns).unwrap()).unwrap();
        let gt = load_nuscenes(&tmp, "v1.0-fixture").unwrap();
        assert_eq!(names(&gt), ["inst-ped", "inst-car"]);
    }

    fn copy_fixture(tmp: &Path) -> PathBuf {
        let dst = tmp.join("v1.0-fixture");
        std::fs::create_dir_all(&dst).unwrap();
        for e in std::fs::read_dir(fixture().join("v1.0-fixture")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), dst.join(e.file_name())).unwrap();
        }
        dst
    }

    fn tmpdir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("v2x-sim-test-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn missing_directory_and_table() {
        let e = load_nuscenes(Path::new("/nonexistent"), "v1.0-x").unwrap_err();
        assert!(
            e.to_string()
                .contains("/nonexistent/v1.0-x: no such directory"),
            "{e}"
        );
        let tmp = tmpdir("missing");
        let dir = copy_fixture(&tmp);
        std::fs::remove_file(dir.join("instance.json")).unwrap();
        let e = load_nuscenes(&tmp, "v1.0-fixture").unwrap_err();
        assert!(e.to_string().contains("missing table 'instance'"), "{e}");
    }

    #[test]
    fn malformed_tables() {
        let cases: &[(&str, &str, &str, &str)] = &[
            (
                "sample_annotation.json",
                "\"translation\": [10.0, 20.0, 1.0]",
                "\"translation\": [10.0, 20.0]",
                "field 'translation': expected 3 numbers",
            ),
            (
                "sample_annotation.json",
                "\"size\": [2.0, 4.5, 1.6]",
                "\"size\": [2.0, 0.0, 1.6]",
                "field 'size': sizes must be positive",
            ),
            (
                "sample_annotation.json",
                "\"instance_token\": \"inst-car\"",
                "\"instance_token\": \"inst-zzz\"",
                "field 'instance_token': 'inst-zzz' is not in instance.json",
            ),
            (
                "sample.json",
                "\"timestamp\": 1000000",
                "\"timestamp\": \"soon\"",
                "field 'timestamp': expected a non-negative integer",
            ),
            (
                "category.json",
                "\"name\": \"vehicle.car\"",
                "\"nom\": \"vehicle.car\"",
                "field 'name': missing",
            ),
            ("scene.json", "[", "{", "not valid JSON"),
        ];
        for (i, (table, from, to, msg)) in cases.iter().enumerate() {
            let tmp = tmpdir(&format!("bad{i}"));
            let dir = copy_fixture(&tmp);
            let p = dir.join(table);
            let text = std::fs::read_to_string(&p).unwrap();
            assert!(text.contains(from), "{table}: {from}");
            std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
            let e = load_nuscenes(&tmp, "v1.0-fixture").unwrap_err().to_string();
            assert!(e.contains(msg), "{e}");
            assert!(e.contains(table), "{e}");
        }
    }

    #[test]
    fn parts_cut_each_scene_in_time_order_and_together_hold_every_frame() {
        let frame = |scene: usize, t: u64| GtFrame {
            sample_token: format!("{scene}-{t}"),
            scene,
            timestamp_us: t,
            ego: None,
            objects: Vec::new(),
        };
        let gt = GroundTruth {
            scenes: vec!["a".into(), "b".into()],
            frames: (0..5)
                .map(|t| frame(0, t))
                .chain((0..2).map(|t| frame(1, t)))
                .collect(),
            ..Default::default()
        };
        let tokens = |g: &GroundTruth| -> Vec<String> {
            g.frames.iter().map(|f| f.sample_token.clone()).collect()
        };
        let halves: Vec<GroundTruth> = (0..2).map(|k| gt.part(k, 2).unwrap()).collect();
        assert_eq!(tokens(&halves[0]), ["0-0", "0-1", "0-2", "1-0"]);
        assert_eq!(tokens(&halves[1]), ["0-3", "0-4", "1-1"]);
        assert_eq!(halves[1].scenes, gt.scenes);
        assert_eq!(tokens(&gt.part(0, 1).unwrap()), tokens(&gt));
        assert!(gt.part(2, 2).is_none());
    }
}
