//! The keyword options of the offline functions (`fuse_results`, `fuse_files`, `track_files`):
//! the fuser's settings (`v2x_fuser::settings`) under their scenario keys, checked by them as
//! `v2x-fuser fuse` and `track` check their flags.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::{Map, Value};
use v2x_fuser::offline::OfflineOptions;
use v2x_fuser::settings::{keys_of, FusionSettings, SettingsError, TrackSettings};
use v2x_fuser::tracker::TrackerParams;
use v2x_fuser::Method;
use v2x_protocol::nuscenes_json::MissingStd;

/// The keys that are the files' own, not the fuser's: the stds of boxes that state none, the
/// reference agent of registration (0-based) and the replay speed.
const FILE_KEYS: [&str; 3] = ["default_std", "align_to", "time_scale"];

/// The options as the package's Python half passes them: the keywords given, and the method.
pub struct Options {
    fusion: FusionSettings,
    tracking: TrackSettings,
    default_std: Option<String>,
    align_to: Option<usize>,
}

impl<'a, 'py> FromPyObject<'a, 'py> for Options {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let dict = obj.cast::<PyDict>()?;
        let Value::Object(mut map) = crate::pyjson::to_value(&dict, &|| "options".into())? else {
            return Err(PyValueError::new_err("options: expected a dict"));
        };
        let mut known = keys_of::<FusionSettings>();
        known.extend(keys_of::<TrackSettings>());
        known.extend(FILE_KEYS.map(String::from));
        known.sort();
        if let Some(k) = map.keys().find(|k| !known.contains(k)) {
            return Err(PyValueError::new_err(format!(
                "unknown option '{k}' (expected one of: {})",
                known.join(", ")
            )));
        }
        let default_std = take(&mut map, "default_std")?;
        let align_to = take(&mut map, "align_to")?;
        let time_scale: Option<f64> = take(&mut map, "time_scale")?;
        let value = Value::Object(map);
        let bad = |e: serde_json::Error| PyValueError::new_err(format!("options: {e}"));
        let mut fusion: FusionSettings = serde_json::from_value(value.clone()).map_err(bad)?;
        if let Some(s) = time_scale {
            fusion.motion.time_scale = s;
        }
        let tracking: TrackSettings = serde_json::from_value(value).map_err(bad)?;
        Ok(Options {
            fusion,
            tracking,
            default_std,
            align_to,
        })
    }
}

/// Takes `key` out of `map`, None when absent or null.
fn take<T: serde::de::DeserializeOwned>(
    map: &mut Map<String, Value>,
    key: &str,
) -> PyResult<Option<T>> {
    match map.remove(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => serde_json::from_value(v)
            .map(Some)
            .map_err(|e| PyValueError::new_err(format!("{key}: {e}"))),
    }
}

/// A setting's error, by its key.
fn setting(e: SettingsError) -> PyErr {
    PyValueError::new_err(e.to_string())
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
        Some(s) => MissingStd::Default(parse_std(s)?),
    })
}

/// `default_std` read as the command line reads it.
fn parse_std(s: &str) -> PyResult<v2x_protocol::Uncertainty> {
    v2x_protocol::parse_std(s).map_err(|e| PyValueError::new_err(format!("default_std: {e}")))
}

impl Options {
    /// How boxes without stds are read and the offline options (the method among their steps),
    /// for `inputs` agents.
    pub fn offline(&self, inputs: usize) -> PyResult<(MissingStd, OfflineOptions)> {
        let default_std = self.default_std.as_deref().map(parse_std).transpose()?;
        let (missing, mut opts) = self.fusion.offline(inputs, default_std).map_err(setting)?;
        // align_to names the reference agent and turns registration on.
        let registration = self.fusion.align.registration.params().map_err(setting)?;
        match self.align_to {
            None if self.fusion.align.align => {
                return Err(PyValueError::new_err(
                    "align: give align_to, the reference agent's index",
                ))
            }
            None => opts.steps.align = None,
            Some(k) if k < inputs => {
                opts.steps.align = Some(registration);
                opts.reference = k;
            }
            Some(k) => {
                return Err(PyValueError::new_err(format!(
                    "align_to {k}: there are {inputs} agents (give their index, 0 to {})",
                    inputs.saturating_sub(1)
                )))
            }
        }
        Ok((missing, opts))
    }

    /// Refuses a tracking key, for the functions that do not track.
    pub fn refuse_tracking(&self) -> PyResult<()> {
        match self.tracking.first_set() {
            Some(key) => Err(PyValueError::new_err(format!(
                "{key}: a tracking option (track_files takes it)"
            ))),
            None => Ok(()),
        }
    }

    /// The tracker's parameters, as `v2x-fuser track` makes them.
    pub fn tracker(&self) -> PyResult<TrackerParams> {
        self.tracking.params().map_err(setting)
    }
}

/// The tracker's parameters of the `Tracker` class: `v2x-fuser track`'s, at `time_scale`.
pub fn tracker_params(tracking: &TrackSettings, time_scale: f64) -> PyResult<TrackerParams> {
    if !(time_scale > 0.0 && time_scale.is_finite()) {
        return Err(PyValueError::new_err("time_scale must be > 0"));
    }
    let mut p = tracking.params().map_err(setting)?;
    p.motion.time_scale = time_scale;
    Ok(p)
}
