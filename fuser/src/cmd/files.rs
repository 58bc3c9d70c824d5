//! `v2x-fuser fuse` and `track`: results files (or KITTI folders) fused offline, and followed
//! over time.

use std::path::PathBuf;
use v2x_fuser::Method;
use v2x_protocol::nuscenes_json::MissingStd;

use super::settings::*;

/// How `fuse` and `track` fuse files: method, stds, motion and windows.
#[derive(clap::Args)]
pub(crate) struct FilesArgs {
    /// Fusion method of each window (see the list below).
    #[arg(long, short, default_value_t = Method::default())]
    pub(crate) method: Method,
    /// Stds for boxes that carry no translation_std/size_std/yaw_std: mild, moderate, large,
    /// or POS,SIZE,YAW_DEG (metres, metres, degrees). Without it (or --learn-std, or a
    /// --std-model for every input), a missing std is an error in a results file; KITTI rows,
    /// which state none, take mild.
    #[arg(long, value_parser = v2x_protocol::parse_std)]
    pub(crate) default_std: Option<v2x_protocol::Uncertainty>,
    /// The inputs are a detector's boxes (docs/method.md §11): each box's stds from its score, replacing
    /// any it states (the first input is the receiver, the others add a pose std), or from the
    /// input's --std-model when it has one (`v2x-sim calibrate` fits it); each fused box scored
    /// by its chance of being a real object (--existence-model), and --min-score the operating
    /// point. The default for KITTI folders given without --default-std; give it for results
    /// files, such as `v2x-sim gen --dataset v2v4real` writes.
    #[arg(long, conflicts_with_all = ["default_std", "learn_std"])]
    pub(crate) detector: bool,
    /// A detector's fused boxes are scored by the chance each is a real object: by the model
    /// fitted on V2V4Real's train split (`default`), by a model `v2x-sim fit-score` wrote for
    /// your detector (a JSON file), or (`noisy-or`) by the noisy-OR of the members' scores.
    #[arg(long, default_value = "default", value_name = "default|noisy-or|FILE")]
    pub(crate) existence_model: String,
    /// The operating point on a detector's scores, each a chance of being a real object: `fuse`
    /// leaves out fused boxes scoring below it; `track` gives the tracker every box and leaves
    /// out tracked boxes scoring below it. 0 keeps everything.
    #[arg(long, default_value_t = v2x_fuser::uncertainty::detector::DetectorParams::default().min_score)]
    pub(crate) min_score: f64,
    #[command(flatten)]
    pub(crate) motion: v2x_fuser::settings::MotionSettings,
    #[command(flatten)]
    pub(crate) stds: v2x_fuser::settings::StdSettings,
    /// Window width delta t (ms) when the files carry capture times.
    #[arg(long, default_value_t = 100.0)]
    pub(crate) window_ms: f64,
    /// The output's layout: auto (KITTI folders for KITTI folder inputs, else nuScenes JSON),
    /// nuscenes (one results file) or kitti (a folder of NNNN.txt per sequence, as V2V4Real's
    /// and AB3DMOT's evaluators read them).
    #[arg(long, value_enum, default_value_t = Layout::Auto)]
    pub(crate) output_format: Layout,
}

/// The layout of `fuse` and `track` output.
#[derive(Copy, Clone, Debug, clap::ValueEnum)]
pub(crate) enum Layout {
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
    pub(crate) fn options(
        &self,
        inputs: usize,
    ) -> anyhow::Result<(MissingStd, v2x_fuser::offline::OfflineOptions)> {
        if !(self.window_ms > 0.0 && self.window_ms.is_finite()) {
            anyhow::bail!("--window-ms must be > 0");
        }
        let mut opts = v2x_fuser::offline::OfflineOptions {
            motion: self.motion.params().map_err(flag_error)?,
            window_ms: self.window_ms,
            align: None,
            learn: self.stds.learn().map_err(flag_error)?,
            models: models_by_input(&self.stds, inputs)?,
            detector: None,
            detector_params: v2x_fuser::offline::detector_params(
                &self.existence_model,
                self.min_score,
            )?,
        };
        opts.detector = self.detector.then_some(opts.detector_params);
        opts.set_time_scale(self.motion.time_scale);
        let missing = match self.detector {
            // Every std is replaced by the detector's.
            true => MissingStd::Default(v2x_fuser::offline::kitti_default_std()),
            false => missing(&self.stds, self.default_std, inputs),
        };
        Ok((missing, opts))
    }
}

