//! Scenario files (TOML): the data, the agents with their kind, noise, sensing range and link,
//! the fuser's method and window, the run's length and speed, and each role's Zenoh endpoints.
//! `scenarios/` holds examples; the README documents every field.

use crate::cli::DataArgs;
use crate::faults::Faults;
use crate::noise::{AgentNoise, NoiseSetting};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use v2x_agent::Link;
use v2x_fuser::Method;
use v2x_protocol::net::ZenohArgs;
use v2x_protocol::{keys, AgentKind};

/// The embedded default scenario (`scenarios/default.toml`).
pub const DEFAULT: &str = include_str!("../../scenarios/default.toml");

/// Where the ground truth comes from.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct DatasetSpec {
    /// nuScenes data root (absent: the synthetic town). Relative to the scenario file.
    pub dataroot: Option<PathBuf>,
    /// nuScenes version folder.
    pub version: Option<String>,
    /// Synthetic town: scenes.
    pub scenes: usize,
    /// Synthetic town: seconds per scene.
    pub seconds: f64,
    /// Synthetic town: frames per second.
    pub hz: f64,
    /// Synthetic town: layout seed.
    pub town_seed: u64,
}

impl Default for DatasetSpec {
    fn default() -> Self {
        DatasetSpec {
            dataroot: None,
            version: None,
            scenes: 1,
            seconds: 20.0,
            hz: 10.0,
            town_seed: 7,
        }
    }
}

impl DatasetSpec {
    /// The same as command-line data arguments.
    pub fn data_args(&self) -> DataArgs {
        DataArgs {
            dataroot: self.dataroot.clone(),
            version: self.version.clone(),
            scenes: self.scenes,
            seconds: self.seconds,
            hz: self.hz,
            validation_size: false,
            town_seed: self.town_seed,
        }
    }
}

/// The fuser role.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct FuserSpec {
    /// Method name (`v2x-fuser fuse --help` lists them).
    pub method: String,
    /// Window width delta t (ms).
    pub window_ms: f64,
    /// Longest wait for missing live agents (ms).
    pub max_wait_ms: f64,
    /// Motion-compensate each window to its latest capture time.
    pub compensation: bool,
    /// Register every agent to the roadside unit by its boxes before association
    /// (`v2x-fuser node --align`).
    pub align: bool,
    /// Follow the fused boxes over time and publish tracks on `v2x/NS/tracks`
    /// (`v2x-fuser node --track`).
    pub track: bool,
    /// The fuser's Zenoh options (used when roles run on separate hosts).
    pub zenoh: ZenohArgs,
}

impl Default for FuserSpec {
    fn default() -> Self {
        FuserSpec {
            method: "csba-wls+".into(),
            window_ms: 100.0,
            max_wait_ms: 150.0,
            compensation: true,
            align: false,
            track: false,
            zenoh: ZenohArgs::default(),
        }
    }
}

/// How the roles talk to each other.
#[derive(Copy, Clone, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum SecurityMode {
    /// Plain TCP between peers, no access control.
    #[default]
    Plain,
    /// Mutual TLS through a Zenoh router that holds the access-control policy; every role is a
    /// client of the router.
    Mtls,
}

impl SecurityMode {
    /// The mode's name.
    pub fn name(self) -> &'static str {
        match self {
            SecurityMode::Plain => "plain",
            SecurityMode::Mtls => "mtls",
        }
    }
}

/// Security of a run.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct SecuritySpec {
    /// `plain` or `mtls`.
    pub mode: SecurityMode,
    /// A directory written by `v2x-sim certs` (relative to the scenario file); required when
    /// roles run on separate hosts. A one-process run without it makes its own certificates.
    pub certs: Option<PathBuf>,
    /// The router role's Zenoh options (used with `--role router`).
    pub router: ZenohArgs,
}

