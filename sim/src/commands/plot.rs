//! `v2x-sim plot`.

use super::*;
use std::path::PathBuf;
use v2x_fuser::Method;
use v2x_sim::cli::DataArgs;
use v2x_sim::noise::NoiseSetting;

/// The options of `v2x-sim plot`.
#[derive(clap::Args)]
pub struct PlotArgs {
    #[command(flatten)]
    pub data: DataArgs,
    /// Frame index over all frames.
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Noise setting.
    #[arg(long, default_value = "mild+large")]
    pub noise: String,
    /// Method for the fused boxes.
    #[arg(long, default_value_t = v2x_fuser::Method::default())]
    pub method: Method,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory (with --timeline: the SVG file to write).
    #[arg(long)]
    pub out: PathBuf,
    /// Instead of a frame: draw a run's per-second series (`v2x-sim run --timeline
    /// FILE.json`), one panel per measure, the scripted events marked.
    #[arg(long)]
    pub timeline: Option<PathBuf>,
}

/// Runs `v2x-sim plot`.
pub fn run(args: PlotArgs) -> anyhow::Result<()> {
    let PlotArgs {
        data,
        frame,
        noise,
        method,
        seed,
        out,
        timeline,
    } = args;
    if let Some(path) = timeline {
        let tl = v2x_sim::run::series::Timeline::read(&path)?;
        std::fs::write(&out, v2x_sim::run::series_plot::svg(&tl))
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", out.display()))?;
        eprintln!("drew {}", out.display());
        return Ok(());
    }
    let gt = data.load()?;
    let setting = NoiseSetting::parse(&noise, 2).map_err(anyhow::Error::msg)?;
    eprintln!(
        "drew {}",
        plot(&gt, frame, &setting, &method, seed, &out)?.display()
    );
    Ok(())
}
