//! Command-line pieces shared by the `v2x-sim` subcommands: where the ground truth comes from,
//! and reading predictions against it.

use crate::dataset::{load_nuscenes, GroundTruth};
use crate::detection_eval::{DetectionEval, DetectionMetrics};
use crate::metrics::{Accumulator, Metrics};
use crate::town::{generate, TownConfig};
use anyhow::{bail, Context};
use clap::Args;
use std::path::{Path, PathBuf};
use v2x_protocol::nuscenes_json::{read_results, MissingStd};
use v2x_protocol::{Uncertainty, NO_ID};

/// Where the ground truth comes from: nuScenes tables, or the synthetic town (the default).
#[derive(Args, Clone, Debug)]
pub struct DataArgs {
    /// nuScenes data root (the folder holding VERSION/); without it, the synthetic town is used.
    #[arg(long, requires = "version")]
    pub dataroot: Option<PathBuf>,
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

    /// Loads or generates the ground truth.
    pub fn load(&self) -> anyhow::Result<GroundTruth> {
        match (&self.dataroot, &self.version) {
            (Some(root), Some(version)) => Ok(load_nuscenes(root, version)?),
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

/// Each sample of a results file with its time (us) and scene: the `v2x_timestamps` entry of
/// the file's meta, else the time of the sample token's frame, else the `t<microseconds>` of a
/// key mapped through `replay`. Keys with no time in the ground truth's span are returned apart.
pub fn sample_times(
    gt: &GroundTruth,
    results: &v2x_protocol::nuscenes_json::Results,
    replay: Option<ReplayMap>,
) -> (Vec<(String, u64, usize)>, Vec<String>) {
    let by_token = gt.frame_index();
    let stamps = v2x_fuser::offline::capture_times(results);
    let first_us = gt.frames.iter().map(|f| f.timestamp_us).min().unwrap_or(0);
    let last_us = gt.frames.iter().map(|f| f.timestamp_us).max().unwrap_or(0);
    let mut known = Vec::new();
    let mut unknown = Vec::new();
    for key in results.samples.keys() {
        let time = stamps
            .as_ref()
            .and_then(|m| m.get(key).copied())
            .or_else(|| {
                by_token
                    .get(key.as_str())
                    .map(|&i| gt.frames[i].timestamp_us)
            })
            .or_else(|| {
                key.strip_prefix('t')
                    .and_then(|t| t.parse::<u64>().ok())
                    .map(|t| match replay {
                        Some(m) => (first_us as f64 + (t as f64 - m.start_us as f64) * m.speed)
                            .max(0.0) as u64,
                        None => t,
                    })
            });
        match time.filter(|t| (first_us.saturating_sub(1_000)..=last_us + 1_000).contains(t)) {
            Some(t) => {
                let scene = by_token
                    .get(key.as_str())
                    .map_or_else(|| gt.scene_at(t), |&i| gt.frames[i].scene);
                known.push((key.clone(), t, scene));
            }
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

/// Scores a results file against the ground truth. Each sample is scored at its time against
/// the ground truth of that instant: the time is the `v2x_timestamps` entry of the file's meta
/// when there is one (fused output carries its windows' reference times there), else the time
/// of the sample token's frame, else the `t<microseconds>` of a key (as the fuser node records
/// them, mapped back through `replay` when the agents replayed on the real clock). A time within
/// 1 ms of a frame is that frame; between frames the ground truth is interpolated. Only the
/// frames the file covers are scored unless `all_frames`, which counts every other frame's
/// objects as missed. `how` says how predictions are matched to ground truth. Returns the
/// metrics and a note on coverage and matching.
pub fn evaluate_file(
    gt: &GroundTruth,
    path: &Path,
    all_frames: bool,
    replay: Option<ReplayMap>,
    how: Match,
) -> anyhow::Result<(Evaluation, String)> {
    let mut tokens = gt.tokens.clone();
    let results = read_results(
        path,
        &mut tokens,
        MissingStd::Default(Uncertainty::uniform(1.0, 1.0, 1.0)),
    )?;
    let (samples, unknown) = sample_times(gt, &results, replay);
    let mut covered = vec![false; gt.frames.len()];
    let mut acc = Accumulator::new();
    let mut det = DetectionEval::new();
    let has_ids = results.samples.values().flatten().any(|d| d.id != NO_ID);
    let by_distance = match how {
        Match::Id => false,
        Match::Distance => true,
        Match::Auto => !has_ids,
    };
    let mut scored = 0;
    for (key, t, scene) in &samples {
        let near = gt.nearest_frame(*scene, *t);
        let objects = match near {
            Some(i) if gt.frames[i].timestamp_us.abs_diff(*t) <= 1_000 => {
                covered[i] = true;
                gt.frames[i].objects.clone()
            }
            _ => {
                if let Some(i) = near {
                    covered[i] = true;
                }
                gt.objects_at(*scene, *t)
            }
        };
        if by_distance {
            det.add_frame(&objects, &results.samples[key]);
        } else {
            acc.add_frame(&objects, &results.samples[key]);
        }
        scored += 1;
    }
    if !unknown.is_empty() {
        bail!(
            "{}: {} sample(s) are not in the ground truth, e.g. '{}' (is this the right --dataroot/--version, or the same synthetic town flags as when it was made? A recording of agents replaying on the real clock needs --replay-start-at and --replay-speed)",
            path.display(),
            unknown.len(),
            unknown[0]
        );
    }
    let mut missed = 0;
    if all_frames {
        for (i, f) in gt.frames.iter().enumerate() {
            if !covered[i] {
                if by_distance {
                    det.add_frame(&f.objects, &[]);
                } else {
                    acc.add_frame(&f.objects, &[]);
                }
                missed += 1;
            }
        }
    }
    let note = format!(
        "{}: scored {scored} samples of the file against {} ground-truth frames{}",
        path.display(),
        gt.frames.len(),
        if all_frames {
            format!(", and {missed} frames the file does not cover as missed")
        } else {
            String::new()
        }
    );
    let matching = match (how, by_distance) {
        (Match::Auto, true) => {
            "; matched by centre distance (nuScenes detection benchmark), as no box carries a ground-truth id"
        }
        (_, true) => "; matched by centre distance (nuScenes detection benchmark)",
        (Match::Auto, false) => {
            "; matched by ground-truth id (the paper's protocol), as the boxes carry ids (--match distance for the nuScenes benchmark)"
        }
        (_, false) => "; matched by ground-truth id (the paper's protocol)",
    };
    let evaluation = if by_distance {
        Evaluation::Distance(det.summary())
    } else {
        Evaluation::Id(acc.summary())
    };
    Ok((evaluation, format!("{note}{matching}")))
}

/// Reads a file's text with the path in the error.
pub fn read_text(path: &Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))
}
