//! `v2x-fuser`: the roadside fuser. `fuse` fuses nuScenes results files offline and `track`
//! tracks a fused one; `node` runs the fuser on the network, `router` a Zenoh router for the
//! secure mode, and `stats` asks a running node for its statistics.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use v2x_fuser::align::AlignParams;
use v2x_fuser::{node, Method, METHODS};
use v2x_protocol::nuscenes_json::MissingStd;
use v2x_protocol::nuscenes_json::{
    default_meta, provenance_json, write_results, Results, TokenTable,
};

fn methods_help() -> String {
    let mut s = String::from("Methods:\n");
    for m in METHODS {
        s.push_str(&format!("  {:<16} {}\n", m.name, m.about));
    }
    s
}

#[derive(Parser)]
#[command(
    name = "v2x-fuser",
    version,
    about = "Late fusion of V2X agents' 3D boxes (CSBA-3D + WLS-3D and baselines)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fuse nuScenes detection-results files offline, one file per agent.
    #[command(after_help = methods_help())]
    Fuse(FuseArgs),
    /// Fuse results files, one per agent, then follow the fused boxes over time with a
    /// constant-velocity Kalman tracker, and write nuScenes tracking results (`tracking_id`,
    /// `tracking_name`, `tracking_score`, beside the detection fields). The files must carry
    /// capture times (meta.v2x_timestamps, as `v2x-sim gen` writes them).
    #[command(after_help = methods_help())]
    Track(TrackArgs),
    /// Run the fuser on the network: subscribe to every agent, fuse each time window, publish.
    #[command(after_help = methods_help())]
    Node(Box<NodeArgs>),
    /// Run a Zenoh router: the access-control point of a secure deployment (mutual TLS and the
    /// ACL come from its --zenoh-config, as `v2x-sim certs` writes it), until Ctrl-C or SIGTERM.
    /// Agents, fuser and observers connect to it as clients. Access control holds only through
    /// a router: in peer mode sessions talk to each other directly.
    Router(RouterArgs),
    /// Ask a running fuser for its statistics (JSON).
    Stats(StatsArgs),
}

/// How `fuse` and `track` fuse files: method, stds, motion and windows.
#[derive(clap::Args)]
struct FilesArgs {
    /// Fusion method of each window (see the list below).
    #[arg(long, short, default_value = "csba-wls+")]
    method: Method,
    /// Stds for boxes that carry no translation_std/size_std/yaw_std: mild, moderate, large,
    /// or POS,SIZE,YAW_DEG (metres, metres, degrees). Without it (or --learn-std, or a
    /// --std-model for every input), a missing std is an error in a results file; KITTI rows,
    /// which state none, take mild.
    #[arg(long, value_parser = v2x_protocol::parse_std)]
    default_std: Option<v2x_protocol::Uncertainty>,
    /// The inputs are a detector's boxes (docs/method.md §11): each box's stds from its score,
    /// replacing any it states (the first input is the receiver, the others add a pose std),
    /// or from the input's --std-model when it has one (`v2x-sim calibrate` fits it);
    /// CSBA-3D groups scored by the noisy-OR of their members; `fuse` drops fused boxes below
    /// 0.4, `track` keeps them and shows a track from its first box. The default for KITTI
    /// folders given without --default-std; give it for results files, such as
    /// `v2x-sim gen --dataset v2v4real` writes.
    #[arg(long, conflicts_with_all = ["default_std", "learn_std"])]
    detector: bool,
    #[command(flatten)]
    motion: MotionArgs,
    #[command(flatten)]
    stds: StdArgs,
    /// Window width delta t (ms) when the files carry capture times.
    #[arg(long, default_value_t = 100.0)]
    window_ms: f64,
    /// The output's layout: auto (KITTI folders for KITTI folder inputs, else nuScenes JSON),
    /// nuscenes (one results file) or kitti (a folder of NNNN.txt per sequence, as V2V4Real's
    /// and AB3DMOT's evaluators read them).
    #[arg(long, value_enum, default_value_t = Layout::Auto)]
    output_format: Layout,
}

