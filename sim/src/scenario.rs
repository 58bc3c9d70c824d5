//! Scenario files (TOML): the data, the agents with their kind, noise, sensing range and link,
//! the fuser's method and window, the run's length and speed, and each role's Zenoh endpoints.
//! `scenarios/` holds examples; the guide (docs/guide.md, "Scenarios") documents every field.

use crate::cli::DataArgs;
use crate::faults::Faults;
use crate::noise::{AgentNoise, NoiseSetting};
use crate::timeline::fuser_restarts;
use anyhow::{anyhow, bail};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use v2x_agent::Link;
use v2x_fuser::settings::FuserSettings;
use v2x_fuser::Method;
use v2x_protocol::net::ZenohArgs;
use v2x_protocol::{keys, AgentKind};
use v2x_truth::stated::Stated;

mod deploy;
pub use deploy::{RegionFuserSpec, RegionsSpec, RouterSpec, SecurityMode, SecuritySpec};

/// The embedded default scenario (`scenarios/default.toml`).
pub const DEFAULT: &str = include_str!("../../scenarios/default.toml");

/// Where the ground truth comes from.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct DatasetSpec {
    /// Data root (absent: the synthetic town). Relative to the scenario file.
    pub dataroot: Option<PathBuf>,
    /// What the root holds: `nuscenes` (tables under `version`) or `dair-v2x` (DAIR-V2X-C or
    /// V2X-Seq-SPD: the two agents are the data's vehicle and roadside unit, replayed at their
    /// recorded capture times).
    pub kind: crate::cli::DatasetKind,
    /// DAIR-V2X: move the roadside by each pair's calibration offset.
    pub calibration_offset: bool,
    /// V2V4Real: the split, `train` or `val`.
    #[serde(deserialize_with = "split")]
    pub split: v2x_truth::v2v4real::Split,
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
            kind: Default::default(),
            calibration_offset: true,
            split: Default::default(),
            version: None,
            scenes: 1,
            seconds: 20.0,
            hz: 10.0,
            town_seed: 7,
        }
    }
}

/// A split by name (`train`, or `val`/`test`).
fn split<'de, D: serde::Deserializer<'de>>(d: D) -> Result<v2x_truth::v2v4real::Split, D::Error> {
    let name = String::deserialize(d)?;
    name.parse().map_err(serde::de::Error::custom)
}

impl DatasetSpec {
    /// The same as command-line data arguments.
    pub fn data_args(&self) -> DataArgs {
        DataArgs {
            dataroot: self.dataroot.clone(),
            dataset: self.kind,
            dair_results: Vec::new(),
            calibration_offset: if self.calibration_offset {
                crate::cli::Switch::On
            } else {
                crate::cli::Switch::Off
            },
            split: self.split,
            version: self.version.clone(),
            scenes: self.scenes,
            seconds: self.seconds,
            hz: self.hz,
            validation_size: false,
            town_seed: self.town_seed,
        }
    }
}

/// The fuser role: its settings, the keys of `v2x-fuser node`'s flags
/// ([`v2x_fuser::settings`]; the replay speed is the run's `speed`), and its Zenoh options.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FuserSpec {
    /// Method, window, stds, registration, tracking and admission.
    pub settings: FuserSettings,
    /// The fuser's Zenoh options (used when roles run on separate hosts).
    pub zenoh: ZenohArgs,
}

impl<'de> Deserialize<'de> for FuserSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        FuserSpec::from_table(toml::Table::deserialize(d)?).map_err(serde::de::Error::custom)
    }
}

impl FuserSpec {
    /// Reads a `[fuser]` table; an error names the key it is about.
    fn from_table(mut table: toml::Table) -> Result<FuserSpec, String> {
        let zenoh = match table.remove("zenoh") {
            Some(z) => z.try_into().map_err(|e| format!("fuser.zenoh: {e}"))?,
            None => ZenohArgs::default(),
        };
        if let Some(k) = FuserSettings::unknown_keys(table.keys().map(String::as_str)).first() {
            return Err(format!(
                "fuser: unknown key '{k}' (expected one of: {}, zenoh)",
                FuserSettings::keys().join(", ")
            ));
        }
        // Each key alone first: every setting has a default, so the one that fails is named.
        for (k, v) in &table {
            let one = toml::Table::from_iter([(k.clone(), v.clone())]);
            toml::Value::Table(one)
                .try_into::<FuserSettings>()
                .map_err(|e| format!("fuser.{k}: {e}"))?;
        }
        let settings = toml::Value::Table(table)
            .try_into()
            .map_err(|e| format!("fuser: {e}"))?;
        Ok(FuserSpec { settings, zenoh })
    }

