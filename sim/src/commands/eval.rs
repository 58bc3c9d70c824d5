//! `v2x-sim eval`.

use super::*;
use anyhow::bail;
use std::path::PathBuf;
use v2x_sim::bench;
use v2x_sim::cli::{evaluate_file, DataArgs, EvalOptions, Evaluation};
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

/// Runs `v2x-sim eval`.
pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    let EvalArgs {
        data,
        all_frames,
        matching: v2x_sim::cli::MatchArg { matching },
        tracking,
        format: v2x_sim::cli::FormatArg { format },
        replay: v2x_protocol::cli::ReplayArg { replay },
        at,
        classes,
        pred,
    } = args;
    if data.is_v2v4real() {
        return v2v4real(&data, &pred, tracking, format);
    }
    if tracking {
        return tracking_table(&data, &pred, all_frames, format);
    }
    let replay = replay_map(replay)?;
    let dair = if data.is_dair() {
        Some(data.load_dair()?)
    } else {
        None
    };
    let gt = match &dair {
        Some(d) => d.gt.clone(),
        None => data.load()?,
    };
    let opts = EvalOptions {
        all_frames,
        replay,
        how: matching,
        timing: at,
        classes,
    };
    let (evaluation, note) = evaluate_file(&gt, &pred, &opts)?;
    eprintln!("{note}");
    let csv = format == Format::Csv;
    if let Some(d) = &dair {
        return dair_eval(d, &pred, all_frames, evaluation, format);
    }
    match evaluation {
        e if format == Format::Json => println!("{}", serde_json::to_string_pretty(&e)?),
        Evaluation::Distance(d) => {
            let rows = [bench::DetectionRow {
                noise: String::new(),
                method: pred.display().to_string(),
                metrics: d,
            }];
            print!("{}", table_or_csv(&rows[..], csv));
        }
        Evaluation::Id(m) => {
            let rows = [bench::Row {
                noise: "-".into(),
                method: pred.display().to_string(),
                metrics: m,
            }];
            print!("{}", table_or_csv(&rows[..], csv));
        }
    }
    Ok(())
}

/// The rows as CSV when asked and they have a CSV form, else as a table.
fn table_or_csv<R: Rows + ?Sized>(rows: &R, csv: bool) -> String {
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

/// The DAIR-V2X protocol beside the devkit-style figures, for one results file.
fn dair_eval(
    d: &v2x_sim::dair::Dair,
    pred: &std::path::Path,
    all_frames: bool,
    evaluation: Evaluation,
    format: Format,
) -> anyhow::Result<()> {
    let results = v2x_protocol::nuscenes_json::read_results(
        pred,
        &mut d.gt.tokens.clone(),
        v2x_protocol::nuscenes_json::MissingStd::Default(v2x_protocol::Uncertainty::uniform(
            1.0, 1.0, 1.0,
        )),
    )?;
    let (dair, scored) = v2x_sim::bench::dair::score_results(d, &results, all_frames);
    eprintln!(
        "DAIR-V2X protocol over {scored} pairs, in the vehicle's frame within its evaluation range"
    );
    let Evaluation::Distance(detection) = evaluation else {
        bail!("{}: DAIR-V2X boxes carry no ground-truth ids: score them with --match distance (or auto)", pred.display());
    };
    let rows = [v2x_sim::bench::dair::DairRow {
        method: pred.display().to_string(),
        detection,
        dair,
        bytes_per_frame: None,
        cpm_bytes_per_frame: None,
        official_ab: None,
    }];
    match format {
        Format::Json => println!("{}", serde_json::to_string_pretty(&rows[0])?),
        _ => print!("{}", table_or_csv(&rows[..], format == Format::Csv)),
    }
    Ok(())
}

/// `--tracking`: the nuScenes tracking benchmark's figures of a tracking results file.
fn tracking_table(
    data: &DataArgs,
    pred: &std::path::Path,
    all_frames: bool,
    format: Format,
) -> anyhow::Result<()> {
    let gt = data.load()?;
    let m = evaluate_tracking(&gt, pred, all_frames)?;
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

/// `--dataset v2v4real`: a folder of KITTI rows scored by V2V4Real's detection protocol, or with
/// `--tracking` by AB3DMOT's tracking evaluation.
fn v2v4real(
    data: &DataArgs,
    dir: &std::path::Path,
    tracking: bool,
    format: Format,
) -> anyhow::Result<()> {
    let d = data.load_v2v4real(v2x_fuser::offline::kitti_default_std())?;
    if !dir.is_dir() {
        bail!(
            "{}: --dataset v2v4real scores a folder of KITTI rows (one NNNN.txt per sequence)",
            dir.display()
        );
    }
    if tracking {
        let row = v2x_sim::bench::v2v4real::score_track_dir(&d, dir)?;
        match format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&row)?),
            _ => print!("{}", [row][..].table()),
        }
    } else {
        let m = v2x_sim::bench::v2v4real::score_detection_dir(&d, dir)?;
        match format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&m)?),
            _ => println!(
                "{}: AP-BEV {} · AP-3D {} in frame order (V2V4Real's protocol); globally sorted \
                 (OpenCOOD's --global_sort_detections) AP-BEV {} · AP-3D {} ({} frames, {} \
                 labelled cars, {} boxes)",
                dir.display(),
                serde_json::to_string(&m.ap_bev)?,
                serde_json::to_string(&m.ap_3d)?,
                serde_json::to_string(&m.global.bev)?,
                serde_json::to_string(&m.global.three_d)?,
                m.frames,
                m.gt,
                m.predictions
            ),
        }
    }
    Ok(())
}