/// The layout of `fuse` and `track` output.
#[derive(Copy, Clone, Debug, clap::ValueEnum)]
enum Layout {
    /// KITTI folders when the inputs are KITTI folders, else nuScenes JSON.
    Auto,
    /// One nuScenes results JSON file.
    Nuscenes,
    /// A folder of per-sequence NNNN.txt rows.
    Kitti,
}

impl From<Layout> for v2x_fuser::offline::OutputFormat {
    fn from(l: Layout) -> Self {
        match l {
            Layout::Auto => Self::Auto,
            Layout::Nuscenes => Self::Nuscenes,
            Layout::Kitti => Self::Kitti,
        }
    }
}

impl FilesArgs {
    /// How boxes without stds are read, and the offline options (without registration) for
    /// `inputs` files.
    fn options(
        &self,
        inputs: usize,
    ) -> anyhow::Result<(MissingStd, v2x_fuser::offline::OfflineOptions)> {
        if !(self.window_ms > 0.0 && self.window_ms.is_finite()) {
            anyhow::bail!("--window-ms must be > 0");
        }
        let mut opts = v2x_fuser::offline::OfflineOptions {
            motion: self.motion.params()?,
            window_ms: self.window_ms,
            align: None,
            learn: self.stds.params()?,
            models: self.stds.models_by_input(inputs)?,
            detector: self
                .detector
                .then(v2x_fuser::detector::DetectorParams::default),
        };
        opts.set_time_scale(self.motion.time_scale);
        let missing = match self.detector {
            // Every std is replaced by the detector's.
            true => MissingStd::Default(v2x_fuser::offline::kitti_default_std()),
            false => self.stds.missing(self.default_std, inputs),
        };
        Ok((missing, opts))
    }
}

/// The options of `v2x-fuser fuse`.
#[derive(clap::Args)]
struct FuseArgs {
    #[command(flatten)]
    files: FilesArgs,
    #[command(flatten)]
    align: AlignArgs,
    /// With --align: the reference agent, as its position among the inputs (1 = first).
    /// `v2x-sim gen` writes the roadside unit as agent2.json.
    #[arg(long, default_value_t = 2, requires = "align")]
    align_to: usize,
    /// Where to write the fused results file (a folder with --output-format kitti).
    #[arg(long, short)]
    output: PathBuf,
    /// Inputs, one per agent, in agent order: nuScenes results files, or folders of KITTI
    /// detection rows (NNNN.txt per sequence, every box in the first agent's frame at 10 Hz,
    /// as V2V4Real's per-car detections come).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
}

/// The options of `v2x-fuser track`.
#[derive(clap::Args)]
struct TrackArgs {
    #[command(flatten)]
    files: FilesArgs,
    /// Hits in a row that confirm a track: by default 2 (a box seen once never becomes one),
    /// and 1 for a detector's boxes (--detector, or KITTI rows with no stated std: each box
    /// shown at once, its track's mean score ranking it).
    #[arg(long)]
    confirm_hits: Option<u32>,
    /// Windows in a row without a box a confirmed track survives.
    #[arg(long, default_value_t = 3)]
    max_misses: u32,
    /// Also track the classes the nuScenes tracking benchmark does not score (barrier,
    /// traffic cone, construction vehicle). Without it the file holds the seven tracking
    /// classes only, as the official devkit's loader requires; with it the devkit refuses it.
    #[arg(long)]
    all_classes: bool,
    /// Associate each agent's boxes with the tracks' predictions first, one agent after another,
    /// and fuse between agents (with --method) only the boxes no track explains
    /// (docs/method.md §8.1). Default: track the fused boxes.
    #[arg(long)]
    guided: bool,
    /// Where to write the tracking results file (a folder with --output-format kitti).
    #[arg(long, short)]
    output: PathBuf,
    /// Inputs, one per agent, in agent order: nuScenes results files, or folders of KITTI
    /// detection rows (NNNN.txt per sequence, every box in the first agent's frame at 10 Hz,
    /// as V2V4Real's per-car detections come).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
}