/// One agent role.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AgentSpec {
    /// Name (the last segment of v2x/NS/det/NAME).
    pub name: String,
    /// vehicle or infrastructure.
    #[serde(default)]
    pub kind: AgentKind,
    /// Noise: mild, moderate, large, realistic, or "POS,SIZE,YAW_DEG".
    pub noise: String,
    /// Detector faults: none, realistic, or "KEY=VALUE,..." (`v2x-sim gen --help` lists the
    /// keys); absent: the noise profile's own (none, except for `realistic`).
    #[serde(default)]
    pub faults: Option<String>,
    /// Sensing range (m); absent: the agent sees every object.
    #[serde(default)]
    pub range_m: Option<f64>,
    /// Capture rate (Hz); absent: the data's frame rate.
    #[serde(default)]
    pub hz: Option<f64>,
    /// Capture phase: the first capture comes this long after the data's first frame (ms).
    #[serde(default)]
    pub phase_ms: f64,
    /// The simulated link and clock.
    #[serde(default)]
    pub link: Link,
    /// The agent's Zenoh options (used when roles run on separate hosts).
    #[serde(default)]
    pub zenoh: ZenohArgs,
}

impl AgentSpec {
    /// The agent's noise with its faults (checked when the scenario loaded).
    pub fn agent_noise(&self) -> AgentNoise {
        let mut n: AgentNoise = self
            .noise
            .parse()
            .expect("checked when the scenario loaded");
        if let Some(f) = &self.faults {
            n.faults = f.parse().expect("checked when the scenario loaded");
        }
        n
    }
}

/// A whole scenario.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Namespace of every key (v2x/NS/...).
    #[serde(default = "default_ns")]
    pub namespace: String,
    /// Seed of the noise and link simulation.
    #[serde(default = "one")]
    pub seed: u64,
    /// How long to replay (s of data).
    #[serde(default = "twenty")]
    pub duration_s: f64,
    /// Playback speed factor.
    #[serde(default = "onef")]
    pub speed: f64,
    /// Ground truth.
    #[serde(default)]
    pub dataset: DatasetSpec,
    /// The fuser.
    #[serde(default)]
    pub fuser: FuserSpec,
    /// Plain, or mutual TLS through a router with access control.
    #[serde(default)]
    pub security: SecuritySpec,
    /// The agents, in fusion order.
    pub agents: Vec<AgentSpec>,
    /// What happens to which agent when (`[[events]]`, [`crate::timeline`]).
    #[serde(default)]
    pub events: Vec<crate::timeline::EventSpec>,
}

fn default_ns() -> String {
    "default".into()
}
fn one() -> u64 {
    1
}
fn twenty() -> f64 {
    20.0
}
fn onef() -> f64 {
    1.0
}

impl Scenario {
    /// Parses and checks a scenario; `source` names it in errors, `base` resolves relative paths.
    pub fn parse(text: &str, source: &str, base: Option<&Path>) -> anyhow::Result<Scenario> {
        let mut s: Scenario = toml::from_str(text).map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
        if let (Some(root), Some(base)) = (&s.dataset.dataroot, base) {
            if root.is_relative() {
                s.dataset.dataroot = Some(base.join(root));
            }
        }
        if let (Some(certs), Some(base)) = (&s.security.certs, base) {
            if certs.is_relative() {
                s.security.certs = Some(base.join(certs));
            }
        }
        s.check().map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
        Ok(s)
    }

