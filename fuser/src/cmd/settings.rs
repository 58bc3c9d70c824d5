//! The option groups `fuse`, `track` and `node` share: motion, stds, registration, region and
//! admission limits, each turned into the fuser's settings.

use std::path::PathBuf;
use v2x_fuser::align::AlignParams;
use v2x_fuser::node;
use v2x_protocol::nuscenes_json::MissingStd;

/// Motion compensation of a window to its latest capture time.
#[derive(clap::Args)]
pub(crate) struct MotionArgs {
    /// Fuse boxes as captured, without predicting them to the window's reference time.
    #[arg(long)]
    pub(crate) no_compensation: bool,
    /// Speed bound (m/s) for boxes without a velocity: their position variance grows by
    /// (v dt)^2 / 3 over dt.
    #[arg(long, default_value_t = 15.0)]
    pub(crate) speed_bound_mps: f64,
    /// Std of the unmodelled acceleration (m/s^2) in the constant-velocity prediction.
    #[arg(long, default_value_t = 2.0)]
    pub(crate) accel_std: f64,
    /// Seconds of motion per second of capture time: set it to the replay speed when agents
    /// replay recorded data faster than real time and stamp frames with the wall clock (motion
    /// compensation and, with --track, the tracks' prediction and velocities).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) time_scale: f64,
}

impl MotionArgs {
    pub(crate) fn params(&self) -> anyhow::Result<Option<v2x_fuser::motion::MotionParams>> {
        let ok = |x: f64| x >= 0.0 && x.is_finite();
        if !ok(self.speed_bound_mps) || !ok(self.accel_std) {
            anyhow::bail!("--speed-bound-mps and --accel-std must be >= 0");
        }
        if !(self.time_scale > 0.0 && self.time_scale.is_finite()) {
            anyhow::bail!("--time-scale must be > 0, the replay speed (1 live)");
        }
        Ok(
            (!self.no_compensation).then_some(v2x_fuser::motion::MotionParams {
                accel_std: self.accel_std,
                speed_bound: self.speed_bound_mps,
                ..Default::default()
            }),
        )
    }
}

/// Where each agent's stds come from: as stated, a calibrated model, or learned
/// (`docs/method.md` §10).
#[derive(clap::Args)]
pub(crate) struct StdArgs {
    /// An agent's error model, as `v2x-sim calibrate` writes it: its bias is taken off the
    /// agent's boxes and its stds replace the stated ones (per class and score bin). AGENT is
    /// the agent's name (fuse and track: agentN, N its input's position from 1). Repeatable.
    #[arg(long, value_name = "AGENT=FILE", value_parser = parse_model_arg)]
    pub(crate) std_model: Vec<(String, PathBuf)>,
    /// Learn each agent's stds from its boxes as they flow, without ground truth (from how
    /// each agent's boxes of an object scatter about their track), and fuse with the learned
    /// stds instead of the stated ones; boxes without stds need no --default-std. Also flags an
    /// agent whose stated stds are off (the report: fuse and track print it and write
    /// meta.v2x_learned_std; node: the stats and MCAP).
    #[arg(long)]
    pub(crate) learn_std: bool,
    /// With --learn-std: flag an agent whose stated centre stds are off by more than this
    /// factor, either way.
    #[arg(long, requires = "learn_std", default_value_t = v2x_fuser::learn::LearnParams::default().flag_ratio)]
    pub(crate) std_flag_ratio: f64,
}

/// Splits AGENT=FILE.
pub(crate) fn parse_model_arg(s: &str) -> Result<(String, PathBuf), String> {
    match s.split_once('=') {
        Some((a, f)) if !a.is_empty() && !f.is_empty() => Ok((a.to_owned(), f.into())),
        _ => Err(format!(
            "'{s}': expected AGENT=FILE, e.g. agent2=rsu-model.json"
        )),
    }
}

