//! How each window is fused: method, window, a detector's scores, motion, stds and
//! registration, read by `fuse`, `track` and the node alike.

use super::SettingsError;
use crate::offline::OfflineOptions;
use crate::pipeline::Steps;
use crate::time::align::AlignParams;
use crate::time::motion::MotionParams;
use crate::uncertainty::detector::DetectorParams;
use crate::uncertainty::learn::LearnParams;
use crate::uncertainty::stdmodel::{ErrorModel, Models};
use crate::Method;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;
use std::path::PathBuf;
use v2x_protocol::nuscenes_json::MissingStd;
use v2x_protocol::{InvalidValue, Uncertainty};

/// How each window is fused: method, window, a detector's scores, motion, stds, registration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct FusionSettings {
    /// Fusion method of each window.
    #[cfg_attr(feature = "node", arg(long, short, default_value_t = Method::default(), value_parser = crate::maths::method::method_parser()))]
    pub method: Method,
    /// Window width delta t (ms), when the boxes carry capture times.
    #[cfg_attr(feature = "node", arg(long, default_value_t = FusionSettings::default().window_ms))]
    pub window_ms: f64,
    /// A detector's boxes and their scores.
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub detector: DetectorSettings,
    /// Motion compensation.
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub motion: MotionSettings,
    /// Where the stds come from.
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub stds: StdSettings,
    /// Registration.
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub align: AlignSettings,
}

impl Default for FusionSettings {
    fn default() -> Self {
        FusionSettings {
            method: Method::default(),
            window_ms: 100.0,
            detector: DetectorSettings::default(),
            motion: MotionSettings::default(),
            stds: StdSettings::default(),
            align: AlignSettings::default(),
        }
    }
}

impl FusionSettings {
    /// Every setting checked, without reading any file.
    pub fn check(&self) -> Result<(), SettingsError> {
        if !(self.window_ms > 0.0 && self.window_ms.is_finite()) {
            return Err(SettingsError::of("window_ms", "must be > 0"));
        }
        self.detector.check()?;
        self.motion.params()?;
        self.stds.learn()?;
        self.align.params()?;
        Ok(())
    }
}

/// How `fuse` and `track` (and the Python package) read files: which inputs' boxes are
/// refused for want of stds, and the offline steps.
impl FusionSettings {
    /// What to do with a box of the `inputs` files that states no std (`default_std`: fill it
    /// in), and the offline options, the model files read. The caller sets the reference agent
    /// of registration ([`OfflineOptions::reference`]).
    pub fn offline(
        &self,
        inputs: usize,
        default_std: Option<Uncertainty>,
    ) -> Result<(MissingStd, OfflineOptions), SettingsError> {
        self.check()?;
        if self.detector.detector && (default_std.is_some() || self.stds.learn_std) {
            return Err(SettingsError::of(
                "detector",
                "gives every box its stds (or --std-model an input's): leave out default_std and learn_std",
            ));
        }
        let models = self.models_by_input(inputs)?;
        let mut opts = OfflineOptions {
            steps: self.steps_with(Models::default())?,
            window_ms: self.window_ms,
            reference: 0,
            detector_params: self.detector.params()?,
        };
        opts.set_models(models);
        opts.set_time_scale(self.motion.time_scale);
        // A detector's boxes or a model for every input replace the stds; a learner starts
        // from its prior.
        let replaced = self.stds.learn_std || (inputs > 0 && opts.steps.models.0.len() >= inputs);
        let missing = match (default_std, replaced) {
            _ if self.detector.detector => MissingStd::Default(crate::offline::kitti_default_std()),
            (Some(u), _) => MissingStd::Default(u),
            (None, true) => MissingStd::Default(LearnParams::default().prior),
            (None, false) => MissingStd::Error,
        };
        Ok((missing, opts))
    }

    /// The per-window steps these settings give: the method and every step around it, the
    /// error models read from their files and keyed by agent name.
    pub fn steps(&self) -> Result<Steps, SettingsError> {
        self.steps_with(self.stds.models()?)
    }

    /// [`FusionSettings::steps`] with `models` as the error models.
    fn steps_with(&self, models: Models) -> Result<Steps, SettingsError> {
        let detector = self.detector.params()?;
        Ok(Steps {
            method: self.method,
            detector: self.detector.detector.then_some(detector),
            motion: self.motion.params()?,
            align: self.align.params()?,
            learn: self.stds.learn()?,
            models: std::sync::Arc::new(models),
        })
    }

