//! `v2x-sim eval`.

use super::*;
use anyhow::bail;
use std::path::PathBuf;
use v2x_sim::bench;
use v2x_sim::cli::{DataArgs, EvalOptions};
use v2x_sim::table::{
    markdown,
    Align::{Left, Right},
    Rows,
};

/// The options of `v2x-sim eval`.
#[derive(clap::Args)]
pub struct EvalArgs {
    #[command(flatten)]
    pub data: DataArgs,
    /// Count ground-truth frames absent from the file as all missed (default: score only the
    /// frames the file has).
    #[arg(long)]
    pub all_frames: bool,
    #[command(flatten)]
    pub matching: v2x_sim::cli::MatchArg,
    /// Score a tracking results file (`v2x-fuser track`) as the nuScenes tracking benchmark
    /// does: AMOTA, AMOTP, and MOTA, MOTP, IDS, FRAG at each class's best score threshold,
    /// 2 m centre distance, the seven tracking classes. The same file without --tracking
    /// scores its boxes as detections. With --dataset v2v4real: a folder of KITTI tracking rows
    /// scored by AB3DMOT's evaluation (3D IoU 0.25), as DMSTrack reports V2V4Real.
    #[arg(long, conflicts_with_all = ["replay", "at", "classes"])]
    pub tracking: bool,
    #[command(flatten)]
    pub format: v2x_sim::cli::FormatArg,
    /// For a fuser recording of agents' replays on the real clock: the agents' --replay (its
    /// start_at and speed), so that capture times map back to the data's frames.
    #[command(flatten)]
    pub replay: v2x_protocol::cli::ReplayArg,
    /// When a sample is scored: `frame` (a sample token at its own frame, whatever the
    /// file's meta.v2x_timestamps say) or `capture` (at its capture time from
    /// meta.v2x_timestamps, the ground truth interpolated along its tracks; only for ground
    /// truth tracked across frames). Keys that are no sample token (t<us>) use their time.
    #[arg(long, value_enum, default_value = "frame")]
    pub at: v2x_sim::cli::Timing,
    /// The classes to score, comma-separated nuScenes names (e.g. car,truck,bus): other
    /// classes' boxes, ground truth and predictions, are left out. Default: every class, the
    /// benchmark's headline averaged over the classes the ground truth holds.
    #[arg(long, value_delimiter = ',')]
    pub classes: Option<Vec<v2x_protocol::Class>>,
    /// The results file to score (with --dataset v2v4real, a folder of KITTI rows: detection
    /// rows scored by V2V4Real's protocol, or tracking rows with --tracking).
    pub pred: PathBuf,
}

/// The results file scored against `gt` as the options say, its note printed.
pub(crate) fn evaluate(
    args: &EvalArgs,
    gt: &v2x_sim::dataset::GroundTruth,
) -> anyhow::Result<v2x_sim::cli::Evaluation> {
    let (evaluation, note) = v2x_sim::cli::evaluate_file(gt, &args.pred, &options(args)?)?;
    eprintln!("{note}");
    Ok(evaluation)
}

/// How a results file is matched and which frames and classes count.
fn options(args: &EvalArgs) -> anyhow::Result<EvalOptions> {
    Ok(EvalOptions {
        all_frames: args.all_frames,
        replay: replay_map(args.replay.replay)?,
        how: args.matching.matching,
        timing: args.at,
        classes: args.classes.clone(),
    })
}

/// The rows as CSV when asked and they have a CSV form, else as a table.
pub(crate) fn table_or_csv<R: Rows + ?Sized>(rows: &R, csv: bool) -> String {
    csv.then(|| rows.csv())
        .flatten()
        .unwrap_or_else(|| rows.table())
}

/// How a recording on the real clock maps to data time (`--replay`'s start_at and speed,
/// checked when parsed); none for the data's own clock.
fn replay_map(
    replay: v2x_protocol::cli::Replay,
) -> anyhow::Result<Option<v2x_sim::cli::ReplayMap>> {
    use v2x_protocol::cli::ReplayClock;
    match (replay.clock, replay.start_at) {
        (ReplayClock::Real, Some(t)) => Ok(Some(v2x_sim::cli::ReplayMap {
            start_us: (t * 1e6) as u64,
            speed: replay.speed,
        })),
        (ReplayClock::Real, None) if replay.speed != 1.0 => {
            bail!("--replay: give the agents' start_at with their speed")
        }
        _ => Ok(None),
    }
}

/// `--tracking`: the nuScenes tracking benchmark's figures of a tracking results file.
pub(crate) fn tracking_table(args: &EvalArgs) -> anyhow::Result<()> {
    let (pred, format) = (args.pred.as_path(), args.format.format);
    let gt = args.data.load()?;
    let m = evaluate_tracking(&gt, pred, args.all_frames)?;
    match format {
        Format::Json => println!("{}", serde_json::to_string_pretty(&m)?),
        Format::Table | Format::Csv => {
            let mut row = vec![pred.display().to_string()];
            row.extend(bench::tracking_cells(Some(&m)));
            row.extend([m.tp, m.fp, m.fn_, m.gt_tracks].map(|n| n.to_string()));
            let mut columns = vec![("predictions", Left)];
            columns.extend(bench::TRACKING_COLUMNS);
            columns.extend([
                ("TP", Right),
                ("FP", Right),
                ("FN", Right),
                ("objects", Right),
            ]);
            print!("{}", markdown(&columns, [row]));
        }
    }
    Ok(())
}