impl StdArgs {
    /// The models by agent name, each file read and checked.
    pub(crate) fn models(&self) -> anyhow::Result<v2x_fuser::stdmodel::Models> {
        let mut models = v2x_fuser::stdmodel::Models::default();
        for (agent, path) in &self.std_model {
            let text = std::fs::read_to_string(path).map_err(|e| {
                anyhow::anyhow!("--std-model {agent}: cannot read {}: {e}", path.display())
            })?;
            let m = v2x_fuser::stdmodel::ErrorModel::from_json(&text)
                .map_err(|e| anyhow::anyhow!("--std-model {agent}: {}: {e}", path.display()))?;
            if models.0.insert(agent.clone(), m).is_some() {
                anyhow::bail!("--std-model {agent}: given twice");
            }
        }
        Ok(models)
    }

    /// The models by input position, for files: AGENT must be agentN with 1 <= N <= `inputs`.
    pub(crate) fn models_by_input(
        &self,
        inputs: usize,
    ) -> anyhow::Result<std::collections::BTreeMap<usize, v2x_fuser::stdmodel::ErrorModel>> {
        self.models()?
            .0
            .into_iter()
            .map(|(agent, m)| {
                let n = agent
                    .strip_prefix("agent")
                    .and_then(|n| n.parse::<usize>().ok())
                    .filter(|n| (1..=inputs).contains(n))
                    .ok_or_else(|| {
                        anyhow::anyhow!(
                            "--std-model {agent}: name the input as agentN, N from 1 to {inputs} (its position)"
                        )
                    })?;
                Ok((n - 1, m))
            })
            .collect()
    }

    pub(crate) fn params(&self) -> anyhow::Result<Option<v2x_fuser::learn::LearnParams>> {
        if !(self.std_flag_ratio > 1.0 && self.std_flag_ratio.is_finite()) {
            anyhow::bail!("--std-flag-ratio must be > 1");
        }
        let p = v2x_fuser::learn::LearnParams {
            flag_ratio: self.std_flag_ratio,
            ..Default::default()
        };
        Ok(self.learn_std.then_some(p))
    }

    /// What to do with a box that states no std: the default given, else the learner's prior
    /// when learning or when every one of the `inputs` has a model (which replaces the stds),
    /// else an error.
    pub(crate) fn missing(
        &self,
        default_std: Option<v2x_protocol::Uncertainty>,
        inputs: usize,
    ) -> MissingStd {
        let replaced = self.learn_std || (inputs > 0 && self.std_model.len() >= inputs);
        match (default_std, replaced) {
            (Some(u), _) => MissingStd::Default(u),
            (None, true) => MissingStd::Default(v2x_fuser::learn::LearnParams::default().prior),
            (None, false) => MissingStd::Error,
        }
    }
}

/// Prints what was learned of each agent's stds.
pub(crate) fn print_learned(
    learned: &std::collections::BTreeMap<String, v2x_fuser::learn::AgentReport>,
) {
    for (agent, r) in learned {
        match &r.all.pos_xy {
            Some(g) => eprintln!(
                "learned stds of {agent}: centre {:.2} m where it states {:.2} m (x{:.2}{}) from {} residuals; per class in meta.v2x_learned_std",
                g.estimated,
                g.stated,
                g.ratio,
                if r.flagged { ", flagged: its stated stds are inconsistent" } else { "" },
                g.samples
            ),
            None => eprintln!("learned stds of {agent}: too few boxes followed over three frames"),
        }
    }
}

