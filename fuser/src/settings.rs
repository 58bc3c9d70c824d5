//! The fuser's settings, once: `v2x-fuser node`'s command line and a scenario's `[fuser]` table
//! read the same fields with the same defaults (`fuse` and `track` share the motion and std
//! groups), checked here, and turned here into the node's configuration with the replay speed
//! applied to every step that predicts over time.
//!
//! On the command line a field is the flag of its name (`max_wait_ms`: `--max-wait-ms`), except
//! where its doc says otherwise; in a scenario it is the key of its name, the registration's
//! under `[fuser.registration]`.

use crate::intake::ingest::{Area, IngestConfig};
use crate::time::align::AlignParams;
use crate::time::motion::MotionParams;
use crate::tracker::TrackerParams;
use crate::uncertainty::learn::LearnParams;
use crate::uncertainty::stdmodel::{ErrorModel, Models};
use crate::Method;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::path::PathBuf;
use v2x_protocol::InvalidValue;

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

/// Everything the fuser is set by, apart from where it runs (namespace, region, Zenoh).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct FuserSettings {
    /// Fusion method.
    #[cfg_attr(feature = "node", arg(long, short, default_value_t = FuserSettings::default().method))]
    pub method: Method,
    /// Window width delta t (ms).
    #[cfg_attr(feature = "node", arg(long, default_value_t = FuserSettings::default().window_ms))]
    pub window_ms: f64,
    /// Longest wait for missing live agents after a window's first frame (ms).
    #[cfg_attr(feature = "node", arg(long, default_value_t = FuserSettings::default().max_wait_ms))]
    pub max_wait_ms: f64,
    /// The agents send a detector's boxes with the stds it is given (as `v2x-agent` replays
    /// `v2x-sim gen --dataset v2v4real`'s files): each CSBA-3D group scored by its chance of
    /// being a real object (the default existence model) and fused boxes below 0.2 dropped, as
    /// `v2x-fuser fuse --detector` does with its defaults.
    #[cfg_attr(feature = "node", arg(long))]
    pub detector: bool,
    /// Admission limits.
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub admission: AdmissionSettings,
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
    /// Tracking.
    #[cfg_attr(feature = "node", command(flatten))]
    #[serde(flatten)]
    pub track: TrackSettings,
}

