//! Command-line pieces shared by the `v2x-sim` subcommands: where the ground truth comes from,
//! and reading predictions against it.

use crate::dair::{load_dair, Dair};
use crate::dataset::{load_nuscenes, GroundTruth, GtObject};
use crate::detection_eval::{DetectionEval, DetectionMetrics};
use crate::metrics::{Accumulator, Metrics};
use crate::town::{generate, TownConfig};
use anyhow::{bail, Context};
use clap::Args;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use v2x_protocol::nuscenes_json::{read_results, MissingStd};
use v2x_protocol::{Class, Detection, Uncertainty, NO_ID};

/// Which kind of data `--dataroot` holds.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DatasetKind {
    /// nuScenes tables (DATAROOT/VERSION/*.json).
    #[default]
    Nuscenes,
    /// DAIR-V2X-C or V2X-Seq-SPD (DATAROOT holds cooperative/, vehicle-side/ and
    /// infrastructure-side/): the agents are the data's vehicle `veh` and roadside unit `inf`.
    DairV2x,
}

/// On or off.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Switch {
    /// On.
    On,
    /// Off.
    Off,
}

/// Where the ground truth comes from: nuScenes tables, DAIR-V2X cooperative data, or the
/// synthetic town (the default).
#[derive(Args, Clone, Debug)]
pub struct DataArgs {
    /// Data root: the folder holding VERSION/ (nuScenes), or cooperative/, vehicle-side/ and
    /// infrastructure-side/ (--dataset dair-v2x); without it, the synthetic town is used.
    #[arg(long)]
    pub dataroot: Option<PathBuf>,
    /// What --dataroot holds.
    #[arg(long, value_enum, default_value = "nuscenes", requires = "dataroot")]
    pub dataset: DatasetKind,
    /// DAIR-V2X: move the roadside by each pair's calibration offset (system_error_offset), as
    /// the official loader does.
    #[arg(long, value_enum, default_value = "on")]
    pub calibration_offset: Switch,
    /// DAIR-V2X: the vehicle's boxes from a detector's results instead of its labels: a folder
    /// of {frame_id}.json, or one JSON object by frame id, each with `boxes_3d` (8 corners in
    /// mmdetection3d's order, in the vehicle's LiDAR frame), `labels_3d` and `scores_3d`.
    #[arg(long, requires = "dataroot")]
    pub veh_results: Option<PathBuf>,
    /// DAIR-V2X: the roadside's boxes from a detector's results (as --veh-results, in its
    /// virtual LiDAR frame).
    #[arg(long, requires = "dataroot")]
    pub inf_results: Option<PathBuf>,
    /// nuScenes version folder name, e.g. v1.0-mini.
    #[arg(long)]
    pub version: Option<String>,
    /// Synthetic town: number of scenes.
    #[arg(long, default_value_t = 1)]
    pub scenes: usize,
    /// Synthetic town: seconds per scene.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Synthetic town: frames per second (nuScenes key frames are 2 Hz).
    #[arg(long, default_value_t = 10.0)]
    pub hz: f64,
    /// Synthetic town: the nuScenes-validation-sized set (150 scenes x 20 s at 2 Hz); overrides
    /// --scenes, --seconds and --hz.
    #[arg(long)]
    pub validation_size: bool,
    /// Synthetic town: layout seed.
    #[arg(long, default_value_t = 7)]
    pub town_seed: u64,
}

impl DataArgs {
    /// The synthetic town these arguments describe.
    pub fn town(&self) -> TownConfig {
        if self.validation_size {
            TownConfig::validation(self.town_seed)
        } else {
            TownConfig {
                scenes: self.scenes,
                seconds: self.seconds,
                hz: self.hz,
                seed: self.town_seed,
            }
        }
    }

    /// Whether the data is DAIR-V2X cooperative data.
    pub fn is_dair(&self) -> bool {
        self.dataroot.is_some() && self.dataset == DatasetKind::DairV2x
    }

