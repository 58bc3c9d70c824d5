//! `v2x-sim bench tracking`: single-frame fusion against tracking, on one log under one seed or
//! summarised over several seeds and logs.

use super::*;
use std::time::Instant;
use v2x_sim::bench;
use v2x_sim::dataset::GroundTruth;
use v2x_sim::table::render;

/// The options of `bench tracking`.
#[derive(clap::Args)]
pub struct TrackingArgs {
    #[command(flatten)]
    pub common: Common,
    #[command(flatten)]
    pub noise: NoiseArg,
    #[command(flatten)]
    pub association: AssociationArg,
    /// Several noise seeds, comma-separated (e.g. 1,2,3,4,5,6,7,8), in place of --seed; each
    /// tracked row's AMOTA and identity switches are summarised over them (mean, lowest,
    /// highest) and, seed by seed, against `gt-wls tracked`: the worst ratio.
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    pub seeds: Vec<u64>,
    /// With --seeds: further logs in --dataroot's form (nuScenes tables of the same --version),
    /// each run under every seed and summarised on its own and with the others.
    #[arg(long, value_name = "DATAROOT", requires_all = ["seeds", "dataroot"])]
    pub more_dataroot: Vec<PathBuf>,
    /// With --seeds and the synthetic town: its layout seeds, comma-separated, each town a log
    /// of its own (in place of --town-seed).
    #[arg(long, requires = "seeds", conflicts_with = "dataroot", value_delimiter = ',', num_args = 1..)]
    pub town_seeds: Vec<u64>,
    /// With --seeds: each log cut into this many parts in time (2: halves), each scored as a
    /// log of its own.
    #[arg(long, requires = "seeds", default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=16))]
    pub parts: u16,
}

/// Runs `bench tracking`: over several seeds and logs with --seeds, else the one table.
pub(super) fn run(args: &TrackingArgs) -> anyhow::Result<()> {
    if !args.seeds.is_empty() {
        return tracking_seeds(args);
    }
    let c = &args.common;
    let (data, noise, methods) = (&c.data, args.noise.noise.as_str(), c.methods.as_str());
    let (seed, range) = (c.draw.seed, c.draw.range);
    let gt = &data.load()?;
    let cfg = paper_settings(methods, &beside_oracle(), noise, seed, range)?;
    let start = Instant::now();
    let rows = bench::run_tracking(gt, &cfg, args.association.tracker());
    let what = format!("noise seed {seed}; id matching for the boxes, 2 m for tracking");
    c.print(&rows[..], gt, &what, start)
}

/// The logs of `tracking --seeds`: --dataroot and each --more-dataroot, or the town under
/// each --town-seeds (--town-seed without), each cut into --parts.
pub(super) fn tracking_logs(args: &TrackingArgs) -> anyhow::Result<Vec<(String, GroundTruth)>> {
    let mut whole = Vec::new();
    if args.town_seeds.is_empty() {
        whole.push((args.common.data.source(), args.common.data.load()?));
    }
    for &seed in &args.town_seeds {
        let data = DataArgs {
            town_seed: seed,
            ..args.common.data.clone()
        };
        whole.push((data.source(), data.load()?));
    }
    for root in &args.more_dataroot {
        let data = DataArgs {
            dataroot: Some(root.clone()),
            ..args.common.data.clone()
        };
        whole.push((data.source(), data.load()?));
    }
    let n = usize::from(args.parts);
    let mut out = Vec::new();
    for (name, gt) in whole {
        if n == 1 {
            out.push((v2x_sim::cli::described(&name, &gt), gt));
            continue;
        }
        for k in 0..n {
            let Some(part) = gt.part(k, n) else {
                bail!("{name}: --parts cuts nuScenes tables and the town, not data with recorded agents");
            };
            let name = format!("{name}, part {} of {n}", k + 1);
            out.push((v2x_sim::cli::described(&name, &part), part));
        }
    }
    Ok(out)
}

/// `tracking --seeds`: the tracking table of each log under each seed, summarised per log and
/// over them all.
fn tracking_seeds(args: &TrackingArgs) -> anyhow::Result<()> {
    let (noise, methods) = (args.noise.noise.as_str(), args.common.methods.as_str());
    let logs = tracking_logs(args)?;
    let start = Instant::now();
    let mut runs = Vec::with_capacity(logs.len());
    for (name, gt) in &logs {
        let mut per_seed = Vec::with_capacity(args.seeds.len());
        for &seed in &args.seeds {
            let cfg = paper_settings(
                methods,
                &beside_oracle(),
                noise,
                seed,
                args.common.draw.range,
            )?;
            per_seed.push(bench::run_tracking(gt, &cfg, args.association.tracker()));
        }
        runs.push(bench::LogSeeds::new(
            name.clone(),
            args.seeds.clone(),
            per_seed,
        ));
    }
    let report = bench::SeedsReport::new(runs);
    let seeds: Vec<String> = args.seeds.iter().map(u64::to_string).collect();
    let what = match &logs[..] {
        [(name, _)] => name.clone(),
        _ => format!("{} logs", logs.len()),
    };
    let heading = format!(
        "{what} ; noise seeds {}; id matching for the boxes, 2 m for tracking; {:.1} s",
        seeds.join(", "),
        start.elapsed().as_secs_f64()
    );
    print!("{}", render(&report, args.common.format.format, &heading)?);
    Ok(())
}