    /// The error models by input position: each agent named agentN, 1 <= N <= `inputs`.
    fn models_by_input(&self, inputs: usize) -> Result<BTreeMap<usize, ErrorModel>, SettingsError> {
        self.stds
            .models()?
            .0
            .into_iter()
            .map(|(agent, m)| {
                let n = agent
                    .strip_prefix("agent")
                    .and_then(|n| n.parse::<usize>().ok())
                    .filter(|n| (1..=inputs).contains(n))
                    .ok_or_else(|| {
                        SettingsError::new(
                            &format!("std_models.{agent}"),
                            &format!("--std-model {agent}"),
                            format!(
                                "name the input as agentN, N from 1 to {inputs} (its position)"
                            ),
                        )
                    })?;
                Ok((n - 1, m))
            })
            .collect()
    }
}

/// A detector's boxes: stds from their scores, each fused box scored by its chance of being a
/// real object (`docs/method.md` §11).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct DetectorSettings {
    /// The inputs are a detector's boxes (docs/method.md §11): each box's stds from its score,
    /// replacing any it states (the receiver's without the pose term), or from the agent's
    /// --std-model when it has one; each fused box scored by its chance of being a real object
    /// (--existence-model), and --min-score the operating point. `fuse` and `track` take it for
    /// KITTI folders given without --default-std.
    #[cfg_attr(feature = "node", arg(long))]
    pub detector: bool,
    /// How a detector's fused boxes are scored: by the model fitted on V2V4Real's train split
    /// (`default`), by a model `v2x-sim fit-score` wrote for your detector (a JSON file), or
    /// (`noisy-or`) by the noisy-OR of the members' scores.
    #[cfg_attr(feature = "node", arg(long, default_value_t = DetectorSettings::default().existence_model, value_name = "default|noisy-or|FILE"))]
    pub existence_model: String,
    /// The operating point on a detector's scores, each a chance of being a real object: fused
    /// boxes scoring below it are left out; tracking gives the tracker every box and leaves out
    /// tracked boxes scoring below it. 0 keeps everything.
    #[cfg_attr(feature = "node", arg(long, default_value_t = DetectorParams::default().min_score))]
    pub min_score: f64,
}

impl Default for DetectorSettings {
    fn default() -> Self {
        DetectorSettings {
            detector: false,
            existence_model: "default".into(),
            min_score: DetectorParams::default().min_score,
        }
    }
}

impl DetectorSettings {
    /// The operating point checked (the model file is read by [`DetectorSettings::params`]).
    pub fn check(&self) -> Result<(), SettingsError> {
        if !(0.0..=1.0).contains(&self.min_score) {
            return Err(SettingsError::of(
                "min_score",
                format!(
                    "{} is not a chance: give a value from 0 to 1",
                    self.min_score
                ),
            ));
        }
        Ok(())
    }

    /// The detector's parameters wherever its treatment applies, the model file read and
    /// checked.
    pub fn params(&self) -> Result<DetectorParams, SettingsError> {
        use crate::uncertainty::existence::{ExistenceFile, ExistenceModel, DETECTOR_DEFAULT};
        self.check()?;
        let path = &self.existence_model;
        let bad = |why: String| {
            SettingsError::of(
                "existence_model",
                format!("{path}: {why} (give default, noisy-or or a model file `v2x-sim fit-score` wrote)"),
            )
        };
        let existence = match path.as_str() {
            "default" => Some(DETECTOR_DEFAULT),
            "noisy-or" => None,
            _ => {
                let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
                let file: ExistenceFile =
                    serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
                Some(ExistenceModel::try_from(file).map_err(|e| bad(e.to_string()))?)
            }
        };
        Ok(DetectorParams {
            min_score: self.min_score,
            existence,
            ..DetectorParams::default()
        })
    }
}

/// Motion compensation of a window to its latest capture time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct MotionSettings {
    /// Fuse boxes as captured, without predicting them to the window's reference time.
    #[cfg_attr(feature = "node", arg(long = "no-compensation", action = clap::ArgAction::SetFalse))]
    pub compensation: bool,
    /// Speed bound (m/s) for boxes without a velocity: their position variance grows by
    /// (v dt)^2 / 3 over dt.
    #[cfg_attr(feature = "node", arg(long, default_value_t = MotionSettings::default().speed_bound_mps))]
    pub speed_bound_mps: f64,
    /// Std of the unmodelled acceleration (m/s^2) in the constant-velocity prediction.
    #[cfg_attr(feature = "node", arg(long, default_value_t = MotionSettings::default().accel_std))]
    pub accel_std: f64,
    /// Seconds of motion per second of capture time: set it to the replay speed when agents
    /// replay recorded data faster than real time and stamp frames with the wall clock (motion
    /// compensation and, with --track, the tracks' prediction and velocities).
    #[cfg_attr(feature = "node", arg(long, default_value_t = 1.0))]
    #[serde(skip)]
    pub time_scale: f64,
}

