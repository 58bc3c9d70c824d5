//! Scoring a results file against the ground truth: each sample placed in the data's time (its
//! frame, its capture time, or a replay's wall-clock time mapped back), matched by ground-truth id
//! (the paper's protocol) or by centre distance (the nuScenes detection benchmark), with a note
//! on what was scored and how.

use crate::detection_eval::{DetectionEval, DetectionMetrics};
use crate::metrics::{Accumulator, Metrics};
use crate::tracking_eval::{TrackBox, TrackingEval, TrackingMetrics};
use std::collections::BTreeMap;
use std::path::Path;
use v2x_protocol::nuscenes_json::{parse_results, MissingStd, Results};
use v2x_protocol::{Class, Detection, Uncertainty, NO_ID};
use v2x_truth::dataset::{GroundTruth, GtObject};

/// Why a results file could not be scored.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalError(pub String);

impl std::fmt::Display for EvalError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for EvalError {}

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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
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
) -> Result<(Evaluation, String), EvalError> {
    let results = read_scored(gt, path)?;
    evaluate_results(gt, &results, path, opts)
}

/// Scores parsed results as [`evaluate_file`] scores a file; `path` only names them in the note
/// and errors.
pub fn evaluate_results(
    gt: &GroundTruth,
    results: &Results,
    path: &Path,
    opts: &EvalOptions,
) -> Result<(Evaluation, String), EvalError> {
    let tracked = gt.tracked_across_frames();
    let samples = scorable_samples(gt, results, path, opts, tracked)?;
    let keep = |c: Class| opts.classes.as_ref().is_none_or(|k| k.contains(&c));
    let mut covered = vec![false; gt.frames.len()];
    let has_ids = results.samples.values().flatten().any(|d| d.id != NO_ID);
    let by_distance = match opts.how {
        Match::Id => false,
        Match::Distance => true,
        Match::Auto => !has_ids,
    };
    let mut scorer = match by_distance {
        true => Scorer::Distance(DetectionEval::new()),
        false => Scorer::Id(Accumulator::new()),
    };
    let mut t = Tally::default();
    for st in &samples {
        let objects: Vec<GtObject> = sample_objects(gt, st, tracked, &mut covered, &mut t)
            .into_iter()
            .filter(|o| keep(o.class))
            .collect();
        let mut preds: Vec<Detection> = Vec::new();
        for d in &results.samples[&st.key] {
            *t.predicted.entry(d.class).or_default() += 1;
            if keep(d.class) {
                preds.push(d.clone());
            }
        }
        t.predictions += preds.len();
        if !preds.is_empty() && (objects.len() as f64) < SPARSE_SHARE * preds.len() as f64 {
            t.sparse += preds.len();
        }
        scorer.add_frame(&objects, &preds);
        t.scored += 1;
    }
    if opts.all_frames {
        for (f, _) in gt.frames.iter().zip(&covered).filter(|(_, c)| !**c) {
            let objects: Vec<GtObject> = f
                .objects
                .iter()
                .filter(|o| keep(o.class))
                .cloned()
                .collect();
            scorer.add_frame(&objects, &[]);
            t.missed += 1;
        }
    }
    let mut note = coverage_note(gt, path, opts, by_distance, &t);
    let (evaluation, scored_classes) = match scorer {
        Scorer::Distance(det) => {
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
        }
        Scorer::Id(acc) => (Evaluation::Id(acc.summary()), opts.classes.clone()),
    };
    note += &classes_note(&t, scored_classes.as_deref());
    Ok((evaluation, note))
}

/// The file's samples with the time each is scored at; an error when one is not in the ground
/// truth, or capture times are asked of ground truth that is not tracked across frames.
fn scorable_samples(
    gt: &GroundTruth,
    results: &Results,
    path: &Path,
    opts: &EvalOptions,
    tracked: bool,
) -> Result<Vec<SampleTime>, EvalError> {
    if opts.timing == Timing::Capture && !tracked {
        return Err(EvalError(format!(
            "{}: --at capture interpolates the ground truth between frames, but no object in it is annotated in more than one frame; score each sample at its own frame (--at frame, the default)",
            path.display()
        )));
    }
    let (samples, unknown) = sample_times(gt, results, opts.replay, opts.timing);
    if !unknown.is_empty() {
        return Err(EvalError(format!(
            "{}: {} sample(s) are not in the ground truth, e.g. '{}' (is this the right --dataroot/--version, or the same synthetic town flags as when it was made? A recording of agents replaying on the real clock needs their --replay start_at and speed)",
            path.display(),
            unknown.len(),
            unknown[0]
        )));
    }
    Ok(samples)
}

/// What scores the frames: matching by ground-truth id, or by distance (nuScenes).
enum Scorer {
    /// The paper's protocol.
    Id(Accumulator),
    /// The nuScenes detection benchmark.
    Distance(DetectionEval),
}

impl Scorer {
    /// Scores one frame's predictions against its objects.
    fn add_frame(&mut self, objects: &[GtObject], preds: &[Detection]) {
        match self {
            Scorer::Id(acc) => acc.add_frame(objects, preds),
            Scorer::Distance(det) => det.add_frame(objects, preds),
        }
    }
}

/// Reads a results file to score against `gt`: stated stds play no part, so boxes without them
/// are read too.
pub fn read_scored(gt: &GroundTruth, path: &Path) -> Result<Results, EvalError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| EvalError(format!("{}: cannot read: {e}", path.display())))?;
    parse_scored(gt, path, &text)
}

