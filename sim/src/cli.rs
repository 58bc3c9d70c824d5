//! Command-line pieces shared by the `v2x-sim` subcommands: where the ground truth comes from;
//! scoring a results file against it is `v2x-eval`'s ([`evaluate_file`], re-exported here).

use crate::dair::{load_dair, Dair};
use crate::dataset::{load_nuscenes, GroundTruth};
use crate::town::{generate, TownConfig};
use anyhow::{bail, Context};
use clap::Args;
use std::path::{Path, PathBuf};

/// Which kind of data `--dataroot` holds.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DatasetKind {
    /// nuScenes tables (DATAROOT/VERSION/*.json).
    #[default]
    Nuscenes,
    /// DAIR-V2X-C or V2X-Seq-SPD (DATAROOT holds cooperative/, vehicle-side/ and
    /// infrastructure-side/): the agents are the data's vehicle `veh` and roadside unit `inf`.
    DairV2x,
    /// V2V4Real's detections in the AB3DMOT layout (DATAROOT is the AB3DMOT/ folder of a
    /// DMSTrack checkout): the agents are the two cars `ego` and `1`, real PointPillars output.
    V2v4real,
}

/// On or off.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Switch {
    /// On.
    On,
    /// Off.
    Off,
}

/// Where the ground truth comes from: nuScenes tables, DAIR-V2X cooperative data, or the
/// synthetic town (the default).
#[derive(Args, Clone, Debug)]
pub struct DataArgs {
    /// Data root: the folder holding VERSION/ (nuScenes), or cooperative/, vehicle-side/ and
    /// infrastructure-side/ (--dataset dair-v2x); without it, the synthetic town is used.
    #[arg(long)]
    pub dataroot: Option<PathBuf>,
    /// What --dataroot holds.
    #[arg(long, value_enum, default_value = "nuscenes", requires = "dataroot")]
    pub dataset: DatasetKind,
    /// DAIR-V2X: move the roadside by each pair's calibration offset (system_error_offset), as
    /// the official loader does.
    #[arg(long, value_enum, default_value = "on")]
    pub calibration_offset: Switch,
    /// DAIR-V2X: a side's boxes from a detector's results instead of its labels, SIDE=PATH
    /// (veh or inf; repeat for both): a folder of {frame_id}.json, or one JSON object by frame
    /// id, each with `boxes_3d` (8 corners in mmdetection3d's order, in that side's LiDAR frame,
    /// the roadside's virtual one), `labels_3d` and `scores_3d`.
    #[arg(long, value_name = "SIDE=PATH", value_parser = parse_dair_results, requires = "dataroot")]
    pub dair_results: Vec<(usize, PathBuf)>,
    /// V2V4Real: the split, train (develop and tune here) or val (the dataset's test split).
    #[arg(long, default_value = "train")]
    pub split: v2x_truth::v2v4real::Split,
    /// nuScenes version folder name, e.g. v1.0-mini.
    #[arg(long)]
    pub version: Option<String>,
    /// Synthetic town: number of scenes.
    #[arg(long, default_value_t = 1)]
    pub scenes: usize,
    /// Synthetic town: seconds per scene.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Synthetic town: frames per second (nuScenes key frames are 2 Hz).
    #[arg(long, default_value_t = 10.0)]
    pub hz: f64,
    /// Synthetic town: the nuScenes-validation-sized set (150 scenes x 20 s at 2 Hz); overrides
    /// --scenes, --seconds and --hz.
    #[arg(long)]
    pub validation_size: bool,
    /// Synthetic town: layout seed.
    #[arg(long, default_value_t = 7)]
    pub town_seed: u64,
}

impl DataArgs {
    /// The synthetic town these arguments describe.
    pub fn town(&self) -> TownConfig {
        if self.validation_size {
            TownConfig::validation(self.town_seed)
        } else {
            TownConfig {
                scenes: self.scenes,
                seconds: self.seconds,
                hz: self.hz,
                seed: self.town_seed,
            }
        }
    }

    /// Whether the data is DAIR-V2X cooperative data.
    pub fn is_dair(&self) -> bool {
        self.dataroot.is_some() && self.dataset == DatasetKind::DairV2x
    }

    /// Whether the data is V2V4Real's.
    pub fn is_v2v4real(&self) -> bool {
        self.dataroot.is_some() && self.dataset == DatasetKind::V2v4real
    }

    /// Loads V2V4Real's split (`--dataset v2v4real`), the cars' boxes with `std`.
    pub fn load_v2v4real(
        &self,
        std: v2x_protocol::Uncertainty,
    ) -> anyhow::Result<v2x_truth::v2v4real::V2v4real> {
        match (&self.dataroot, self.dataset) {
            (Some(root), DatasetKind::V2v4real) => {
                Ok(v2x_truth::v2v4real::load(root, self.split, std)?)
            }
            _ => bail!("this needs --dataset v2v4real --dataroot AB3DMOT_DIR"),
        }
    }

    /// Loads DAIR-V2X cooperative data (`--dataset dair-v2x`).
    pub fn load_dair(&self) -> anyhow::Result<Dair> {
        match (&self.dataroot, self.dataset) {
            (Some(root), DatasetKind::DairV2x) => {
                let mut d = load_dair(root, self.calibration_offset == Switch::On)?;
                if d.corner_mismatches > 0 {
                    eprintln!(
                        "{}: {} world labels place their box more than 10 cm from their world_8_points; the corners were used",
                        root.display(),
                        d.corner_mismatches
                    );
                }
                for &(agent, ref path) in &self.dair_results {
                    let results = crate::dair::results::read_results(path)?;
                    let missing = d.use_results(agent, &results);
                    if missing > 0 {
                        eprintln!(
                            "{}: no results for {missing} of {} {} frames (those frames get no boxes)",
                            path.display(),
                            d.rec.pairs.len(),
                            crate::dair::AGENTS[agent]
                        );
                    }
                }
                Ok(d)
            }
            _ => bail!("this needs --dataset dair-v2x --dataroot DIR"),
        }
    }