impl Default for MotionSettings {
    fn default() -> Self {
        let p = MotionParams::default();
        MotionSettings {
            compensation: true,
            speed_bound_mps: p.speed_bound,
            accel_std: p.accel_std,
            time_scale: 1.0,
        }
    }
}

impl MotionSettings {
    /// The motion model (`None`: boxes fused as captured), at replay speed 1.
    pub fn params(&self) -> Result<Option<MotionParams>, SettingsError> {
        let ok = |x: f64| x >= 0.0 && x.is_finite();
        if !ok(self.speed_bound_mps) {
            return Err(SettingsError::of("speed_bound_mps", "must be >= 0"));
        }
        if !ok(self.accel_std) {
            return Err(SettingsError::of("accel_std", "must be >= 0"));
        }
        if !(self.time_scale > 0.0 && self.time_scale.is_finite()) {
            return Err(SettingsError::of(
                "time_scale",
                "must be > 0, the replay speed (1 live)",
            ));
        }
        Ok(self.compensation.then(|| MotionParams {
            accel_std: self.accel_std,
            speed_bound: self.speed_bound_mps,
            ..Default::default()
        }))
    }
}

/// Where each agent's stds come from: as stated, a calibrated model, or learned
/// (`docs/method.md` §10).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct StdSettings {
    /// An agent's error model, as `v2x-sim calibrate` writes it: its bias is taken off the
    /// agent's boxes and its stds replace the stated ones (per class and score bin). AGENT is
    /// the agent's name (fuse and track: agentN, N its input's position from 1). Repeatable.
    /// (A scenario: `std_models = { AGENT = "FILE" }`.)
    #[cfg_attr(feature = "node", arg(long = "std-model", value_name = "AGENT=FILE", value_parser = parse_model_arg))]
    #[serde(deserialize_with = "models_by_name", serialize_with = "models_as_map")]
    pub std_models: Vec<(String, PathBuf)>,
    /// Learn each agent's stds from its boxes as they flow, without ground truth (from how
    /// each agent's boxes of an object scatter about their track), and fuse with the learned
    /// stds instead of the stated ones; boxes without stds need no --default-std. Also flags an
    /// agent whose stated stds are off (the report: fuse and track print it and write
    /// meta.v2x_learned_std; node: the stats and MCAP).
    #[cfg_attr(feature = "node", arg(long))]
    pub learn_std: bool,
    /// With --learn-std: flag an agent whose stated centre stds are off by more than this
    /// factor, either way.
    #[cfg_attr(feature = "node", arg(long, requires = "learn_std", default_value_t = StdSettings::default().std_flag_ratio))]
    pub std_flag_ratio: f64,
}

impl Default for StdSettings {
    fn default() -> Self {
        StdSettings {
            std_models: Vec::new(),
            learn_std: false,
            std_flag_ratio: LearnParams::default().flag_ratio,
        }
    }
}

/// Splits AGENT=FILE.
pub fn parse_model_arg(s: &str) -> Result<(String, PathBuf), InvalidValue> {
    match s.split_once('=') {
        Some((a, f)) if !a.is_empty() && !f.is_empty() => Ok((a.to_owned(), f.into())),
        _ => Err(InvalidValue::new(
            "std model",
            "AGENT=FILE, e.g. agent2=rsu-model.json",
            s,
        )),
    }
}

/// A scenario's `{ AGENT = "FILE" }`, in name order.
fn models_by_name<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<(String, PathBuf)>, D::Error> {
    let map = std::collections::BTreeMap::<String, PathBuf>::deserialize(d)?;
    Ok(map.into_iter().collect())
}

/// [`models_by_name`] written back.
fn models_as_map<S: Serializer>(m: &[(String, PathBuf)], s: S) -> Result<S::Ok, S::Error> {
    s.collect_map(m.iter().map(|(a, p)| (a, p)))
}

impl StdSettings {
    /// The online learner (`None`: the stated stds are trusted).
    pub fn learn(&self) -> Result<Option<LearnParams>, SettingsError> {
        if !(self.std_flag_ratio > 1.0 && self.std_flag_ratio.is_finite()) {
            return Err(SettingsError::of("std_flag_ratio", "must be > 1"));
        }
        Ok(self.learn_std.then(|| LearnParams {
            flag_ratio: self.std_flag_ratio,
            ..Default::default()
        }))
    }