    /// The node's configuration on `ns` at replay speed `speed`: the window shortened by it, the
    /// predictions scaled by it.
    pub fn node_config(&self, ns: &str, speed: f64) -> anyhow::Result<v2x_fuser::node::NodeConfig> {
        let mut s = self.settings.clone();
        s.fusion.motion.time_scale = speed;
        s.fusion.window_ms /= speed;
        s.node_config(ns).map_err(|e| anyhow::anyhow!("fuser.{e}"))
    }
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
    /// The stds it states with its boxes (`v2x-sim gen --stated-std`): honest (absent), xK, a
    /// profile or "POS,SIZE,YAW_DEG".
    #[serde(default)]
    pub stated_std: Option<String>,
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
    /// Sends ETSI CPMs instead of frames (docs/cpm.md), placed on the earth by the scenario's
    /// `map_origin`.
    #[serde(default)]
    pub cpm: bool,
}

impl AgentSpec {
    /// The agent's timeline: its scripted events, from its own link and noise.
    pub fn timeline(
        &self,
        events: &[crate::timeline::EventSpec],
    ) -> crate::timeline::AgentTimeline {
        crate::timeline::AgentTimeline::new(
            &self.name,
            self.link.clone(),
            self.agent_noise(),
            events,
        )
    }

    /// The agent's noise with its faults (checked when the scenario loaded).
    pub fn agent_noise(&self) -> AgentNoise {
        let mut n: AgentNoise = self
            .noise
            .parse()
            .expect("checked when the scenario loaded");
        if let Some(f) = &self.faults {
            n.faults = f.parse().expect("checked when the scenario loaded");
        }
        if let Some(s) = &self.stated_std {
            n.stated = s.parse().expect("checked when the scenario loaded");
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
    /// A city of regional fusers over meshed routers instead of one fuser (`[regions]`).
    #[serde(default)]
    pub regions: Option<RegionsSpec>,
    /// WGS84 latitude and longitude (degrees) of the map's origin, for agents that send CPMs.
    #[serde(default)]
    pub map_origin: [f64; 2],
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
    /// Where the map lies on the earth, for CPMs.
    pub fn geo(&self) -> v2x_cpm::Geo {
        v2x_cpm::Geo {
            lat_deg: self.map_origin[0],
            lon_deg: self.map_origin[1],
        }
    }

    /// Parses and checks a scenario; `source` names it in errors, `base` resolves relative paths.
    pub fn parse(text: &str, source: &str, base: Option<&Path>) -> anyhow::Result<Scenario> {
        let mut s: Scenario = toml::from_str(text).map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
        if let (Some(root), Some(base)) = (&s.dataset.dataroot, base) {
            if root.is_relative() {
                s.dataset.dataroot = Some(base.join(root));
            }
        }
        if let Some(base) = base {
            for (_, path) in &mut s.fuser.settings.fusion.stds.std_models {
                if path.is_relative() {
                    *path = base.join(&*path);
                }
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

    fn check(&self) -> anyhow::Result<()> {
        keys::validate_chunk("namespace", &self.namespace).map_err(anyhow::Error::msg)?;
        if self.agents.is_empty() {
            bail!("a scenario needs at least one [[agents]] entry");
        }
        if !(self.duration_s > 0.0 && self.duration_s.is_finite()) {
            bail!("duration_s must be > 0 (got {})", self.duration_s);
        }
        if !(self.speed > 0.0 && self.speed.is_finite()) {
            bail!("speed must be > 0 (got {})", self.speed);
        }
        let [lat, lon] = self.map_origin;
        if !(lat.abs() <= 90.0 && lon.abs() <= 180.0) {
            bail!("map_origin must be [latitude, longitude] in degrees (got [{lat}, {lon}])");
        }
        self.check_dataset()?;
        self.check_fuser()?;
        self.check_agents()?;
        self.check_regions()?;
        let names: Vec<&str> = self.agents.iter().map(|a| a.name.as_str()).collect();
        crate::timeline::check(&self.events, &names, self.duration_s).map_err(anyhow::Error::from)
    }

    /// A recorded data set's scenario (DAIR-V2X, V2V4Real): a data root, its two agents at their
    /// recorded times.
    fn check_dataset(&self) -> anyhow::Result<()> {
        let (data, root, agents) = match self.dataset.kind {
            crate::cli::DatasetKind::DairV2x => (
                "DAIR-V2X",
                "\"dair-v2x\" needs a dataroot (the folder holding cooperative/, vehicle-side/ and infrastructure-side/)",
                "the vehicle then the roadside unit",
            ),
            crate::cli::DatasetKind::V2v4real => (
                "V2V4Real",
                "\"v2v4real\" needs a dataroot (the AB3DMOT/ folder of a DMSTrack checkout)",
                "the ego car then car 1",
            ),
            _ => return Ok(()),
        };
        if self.dataset.dataroot.is_none() {
            bail!("dataset: kind = {root}");
        }
        if self.agents.len() != 2 {
            bail!(
                "dataset: {data} has two agents, {agents}; the scenario names {}",
                self.agents.len()
            );
        }
        if let Some(a) = self
            .agents
            .iter()
            .find(|a| a.hz.is_some() || a.phase_ms != 0.0)
        {
            bail!(
                "agents: {}: {data} agents capture at their recorded times; leave out hz and phase_ms",
                a.name
            );
        }
        if self.regions.is_some() {
            bail!("regions: a city runs on the synthetic town or nuScenes tables");
        }
        Ok(())
    }

    /// The fuser's settings: known keys, values in range, models that read, agents that exist.
    fn check_fuser(&self) -> anyhow::Result<()> {
        let settings = &self.fuser.settings;
        settings.check().map_err(|e| anyhow!("fuser.{e}"))?;
        if let Some((a, _)) = settings
            .fusion
            .stds
            .std_models
            .iter()
            .find(|(a, _)| !self.agents.iter().any(|s| &s.name == a))
        {
            bail!("fuser.std_models: '{a}' is not an agent of this scenario");
        }
        settings
            .fusion
            .stds
            .models()
            .map_err(|e| anyhow!("fuser.{e}"))?;
        Ok(())
    }

    /// Every agent: a free name, its noise, faults, link, range, rate and phase.
    fn check_agents(&self) -> anyhow::Result<()> {
        let mut names = std::collections::BTreeSet::new();
        for a in &self.agents {
            keys::validate_chunk("agent name", &a.name).map_err(|e| anyhow!("agents: {e}"))?;
            if a.name == "fuser" || v2x_protocol::acl::reserved(&a.name) {
                bail!("agents: the name '{}' belongs to another role", a.name);
            }
            if !names.insert(a.name.clone()) {
                bail!("agents: the name '{}' is used twice", a.name);
            }
            a.noise
                .parse::<AgentNoise>()
                .map_err(|e| anyhow!("agent {}: noise: {e}", a.name))?;
            if let Some(f) = &a.faults {
                f.parse::<Faults>()
                    .map_err(|e| anyhow!("agent {}: faults: {e}", a.name))?;
            }
            match a.stated_std.as_deref().map(str::parse::<Stated>) {
                Some(Err(e)) => bail!("agent {}: stated_std: {e}", a.name),
                Some(Ok(Stated::Nothing)) => {
                    bail!(
                        "agent {}: stated_std: every box on the wire carries stds; state x1000 for an agent that knows nothing",
                        a.name
                    )
                }
                _ => {}
            }
            a.link
                .validate()
                .map_err(|e| anyhow!("agent {}: link: {e}", a.name))?;
            if let Some(r) = a.range_m {
                if !(r > 0.0) {
                    bail!("agent {}: range_m must be > 0", a.name);
                }
            }
            if let Some(hz) = a.hz {
                if !(hz > 0.0 && hz <= 1000.0) {
                    bail!("agent {}: hz must be in (0, 1000]", a.name);
                }
            }
            if !(a.phase_ms >= 0.0 && a.phase_ms < 60_000.0) {
                bail!("agent {}: phase_ms must be in [0, 60000)", a.name);
            }
        }
        Ok(())
    }

    /// A city: its routers and fusers, one fuser's features left out, agents in step.
    fn check_regions(&self) -> anyhow::Result<()> {
        let Some(r) = &self.regions else {
            return Ok(());
        };
        r.check(self.security.mode)?;
        if self.fuser.settings.fusion.align.align {
            bail!("regions: fuser.align needs one fuser");
        }
        if !fuser_restarts(&self.events).is_empty() {
            bail!("regions: scripted fuser restarts need one fuser");
        }
        // The regions' windows are joined by reference time: agents capture in step.
        let first = &self.agents[0];
        if let Some(a) = self
            .agents
            .iter()
            .find(|a| a.hz != first.hz || a.phase_ms != first.phase_ms)
        {
            bail!(
                "regions: agent {} captures out of step with {} (a city's agents share hz and phase_ms)",
                a.name, first.name
            );
        }
        if let Some(a) = self
            .agents
            .iter()
            .find(|a| a.name.starts_with("router-") || a.name.starts_with("fuser-"))
        {
            bail!(
                "agents: the name '{}' is a city role's (router-NAME, fuser-TILE)",
                a.name
            );
        }
        Ok(())
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
        self.fuser.settings.fusion.method
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_fuser::tracker::Association;
    use v2x_protocol::tiles::Tile;

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
        let fuser = |table: &str| {
            bad(&format!(
                "{table}\n[[agents]]\nname = \"a\"\nnoise = \"mild\""
            ))
        };
        for (table, message) in [
            (
                "[fuser]\nmethod = \"kalman\"",
                "fuser.method: unknown method 'kalman'",
            ),
            (
                "[fuser]\nwindw_ms = 50",
                "fuser: unknown key 'windw_ms' (expected one of: ",
            ),
            ("[fuser]\ntime_scale = 2", "unknown key 'time_scale'"),
            ("[fuser.registration]\nchi3 = 1", "unknown field `chi3`"),
            (
                "[fuser]\nwindow_ms = \"x\"",
                "fuser.window_ms: invalid type: string \"x\", expected f64",
            ),
        ] {
            assert!(fuser(table).contains(message), "{table}: {}", fuser(table));
        }
        let z = Scenario::parse(
            "[fuser.zenoh]\nlisten = [\"tcp/127.0.0.1:7000\"]\n[[agents]]\nname = \"a\"\nnoise = \"mild\"",
            "x.toml",
            None,
        )
        .unwrap();
        assert_eq!(z.fuser.zenoh.listen, ["tcp/127.0.0.1:7000"]);
        assert!(bad("[[agents]]\nname = \"a\"\nnoise = \"mild\"\ncolour = 3").contains("colour"));
        assert!(bad(
            "[fuser.registration]\ntau_s = -1\n[[agents]]\nname = \"a\"\nnoise = \"mild\""
        )
        .contains("fuser.registration: tau_s must be a finite value > 0 (got -1)"));
        let s = Scenario::parse(
            "[fuser]\nalign = true\n[fuser.registration]\nchi2 = 30\nmin_matches = 5\n[[agents]]\nname = \"a\"\nnoise = \"mild\"",
            "x.toml",
            None,
        )
        .unwrap();
        let p = s.fuser.settings.fusion.align.registration.params().unwrap();
        assert_eq!((p.chi2, p.min_matches), (30.0, 5));
        assert_eq!(
            p.tau_s,
            v2x_fuser::time::align::AlignParams::default().tau_s
        );
        assert!(bad("[[agents]]\nname = \"a/b\"\nnoise = \"mild\"").contains("'/'"));
        let stated = |v: &str| {
            bad(&format!(
                "[[agents]]\nname = \"a\"\nnoise = \"mild\"\nstated_std = \"{v}\""
            ))
        };
        assert!(stated("loud").contains("agent a: stated_std"));
        assert!(stated("none").contains("every box on the wire carries stds"));
        let models = |m: &str| {
            bad(&format!(
                "[fuser]\nstd_models = {{ {m} }}\n[[agents]]\nname = \"a\"\nnoise = \"mild\""
            ))
        };
        assert!(models("ghost = \"m.json\"").contains("'ghost' is not an agent"));
        assert!(models("a = \"/nonexistent/m.json\"")
            .contains("fuser.std_models.a: /nonexistent/m.json"));
        let agent = "[[agents]]\nname = \"a\"\nnoise = \"mild\"";
        assert!(bad(&format!("[fuser]\narea = [0, 0, 0]\n{agent}"))
            .contains("fuser.area: the area's radius must be finite and > 0"));
        assert!(bad(&format!("[fuser]\nmax_objects_per_agent = 0\n{agent}"))
            .contains("fuser.max_objects_per_agent"));
        assert!(bad(&format!("[fuser]\nassociation = \"guided\"\n{agent}"))
            .contains("fuser.association: set track too"));
        assert!(bad(&format!(
            "[fuser]\ntrack = true\nassociation = \"by-id\"\n{agent}"
        ))
        .contains("unknown variant `by-id`, expected one of `assignment`, `soft`, `guided`"));
        for mode in Association::CHOICES {
            let s = Scenario::parse(
                &format!("[fuser]\ntrack = true\nassociation = \"{mode}\"\n{agent}"),
                "x.toml",
                None,
            )
            .unwrap();
            let p = s.fuser.settings.tracker().unwrap().unwrap();
            assert_eq!(p.association.mode, mode);
        }
        let s = Scenario::parse(
            &format!("[fuser]\narea = [5, 6, 70]\n{agent}"),
            "x.toml",
            None,
        )
        .unwrap();
        assert_eq!(
            s.fuser.settings.admission.area,
            Some(v2x_fuser::intake::ingest::Area::Given {
                center: [5.0, 6.0],
                radius_m: 70.0
            })
        );
        assert!(
            bad("[[agents]]\nname = \"a\"\nnoise = \"mild\"\nfaults = \"flip=3\"")
                .contains("agent a: faults: invalid faults 'flip=3': flip must be a probability")
        );
    }

    #[test]
    fn city_errors_name_the_field() {
        let city = |extra: &str, regions: &str| {
            format!(
                "[[agents]]\nname = \"v\"\nnoise = \"mild\"\n{extra}\n[regions]\n{regions}\n\
                 [[regions.routers]]\nname = \"r0\"\n\
                 [[regions.fusers]]\ntile = \"0_0\"\nrouter = \"r0\"\n"
            )
        };
        let s = Scenario::parse(&city("", "tile_m = 50.0"), "c.toml", None).unwrap();
        let r = s.regions.as_ref().unwrap();
        assert_eq!(r.halo_m, v2x_fuser::intake::region::DEFAULT_HALO_M);
        assert_eq!(r.regions()[0].tile, Tile { x: 0, y: 0 });
        assert_eq!(r.tiling().size_m(), 50.0);
        let bad = |t: String| Scenario::parse(&t, "c.toml", None).unwrap_err().to_string();
        assert!(bad(city("", "tile_m = 0.1")).contains("regions.tile_m"));
        assert!(bad(city("", "halo_m = -1.0")).contains("regions.halo_m"));
        assert!(bad(city(
            "[[agents]]\nname = \"w\"\nnoise = \"mild\"\nhz = 5.0",
            ""
        ))
        .contains("agent w captures out of step with v"));
        assert!(bad(city("[security]\nmode = \"mtls\"", "")).contains("plain"));
        assert!(bad(city("[fuser]\nalign = true", "")).contains("one fuser"));
        let t = city("", "").replace("router = \"r0\"", "router = \"r9\"");
        assert!(bad(t).contains("tile 0_0: no router named 'r9'"));
        let t = city("", "").replace("tile = \"0_0\"", "tile = \"00_0\"");
        assert!(bad(t).contains("COLUMN_ROW"));
        let t = city("", "") + "[[regions.fusers]]\ntile = \"0_0\"\nrouter = \"r0\"\n";
        assert!(bad(t).contains("tile 0_0 has two fusers"));
        let t = city("", "").replace("name = \"v\"", "name = \"fuser-0_0\"");
        assert!(bad(t).contains("city role"));
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
        assert!(!s.fuser.settings.fusion.align.align);
    }
}
