//! The fuser's settings, each declared once: `v2x-fuser fuse`, `track` and `node`'s command
//! lines, a scenario's `[fuser]` table and the Python package's keywords read the same fields
//! with the same defaults, checked here, and turned here into the steps' parameters (the node's
//! configuration with the replay speed applied to every step that predicts over time). The
//! groups say who reads them: [`FusionSettings`] every command, [`TrackSettings`] what tracks,
//! [`AdmissionSettings`] the node.
//!
//! On the command line a field is the flag of its name (`max_wait_ms`: `--max-wait-ms`), except
//! where its doc says otherwise; in a scenario and in Python it is the key of its name, the
//! registration's under `registration` (`[fuser.registration]`, `--registration KEY=VALUE,...`).

use crate::intake::ingest::IngestConfig;
use crate::tracker::TrackerParams;
use serde::{Deserialize, Serialize};

mod admission;
mod fusion;
mod track;

pub use admission::AdmissionSettings;
pub use fusion::{
    parse_model_arg, AlignSettings, DetectorSettings, FusionSettings, MotionSettings,
    RegistrationSettings, StdSettings,
};
pub use track::TrackSettings;

/// A setting out of its range: its scenario key, its flag and what is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{key}: {problem}")]
pub struct SettingsError {
    /// The key in a scenario's `[fuser]` table.
    pub key: String,
    /// The command-line flag.
    pub flag: String,
    /// What is wrong.
    pub problem: String,
}

impl SettingsError {
    fn new(key: &str, flag: &str, problem: impl Into<String>) -> SettingsError {
        SettingsError {
            key: key.into(),
            flag: flag.into(),
            problem: problem.into(),
        }
    }

    /// A setting whose flag is its key's (`max_wait_ms`: `--max-wait-ms`).
    fn of(key: &str, problem: impl Into<String>) -> SettingsError {
        SettingsError::new(key, &format!("--{}", key.replace('_', "-")), problem)
    }

    /// The error as the command line says it: by its flag.
    pub fn on_command_line(&self) -> String {
        format!("{}: {}", self.flag, self.problem)
    }
}

/// The keys of a settings group as a scenario or Python names them, in name order.
pub fn keys_of<T: Serialize + Default>() -> Vec<String> {
    match serde_json::to_value(T::default()) {
        Ok(serde_json::Value::Object(m)) => m.keys().cloned().collect(),
        _ => Vec::new(),
    }
}

/// Everything the fuser is set by, apart from where it runs (namespace, region, Zenoh).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct FuserSettings {
    /// How each window is fused (the same for `fuse`, `track` and the node).
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub fusion: FusionSettings,
    /// Longest wait for missing live agents after a window's first frame (ms).
    #[cfg_attr(feature = "node", arg(long, default_value_t = FuserSettings::default().max_wait_ms))]
    pub max_wait_ms: f64,
    /// Admission limits.
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub admission: AdmissionSettings,
    /// Also follow the fused boxes over time (`v2x-fuser track`'s tracker) and publish the
    /// tracks each window updated on v2x/NS/tracks, each box's id its track's (the seven
    /// classes of the nuScenes tracking benchmark, as `v2x-fuser track` writes them).
    #[cfg_attr(feature = "node", arg(long))]
    pub track: bool,
    /// How the tracks are kept (with --track).
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub tracking: TrackSettings,
}

impl Default for FuserSettings {
    fn default() -> Self {
        FuserSettings {
            fusion: FusionSettings::default(),
            max_wait_ms: 150.0,
            admission: AdmissionSettings::default(),
            track: false,
            tracking: TrackSettings::default(),
        }
    }
}