    /// The models by agent name, each file read and checked.
    pub fn models(&self) -> Result<Models, SettingsError> {
        let mut models = Models::default();
        for (agent, path) in &self.std_models {
            let bad = |e: String| {
                SettingsError::new(
                    &format!("std_models.{agent}"),
                    &format!("--std-model {agent}"),
                    format!("{}: {e}", path.display()),
                )
            };
            let text =
                std::fs::read_to_string(path).map_err(|e| bad(format!("cannot read: {e}")))?;
            let m = ErrorModel::from_json(&text).map_err(|e| bad(e.to_string()))?;
            if models.0.insert(agent.clone(), m).is_some() {
                return Err(bad("given twice".into()));
            }
        }
        Ok(models)
    }
}

/// Registration of agents whose own pose is wrong (`docs/method.md` §3.1).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct AlignSettings {
    /// Register every agent to a reference agent by the boxes both see, before association: a
    /// rigid shift and turn per agent, measured each window, filtered over time (decaying to
    /// none across gaps), and applied only when it differs significantly from no correction.
    /// Each estimate is reported (fuse: meta.v2x_registration; node: the stats and MCAP).
    #[cfg_attr(feature = "node", arg(long))]
    pub align: bool,
    /// With --align: the registration's settings, KEY=VALUE,... (a scenario's
    /// `[fuser.registration]` table, docs/guide.md); each key left out keeps its default.
    #[cfg_attr(feature = "node", arg(long, value_name = "KEY=VALUE,...", requires = "align", default_value = "", hide_default_value = true, value_parser = RegistrationSettings::parse, long_help = RegistrationSettings::help()))]
    pub registration: RegistrationSettings,
}

/// The registration's settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RegistrationSettings {
    /// Fewest matched boxes a window measures an offset from.
    pub min_matches: usize,
    /// Std per axis (m) of how far two agents' boxes of one object disagree at least, beyond
    /// their stated stds (a window whose matches scatter more is widened by it).
    pub disagreement_m: f64,
    /// Time constant (s) with which an estimate fades to none without matches.
    pub tau_s: f64,
    /// The chi-square (2 degrees of freedom) an estimated shift must reach against none to be
    /// applied (5.99: 95%; 0 applies every estimate).
    pub chi2: f64,
    /// The chi-square (1 degree of freedom) an estimated turn must reach against none to be
    /// applied (10.83: 99.9%; a turn moves far boxes by its lever arm).
    pub turn_chi2: f64,
    /// Largest centre distance (m) of a candidate match before any correction.
    pub gate_m: f64,
}

impl Default for RegistrationSettings {
    fn default() -> Self {
        let p = AlignParams::default();
        RegistrationSettings {
            min_matches: p.min_matches,
            disagreement_m: p.disagreement_m,
            tau_s: p.tau_s,
            chi2: p.chi2,
            turn_chi2: p.turn_chi2,
            gate_m: p.gate_m,
        }
    }
}

impl RegistrationSettings {
    /// `KEY=VALUE,...`, the keys of the scenario's `[fuser.registration]` table.
    pub fn parse(s: &str) -> Result<RegistrationSettings, String> {
        v2x_protocol::pairs::from_pairs(s)
    }

    /// The flag's help: what it takes, its keys and their defaults.
    pub fn help() -> String {
        format!(
            "With --align: the registration's settings, KEY=VALUE,... (a scenario's \
             [fuser.registration] table); each key left out keeps its default. Keys and \
             defaults: {}. min_matches: fewest matched boxes a window measures an offset from; \
             disagreement_m: least std per axis (m) of two agents' boxes of one object beyond \
             their stds; tau_s: time constant (s) with which an estimate fades without matches; \
             chi2, turn_chi2: the chi-square a shift (2 degrees of freedom) or turn (1) must \
             reach against none to be applied (0 applies every estimate); gate_m: largest centre \
             distance (m) of a candidate match (docs/method.md §3.1).",
            v2x_protocol::pairs::to_pairs(&RegistrationSettings::default())
        )
    }

    /// The registration's parameters, checked.
    pub fn params(&self) -> Result<AlignParams, SettingsError> {
        let p = AlignParams {
            min_matches: self.min_matches,
            disagreement_m: self.disagreement_m,
            tau_s: self.tau_s,
            chi2: self.chi2,
            turn_chi2: self.turn_chi2,
            gate_m: self.gate_m,
            ..Default::default()
        };
        p.validate()
            .map_err(|e| SettingsError::new("registration", "--registration", e.to_string()))?;
        Ok(p)
    }
}

impl AlignSettings {
    /// The registration (`None`: the agents' poses are trusted).
    pub fn params(&self) -> Result<Option<AlignParams>, SettingsError> {
        let p = self.registration.params()?;
        Ok(self.align.then_some(p))
    }
}
