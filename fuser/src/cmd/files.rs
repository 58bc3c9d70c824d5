//! `v2x-fuser fuse` and `track`: results files (or KITTI folders) fused offline, and followed
//! over time.

use std::path::PathBuf;
use v2x_protocol::nuscenes_json::MissingStd;

use super::settings::*;

/// How `fuse` and `track` fuse files: the fuser's settings, and how the files are read and
/// written.
#[derive(clap::Args)]
pub(crate) struct FilesArgs {
    #[command(flatten)]
    pub(crate) fusion: v2x_fuser::settings::FusionSettings,
    /// Stds for boxes that carry no translation_std/size_std/yaw_std: mild, moderate, large,
    /// or POS,SIZE,YAW_DEG (metres, metres, degrees). Without it (or --learn-std, or a
    /// --std-model for every input), a missing std is an error in a results file; KITTI rows,
    /// which state none, take a detector's stds.
    #[arg(long, value_parser = v2x_protocol::parse_std, conflicts_with_all = ["detector", "learn_std"])]
    pub(crate) default_std: Option<v2x_protocol::Uncertainty>,
    /// The output's layout: auto (KITTI folders for KITTI folder inputs, else nuScenes JSON),
    /// nuscenes (one results file) or kitti (a folder of NNNN.txt per sequence, as V2V4Real's
    /// and AB3DMOT's evaluators read them).
    #[arg(long, value_enum, default_value_t = Layout::Auto)]
    pub(crate) output_format: Layout,
    /// With --align: the reference agent, as its position among the inputs (1 = first).
    /// `v2x-sim gen` writes the roadside unit as agent2.json.
    #[arg(long, default_value_t = 2, requires = "align")]
    pub(crate) align_to: usize,
    #[command(flatten)]
    pub(crate) output: v2x_protocol::cli::Output,
    /// Inputs, one per agent, in agent order: nuScenes results files, or folders of KITTI
    /// detection rows (NNNN.txt per sequence, every box in the first agent's frame at 10 Hz,
    /// as V2V4Real's per-car detections come).
    #[arg(required = true)]
    pub(crate) inputs: Vec<PathBuf>,
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
    /// How boxes without stds are read, and the offline options for the inputs.
    pub(crate) fn options(
        &self,
    ) -> anyhow::Result<(MissingStd, v2x_fuser::offline::OfflineOptions)> {
        let inputs = self.inputs.len();
        let (missing, mut opts) = self
            .fusion
            .offline(inputs, self.default_std)
            .map_err(flag_error)?;
        if opts.steps.align.is_some() {
            if !(1..=inputs).contains(&self.align_to) {
                anyhow::bail!(
                    "--align-to {}: there are {inputs} inputs (give 1 to {inputs})",
                    self.align_to
                );
            }
            opts.reference = self.align_to - 1;
        }
        Ok((missing, opts))
    }
}

/// The options of `v2x-fuser fuse`.
#[derive(clap::Args)]
pub(crate) struct FuseArgs {
    #[command(flatten)]
    pub(crate) files: FilesArgs,
}

/// The options of `v2x-fuser track`.
#[derive(clap::Args)]
pub(crate) struct TrackArgs {
    #[command(flatten)]
    pub(crate) files: FilesArgs,
    #[command(flatten)]
    pub(crate) tracking: v2x_fuser::settings::TrackSettings,
}

/// `v2x-fuser fuse`.
pub(crate) fn fuse(args: FuseArgs) -> anyhow::Result<()> {
    let FuseArgs { files } = args;
    let (method, inputs, output) = (files.fusion.method, &files.inputs, &files.output.path);
    let (missing, opts) = files.options()?;
    let report =
        v2x_fuser::offline::fuse_files(inputs, output, missing, &opts, files.output_format.into())?;
    let how = match (report.by_time, opts.steps.motion.is_some()) {
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
    let TrackArgs { files, tracking } = args;
    let (method, inputs, output) = (files.fusion.method, &files.inputs, &files.output.path);
    let (missing, opts) = files.options()?;
    let params = tracking.params().map_err(flag_error)?;
    let tracks = v2x_fuser::offline::track_files(
        inputs,
        output,
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
