//! `v2x-sim mcap`.

use anyhow::bail;
use std::path::PathBuf;
use v2x_sim::cli::DataArgs;

/// The options of `v2x-sim mcap`.
#[derive(clap::Args)]
pub struct McapArgs {
    #[command(flatten)]
    pub data: DataArgs,
    /// The results file (from `v2x-fuser fuse`, `node --record`, `v2x-sim gen` or `run --record`).
    pub pred: PathBuf,
    #[command(flatten)]
    pub out: v2x_protocol::cli::Output,
}

/// Runs `v2x-sim mcap`.
pub fn run(args: McapArgs) -> anyhow::Result<()> {
    let McapArgs {
        data,
        pred,
        out: v2x_protocol::cli::Output { path: out },
    } = args;
    let gt = data.load()?;
    let mut tokens = gt.tokens.clone();
    let results = v2x_protocol::nuscenes_json::read_results(
        &pred,
        &mut tokens,
        v2x_protocol::nuscenes_json::MissingStd::Default(v2x_protocol::Uncertainty::uniform(
            1.0, 1.0, 1.0,
        )),
    )?;
    let (samples, unknown) =
        v2x_sim::cli::sample_times(&gt, &results, None, v2x_sim::cli::Timing::Capture);
    if let Some(k) = unknown.first() {
        bail!(
            "{}: {} sample(s) have no time within the ground truth, e.g. '{k}' (is this the right --dataroot/--version?)",
            pred.display(),
            unknown.len()
        );
    }
    let rt = v2x_protocol::net::runtime()?;
    let viz = rt.block_on(v2x_fuser::viz::Viz::open(Some(&out), None))?;
    for v2x_sim::cli::SampleTime {
        key,
        t_us: t,
        scene,
        ..
    } in &samples
    {
        let truth: Vec<_> = gt
            .objects_at(*scene, *t)
            .iter()
            .map(v2x_sim::dataset::GtObject::as_detection)
            .collect();
        viz.boxes(
            "/ground_truth",
            "gt",
            *t,
            &truth,
            v2x_fuser::viz::GROUND_TRUTH,
        );
        viz.boxes(
            "/boxes",
            "boxes",
            *t,
            &results.samples[key],
            v2x_fuser::viz::FUSED,
        );
    }
    viz.close()?;
    eprintln!("wrote {} ({} samples)", out.display(), samples.len());
    Ok(())
}
