//! Command-line pieces shared by the `v2x-sim` subcommands: where the ground truth comes from,
//! and reading predictions against it.

use crate::dataset::{load_nuscenes, GroundTruth};
use crate::metrics::{Accumulator, Metrics};
use crate::town::{generate, TownConfig};
use anyhow::{bail, Context};
use clap::Args;
use std::path::{Path, PathBuf};
use v2x_protocol::nuscenes_json::{read_results, MissingStd};
use v2x_protocol::Uncertainty;

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

/// Scores a results file against the ground truth. Samples are matched by sample token, or by
/// `t<microseconds>` keys (as the fuser node records them) against frame timestamps, mapped back
/// through `replay` when the agents replayed on the real clock. Only frames present in the file
/// are scored unless `all_frames`. Returns the metrics and a note on coverage.
pub fn evaluate_file(
    gt: &GroundTruth,
    path: &Path,
    all_frames: bool,
    replay: Option<ReplayMap>,
) -> anyhow::Result<(Metrics, String)> {
    let mut tokens = gt.tokens.clone();
    let results = read_results(
        path,
        &mut tokens,
        MissingStd::Default(Uncertainty::uniform(1.0, 1.0, 1.0)),
    )?;
    let by_token = gt.frame_index();
    let mut by_time: Vec<(u64, usize)> = gt
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| (f.timestamp_us, i))
        .collect();
    by_time.sort_unstable();
    // `t<us>` keys (fuser recordings) match the nearest frame within 50 ms.
    let nearest = |t: u64| -> Option<usize> {
        let k = by_time.partition_point(|&(ts, _)| ts < t);
        [k.checked_sub(1), Some(k)]
            .into_iter()
            .flatten()
            .filter_map(|j| by_time.get(j))
            .filter(|(ts, _)| ts.abs_diff(t) <= 50_000)
            .min_by_key(|(ts, _)| ts.abs_diff(t))
            .map(|&(_, i)| i)
    };
    let first_us = gt.frames.iter().map(|f| f.timestamp_us).min().unwrap_or(0);
    let to_data_time = |t: u64| -> u64 {
        match replay {
            Some(m) => (first_us as f64 + (t as f64 - m.start_us as f64) * m.speed).max(0.0) as u64,
            None => t,
        }
    };
    let mut preds: Vec<Option<&[v2x_protocol::Detection]>> = vec![None; gt.frames.len()];
    let mut unknown = Vec::new();
    for (key, dets) in &results.samples {
        let frame = by_token.get(key.as_str()).copied().or_else(|| {
            key.strip_prefix('t')
                .and_then(|t| t.parse::<u64>().ok())
                .map(to_data_time)
                .and_then(nearest)
        });
        match frame {
            Some(i) => preds[i] = Some(dets),
            None => unknown.push(key.clone()),
        }
    }
    if !unknown.is_empty() {
        bail!(
            "{}: {} sample(s) are not in the ground truth, e.g. '{}' (is this the right --dataroot/--version, or the same synthetic town flags as when it was made? A recording of agents replaying on the real clock needs --replay-start-at and --replay-speed)",
            path.display(),
            unknown.len(),
            unknown[0]
        );
    }
    let mut acc = Accumulator::new();
    let mut scored = 0;
    for (i, f) in gt.frames.iter().enumerate() {
        match preds[i] {
            Some(d) => acc.add_frame(&f.objects, d),
            None if all_frames => acc.add_frame(&f.objects, &[]),
            None => continue,
        }
        scored += 1;
    }
    let present = preds.iter().filter(|p| p.is_some()).count();
    let note = format!(
        "{}: scored {scored} of {} ground-truth frames ({present} in the file)",
        path.display(),
        gt.frames.len()
    );
    Ok((acc.summary(), note))
}

/// Reads a file's text with the path in the error.
pub fn read_text(path: &Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))
}