impl FuserSettings {
    /// Of `keys` (a scenario's `[fuser]` table), those that name no setting.
    pub fn unknown_keys<'a>(keys: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
        let known = FuserSettings::keys();
        keys.into_iter()
            .filter(|k| !known.iter().any(|n| n == k))
            .collect()
    }

    /// Every key of a scenario's `[fuser]` table, in name order.
    pub fn keys() -> Vec<String> {
        keys_of::<FuserSettings>()
    }

    /// Checks every setting without reading the model files.
    pub fn check(&self) -> Result<(), SettingsError> {
        self.fusion.check()?;
        if !(self.max_wait_ms >= 0.0 && self.max_wait_ms.is_finite()) {
            return Err(SettingsError::of("max_wait_ms", "must be >= 0"));
        }
        self.admission.apply(&mut IngestConfig::default())?;
        self.tracker()?;
        Ok(())
    }

    /// The tracker (`None`: no tracks), at replay speed 1.
    pub fn tracker(&self) -> Result<Option<TrackerParams>, SettingsError> {
        if !self.track {
            if let Some(key) = self.tracking.first_set() {
                return Err(SettingsError::of(
                    key,
                    "set track too (it says how to track)",
                ));
            }
            return Ok(None);
        }
        self.tracking.params().map(Some)
    }

    /// The node's configuration on namespace `ns`: every step from these settings, the model
    /// files read, the replay speed ([`MotionSettings::time_scale`]) applied once.
    #[cfg(feature = "node")]
    pub fn node_config(&self, ns: &str) -> Result<crate::node::NodeConfig, SettingsError> {
        self.check()?;
        let f = &self.fusion;
        let mut cfg = crate::node::NodeConfig::new(ns, f.method);
        cfg.window_ms = f.window_ms;
        cfg.max_wait_ms = self.max_wait_ms;
        cfg.steps = f.steps()?;
        self.admission.apply(&mut cfg.ingest)?;
        cfg.queue = self.admission.fusion_queue;
        cfg.log_interval_s = self.admission.log_interval_s;
        cfg.track = self
            .tracker()?
            .map(|p| cfg.steps.detector.map_or(p, |d| d.tracker(p)));
        cfg.set_time_scale(f.motion.time_scale);
        Ok(cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::intake::ingest::Area;
    use crate::time::align::AlignParams;
    use crate::time::motion::MotionParams;
    use crate::tracker::Association;
    use crate::uncertainty::detector::DetectorParams;
    use crate::Method;

    #[test]
    fn a_table_and_the_defaults_agree_key_by_key() {
        let s: FuserSettings = toml_like(
            r#"{"method": "nms-3d", "window_ms": 50, "compensation": false,
                "registration": {"chi2": 3.0}, "track": true, "association": "guided",
                "std_models": {"rsu": "m.json", "car": "c.json"}, "area": [1, 2, 30],
                "max_agents": 8}"#,
        );
        let f = &s.fusion;
        assert_eq!(f.method, Method::Nms3d);
        assert_eq!(f.window_ms, 50.0);
        assert!(!f.motion.compensation);
        // The replay speed is not a key: it comes from the run.
        assert_eq!(f.motion.time_scale, 1.0);
        assert_eq!(f.align.registration.chi2, 3.0);
        assert_eq!(
            f.align.registration.min_matches,
            AlignParams::default().min_matches
        );
        assert!(s.track && s.tracking.association == Association::Guided);
        assert_eq!(
            f.stds.std_models,
            vec![
                ("car".into(), "c.json".into()),
                ("rsu".into(), "m.json".into())
            ]
        );
        assert_eq!(
            s.admission.area,
            Some(Area::Given {
                center: [1.0, 2.0],
                radius_m: 30.0
            })
        );
        assert_eq!(s.admission.max_agents, 8);
        let d = FuserSettings::default();
        assert_eq!(s.max_wait_ms, d.max_wait_ms);
        assert_eq!(toml_like("{}"), d);
    }

    #[test]
    fn the_defaults_are_the_steps_defaults() {
        let mut i = IngestConfig::default();
        let before = i.clone();
        FuserSettings::default().admission.apply(&mut i).unwrap();
        assert_eq!(format!("{i:?}"), format!("{before:?}"));
        let d = FuserSettings::default();
        let f = &d.fusion;
        assert_eq!(f.motion.params().unwrap(), Some(MotionParams::default()));
        assert_eq!(f.stds.learn().unwrap(), None);
        assert_eq!(f.align.params().unwrap(), None);
        assert_eq!(d.tracker().unwrap(), None);
        assert_eq!(d.tracking.params().unwrap(), TrackerParams::default());
        assert_eq!(f.detector.params().unwrap(), DetectorParams::default());
    }

    #[test]
    fn each_bad_value_names_its_key_and_its_flag() {
        type Case = (fn(&mut FuserSettings), &'static str, &'static str);
        let cases: [Case; 8] = [
            (|s| s.fusion.window_ms = 0.0, "window_ms", "--window-ms"),
            (
                |s| s.fusion.motion.accel_std = -1.0,
                "accel_std",
                "--accel-std",
            ),
            (
                |s| s.fusion.motion.time_scale = f64::NAN,
                "time_scale",
                "--time-scale",
            ),
            (
                |s| s.fusion.detector.min_score = 1.5,
                "min_score",
                "--min-score",
            ),
            (|s| s.admission.max_agents = 0, "max_agents", "--max-agents"),
            (
                |s| s.admission.area_radius_m = -1.0,
                "area_radius_m",
                "--area-radius-m",
            ),
            (
                |s| s.tracking.association = Association::Assignment,
                "association",
                "--association",
            ),
            (
                |s| {
                    s.track = true;
                    s.tracking.confirm_hits = 0;
                },
                "confirm_hits",
                "--confirm-hits",
            ),
        ];
        for (set, key, flag) in cases {
            let mut s = FuserSettings::default();
            set(&mut s);
            let e = s.check().unwrap_err();
            assert_eq!((e.key.as_str(), e.flag.as_str()), (key, flag));
            assert!(e.to_string().starts_with(&format!("{key}: ")), "{e}");
            assert!(e.on_command_line().starts_with(&format!("{flag}: ")));
        }
    }

    #[test]
    fn a_model_file_that_cannot_be_read_is_named() {
        let s = StdSettings {
            std_models: vec![("rsu".into(), "/nonexistent/m.json".into())],
            ..Default::default()
        };
        let e = s.models().unwrap_err();
        assert_eq!(e.key, "std_models.rsu");
        assert!(
            e.problem.starts_with("/nonexistent/m.json: cannot read"),
            "{e}"
        );
    }

    #[test]
    fn what_is_read_is_written_back_and_every_key_is_known() {
        let s: FuserSettings =
            toml_like(r#"{"method": "gt-wls", "std_models": {"a": "m.json"}, "area": [1, 2, 30]}"#);
        let back: FuserSettings =
            serde_json::from_value(serde_json::to_value(&s).unwrap()).unwrap();
        assert_eq!(back, s);
        let keys = FuserSettings::keys();
        for k in [
            "method",
            "compensation",
            "registration",
            "std_models",
            "area",
            "association",
            "existence_model",
            "min_score",
            "confirm_hits",
        ] {
            assert!(keys.iter().any(|x| x == k), "{k}");
        }
        assert!(!keys.iter().any(|x| x == "time_scale"));
        assert_eq!(
            FuserSettings::unknown_keys(["window_ms", "windw_ms", "time_scale"]),
            vec!["windw_ms", "time_scale"]
        );
    }

    fn toml_like(json: &str) -> FuserSettings {
        serde_json::from_str(json).unwrap()
    }
}