/// Parses results JSON text to score against `gt`, as [`read_scored`] reads a file; `path` only
/// names the source in errors.
pub fn parse_scored(gt: &GroundTruth, path: &Path, text: &str) -> Result<Results, EvalError> {
    let mut tokens = gt.tokens.clone();
    parse_results(
        path,
        text,
        &mut tokens,
        MissingStd::Default(Uncertainty::uniform(1.0, 1.0, 1.0)),
    )
    .map_err(|e| EvalError(e.to_string()))
}

/// What scoring a file counted.
#[derive(Default)]
struct Tally {
    scored: usize,
    interpolated: usize,
    nearest: usize,
    missed: usize,
    predictions: usize,
    sparse: usize,
    predicted: BTreeMap<Class, usize>,
}

/// The ground truth a sample is scored against, marking the frame it covers: its frame when
/// within 1 ms, else interpolated along the tracks when there are any and the time lies within
/// its scene, else the nearest frame.
fn sample_objects(
    gt: &GroundTruth,
    st: &SampleTime,
    tracked: bool,
    covered: &mut [bool],
    t: &mut Tally,
) -> Vec<GtObject> {
    let near = gt.nearest_frame(st.scene, st.t_us);
    if let Some(i) = near {
        covered[i] = true;
    }
    match near {
        Some(i) if gt.frames[i].timestamp_us.abs_diff(st.t_us) <= 1_000 => {
            gt.frames[i].objects.clone()
        }
        // nothing to interpolate, or beyond the scene's first or last frame
        Some(i)
            if !tracked
                || gt
                    .scene_span(st.scene)
                    .is_some_and(|(a, b)| st.t_us < a || st.t_us > b) =>
        {
            t.nearest += 1;
            gt.frames[i].objects.clone()
        }
        _ => {
            t.interpolated += 1;
            gt.objects_at(st.scene, st.t_us)
        }
    }
}

/// The note on predicted classes left out, and a warning when most predictions fall where the
/// ground truth has (almost) nothing.
fn classes_note(t: &Tally, scored: Option<&[Class]>) -> String {
    let mut note = String::new();
    let left_out: Vec<String> = t
        .predicted
        .iter()
        .filter(|(c, _)| scored.is_some_and(|k| !k.contains(c)))
        .map(|(c, n)| format!("{c} {n}"))
        .collect();
    if !left_out.is_empty() {
        note += &format!(
            "; predicted boxes of classes not scored: {}",
            left_out.join(", ")
        );
    }
    if t.predictions > 0 && t.sparse as f64 > SPARSE_SHARE * t.predictions as f64 {
        let (sparse, predictions) = (t.sparse, t.predictions);
        note += &format!(
            "\nwarning: {sparse} of {predictions} predictions fall in samples whose ground truth holds fewer than a tenth as many objects: is the timing right (--at), and the data root?"
        );
    }
    note
}

/// The note on what was scored, when, and how it was matched.
fn coverage_note(
    gt: &GroundTruth,
    path: &Path,
    opts: &EvalOptions,
    by_distance: bool,
    t: &Tally,
) -> String {
    let mut note = format!(
        "{}: scored {} samples of the file against {} ground-truth frames{}",
        path.display(),
        t.scored,
        gt.frames.len(),
        if opts.all_frames {
            format!(
                ", and {} frames the file does not cover as missed",
                t.missed
            )
        } else {
            String::new()
        }
    );
    if t.interpolated > 0 {
        note += &format!(
            "; {} sample(s) scored at a time between frames, the ground truth interpolated along its tracks",
            t.interpolated
        );
    }
    if t.nearest > 0 {
        note += &format!(
            "; {} sample(s) at a time between frames scored against the nearest frame (the ground truth has no tracks to interpolate there)",
            t.nearest
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
    note
}

/// Scores tracking results (per sample, as [`crate::tracking_eval::read_tracking`] reads them)
/// as the nuScenes tracking benchmark does, over the ground truth's frames in time order: only
/// the frames the results have, or with `all_frames` every frame (absent ones all missed).
/// Returns the figures and, when boxes of classes the benchmark does not score were left out, a
/// note saying so; `path` only names the results.
pub fn evaluate_tracking(
    gt: &GroundTruth,
    tracks: &BTreeMap<String, Vec<TrackBox>>,
    path: &Path,
    all_frames: bool,
) -> Result<(TrackingMetrics, Option<String>), EvalError> {
    let known: std::collections::HashSet<&str> =
        gt.frames.iter().map(|f| f.sample_token.as_str()).collect();
    if let Some(s) = tracks.keys().find(|s| !known.contains(s.as_str())) {
        return Err(EvalError(format!(
            "{}: sample {s} is not in the ground truth: score the file against the data it was made from (--dataroot/--version, or the same town flags)",
            path.display()
        )));
    }
    let mut other: BTreeMap<&str, usize> = BTreeMap::new();
    for b in tracks.values().flatten() {
        if !b.class.is_tracking() {
            *other.entry(b.class.name()).or_default() += 1;
        }
    }
    let note = (!other.is_empty()).then(|| {
        let list: Vec<String> = other.iter().map(|(c, n)| format!("{c} {n}")).collect();
        format!(
            "{}: boxes of classes the tracking benchmark does not score were left out ({}); the official devkit refuses a file with them",
            path.display(),
            list.join(", ")
        )
    });
    let mut eval = TrackingEval::new();
    for f in &gt.frames {
        match tracks.get(&f.sample_token) {
            Some(boxes) => eval.add_frame(f.scene, f.timestamp_us, &f.objects, boxes),
            None if all_frames => eval.add_frame(f.scene, f.timestamp_us, &f.objects, &[]),
            None => {}
        }
    }
    Ok((eval.summary(), note))
}