    /// Loads or generates the ground truth (for DAIR-V2X, its cooperative labels).
    pub fn load(&self) -> anyhow::Result<GroundTruth> {
        if !self.is_dair() && !self.dair_results.is_empty() {
            bail!("--dair-results reads DAIR-V2X detection results: it needs --dataset dair-v2x");
        }
        if self.is_dair() {
            return Ok(self.load_dair()?.gt);
        }
        if self.is_v2v4real() {
            // Both cars replay their own boxes, with the stds a detector's boxes are given.
            let mut d = self.load_v2v4real(v2x_fuser::offline::kitti_default_std())?;
            d.cars = crate::gen::ready_cars(&d.cars, &Default::default());
            return Ok(d.ground_truth());
        }
        match (&self.dataroot, &self.version) {
            (Some(root), Some(version)) => Ok(load_nuscenes(root, version)?),
            (Some(_), None) => bail!(
                "--dataroot needs --version NAME for nuScenes tables (DATAROOT/NAME/*.json), or --dataset dair-v2x"
            ),
            (None, Some(_)) => bail!("--version needs --dataroot"),
            _ => {
                let t = self.town();
                if t.scenes == 0
                    || !t.hz.is_finite()
                    || t.hz <= 0.0
                    || !t.seconds.is_finite()
                    || t.seconds <= 0.0
                {
                    bail!("the synthetic town needs --scenes >= 1, --hz > 0 and --seconds > 0");
                }
                Ok(generate(&t))
            }
        }
    }

    /// A short description of the source, for reports.
    pub fn describe(&self, gt: &GroundTruth) -> String {
        described(&self.source(), gt)
    }

    /// The source's name, for reports: its data root or the town's settings.
    pub fn source(&self) -> String {
        match &self.dataroot {
            Some(r) if self.is_dair() => format!(
                "DAIR-V2X {} (calibration offset {})",
                r.display(),
                if self.calibration_offset == Switch::On {
                    "on"
                } else {
                    "off"
                }
            ),
            Some(r) => format!(
                "nuScenes tables {}",
                r.join(self.version.as_deref().unwrap_or("")).display()
            ),
            None => {
                let t = self.town();
                format!(
                    "synthetic town (seed {}, {} scenes x {} s at {} Hz)",
                    t.seed, t.scenes, t.seconds, t.hz
                )
            }
        }
    }
}

/// A data set's name and size, for reports: `NAME: N frames, M boxes`.
pub fn described(name: &str, gt: &GroundTruth) -> String {
    format!("{name}: {} frames, {} boxes", gt.frames.len(), gt.boxes())
}

pub use v2x_eval::file_eval::{
    evaluate_file, sample_times, EvalError, EvalOptions, Evaluation, Match, ReplayMap, SampleTime,
    Timing,
};

/// Reads a file's text with the path in the error.
pub fn read_text(path: &Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))
}

/// `--dair-results SIDE=PATH`: the side's index among `v2x_truth::dair::AGENTS` and the path.
fn parse_dair_results(s: &str) -> Result<(usize, PathBuf), String> {
    let sides = v2x_truth::dair::AGENTS;
    let (side, path) = s.split_once('=').ok_or_else(|| {
        format!(
            "'{s}': expected SIDE=PATH, SIDE one of {}",
            sides.join(", ")
        )
    })?;
    let i = sides
        .iter()
        .position(|a| *a == side)
        .ok_or_else(|| v2x_protocol::UnknownName::new("side", side, sides).to_string())?;
    Ok((i, PathBuf::from(path)))
}

/// The output format of a command that prints rows (`--format`).
#[derive(Args, Clone, Copy, Debug)]
pub struct FormatArg {
    /// Output format.
    #[arg(long, value_enum, default_value = "table")]
    pub format: crate::table::Format,
}

/// How simulated agents draw their boxes (`--seed`, `--range`).
#[derive(Args, Clone, Copy, Debug)]
pub struct DrawArgs {
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sensing range of each agent in metres (default: every agent sees every object).
    #[arg(long, value_parser = parse_range)]
    pub range: Option<f64>,
}

/// A sensing range: a distance above 0 m.
fn parse_range(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(r) if r.is_finite() && r > 0.0 => Ok(r),
        _ => Err(format!("expected a distance above 0 m, got '{s}'")),
    }
}

/// The fusion method (`-m/--method`).
#[derive(Args, Clone, Copy, Debug)]
pub struct MethodArg {
    /// Fusion method.
    #[arg(long, short, default_value_t = v2x_fuser::Method::default(), value_parser = v2x_fuser::maths::method::method_parser())]
    pub method: v2x_fuser::Method,
}

/// How boxes are matched to the ground truth (`--match`).
#[derive(Args, Clone, Copy, Debug)]
pub struct MatchArg {
    /// How boxes are matched to the ground truth: `id` (by the ground-truth id each box
    /// carries, its instance_token: the paper's protocol, precision, recall, mATE...),
    /// `distance` (by centre distance: in `eval` the nuScenes detection benchmark, AP at
    /// 0.5/1/2/4 m, TP errors at 2 m, NDS; in `calibrate` the nearest object of the box's class
    /// within --max-distance-m), or `auto`: by id when the boxes carry ids, else by distance (a
    /// detector's own output has none).
    #[arg(long = "match", value_enum, default_value = "auto")]
    pub matching: Match,
}