/// The options of `v2x-fuser fuse`.
#[derive(clap::Args)]
pub(crate) struct FuseArgs {
    #[command(flatten)]
    pub(crate) files: FilesArgs,
    #[command(flatten)]
    pub(crate) align: v2x_fuser::settings::AlignSettings,
    /// With --align: the reference agent, as its position among the inputs (1 = first).
    /// `v2x-sim gen` writes the roadside unit as agent2.json.
    #[arg(long, default_value_t = 2, requires = "align")]
    pub(crate) align_to: usize,
    /// Where to write the fused results file (a folder with --output-format kitti).
    #[arg(long, short)]
    pub(crate) output: PathBuf,
    /// Inputs, one per agent, in agent order: nuScenes results files, or folders of KITTI
    /// detection rows (NNNN.txt per sequence, every box in the first agent's frame at 10 Hz,
    /// as V2V4Real's per-car detections come).
    #[arg(required = true)]
    pub(crate) inputs: Vec<PathBuf>,
}

/// The options of `v2x-fuser track`.
#[derive(clap::Args)]
pub(crate) struct TrackArgs {
    #[command(flatten)]
    pub(crate) files: FilesArgs,
    /// Hits in a row that confirm a track: by default 2, for any boxes (a box seen once never
    /// becomes a track); 1 shows every box at once.
    #[arg(long, default_value_t = v2x_fuser::tracker::TrackerParams::default().confirm_hits)]
    pub(crate) confirm_hits: u32,
    /// Windows in a row without a box a confirmed track survives.
    #[arg(long, default_value_t = 3)]
    pub(crate) max_misses: u32,
    /// Also track the classes the nuScenes tracking benchmark does not score (barrier,
    /// traffic cone, construction vehicle). Without it the file holds the seven tracking
    /// classes only, as the official devkit's loader requires; with it the devkit refuses it.
    #[arg(long)]
    pub(crate) all_classes: bool,
    /// Associate each agent's boxes with the tracks' predictions first, one agent after another,
    /// and fuse between agents (with --method) only the boxes no track explains
    /// (docs/method.md §8.1). Default: track the fused boxes.
    #[arg(long)]
    pub(crate) guided: bool,
    /// Update each track with its boxes weighed by the chance each is its own, where a box
    /// could be either of two tracks' (docs/method.md §8.2), instead of with the one box of the
    /// best assignment. For the fused boxes; not with --guided.
    #[arg(long, conflicts_with = "guided")]
    pub(crate) soft: bool,
    /// Where to write the tracking results file (a folder with --output-format kitti).
    #[arg(long, short)]
    pub(crate) output: PathBuf,
    /// Inputs, one per agent, in agent order: nuScenes results files, or folders of KITTI
    /// detection rows (NNNN.txt per sequence, every box in the first agent's frame at 10 Hz,
    /// as V2V4Real's per-car detections come).
    #[arg(required = true)]
    pub(crate) inputs: Vec<PathBuf>,
}

/// `v2x-fuser fuse`.
pub(crate) fn fuse(args: FuseArgs) -> anyhow::Result<()> {
    let FuseArgs {
        files,
        align,
        align_to,
        output,
        inputs,
    } = args;
    let method = files.method;
    let (missing, mut opts) = files.options(inputs.len())?;
    let align_params = align.params().map_err(flag_error)?;
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
pub(crate) fn track(args: TrackArgs) -> anyhow::Result<()> {
    let TrackArgs {
        files,
        confirm_hits,
        max_misses,
        all_classes,
        guided,
        soft,
        output,
        inputs,
    } = args;
    if confirm_hits == 0 {
        anyhow::bail!("--confirm-hits must be at least 1");
    }
    let method = files.method;
    let (missing, opts) = files.options(inputs.len())?;
    let params = v2x_fuser::tracker::TrackerParams {
        confirm_hits,
        max_misses,
        all_classes,
        guided,
        soft,
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
