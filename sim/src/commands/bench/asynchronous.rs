//! `v2x-sim bench async`: two agents captured at different instants, fused with and without
//! motion compensation.

use super::*;
use std::time::Instant;
use v2x_sim::bench::BenchConfig;
use v2x_sim::noise::NoiseSetting;

/// The options of `bench async`.
#[derive(clap::Args)]
pub struct AsyncArgs {
    #[command(flatten)]
    pub common: Common,
    #[command(flatten)]
    pub noise: NoiseArg,
}

/// Runs `bench async`.
pub(super) fn run(args: &AsyncArgs) -> anyhow::Result<()> {
    let c = &args.common;
    let (data, noise, methods) = (&c.data, args.noise.noise.as_str(), c.methods.as_str());
    let (seed, range) = (c.draw.seed, c.draw.range);
    let gt = &data.load()?;
    let noise = if noise == "all" { "mild" } else { noise };
    let setting = NoiseSetting::parse(noise, 2).map_err(anyhow::Error::msg)?;
    let cfg = BenchConfig {
        methods: parse_list(methods, beside_oracle().to_vec(), Method::parse_any)?,
        settings: vec![],
        seed,
        range,
    };
    let start = Instant::now();
    let rows = v2x_sim::bench::asynchronous::run(gt, &cfg, &setting);
    c.print(
        &rows[..],
        gt,
        &format!("noise {setting}, seed {seed}"),
        start,
    )
}