    /// Loads DAIR-V2X cooperative data (`--dataset dair-v2x`).
    pub fn load_dair(&self) -> anyhow::Result<Dair> {
        match (&self.dataroot, self.dataset) {
            (Some(root), DatasetKind::DairV2x) => {
                let mut d = load_dair(root, self.calibration_offset == Switch::On)?;
                if d.corner_mismatches > 0 {
                    eprintln!(
                        "{}: {} world labels place their box more than 10 cm from their world_8_points; the corners were used",
                        root.display(),
                        d.corner_mismatches
                    );
                }
                for (agent, path) in [&self.veh_results, &self.inf_results]
                    .into_iter()
                    .enumerate()
                {
                    let Some(path) = path else { continue };
                    let results = crate::dair::results::read_results(path)?;
                    let missing = d.use_results(agent, &results);
                    if missing > 0 {
                        eprintln!(
                            "{}: no results for {missing} of {} {} frames (those frames get no boxes)",
                            path.display(),
                            d.rec.pairs.len(),
                            crate::dair::AGENTS[agent]
                        );
                    }
                }
                Ok(d)
            }
            _ => bail!("this needs --dataset dair-v2x --dataroot DIR"),
        }
    }

    /// Loads or generates the ground truth (for DAIR-V2X, its cooperative labels).
    pub fn load(&self) -> anyhow::Result<GroundTruth> {
        if !self.is_dair() && (self.veh_results.is_some() || self.inf_results.is_some()) {
            bail!("--veh-results and --inf-results read DAIR-V2X detection results: they need --dataset dair-v2x");
        }
        if self.is_dair() {
            return Ok(self.load_dair()?.gt);
        }
        match (&self.dataroot, &self.version) {
            (Some(root), Some(version)) => Ok(load_nuscenes(root, version)?),
            (Some(_), None) => bail!(
                "--dataroot needs --version NAME for nuScenes tables (DATAROOT/NAME/*.json), or --dataset dair-v2x"
            ),
            (None, Some(_)) => bail!("--version needs --dataroot"),
            _ => {
                let t = self.town();
                if t.scenes == 0
                    || !t.hz.is_finite()
                    || t.hz <= 0.0
                    || !t.seconds.is_finite()
                    || t.seconds <= 0.0
                {
                    bail!("the synthetic town needs --scenes >= 1, --hz > 0 and --seconds > 0");
                }
                Ok(generate(&t))
            }
        }
    }

    /// A short description of the source, for reports.
    pub fn describe(&self, gt: &GroundTruth) -> String {
        let what = match &self.dataroot {
            Some(r) if self.is_dair() => format!(
                "DAIR-V2X {} (calibration offset {})",
                r.display(),
                if self.calibration_offset == Switch::On {
                    "on"
                } else {
                    "off"
                }
            ),
            Some(r) => format!(
                "nuScenes tables {}",
                r.join(self.version.as_deref().unwrap_or("")).display()
            ),
            None => {
                let t = self.town();
                format!(
                    "synthetic town (seed {}, {} scenes x {} s at {} Hz)",
                    t.seed, t.scenes, t.seconds, t.hz
                )
            }
        };
        format!("{what}: {} frames, {} boxes", gt.frames.len(), gt.boxes())
    }
}

/// How the capture times of a replay map back to the data's time: the agents replayed from
/// the data's first frame, captured at `start_us`, `speed` times faster than recorded.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ReplayMap {
    /// Wall-clock capture time of the data's first frame (us since the Unix epoch).
    pub start_us: u64,
    /// Playback speed factor.
    pub speed: f64,
}

/// When a results file's samples are scored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Timing {
    /// A sample named by a ground-truth sample token is scored at that sample's frame; only
    /// keys that name no sample (`t<microseconds>`, as the fuser node records) use a time.
    #[default]
    Frame,
    /// Every sample is scored at its capture time (the `v2x_timestamps` entry of the file's
    /// meta), the ground truth interpolated along its tracks between frames: for agents that
    /// captured between the data's frames. Needs ground truth tracked across frames.
    Capture,
}

