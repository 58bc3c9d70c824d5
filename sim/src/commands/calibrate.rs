//! `v2x-sim calibrate`.

use anyhow::Context;
use std::path::PathBuf;
use v2x_eval::calibrate::{error_samples, CalibrateOptions};
use v2x_fuser::uncertainty::stdmodel::{Cell, ErrorModel};
use v2x_sim::cli::DataArgs;
use v2x_sim::table::{
    markdown,
    Align::{Left, Right},
};

/// The options of `v2x-sim calibrate`.
#[derive(clap::Args)]
pub struct CalibrateArgs {
    #[command(flatten)]
    pub data: DataArgs,
    #[command(flatten)]
    pub matching: v2x_sim::cli::MatchArg,
    /// With matching by distance: the largest centre distance (m) of a match. Errors beyond
    /// it are not seen, so give several times the agent's std.
    #[arg(long, default_value_t = 4.0)]
    pub max_distance_m: f64,
    /// Score bins per class, at the scores' quantiles (1: no bins).
    #[arg(long, default_value_t = 3)]
    pub score_bins: usize,
    #[command(flatten)]
    pub output: v2x_protocol::cli::Output,
    /// The agent's results file (nuScenes detection results, as scored by `v2x-sim eval`).
    pub results: PathBuf,
}

/// Runs `v2x-sim calibrate`.
pub fn run(args: CalibrateArgs) -> anyhow::Result<()> {
    let CalibrateArgs {
        data,
        matching: v2x_sim::cli::MatchArg { matching },
        max_distance_m,
        score_bins,
        output: v2x_protocol::cli::Output { path: output },
        results,
    } = args;
    if !(1..=20).contains(&score_bins) {
        anyhow::bail!("--score-bins must be 1 to 20");
    }
    let gt = data.load()?;
    let opts = CalibrateOptions {
        how: matching,
        max_distance_m,
        ..Default::default()
    };
    let (samples, how) = error_samples(&gt, &results, &opts)?;
    let model = ErrorModel::fit(&samples, score_bins, &how).with_context(|| {
        format!(
            "{}: fewer than two of its boxes matched an object: nothing to calibrate",
            results.display()
        )
    })?;
    let text = serde_json::to_string_pretty(&model)?;
    std::fs::write(&output, text).with_context(|| format!("cannot write {}", output.display()))?;
    eprintln!(
        "{}: {} boxes matched by {how} -> {}",
        results.display(),
        samples.len(),
        output.display()
    );
    let row = |name: &str, c: &Cell| {
        let v = c
            .std
            .velocity
            .map_or("-".into(), |v| format!("{:.3}", 0.5 * (v[0] + v[1])));
        vec![
            name.to_string(),
            c.count.to_string(),
            format!("{:.3}, {:.3}", c.bias.center[0], c.bias.center[1]),
            format!("{:.3}, {:.3}", c.std.center[0], c.std.center[1]),
            format!("{:.3}-{:.3}", c.std_low.center[0], c.std_high.center[0]),
            format!("{:.3}", c.std.size[0]),
            format!("{:.2}", c.std.yaw.to_degrees()),
            v,
        ]
    };
    let columns = [
        ("class", Left),
        ("boxes", Right),
        ("bias x, y (m)", Left),
        ("std x, y (m)", Left),
        ("95% of std x", Left),
        ("std size l (m)", Right),
        ("std yaw (deg)", Right),
        ("std velocity (m/s)", Right),
    ];
    let rows = model.classes.iter().map(|(name, c)| row(name, &c.all));
    let all = std::iter::once(row("all", &model.all));
    print!("{}", markdown(&columns, rows.chain(all)));
    Ok(())
}