/// Registration of agents whose own pose is wrong (`docs/method.md` §3.1).
#[derive(clap::Args)]
pub(crate) struct AlignArgs {
    /// Register every agent to a reference agent by the boxes both see, before association: a
    /// rigid shift and turn per agent, measured each window, filtered over time (decaying to
    /// none across gaps), and applied only when it differs significantly from no correction.
    /// Each estimate is reported (fuse: meta.v2x_registration; node: the stats and MCAP).
    #[arg(long)]
    pub(crate) align: bool,
    /// With --align: fewest matched boxes a window measures an offset from.
    #[arg(long, requires = "align", default_value_t = AlignParams::default().min_matches)]
    pub(crate) align_min_matches: usize,
    /// With --align: std per axis (m) of how far two agents' boxes of one object disagree at
    /// least, beyond their stated stds (a window whose matches scatter more is widened by it).
    #[arg(long, requires = "align", default_value_t = AlignParams::default().disagreement_m)]
    pub(crate) align_disagreement_m: f64,
    /// With --align: time constant (s) with which an estimate fades to none without matches.
    #[arg(long, requires = "align", default_value_t = AlignParams::default().tau_s)]
    pub(crate) align_tau_s: f64,
    /// With --align: the chi-square (2 degrees of freedom) an estimated shift must reach against
    /// none to be applied (5.99: 95%; 0 applies every estimate).
    #[arg(long, requires = "align", default_value_t = AlignParams::default().chi2)]
    pub(crate) align_chi2: f64,
    /// With --align: the chi-square (1 degree of freedom) an estimated turn must reach against
    /// none to be applied (10.83: 99.9%; a turn moves far boxes by its lever arm).
    #[arg(long, requires = "align", default_value_t = AlignParams::default().turn_chi2)]
    pub(crate) align_turn_chi2: f64,
    /// With --align: largest centre distance (m) of a candidate match before any correction.
    #[arg(long, requires = "align", default_value_t = AlignParams::default().gate_m)]
    pub(crate) align_gate_m: f64,
}

impl AlignArgs {
    pub(crate) fn params(&self) -> anyhow::Result<Option<AlignParams>> {
        if !self.align {
            return Ok(None);
        }
        let p = AlignParams {
            min_matches: self.align_min_matches,
            disagreement_m: self.align_disagreement_m,
            tau_s: self.align_tau_s,
            chi2: self.align_chi2,
            turn_chi2: self.align_turn_chi2,
            gate_m: self.align_gate_m,
            ..Default::default()
        };
        p.validate().map_err(|e| anyhow::anyhow!("--align: {e}"))?;
        Ok(Some(p))
    }
}

/// The region a fuser node serves.
#[derive(clap::Args)]
pub(crate) struct RegionArgs {
    /// Serve one tile as a regional fuser (COLUMN_ROW, e.g. 0_0 or -1_2): subscribe to
    /// v2x/NS/det/TILE/* for it and its halo, publish on v2x/NS/fused/TILE the fused boxes whose
    /// centre lies in it. Agents must publish per tile (`v2x-agent --tile-size`, same size).
    #[arg(long)]
    pub(crate) tile: Option<v2x_protocol::tiles::Tile>,
    /// Side of the map's square tiles (m), as the agents use.
    #[arg(long, default_value_t = v2x_fuser::region::DEFAULT_TILE_M, requires = "tile")]
    pub(crate) tile_size: f64,
    /// How far beyond its tile a regional fuser takes boxes (m): at least the association's
    /// reach, so groups across the border are fused as one fuser would.
    #[arg(long, default_value_t = v2x_fuser::region::DEFAULT_HALO_M, requires = "tile")]
    pub(crate) halo: f64,
}

impl RegionArgs {
    pub(crate) fn region(&self) -> anyhow::Result<Option<v2x_fuser::region::Region>> {
        let Some(tile) = self.tile else {
            return Ok(None);
        };
        let tiling = v2x_protocol::tiles::Tiling::new(self.tile_size)
            .map_err(|e| anyhow::anyhow!("--tile-size: {e}"))?;
        if !(self.halo >= 0.0 && self.halo.is_finite()) {
            anyhow::bail!("--halo must be >= 0 m");
        }
        Ok(Some(v2x_fuser::region::Region {
            tiling,
            tile,
            halo_m: self.halo,
        }))
    }
}