/// A sample of a results file placed in the ground truth's time.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleTime {
    /// The sample key.
    pub key: String,
    /// The time it is scored at (us).
    pub t_us: u64,
    /// Its scene.
    pub scene: usize,
    /// Its own frame, when the key is a ground-truth sample token.
    pub frame: Option<usize>,
}

/// Each sample of a results file with its time (us) and scene, in the file's order: with
/// [`Timing::Frame`] a sample token's frame time, with [`Timing::Capture`] the `v2x_timestamps`
/// entry of the file's meta first; for other keys the `v2x_timestamps` entry, else the
/// `t<microseconds>` of the key mapped through `replay`. Keys with no time in the ground
/// truth's span are returned apart.
pub fn sample_times(
    gt: &GroundTruth,
    results: &v2x_protocol::nuscenes_json::Results,
    replay: Option<ReplayMap>,
    timing: Timing,
) -> (Vec<SampleTime>, Vec<String>) {
    let by_token = gt.frame_index();
    let stamps = v2x_fuser::offline::capture_times(results);
    let first_us = gt.frames.iter().map(|f| f.timestamp_us).min().unwrap_or(0);
    let last_us = gt.frames.iter().map(|f| f.timestamp_us).max().unwrap_or(0);
    // a time within half a frame of the data's span still belongs to its first or last frame
    let margin_us = ((0.5e6 / gt.hz()) as u64).max(1_000);
    let mut known = Vec::new();
    let mut unknown = Vec::new();
    for (key, _) in results.in_file_order() {
        let frame = by_token.get(key.as_str()).copied();
        let stamp = stamps.as_ref().and_then(|m| m.get(key).copied());
        let frame_time = frame.map(|i| gt.frames[i].timestamp_us);
        let time = match timing {
            Timing::Frame => frame_time.or(stamp),
            Timing::Capture => stamp.or(frame_time),
        }
        .or_else(|| {
            key.strip_prefix('t')
                .and_then(|t| t.parse::<u64>().ok())
                .map(|t| match replay {
                    Some(m) => {
                        (first_us as f64 + (t as f64 - m.start_us as f64) * m.speed).max(0.0) as u64
                    }
                    None => t,
                })
        });
        match time
            .filter(|t| (first_us.saturating_sub(margin_us)..=last_us + margin_us).contains(t))
        {
            Some(t) => known.push(SampleTime {
                key: key.clone(),
                t_us: t,
                scene: frame.map_or_else(|| gt.scene_at(t), |i| gt.frames[i].scene),
                frame,
            }),
            None => unknown.push(key.clone()),
        }
    }
    (known, unknown)
}

/// How predictions are matched to ground truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Match {
    /// By ground-truth id when the file's boxes carry ids, else by distance.
    Auto,
    /// By ground-truth id, closest claimant first (the paper's protocol).
    Id,
    /// By centre distance, as the nuScenes detection benchmark (AP, TP errors, NDS).
    Distance,
}

/// The metrics of a file, by either protocol.
#[derive(Clone, Debug, serde::Serialize)]
#[serde(untagged)]
pub enum Evaluation {
    /// Matched by id.
    Id(Metrics),
    /// Matched by distance.
    Distance(DetectionMetrics),
}

/// How `v2x-sim eval` scores a results file.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    /// Count the ground-truth frames the file does not cover as all missed.
    pub all_frames: bool,
    /// How a recording of agents replaying on the real clock maps back to the data's time.
    pub replay: Option<ReplayMap>,
    /// How predictions are matched to ground truth.
    pub how: Match,
    /// When samples are scored.
    pub timing: Timing,
    /// The classes scored (ground truth and predictions of other classes are left out); `None`:
    /// all of them, the benchmark's headline averaged over the classes the ground truth holds.
    pub classes: Option<Vec<Class>>,
}