impl Default for FuserSettings {
    fn default() -> Self {
        FuserSettings {
            method: Method::default(),
            window_ms: 100.0,
            max_wait_ms: 150.0,
            detector: false,
            admission: AdmissionSettings::default(),
            motion: MotionSettings::default(),
            stds: StdSettings::default(),
            align: AlignSettings::default(),
            track: TrackSettings::default(),
        }
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
    /// The registration's settings (`--align-*`; a scenario's `[fuser.registration]`).
    #[cfg_attr(feature = "node", command(flatten))]
    pub registration: RegistrationSettings,
}

/// The registration's settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default, deny_unknown_fields)]
pub struct RegistrationSettings {
    /// With --align: fewest matched boxes a window measures an offset from.
    #[cfg_attr(feature = "node", arg(long = "align-min-matches", value_name = "ALIGN_MIN_MATCHES", requires = "align", default_value_t = AlignParams::default().min_matches))]
    pub min_matches: usize,
    /// With --align: std per axis (m) of how far two agents' boxes of one object disagree at
    /// least, beyond their stated stds (a window whose matches scatter more is widened by it).
    #[cfg_attr(feature = "node", arg(long = "align-disagreement-m", value_name = "ALIGN_DISAGREEMENT_M", requires = "align", default_value_t = AlignParams::default().disagreement_m))]
    pub disagreement_m: f64,
    /// With --align: time constant (s) with which an estimate fades to none without matches.
    #[cfg_attr(feature = "node", arg(long = "align-tau-s", value_name = "ALIGN_TAU_S", requires = "align", default_value_t = AlignParams::default().tau_s))]
    pub tau_s: f64,
    /// With --align: the chi-square (2 degrees of freedom) an estimated shift must reach against
    /// none to be applied (5.99: 95%; 0 applies every estimate).
    #[cfg_attr(feature = "node", arg(long = "align-chi2", value_name = "ALIGN_CHI2", requires = "align", default_value_t = AlignParams::default().chi2))]
    pub chi2: f64,
    /// With --align: the chi-square (1 degree of freedom) an estimated turn must reach against
    /// none to be applied (10.83: 99.9%; a turn moves far boxes by its lever arm).
    #[cfg_attr(feature = "node", arg(long = "align-turn-chi2", value_name = "ALIGN_TURN_CHI2", requires = "align", default_value_t = AlignParams::default().turn_chi2))]
    pub turn_chi2: f64,
    /// With --align: largest centre distance (m) of a candidate match before any correction.
    #[cfg_attr(feature = "node", arg(long = "align-gate-m", value_name = "ALIGN_GATE_M", requires = "align", default_value_t = AlignParams::default().gate_m))]
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
            .map_err(|e| SettingsError::new("registration", "--align", e.to_string()))?;
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

/// Tracking of the fused boxes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct TrackSettings {
    /// Also follow the fused boxes over time (`v2x-fuser track`'s tracker) and publish the
    /// tracks each window updated on v2x/NS/tracks, each box's id its track's (the seven
    /// classes of the nuScenes tracking benchmark, as `v2x-fuser track` writes them).
    #[cfg_attr(feature = "node", arg(long))]
    pub track: bool,
    /// With --track: also track barriers, traffic cones and construction vehicles.
    #[cfg_attr(feature = "node", arg(long, requires = "track"))]
    pub track_all_classes: bool,
    /// With --track: associate each agent's boxes with the tracks first and fuse between agents
    /// only the rest (`v2x-fuser track --guided`); the fused frames stay as they are.
    #[cfg_attr(feature = "node", arg(long, requires = "track"))]
    pub track_guided: bool,
    /// With --track: update each track with its fused boxes weighed by the chance each is its
    /// own (`v2x-fuser track --soft`, docs/method.md §8.2); not with --track-guided.
    #[cfg_attr(
        feature = "node",
        arg(long, requires = "track", conflicts_with = "track_guided")
    )]
    pub track_soft: bool,
}

impl TrackSettings {
    /// The tracker (`None`: no tracks).
    pub fn params(&self) -> Result<Option<TrackerParams>, SettingsError> {
        for (on, key) in [
            (self.track_guided, "track_guided"),
            (self.track_soft, "track_soft"),
            (self.track_all_classes, "track_all_classes"),
        ] {
            if on && !self.track {
                return Err(SettingsError::of(
                    key,
                    "set track too (it says how to track)",
                ));
            }
        }
        let params = TrackerParams {
            all_classes: self.track_all_classes,
            guided: self.track_guided,
            soft: self.track_soft,
            ..Default::default()
        };
        if let Some(why) = params.conflict() {
            return Err(SettingsError::of(
                "track_soft",
                format!("not with track_guided ({why})"),
            ));
        }
        Ok(self.track.then_some(params))
    }
}

/// Admission limits of the fuser node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct AdmissionSettings {
    /// Reject frames stamped further than this from the fuser's clock, ahead or behind (ms);
    /// 0 accepts any capture time (agents replaying data on its own clock, `v2x-agent --clock data`).
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().max_clock_skew_ms))]
    pub max_clock_skew_ms: f64,
    /// Most agents tracked at once; beyond, the least recently heard agent without a liveliness
    /// token is forgotten to make room.
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().max_agents))]
    pub max_agents: usize,
    /// Forget an agent with no frame and no liveliness token for this long (s).
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().forget_after_s))]
    pub forget_after_s: f64,
    /// Closed windows that may wait for fusion; beyond, windows are dropped and counted.
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().fusion_queue))]
    pub fusion_queue: usize,
    /// Interval of the rate-limited warning summaries (s).
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().log_interval_s))]
    pub log_interval_s: f64,
    /// Most boxes one agent brings into a window; beyond, its lowest-scoring boxes are dropped
    /// and counted (`over_budget`), so no agent can crowd the others out of the fused frame.
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().max_objects_per_agent))]
    pub max_objects_per_agent: usize,
    /// The area of interest, X,Y,RADIUS in metres of the map frame: boxes outside it are
    /// dropped and counted (`outside`). Default: a disc of --area-radius-m around where most
    /// agents are, learned from their first boxes. (A scenario: `area = [X, Y, RADIUS]`.)
    #[cfg_attr(feature = "node", arg(long, value_name = "X,Y,RADIUS", value_parser = Area::parse, allow_hyphen_values = true))]
    #[serde(
        deserialize_with = "area_from_triple",
        serialize_with = "area_as_triple"
    )]
    pub area: Option<Area>,
    /// The radius of the learned area of interest (m), without --area.
    #[cfg_attr(feature = "node", arg(long, default_value_t = AdmissionSettings::default().area_radius_m, conflicts_with = "area"))]
    pub area_radius_m: f64,
}