/// Admission limits of the fuser node.
#[derive(clap::Args)]
pub(crate) struct IngestArgs {
    /// Reject frames stamped further than this from the fuser's clock, ahead or behind (ms);
    /// 0 accepts any capture time (agents replaying data on its own clock, `v2x-agent --clock data`).
    #[arg(long, default_value_t = 1000.0)]
    pub(crate) max_clock_skew_ms: f64,
    /// Most agents tracked at once; beyond, the least recently heard agent without a liveliness
    /// token is forgotten to make room.
    #[arg(long, default_value_t = 256)]
    pub(crate) max_agents: usize,
    /// Forget an agent with no frame and no liveliness token for this long (s).
    #[arg(long, default_value_t = 60.0)]
    pub(crate) forget_after_s: f64,
    /// Closed windows that may wait for fusion; beyond, windows are dropped and counted.
    #[arg(long, default_value_t = 16)]
    pub(crate) fusion_queue: usize,
    /// Interval of the rate-limited warning summaries (s).
    #[arg(long, default_value_t = 10.0)]
    pub(crate) log_interval_s: f64,
    /// Most boxes one agent brings into a window; beyond, its lowest-scoring boxes are dropped
    /// and counted (`over_budget`), so no agent can crowd the others out of the fused frame.
    #[arg(long, default_value_t = v2x_fuser::ingest::MAX_OBJECTS_PER_AGENT)]
    pub(crate) max_objects_per_agent: usize,
    /// The area of interest, X,Y,RADIUS in metres of the map frame: boxes outside it are
    /// dropped and counted (`outside`). Default: a disc of --area-radius-m around where most
    /// agents are, learned from their first boxes.
    #[arg(long, value_name = "X,Y,RADIUS", value_parser = v2x_fuser::ingest::Area::parse, allow_hyphen_values = true)]
    pub(crate) area: Option<v2x_fuser::ingest::Area>,
    /// The radius of the learned area of interest (m), without --area.
    #[arg(long, default_value_t = 10_000.0, conflicts_with = "area")]
    pub(crate) area_radius_m: f64,
}

impl IngestArgs {
    pub(crate) fn apply(&self, cfg: &mut node::NodeConfig) -> anyhow::Result<()> {
        if !(self.max_clock_skew_ms >= 0.0 && self.max_clock_skew_ms.is_finite()) {
            anyhow::bail!("--max-clock-skew-ms must be >= 0 (0 turns the check off)");
        }
        if !(self.forget_after_s > 0.0 && self.forget_after_s.is_finite()) {
            anyhow::bail!("--forget-after-s must be > 0");
        }
        if self.max_agents == 0 || self.fusion_queue == 0 || self.max_objects_per_agent == 0 {
            anyhow::bail!(
                "--max-agents, --fusion-queue and --max-objects-per-agent must be at least 1"
            );
        }
        let area = self.area.unwrap_or(v2x_fuser::ingest::Area::Learned {
            radius_m: self.area_radius_m,
        });
        area.validate()
            .map_err(|e| anyhow::anyhow!("--area / --area-radius-m: {e}"))?;
        if self.max_agents > v2x_protocol::limits::MAX_WINDOW_AGENTS {
            anyhow::bail!(
                "--max-agents may be at most {} (the most agents a fused frame can name)",
                v2x_protocol::limits::MAX_WINDOW_AGENTS
            );
        }
        cfg.ingest.max_clock_skew_us =
            (self.max_clock_skew_ms > 0.0).then_some((self.max_clock_skew_ms * 1000.0) as u64);
        cfg.ingest.max_agents = self.max_agents;
        cfg.ingest.max_objects = self.max_objects_per_agent;
        cfg.ingest.area = area;
        cfg.ingest.forget_after_us = (self.forget_after_s * 1e6) as u64;
        cfg.queue = self.fusion_queue;
        cfg.log_interval_s = self.log_interval_s;
        Ok(())
    }
}
