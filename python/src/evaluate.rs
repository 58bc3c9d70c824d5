//! Scoring results against ground truth, as `v2x-sim eval` does (`v2x_eval::file_eval`).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use v2x_eval::file_eval::{self, EvalOptions, Match, Timing};
use v2x_protocol::Class;
use v2x_truth::town::TownConfig;

/// Ground truth to score against: nuScenes-format tables or the synthetic town.
#[pyclass(module = "v2x_fusion._native", frozen)]
pub struct GroundTruth {
    gt: v2x_truth::dataset::GroundTruth,
}

#[pymethods]
impl GroundTruth {
    /// The tables of a nuScenes-format data root (DATAROOT/VERSION/*.json).
    #[staticmethod]
    fn nuscenes(py: Python<'_>, dataroot: PathBuf, version: &str) -> PyResult<Self> {
        let gt = py
            .detach(|| v2x_truth::dataset::load_nuscenes(&dataroot, version))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(GroundTruth { gt })
    }

    /// The synthetic town `v2x-sim` makes with the same flags (--scenes, --seconds, --hz,
    /// --town-seed).
    #[staticmethod]
    #[pyo3(signature = (scenes=1, seconds=20.0, hz=10.0, seed=7))]
    fn town(py: Python<'_>, scenes: usize, seconds: f64, hz: f64, seed: u64) -> PyResult<Self> {
        if scenes == 0 || !(hz > 0.0 && hz.is_finite()) || !(seconds > 0.0 && seconds.is_finite()) {
            return Err(PyValueError::new_err(
                "the synthetic town needs scenes >= 1, hz > 0 and seconds > 0",
            ));
        }
        let cfg = TownConfig {
            scenes,
            seconds,
            hz,
            seed,
        };
        Ok(GroundTruth {
            gt: py.detach(|| v2x_truth::town::generate(&cfg)),
        })
    }

    /// The number of frames.
    fn __len__(&self) -> usize {
        self.gt.frames.len()
    }

    /// The sample tokens of the frames, in scene and time order.
    fn sample_tokens(&self) -> Vec<String> {
        self.gt
            .frames
            .iter()
            .map(|f| f.sample_token.clone())
            .collect()
    }
}

/// Scores the JSON of a results document (`label` names it in the note and errors). Returns the
/// JSON of the figures `v2x-sim eval --format json` prints and the note it writes.
#[pyfunction]
#[pyo3(signature = (gt, document, label, tracking, matching, at, all_frames, classes=None))]
#[allow(clippy::too_many_arguments)]
pub fn evaluate_json(
    py: Python<'_>,
    gt: &GroundTruth,
    document: &str,
    label: &str,
    tracking: bool,
    matching: &str,
    at: &str,
    all_frames: bool,
    classes: Option<Vec<String>>,
) -> PyResult<(String, String)> {
    let bad = |e: String| PyValueError::new_err(e);
    let path = Path::new(label);
    let gt = &gt.gt;
    if tracking {
        if classes.is_some() || at != "frame" {
            return Err(bad("tracking is scored at each sample's frame over the seven tracking classes: leave classes and at unset".into()));
        }
        return py.detach(|| {
            let tracks = v2x_eval::tracking_eval::parse_tracking(path, document)
                .map_err(|e| bad(e.to_string()))?;
            let (m, note) = file_eval::evaluate_tracking(gt, &tracks, path, all_frames)
                .map_err(|e| bad(e.0))?;
            Ok((to_json(&m), note.unwrap_or_default()))
        });
    }
    let how = match matching {
        "auto" => Match::Auto,
        "id" => Match::Id,
        "distance" => Match::Distance,
        m => return Err(bad(format!("match '{m}': expected auto, id or distance"))),
    };
    let timing = match at {
        "frame" => Timing::Frame,
        "capture" => Timing::Capture,
        t => return Err(bad(format!("at '{t}': expected frame or capture"))),
    };
    let classes = classes
        .map(|cs| {
            cs.iter()
                .map(|c| c.parse::<Class>())
                .collect::<Result<Vec<_>, _>>()
        })
        .transpose()
        .map_err(|e| bad(format!("classes: {e}")))?;
    let opts = EvalOptions {
        all_frames,
        replay: None,
        how,
        timing,
        classes,
    };
    py.detach(|| {
        let results = file_eval::parse_scored(gt, path, document).map_err(|e| bad(e.0))?;
        let (evaluation, note) =
            file_eval::evaluate_results(gt, &results, path, &opts).map_err(|e| bad(e.0))?;
        Ok((to_json(&evaluation), note))
    })
}

fn to_json(v: &impl serde::Serialize) -> String {
    serde_json::to_string(v).expect("metrics serialize")
}