impl Default for AdmissionSettings {
    fn default() -> Self {
        let i = IngestConfig::default();
        AdmissionSettings {
            max_clock_skew_ms: i.max_clock_skew_us.map_or(0.0, |us| us as f64 / 1000.0),
            max_agents: i.max_agents,
            forget_after_s: i.forget_after_us as f64 / 1e6,
            fusion_queue: 16,
            log_interval_s: 10.0,
            max_objects_per_agent: i.max_objects,
            area: None,
            area_radius_m: i.area.radius_m(),
        }
    }
}

/// A scenario's `area = [X, Y, RADIUS]`.
fn area_from_triple<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Area>, D::Error> {
    let [x, y, r] = <[f64; 3]>::deserialize(d)?;
    Ok(Some(Area::Given {
        center: [x, y],
        radius_m: r,
    }))
}

/// [`area_from_triple`] written back (a learned area: none).
fn area_as_triple<S: Serializer>(a: &Option<Area>, s: S) -> Result<S::Ok, S::Error> {
    match a {
        Some(Area::Given { center, radius_m }) => [center[0], center[1], *radius_m].serialize(s),
        _ => s.serialize_none(),
    }
}

impl AdmissionSettings {
    /// The admission limits, checked, into `ingest`.
    pub fn apply(&self, ingest: &mut IngestConfig) -> Result<(), SettingsError> {
        let bad = |key: &str, problem: &str| Err(SettingsError::of(key, problem));
        if !(self.max_clock_skew_ms >= 0.0 && self.max_clock_skew_ms.is_finite()) {
            return bad("max_clock_skew_ms", "must be >= 0 (0 turns the check off)");
        }
        if !(self.forget_after_s > 0.0 && self.forget_after_s.is_finite()) {
            return bad("forget_after_s", "must be > 0");
        }
        if !(self.log_interval_s > 0.0 && self.log_interval_s.is_finite()) {
            return bad("log_interval_s", "must be > 0");
        }
        for (n, key) in [
            (self.max_agents, "max_agents"),
            (self.fusion_queue, "fusion_queue"),
            (self.max_objects_per_agent, "max_objects_per_agent"),
        ] {
            if n == 0 {
                return bad(key, "must be at least 1");
            }
        }
        if self.max_agents > v2x_protocol::limits::MAX_WINDOW_AGENTS {
            return bad(
                "max_agents",
                &format!(
                    "may be at most {} (the most agents a fused frame can name)",
                    v2x_protocol::limits::MAX_WINDOW_AGENTS
                ),
            );
        }
        let area = self.area.unwrap_or(Area::Learned {
            radius_m: self.area_radius_m,
        });
        if let Err(e) = area.validate() {
            return bad(
                if self.area.is_some() {
                    "area"
                } else {
                    "area_radius_m"
                },
                &e.to_string(),
            );
        }
        ingest.max_clock_skew_us =
            (self.max_clock_skew_ms > 0.0).then_some((self.max_clock_skew_ms * 1000.0) as u64);
        ingest.max_agents = self.max_agents;
        ingest.max_objects = self.max_objects_per_agent;
        ingest.area = area;
        ingest.forget_after_us = (self.forget_after_s * 1e6) as u64;
        Ok(())
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
        match serde_json::to_value(FuserSettings::default()) {
            Ok(serde_json::Value::Object(m)) => m.keys().cloned().collect(),
            _ => Vec::new(),
        }
    }