    /// Reads a scenario file.
    pub fn load(path: &Path) -> anyhow::Result<Scenario> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
        Scenario::parse(&text, &path.display().to_string(), path.parent())
    }

    fn check(&self) -> Result<(), String> {
        keys::validate_chunk("namespace", &self.namespace)?;
        if self.agents.is_empty() {
            return Err("a scenario needs at least one [[agents]] entry".into());
        }
        if !(self.duration_s > 0.0 && self.duration_s.is_finite()) {
            return Err(format!("duration_s must be > 0 (got {})", self.duration_s));
        }
        if !(self.speed > 0.0 && self.speed.is_finite()) {
            return Err(format!("speed must be > 0 (got {})", self.speed));
        }
        self.fuser
            .method
            .parse::<Method>()
            .map_err(|e| format!("fuser.method: {e}"))?;
        if !(self.fuser.window_ms > 0.0) || !(self.fuser.max_wait_ms >= 0.0) {
            return Err("fuser.window_ms must be > 0 and fuser.max_wait_ms >= 0".into());
        }
        let mut names = std::collections::BTreeSet::new();
        for a in &self.agents {
            keys::validate_chunk("agent name", &a.name).map_err(|e| format!("agents: {e}"))?;
            if a.name == "fuser" || v2x_protocol::acl::reserved(&a.name) {
                return Err(format!(
                    "agents: the name '{}' belongs to another role",
                    a.name
                ));
            }
            if !names.insert(a.name.clone()) {
                return Err(format!("agents: the name '{}' is used twice", a.name));
            }
            a.noise
                .parse::<AgentNoise>()
                .map_err(|e| format!("agent {}: noise: {e}", a.name))?;
            if let Some(f) = &a.faults {
                f.parse::<Faults>()
                    .map_err(|e| format!("agent {}: faults: {e}", a.name))?;
            }
            a.link
                .validate()
                .map_err(|e| format!("agent {}: link: {e}", a.name))?;
            if let Some(r) = a.range_m {
                if !(r > 0.0) {
                    return Err(format!("agent {}: range_m must be > 0", a.name));
                }
            }
            if let Some(hz) = a.hz {
                if !(hz > 0.0 && hz <= 1000.0) {
                    return Err(format!("agent {}: hz must be in (0, 1000]", a.name));
                }
            }
            if !(a.phase_ms >= 0.0 && a.phase_ms < 60_000.0) {
                return Err(format!("agent {}: phase_ms must be in [0, 60000)", a.name));
            }
        }
        crate::timeline::check(&self.events, &self.agents, self.duration_s)
    }

    /// The noise setting of the agents, in order.
    pub fn noise(&self) -> NoiseSetting {
        NoiseSetting {
            name: self
                .agents
                .iter()
                .map(|a| a.noise.as_str())
                .collect::<Vec<_>>()
                .join("+"),
            agents: self.agents.iter().map(AgentSpec::agent_noise).collect(),
        }
    }

    /// The fusion method.
    pub fn method(&self) -> Method {
        self.fuser.method.parse().expect("checked")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_and_examples_parse() {
        let s = Scenario::parse(DEFAULT, "default", None).unwrap();
        assert_eq!(s.agents.len(), 2);
        assert_eq!(s.agents[1].kind, AgentKind::Infrastructure);
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
        let mut n = 0;
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                Scenario::load(&p).unwrap_or_else(|e| panic!("{e}"));
                n += 1;
            }
        }
        assert!(n >= 6, "{n} example scenarios");
    }

    #[test]
    fn errors_name_the_field() {
        let bad = |t: &str| Scenario::parse(t, "x.toml", None).unwrap_err().to_string();
        assert!(bad("agents = []").contains("at least one"));
        assert!(bad("[[agents]]\nname = \"a\"\nnoise = \"huge\"").contains("agent a: noise"));
        assert!(
            bad("[[agents]]\nname = \"a\"\nnoise = \"mild\"\n[agents.link]\ndrop_rate = 2.0")
                .contains("drop_rate")
        );
        assert!(
            bad("[fuser]\nmethod = \"kalman\"\n[[agents]]\nname = \"a\"\nnoise = \"mild\"")
                .contains("fuser.method")
        );
        assert!(bad("[[agents]]\nname = \"a\"\nnoise = \"mild\"\ncolour = 3").contains("colour"));
        assert!(bad("[[agents]]\nname = \"a/b\"\nnoise = \"mild\"").contains("'/'"));
        assert!(
            bad("[[agents]]\nname = \"a\"\nnoise = \"mild\"\nfaults = \"flip=3\"")
                .contains("agent a: faults: invalid faults 'flip=3': flip must be a probability")
        );
    }

    #[test]
    fn faults_override_the_profiles_own() {
        let t = "[[agents]]\nname = \"v\"\nnoise = \"realistic\"\n\
                 [[agents]]\nname = \"r\"\nnoise = \"mild\"\nfaults = \"fp=2\"\n\
                 [[agents]]\nname = \"w\"\nnoise = \"realistic\"\nfaults = \"none\"";
        let s = Scenario::parse(t, "x.toml", None).unwrap();
        let n = s.noise();
        assert_eq!(n.agents[0].faults, Faults::REALISTIC);
        assert_eq!(n.agents[1].faults.false_positives, 2.0);
        assert_eq!(
            n.agents[1].std,
            AgentNoise::profile(v2x_protocol::NoiseProfile::Mild).std
        );
        assert_eq!(n.agents[2].faults, Faults::NONE);
        assert_eq!(n.agents[2].std, AgentNoise::realistic().std);
        assert!(!s.fuser.align);
    }
}
