//! `v2x-sim plot`.

use anyhow::{bail, Context};
use std::path::PathBuf;
use v2x_fuser::Method;
use v2x_sim::cli::{DataArgs, DrawArgs};
use v2x_sim::noise::{place_agents, NoiseSetting};

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
    #[command(flatten)]
    pub method: v2x_sim::cli::MethodArg,
    #[command(flatten)]
    pub draw: v2x_sim::cli::DrawArgs,
    #[command(flatten)]
    pub out: v2x_protocol::cli::Output,
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
        method: v2x_sim::cli::MethodArg { method },
        draw,
        out: v2x_protocol::cli::Output { path: out },
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
        plot(&gt, frame, &setting, &method, draw, &out)?.display()
    );
    Ok(())
}

/// Draws frame `frame` of the data: the truth, each agent's boxes and the fused ones.
fn plot(
    data: &v2x_sim::dataset::GroundTruth,
    frame: usize,
    setting: &NoiseSetting,
    method: &Method,
    draw: DrawArgs,
    out: &std::path::Path,
) -> anyhow::Result<PathBuf> {
    let Some(f) = data.frames.get(frame) else {
        bail!(
            "--frame {frame} is out of range: the data has {} frames",
            data.frames.len()
        );
    };
    let agents = v2x_sim::bench::agent_detections(data, frame, setting, draw.seed, draw.range);
    let fused = v2x_sim::bench::fusers::Fusers::new(&[*method], agents.len(), None).fuse(
        0,
        f.timestamp_us,
        &agents,
    );
    let places = place_agents(f, agents.len(), draw.seed);
    let title = format!(
        "frame {frame} ({}), noise {setting}, {method}",
        f.sample_token
    );
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let path = out.join(format!(
        "frame-{frame}-{}.svg",
        setting.name.replace('+', "-")
    ));
    std::fs::write(
        &path,
        v2x_sim::plot::frame_svg(f, &agents, &fused, &places, &title),
    )
    .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path)
}