    /// Checks every setting without reading the model files.
    pub fn check(&self) -> Result<(), SettingsError> {
        self.check_window()?;
        self.admission.apply(&mut IngestConfig::default())?;
        self.motion.params()?;
        self.stds.learn()?;
        self.align.params()?;
        self.track.params()?;
        Ok(())
    }

    /// The window's width and wait.
    fn check_window(&self) -> Result<(), SettingsError> {
        if !(self.window_ms > 0.0 && self.window_ms.is_finite()) {
            return Err(SettingsError::of("window_ms", "must be > 0"));
        }
        if !(self.max_wait_ms >= 0.0 && self.max_wait_ms.is_finite()) {
            return Err(SettingsError::of("max_wait_ms", "must be >= 0"));
        }
        Ok(())
    }

    /// The node's configuration on namespace `ns`: every step from these settings, the model
    /// files read, the replay speed ([`MotionSettings::time_scale`]) applied once.
    #[cfg(feature = "node")]
    pub fn node_config(&self, ns: &str) -> Result<crate::node::NodeConfig, SettingsError> {
        self.check_window()?;
        let mut cfg = crate::node::NodeConfig::new(ns, self.method);
        cfg.window_ms = self.window_ms;
        cfg.max_wait_ms = self.max_wait_ms;
        cfg.detector = self
            .detector
            .then(crate::uncertainty::detector::DetectorParams::default);
        self.admission.apply(&mut cfg.ingest)?;
        cfg.queue = self.admission.fusion_queue;
        cfg.log_interval_s = self.admission.log_interval_s;
        cfg.motion = self.motion.params()?;
        cfg.align = self.align.params()?;
        cfg.learn = self.stds.learn()?;
        cfg.models = self.stds.models()?;
        cfg.track = self.track.params()?;
        cfg.set_time_scale(self.motion.time_scale);
        Ok(cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_and_the_defaults_agree_key_by_key() {
        let s: FuserSettings = toml_like(
            r#"{"method": "nms-3d", "window_ms": 50, "compensation": false,
                "registration": {"chi2": 3.0}, "track": true, "track_guided": true,
                "std_models": {"rsu": "m.json", "car": "c.json"}, "area": [1, 2, 30],
                "max_agents": 8}"#,
        );
        assert_eq!(s.method, Method::Nms3d);
        assert_eq!(s.window_ms, 50.0);
        assert!(!s.motion.compensation);
        // The replay speed is not a key: it comes from the run.
        assert_eq!(s.motion.time_scale, 1.0);
        assert_eq!(s.align.registration.chi2, 3.0);
        assert_eq!(
            s.align.registration.min_matches,
            AlignParams::default().min_matches
        );
        assert!(s.track.track && s.track.track_guided);
        assert_eq!(
            s.stds.std_models,
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
        assert_eq!(d.motion.params().unwrap(), Some(MotionParams::default()));
        assert_eq!(d.stds.learn().unwrap(), None);
        assert_eq!(d.align.params().unwrap(), None);
        assert_eq!(d.track.params().unwrap(), None);
    }

    #[test]
    fn each_bad_value_names_its_key_and_its_flag() {
        type Case = (fn(&mut FuserSettings), &'static str, &'static str);
        let cases: [Case; 8] = [
            (|s| s.window_ms = 0.0, "window_ms", "--window-ms"),
            (|s| s.motion.accel_std = -1.0, "accel_std", "--accel-std"),
            (
                |s| s.motion.time_scale = f64::NAN,
                "time_scale",
                "--time-scale",
            ),
            (|s| s.admission.max_agents = 0, "max_agents", "--max-agents"),
            (
                |s| s.admission.area_radius_m = -1.0,
                "area_radius_m",
                "--area-radius-m",
            ),
            (
                |s| s.track.track_guided = true,
                "track_guided",
                "--track-guided",
            ),
            (|s| s.track.track_soft = true, "track_soft", "--track-soft"),
            (
                |s| {
                    s.track.track = true;
                    s.track.track_guided = true;
                    s.track.track_soft = true;
                },
                "track_soft",
                "--track-soft",
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
            "track_guided",
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
