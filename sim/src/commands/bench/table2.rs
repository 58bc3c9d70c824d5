//! The paper's Table 2 (`v2x-sim bench` over simulated agents).

use super::*;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::time::Instant;
use v2x_fuser::Method;
use v2x_sim::bench::{self, BenchConfig};
use v2x_sim::noise::NoiseSetting;

/// The paper's Table 2: each agent, each method (every one for 'all') and the bound.
pub(crate) fn run(args: &TableArgs) -> anyhow::Result<()> {
    let c = &args.common;
    let (data, noise, methods) = (&c.data, args.noise.noise.as_str(), c.methods.as_str());
    let (seed, range) = (c.draw.seed, c.draw.range);
    let gt = &data.load()?;
    let agents = usize::from(args.agents);
    let settings = parse_list(noise, NoiseSetting::paper_with(agents), |s| {
        NoiseSetting::parse(s, agents)
    })?;
    let methods = parse_list(methods, Method::all_with_ablations(), Method::parse_any)?;
    let cfg = BenchConfig {
        methods,
        settings,
        seed,
        range,
    };
    let total = (gt.frames.len() * cfg.settings.len()) as u64;
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new(total)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed} [{bar:40}] {pos}/{len} frames x settings ({eta} left)",
        )
        .expect("valid template"),
    );
    let start = Instant::now();
    let rows = bench::run(gt, &cfg, &|| bar.inc(1));
    bar.finish_and_clear();
    c.print(&rows[..], gt, &format!("noise seed {seed}"), start)
}