impl Default for EvalOptions {
    fn default() -> Self {
        EvalOptions {
            all_frames: false,
            replay: None,
            how: Match::Auto,
            timing: Timing::Frame,
            classes: None,
        }
    }
}

/// A scored sample whose ground truth holds fewer than this share of its predictions' count
/// counts as scored where the ground truth has (almost) nothing.
const SPARSE_SHARE: f64 = 0.1;

/// Scores a results file against the ground truth, each sample at its time ([`sample_times`]):
/// a time within 1 ms of a frame is that frame; between frames the ground truth is interpolated
/// along its tracks when it has tracks, else the nearest frame is taken, and either is said in
/// the note. Only the frames the file covers are scored unless `all_frames`, which counts every
/// other frame's objects as missed. Samples are added in the file's order (ties in score are
/// broken by it, as in the devkit). Returns the metrics and a note on coverage, timing,
/// classes and matching, with a warning when most predictions fall where the ground truth has
/// (almost) nothing.
pub fn evaluate_file(
    gt: &GroundTruth,
    path: &Path,
    opts: &EvalOptions,
) -> anyhow::Result<(Evaluation, String)> {
    let mut tokens = gt.tokens.clone();
    let results = read_results(
        path,
        &mut tokens,
        MissingStd::Default(Uncertainty::uniform(1.0, 1.0, 1.0)),
    )?;
    let tracked = gt.tracked_across_frames();
    if opts.timing == Timing::Capture && !tracked {
        bail!(
            "{}: --at capture interpolates the ground truth between frames, but no object in it is annotated in more than one frame; score each sample at its own frame (--at frame, the default)",
            path.display()
        );
    }
    let (samples, unknown) = sample_times(gt, &results, opts.replay, opts.timing);
    if !unknown.is_empty() {
        bail!(
            "{}: {} sample(s) are not in the ground truth, e.g. '{}' (is this the right --dataroot/--version, or the same synthetic town flags as when it was made? A recording of agents replaying on the real clock needs --replay-start-at and --replay-speed)",
            path.display(),
            unknown.len(),
            unknown[0]
        );
    }
    let keep = |c: Class| opts.classes.as_ref().is_none_or(|k| k.contains(&c));
    let mut covered = vec![false; gt.frames.len()];
    let mut acc = Accumulator::new();
    let mut det = DetectionEval::new();
    let has_ids = results.samples.values().flatten().any(|d| d.id != NO_ID);
    let by_distance = match opts.how {
        Match::Id => false,
        Match::Distance => true,
        Match::Auto => !has_ids,
    };
    let (mut scored, mut interpolated, mut nearest) = (0, 0, 0);
    let (mut predictions, mut sparse) = (0usize, 0usize);
    let mut predicted: BTreeMap<Class, usize> = BTreeMap::new();
    for st in &samples {
        let near = gt.nearest_frame(st.scene, st.t_us);
        let objects = match near {
            Some(i) if gt.frames[i].timestamp_us.abs_diff(st.t_us) <= 1_000 => {
                covered[i] = true;
                gt.frames[i].objects.clone()
            }
            // nothing to interpolate, or beyond the scene's first or last frame
            Some(i)
                if !tracked
                    || gt
                        .scene_span(st.scene)
                        .is_some_and(|(a, b)| st.t_us < a || st.t_us > b) =>
            {
                covered[i] = true;
                nearest += 1;
                gt.frames[i].objects.clone()
            }
            _ => {
                if let Some(i) = near {
                    covered[i] = true;
                }
                interpolated += 1;
                gt.objects_at(st.scene, st.t_us)
            }
        };
        let objects: Vec<GtObject> = objects.into_iter().filter(|o| keep(o.class)).collect();
        let mut preds: Vec<Detection> = Vec::new();
        for d in &results.samples[&st.key] {
            *predicted.entry(d.class).or_default() += 1;
            if keep(d.class) {
                preds.push(d.clone());
            }
        }
        predictions += preds.len();
        if !preds.is_empty() && (objects.len() as f64) < SPARSE_SHARE * preds.len() as f64 {
            sparse += preds.len();
        }
        if by_distance {
            det.add_frame(&objects, &preds);
        } else {
            acc.add_frame(&objects, &preds);
        }
        scored += 1;
    }
    let mut missed = 0;
    if opts.all_frames {
        for (i, f) in gt.frames.iter().enumerate() {
            if !covered[i] {
                let objects: Vec<GtObject> = f
                    .objects
                    .iter()
                    .filter(|o| keep(o.class))
                    .cloned()
                    .collect();
                if by_distance {
                    det.add_frame(&objects, &[]);
                } else {
                    acc.add_frame(&objects, &[]);
                }
                missed += 1;
            }
        }
    }
    let mut note = format!(
        "{}: scored {scored} samples of the file against {} ground-truth frames{}",
        path.display(),
        gt.frames.len(),
        if opts.all_frames {
            format!(", and {missed} frames the file does not cover as missed")
        } else {
            String::new()
        }
    );
    if interpolated > 0 {
        note += &format!(
            "; {interpolated} sample(s) scored at a time between frames, the ground truth interpolated along its tracks"
        );
    }
    if nearest > 0 {
        note += &format!(
            "; {nearest} sample(s) at a time between frames scored against the nearest frame (the ground truth has no tracks to interpolate there)"
        );
    }
    note += match (opts.how, by_distance) {
        (Match::Auto, true) => {
            "; matched by centre distance (nuScenes detection benchmark), as no box carries a ground-truth id"
        }
        (_, true) => "; matched by centre distance (nuScenes detection benchmark)",
        (Match::Auto, false) => {
            "; matched by ground-truth id (the paper's protocol), as the boxes carry ids (--match distance for the nuScenes benchmark)"
        }
        (_, false) => "; matched by ground-truth id (the paper's protocol)",
    };
    let (evaluation, scored_classes) = if by_distance {
        let classes = opts
            .classes
            .clone()
            .unwrap_or_else(|| det.ground_truth_classes());
        let m = det.summary_over(&classes);
        if opts.classes.is_none() {
            note += &format!(
                "; the headline averages the classes the ground truth holds ({}; --classes to choose; mAP_all10 and NDS_all10 over all ten)",
                m.classes.join(", ")
            );
        }
        (Evaluation::Distance(m), Some(classes))
    } else {
        (Evaluation::Id(acc.summary()), opts.classes.clone())
    };
    let left_out: Vec<String> = predicted
        .iter()
        .filter(|(c, _)| scored_classes.as_ref().is_some_and(|k| !k.contains(c)))
        .map(|(c, n)| format!("{c} {n}"))
        .collect();
    if !left_out.is_empty() {
        note += &format!(
            "; predicted boxes of classes not scored: {}",
            left_out.join(", ")
        );
    }
    if predictions > 0 && sparse as f64 > SPARSE_SHARE * predictions as f64 {
        note += &format!(
            "\nwarning: {sparse} of {predictions} predictions fall in samples whose ground truth holds fewer than a tenth as many objects: is the timing right (--at), and the data root?"
        );
    }
    Ok((evaluation, note))
}

/// Parses a comma-separated list of nuScenes detection names.
pub fn parse_classes(s: &str) -> Result<Vec<Class>, String> {
    s.split(',')
        .map(str::trim)
        .filter(|n| !n.is_empty())
        .map(|n| {
            Class::from_name(n).ok_or_else(|| {
                let known: Vec<&str> = Class::ALL.iter().map(|c| c.name()).collect();
                format!("unknown class '{n}' (known: {})", known.join(", "))
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .and_then(|v| {
            if v.is_empty() {
                Err("expected at least one class".into())
            } else {
                Ok(v)
            }
        })
}

/// Reads a file's text with the path in the error.
pub fn read_text(path: &Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))
}