/// The options of `v2x-fuser node`.
#[derive(clap::Args)]
struct NodeArgs {
    /// Scenario namespace (keys v2x/NS/...).
    #[arg(long, default_value = "default")]
    ns: String,
    /// Fusion method.
    #[arg(long, short, default_value = "csba-wls+")]
    method: Method,
    /// Window width delta t (ms).
    #[arg(long, default_value_t = 100.0)]
    window_ms: f64,
    /// Longest wait for missing live agents after a window's first frame (ms).
    #[arg(long, default_value_t = 150.0)]
    max_wait_ms: f64,
    /// The agents send a detector's boxes with the stds it is given (as `v2x-agent` replays
    /// `v2x-sim gen --dataset v2v4real`'s files): CSBA-3D groups are scored by the noisy-OR of
    /// their members and fused boxes below 0.4 dropped, as `v2x-fuser fuse --detector` does.
    #[arg(long)]
    detector: bool,
    #[command(flatten)]
    limits: Box<IngestArgs>,
    #[command(flatten)]
    motion: MotionArgs,
    #[command(flatten)]
    stds: StdArgs,
    #[command(flatten)]
    region: RegionArgs,
    #[command(flatten)]
    align: AlignArgs,
    /// Also follow the fused boxes over time (`v2x-fuser track`'s tracker) and publish the
    /// tracks each window updated on v2x/NS/tracks, each box's id its track's (the seven
    /// classes of the nuScenes tracking benchmark, as `v2x-fuser track` writes them).
    #[arg(long)]
    track: bool,
    /// With --track: also track barriers, traffic cones and construction vehicles.
    #[arg(long, requires = "track")]
    track_all_classes: bool,
    /// With --track: associate each agent's boxes with the tracks first and fuse between agents
    /// only the rest (`v2x-fuser track --guided`); the fused frames stay as they are.
    #[arg(long, requires = "track")]
    track_guided: bool,
    /// With --track and --tile: do not hear the neighbouring regions' tracks, so that an object
    /// crossing into this tile starts a track of this region's own (by default it keeps the id
    /// its neighbour gave it; docs/method.md §9.1).
    #[arg(long, requires_all = ["track", "tile"])]
    no_track_handover: bool,
    /// WGS84 latitude and longitude (degrees) of the map frame's origin (x East, y North), to
    /// read agents that send ETSI CPMs (`v2x-agent --wire cpm`, docs/cpm.md); give their value.
    #[arg(long, value_name = "LAT,LON", default_value = "0,0")]
    map_origin: v2x_cpm::Geo,
    #[command(flatten)]
    ros: node::ros_out::RosOutArgs,
    /// Record the fused output as a nuScenes results file (keys t<capture us>), scorable by
    /// `v2x-sim eval` against the same ground truth; each frame's provenance (window agents,
    /// completeness, every box's source agents) goes in meta.v2x_provenance.
    #[arg(long)]
    record: Option<PathBuf>,
    #[command(flatten)]
    viz: v2x_fuser::viz::VizArgs,
    /// Stop after this many seconds (default: run until Ctrl-C or SIGTERM, which both write
    /// the recording and print the final statistics).
    #[arg(long)]
    duration_s: Option<f64>,
    #[command(flatten)]
    zenoh: v2x_protocol::net::ZenohArgs,
}

/// The options of `v2x-fuser router`.
#[derive(clap::Args)]
struct RouterArgs {
    #[command(flatten)]
    zenoh: v2x_protocol::net::ZenohArgs,
}

/// The options of `v2x-fuser stats`.
#[derive(clap::Args)]
struct StatsArgs {
    /// Scenario namespace.
    #[arg(long, default_value = "default")]
    ns: String,
    /// Ask the regional fuser of this tile (COLUMN_ROW) instead of the single fuser.
    #[arg(long)]
    tile: Option<v2x_protocol::tiles::Tile>,
    /// How long to wait for an answer (s).
    #[arg(long, default_value_t = 5.0)]
    timeout_s: f64,
    #[command(flatten)]
    zenoh: v2x_protocol::net::ZenohArgs,
}

/// Motion compensation of a window to its latest capture time.
#[derive(clap::Args)]
struct MotionArgs {
    /// Fuse boxes as captured, without predicting them to the window's reference time.
    #[arg(long)]
    no_compensation: bool,
    /// Speed bound (m/s) for boxes without a velocity: their position variance grows by
    /// (v dt)^2 / 3 over dt.
    #[arg(long, default_value_t = 15.0)]
    speed_bound_mps: f64,
    /// Std of the unmodelled acceleration (m/s^2) in the constant-velocity prediction.
    #[arg(long, default_value_t = 2.0)]
    accel_std: f64,
    /// Seconds of motion per second of capture time: set it to the replay speed when agents
    /// replay recorded data faster than real time and stamp frames with the wall clock (motion
    /// compensation and, with --track, the tracks' prediction and velocities).
    #[arg(long, default_value_t = 1.0)]
    time_scale: f64,
}

