//! The keyword options of the offline functions (`fuse_results`, `fuse_files`, `track_files`),
//! checked as `v2x-fuser fuse` and `track` check their flags.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::collections::BTreeMap;
use std::path::PathBuf;
use v2x_fuser::offline::OfflineOptions;
use v2x_fuser::settings::{MotionSettings, SettingsError, StdSettings};
use v2x_fuser::time::align::AlignParams;
use v2x_fuser::tracker::TrackerParams;
use v2x_fuser::uncertainty::learn::LearnParams;
use v2x_fuser::uncertainty::stdmodel::ErrorModel;
use v2x_fuser::Method;
use v2x_protocol::nuscenes_json::MissingStd;

/// The options as the package's Python half passes them: every key present.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct Options {
    method: String,
    default_std: Option<String>,
    compensate: bool,
    speed_bound_mps: f64,
    accel_std: f64,
    time_scale: f64,
    window_ms: f64,
    align_to: Option<usize>,
    detector: bool,
    learn_std: bool,
    std_flag_ratio: f64,
    std_models: BTreeMap<String, PathBuf>,
    existence_model: String,
    min_score: f64,
    confirm_hits: Option<u32>,
    max_misses: u32,
    all_classes: bool,
    guided: bool,
    soft: bool,
}

/// A method by name.
pub fn method(name: &str) -> PyResult<Method> {
    name.parse()
        .map_err(|e: v2x_protocol::UnknownName| PyValueError::new_err(e.to_string()))
}

/// What to do with boxes without stds: fill in `default_std` (mild, moderate, large or
/// POS,SIZE,YAW_DEG), or without it refuse them.
pub fn missing_std(default_std: Option<&str>) -> PyResult<MissingStd> {
    Ok(match default_std {
        None => MissingStd::Error,
        Some(s) => MissingStd::Default(
            v2x_protocol::parse_std(s)
                .map_err(|e| PyValueError::new_err(format!("default_std: {e}")))?,
        ),
    })
}

impl Options {
    /// The method, how boxes without stds are read and the offline options, for `inputs` agents.
    pub fn offline(&self, inputs: usize) -> PyResult<(Method, MissingStd, OfflineOptions)> {
        let bad = |e: String| Err(PyValueError::new_err(e));
        // The motion and std groups of the command line's settings, checked as they check them.
        let setting = |e: SettingsError| PyValueError::new_err(e.to_string());
        let motion = MotionSettings {
            compensation: self.compensate,
            speed_bound_mps: self.speed_bound_mps,
            accel_std: self.accel_std,
            time_scale: self.time_scale,
        }
        .params()
        .map_err(setting)?;
        if !(self.window_ms > 0.0 && self.window_ms.is_finite()) {
            return bad("window_ms must be > 0".into());
        }
        let learn = StdSettings {
            learn_std: self.learn_std,
            std_flag_ratio: self.std_flag_ratio,
            ..Default::default()
        }
        .learn()
        .map_err(setting)?;
        let align = match self.align_to {
            None => None,
            Some(k) if k < inputs => Some((AlignParams::default(), k)),
            Some(k) => {
                return bad(format!(
                    "align_to {k}: there are {inputs} agents (give their index, 0 to {})",
                    inputs.saturating_sub(1)
                ))
            }
        };
        let models = self.models(inputs)?;
        if self.detector && (self.default_std.is_some() || self.learn_std) {
            return bad("detector gives every box its stds (or std_models an input's): leave out default_std and learn_std".into());
        }
        let replaced = self.learn_std || (inputs > 0 && models.len() >= inputs);
        let missing = match (&self.default_std, replaced) {
            // Every std is replaced by the detector's or a model's.
            _ if self.detector => MissingStd::Default(v2x_fuser::offline::kitti_default_std()),
            (Some(s), _) => missing_std(Some(s))?,
            (None, true) => MissingStd::Default(LearnParams::default().prior),
            (None, false) => MissingStd::Error,
        };
        let mut opts = OfflineOptions {
            motion,
            window_ms: self.window_ms,
            align,
            learn,
            models,
            detector: None,
            detector_params: v2x_fuser::offline::detector_params(
                &self.existence_model,
                self.min_score,
            )
            .map_err(|e| PyValueError::new_err(e.to_string()))?,
        };
        opts.detector = self.detector.then_some(opts.detector_params);
        opts.set_time_scale(self.time_scale);
        Ok((method(&self.method)?, missing, opts))
    }

    /// The error models by input: `std_models` names each input agentN, N from 1.
    fn models(&self, inputs: usize) -> PyResult<BTreeMap<usize, ErrorModel>> {
        let mut out = BTreeMap::new();
        for (agent, path) in &self.std_models {
            let n = agent
                .strip_prefix("agent")
                .and_then(|n| n.parse::<usize>().ok())
                .filter(|n| (1..=inputs).contains(n))
                .ok_or_else(|| {
                    PyValueError::new_err(format!(
                        "std_models: name the input as agentN, N from 1 to {inputs} (its position), not '{agent}'"
                    ))
                })?;
            let text = std::fs::read_to_string(path).map_err(|e| {
                PyValueError::new_err(format!(
                    "std_models {agent}: cannot read {}: {e}",
                    path.display()
                ))
            })?;
            let m = ErrorModel::from_json(&text).map_err(|e| {
                PyValueError::new_err(format!("std_models {agent}: {}: {e}", path.display()))
            })?;
            out.insert(n - 1, m);
        }
        Ok(out)
    }

    /// The tracker's parameters (`confirm_hits` as `v2x-fuser track` takes it).
    pub fn tracker(&self) -> PyResult<TrackerParams> {
        let confirm = self
            .confirm_hits
            .unwrap_or(TrackerParams::default().confirm_hits);
        // As `v2x-fuser track`: the files' capture times are the data's own, not a replay's.
        let mut p = tracker_params(confirm, self.max_misses, self.all_classes, 1.0)?;
        p.guided = self.guided;
        p.soft = self.soft;
        match p.conflict() {
            Some(why) => Err(PyValueError::new_err(format!(
                "soft: not with guided ({why})"
            ))),
            None => Ok(p),
        }
    }
}

/// The tracker's parameters from the options `v2x-fuser track` takes.
pub fn tracker_params(
    confirm_hits: u32,
    max_misses: u32,
    all_classes: bool,
    time_scale: f64,
) -> PyResult<TrackerParams> {
    if confirm_hits == 0 {
        return Err(PyValueError::new_err("confirm_hits must be at least 1"));
    }
    if !(time_scale > 0.0 && time_scale.is_finite()) {
        return Err(PyValueError::new_err("time_scale must be > 0"));
    }
    Ok(TrackerParams {
        confirm_hits,
        max_misses,
        all_classes,
        time_scale,
        ..Default::default()
    })
}