impl MotionArgs {
    fn params(&self) -> anyhow::Result<Option<v2x_fuser::motion::MotionParams>> {
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
struct StdArgs {
    /// An agent's error model, as `v2x-sim calibrate` writes it: its bias is taken off the
    /// agent's boxes and its stds replace the stated ones (per class and score bin). AGENT is
    /// the agent's name (fuse and track: agentN, N its input's position from 1). Repeatable.
    #[arg(long, value_name = "AGENT=FILE", value_parser = parse_model_arg)]
    std_model: Vec<(String, PathBuf)>,
    /// Learn each agent's stds from its boxes as they flow, without ground truth (from how
    /// each agent's boxes of an object scatter about their track), and fuse with the learned
    /// stds instead of the stated ones; boxes without stds need no --default-std. Also flags an
    /// agent whose stated stds are off (the report: fuse and track print it and write
    /// meta.v2x_learned_std; node: the stats and MCAP).
    #[arg(long)]
    learn_std: bool,
    /// With --learn-std: flag an agent whose stated centre stds are off by more than this
    /// factor, either way.
    #[arg(long, requires = "learn_std", default_value_t = v2x_fuser::learn::LearnParams::default().flag_ratio)]
    std_flag_ratio: f64,
}

/// Splits AGENT=FILE.
fn parse_model_arg(s: &str) -> Result<(String, PathBuf), String> {
    match s.split_once('=') {
        Some((a, f)) if !a.is_empty() && !f.is_empty() => Ok((a.to_owned(), f.into())),
        _ => Err(format!(
            "'{s}': expected AGENT=FILE, e.g. agent2=rsu-model.json"
        )),
    }
}

impl StdArgs {
    /// The models by agent name, each file read and checked.
    fn models(&self) -> anyhow::Result<v2x_fuser::stdmodel::Models> {
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
    fn models_by_input(
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

    fn params(&self) -> anyhow::Result<Option<v2x_fuser::learn::LearnParams>> {
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
    fn missing(&self, default_std: Option<v2x_protocol::Uncertainty>, inputs: usize) -> MissingStd {
        let replaced = self.learn_std || (inputs > 0 && self.std_model.len() >= inputs);
        match (default_std, replaced) {
            (Some(u), _) => MissingStd::Default(u),
            (None, true) => MissingStd::Default(v2x_fuser::learn::LearnParams::default().prior),
            (None, false) => MissingStd::Error,
        }
    }
}

/// Prints what was learned of each agent's stds.
fn print_learned(learned: &std::collections::BTreeMap<String, v2x_fuser::learn::AgentReport>) {
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
struct AlignArgs {
    /// Register every agent to a reference agent by the boxes both see, before association: a
    /// rigid shift and turn per agent, measured each window, filtered over time (decaying to
    /// none across gaps), and applied only when it differs significantly from no correction.
    /// Each estimate is reported (fuse: meta.v2x_registration; node: the stats and MCAP).
    #[arg(long)]
    align: bool,
    /// With --align: fewest matched boxes a window measures an offset from.
    #[arg(long, requires = "align", default_value_t = AlignParams::default().min_matches)]
    align_min_matches: usize,
    /// With --align: std per axis (m) of how far two agents' boxes of one object disagree at
    /// least, beyond their stated stds (a window whose matches scatter more is widened by it).
    #[arg(long, requires = "align", default_value_t = AlignParams::default().disagreement_m)]
    align_disagreement_m: f64,
    /// With --align: time constant (s) with which an estimate fades to none without matches.
    #[arg(long, requires = "align", default_value_t = AlignParams::default().tau_s)]
    align_tau_s: f64,
    /// With --align: the chi-square (2 degrees of freedom) an estimated shift must reach against
    /// none to be applied (5.99: 95%; 0 applies every estimate).
    #[arg(long, requires = "align", default_value_t = AlignParams::default().chi2)]
    align_chi2: f64,
    /// With --align: the chi-square (1 degree of freedom) an estimated turn must reach against
    /// none to be applied (10.83: 99.9%; a turn moves far boxes by its lever arm).
    #[arg(long, requires = "align", default_value_t = AlignParams::default().turn_chi2)]
    align_turn_chi2: f64,
    /// With --align: largest centre distance (m) of a candidate match before any correction.
    #[arg(long, requires = "align", default_value_t = AlignParams::default().gate_m)]
    align_gate_m: f64,
}

impl AlignArgs {
    fn params(&self) -> anyhow::Result<Option<AlignParams>> {
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
struct RegionArgs {
    /// Serve one tile as a regional fuser (COLUMN_ROW, e.g. 0_0 or -1_2): subscribe to
    /// v2x/NS/det/TILE/* for it and its halo, publish on v2x/NS/fused/TILE the fused boxes whose
    /// centre lies in it. Agents must publish per tile (`v2x-agent --tile-size`, same size).
    #[arg(long)]
    tile: Option<v2x_protocol::tiles::Tile>,
    /// Side of the map's square tiles (m), as the agents use.
    #[arg(long, default_value_t = v2x_fuser::region::DEFAULT_TILE_M, requires = "tile")]
    tile_size: f64,
    /// How far beyond its tile a regional fuser takes boxes (m): at least the association's
    /// reach, so groups across the border are fused as one fuser would.
    #[arg(long, default_value_t = v2x_fuser::region::DEFAULT_HALO_M, requires = "tile")]
    halo: f64,
}

impl RegionArgs {
    fn region(&self) -> anyhow::Result<Option<v2x_fuser::region::Region>> {
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
struct IngestArgs {
    /// Reject frames stamped further than this from the fuser's clock, ahead or behind (ms);
    /// 0 accepts any capture time (agents replaying data on its own clock, `v2x-agent --clock data`).
    #[arg(long, default_value_t = 1000.0)]
    max_clock_skew_ms: f64,
    /// Most agents tracked at once; beyond, the least recently heard agent without a liveliness
    /// token is forgotten to make room.
    #[arg(long, default_value_t = 256)]
    max_agents: usize,
    /// Forget an agent with no frame and no liveliness token for this long (s).
    #[arg(long, default_value_t = 60.0)]
    forget_after_s: f64,
    /// Closed windows that may wait for fusion; beyond, windows are dropped and counted.
    #[arg(long, default_value_t = 16)]
    fusion_queue: usize,
    /// Interval of the rate-limited warning summaries (s).
    #[arg(long, default_value_t = 10.0)]
    log_interval_s: f64,
    /// Most boxes one agent brings into a window; beyond, its lowest-scoring boxes are dropped
    /// and counted (`over_budget`), so no agent can crowd the others out of the fused frame.
    #[arg(long, default_value_t = v2x_fuser::ingest::MAX_OBJECTS_PER_AGENT)]
    max_objects_per_agent: usize,
    /// The area of interest, X,Y,RADIUS in metres of the map frame: boxes outside it are
    /// dropped and counted (`outside`). Default: a disc of --area-radius-m around where most
    /// agents are, learned from their first boxes.
    #[arg(long, value_name = "X,Y,RADIUS", value_parser = v2x_fuser::ingest::Area::parse, allow_hyphen_values = true)]
    area: Option<v2x_fuser::ingest::Area>,
    /// The radius of the learned area of interest (m), without --area.
    #[arg(long, default_value_t = 10_000.0, conflicts_with = "area")]
    area_radius_m: f64,
}

impl IngestArgs {
    fn apply(&self, cfg: &mut node::NodeConfig) -> anyhow::Result<()> {
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

fn main() -> std::process::ExitCode {
    v2x_protocol::net::exit_code(run(Cli::parse()))
}

fn run(cli: Cli) -> anyhow::Result<()> {
    v2x_protocol::net::init_logging("info,zenoh=warn");
    match cli.command {
        Command::Fuse(args) => fuse(args),
        Command::Track(args) => track(args),
        Command::Node(args) => run_node(*args),
        Command::Router(args) => router(args),
        Command::Stats(args) => stats(args),
    }
}

/// `v2x-fuser fuse`.
fn fuse(args: FuseArgs) -> anyhow::Result<()> {
    let FuseArgs {
        files,
        align,
        align_to,
        output,
        inputs,
    } = args;
    let method = files.method;
    let (missing, mut opts) = files.options(inputs.len())?;
    let align_params = align.params()?;
    if align_params.is_some() && !(1..=inputs.len()).contains(&align_to) {
        anyhow::bail!(
            "--align-to {align_to}: there are {} inputs (give 1 to {})",
            inputs.len(),
            inputs.len()
        );
    }
    opts.align = align_params.map(|p| (p, align_to - 1));
    let report = v2x_fuser::offline::fuse_files(
        &method,
        &inputs,
        &output,
        missing,
        &opts,
        files.output_format.into(),
    )?;
    let how = match (report.by_time, opts.motion.is_some()) {
        (true, true) => "grouped by capture time, motion-compensated",
        (true, false) => "grouped by capture time, not compensated",
        (false, _) => "grouped by sample token (the files carry no capture times)",
    };
    eprintln!(
        "{method}: fused {} boxes from {} agents over {} samples into {} boxes ({how}) -> {}",
        report.boxes_in,
        inputs.len(),
        report.samples,
        report.boxes_out,
        output.display()
    );
    for (agent, measured, applied, last) in &report.registration {
        let last = last.map_or(String::new(), |r| {
            format!(
                "; last estimate shift ({:.2}, {:.2}) m +- ({:.2}, {:.2}), turn {:.2} deg, {}",
                r.shift_m[0],
                r.shift_m[1],
                r.std[0],
                r.std[1],
                r.turn_rad.to_degrees(),
                match (r.applied, r.turn_applied) {
                    (true, true) => "applied",
                    (true, false) => "shift applied, turn not",
                    (false, true) => "turn applied, shift not",
                    (false, false) => "not applied",
                }
            )
        });
        eprintln!(
            "registration of {agent}: measured in {measured} of {} windows, applied in {applied}{last} (per window: meta.v2x_registration)",
            report.samples
        );
    }
    print_learned(&report.learned);
    Ok(())
}

/// `v2x-fuser track`.
fn track(args: TrackArgs) -> anyhow::Result<()> {
    let TrackArgs {
        files,
        confirm_hits,
        max_misses,
        all_classes,
        guided,
        output,
        inputs,
    } = args;
    if confirm_hits == Some(0) {
        anyhow::bail!("--confirm-hits must be at least 1");
    }
    let method = files.method;
    let (missing, opts) = files.options(inputs.len())?;
    let confirm_hits = v2x_fuser::offline::confirm_hits(confirm_hits, &inputs, missing, &opts);
    let params = v2x_fuser::tracker::TrackerParams {
        confirm_hits,
        max_misses,
        all_classes,
        guided,
        ..Default::default()
    };
    let tracks = v2x_fuser::offline::track_files(
        &method,
        &inputs,
        &output,
        missing,
        &opts,
        params,
        files.output_format.into(),
    )?;
    let boxes: usize = tracks.results.samples.values().map(Vec::len).sum();
    if let Some(v) = tracks.results.meta.get("v2x_learned_std") {
        print_learned(&serde_json::from_value(v.clone()).unwrap_or_default());
    }
    eprintln!(
        "{method}: {} windows, {boxes} tracked boxes, {} tracks confirmed, {} ended, {} live at the end -> {}",
        tracks.results.samples.len(),
        tracks.stats.births,
        tracks.stats.deaths,
        tracks.stats.live,
        output.display()
    );
    Ok(())
}

/// `v2x-fuser node`.
fn run_node(args: NodeArgs) -> anyhow::Result<()> {
    let NodeArgs {
        ns,
        method,
        window_ms,
        max_wait_ms,
        detector,
        limits,
        motion,
        stds,
        region,
        align,
        track,
        track_all_classes,
        track_guided,
        no_track_handover,
        map_origin,
        ros,
        record,
        viz,
        duration_s,
        zenoh,
    } = args;
    let rt = v2x_protocol::net::runtime()?;
    rt.block_on(async move {
        if let Some(s) = duration_s {
            if !(s > 0.0 && s.is_finite()) {
                anyhow::bail!("--duration-s must be > 0");
            }
        }
        let mut cfg = node::NodeConfig::new(&ns, method);
        cfg.window_ms = window_ms;
        cfg.max_wait_ms = max_wait_ms;
        cfg.detector = detector.then(v2x_fuser::detector::DetectorParams::default);
        limits.apply(&mut cfg)?;
        cfg.motion = motion.params()?;
        cfg.region = region.region()?;
        cfg.align = align.params()?;
        cfg.learn = stds.params()?;
        cfg.models = stds.models()?;
        cfg.track = track.then(|| v2x_fuser::tracker::TrackerParams {
            all_classes: track_all_classes,
            guided: track_guided,
            ..Default::default()
        });
        cfg.set_time_scale(motion.time_scale);
        cfg.handover = !no_track_handover;
        cfg.map_origin = map_origin;
        cfg.viz = viz.open().await?;
        let shown = cfg.viz.clone();
        let session = v2x_protocol::net::open_session(&zenoh).await?;
        let mut recorded = Results::default();
        let mut provenance = serde_json::Map::new();
        let stop = async move {
            match duration_s {
                Some(s) => tokio::select! {
                    _ = tokio::time::sleep(std::time::Duration::from_secs_f64(s)) => {}
                    _ = node::shutdown_signal() => {}
                },
                None => node::shutdown_signal().await,
            }
        };
        let mut ros_out = ros.open(&session).await?;
        let stats = node::run(
            &session,
            cfg,
            |f| {
                if let Some(r) = ros_out.as_mut() {
                    r.publish(f);
                }
                if record.is_some() {
                    let sample = format!("t{}", f.frame.capture_us);
                    provenance.insert(sample.clone(), provenance_json(&f.provenance));
                    recorded.samples.insert(sample, f.frame.detections.clone());
                }
            },
            stop,
        )
        .await?;
        if let Some(v) = shown {
            v.close()?;
        }
        if let Some(path) = &record {
            let mut meta = default_meta();
            meta["v2x_provenance"] = serde_json::Value::Object(provenance);
            if !stats.learned_std.is_empty() {
                meta["v2x_learned_std"] = serde_json::to_value(&stats.learned_std)?;
            }
            recorded.meta = meta;
            write_results(path, &recorded, &TokenTable::new())?;
            eprintln!(
                "recorded {} fused frames -> {}",
                recorded.samples.len(),
                path.display()
            );
        }
        println!("{}", serde_json::to_string_pretty(&stats)?);
        session
            .close()
            .await
            .map_err(|e| anyhow::anyhow!("closing the session: {e}"))?;
        Ok(())
    })
}

/// `v2x-fuser router`.
fn router(args: RouterArgs) -> anyhow::Result<()> {
    let RouterArgs { mut zenoh } = args;
    if zenoh.mode.is_none() {
        zenoh.mode = Some("router".into());
    }
    let rt = v2x_protocol::net::runtime()?;
    rt.block_on(async move {
        let config = v2x_protocol::net::config(&zenoh)?;
        let secure = config
            .get_json("access_control/enabled")
            .is_ok_and(|v| v == "true");
        let session = zenoh::open(config)
            .await
            .map_err(|e| anyhow::anyhow!("cannot start the router: {e}"))?;
        eprintln!(
            "router {} running ({}); Ctrl-C or SIGTERM stops it",
            session.zid(),
            if secure {
                "access control on"
            } else {
                "no access control: any client may publish anything"
            }
        );
        v2x_protocol::net::shutdown_signal().await;
        session
            .close()
            .await
            .map_err(|e| anyhow::anyhow!("closing the router: {e}"))?;
        Ok(())
    })
}

/// `v2x-fuser stats`.
fn stats(args: StatsArgs) -> anyhow::Result<()> {
    let StatsArgs {
        ns,
        tile,
        timeout_s,
        zenoh,
    } = args;
    let rt = v2x_protocol::net::runtime()?;
    rt.block_on(async move {
        let session = v2x_protocol::net::open_session(&zenoh).await?;
        let key = v2x_protocol::keys::FuserKeys::of(&ns, tile).stats;
        let v = node::query_stats_at(
            &session,
            &key,
            std::time::Duration::from_secs_f64(timeout_s),
        )
        .await?;
        println!("{}", serde_json::to_string_pretty(&v)?);
        Ok(())
    })
}
