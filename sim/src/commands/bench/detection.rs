//! `v2x-sim bench detection`: the nuScenes detection benchmark under detector profiles.

use super::*;
use std::time::Instant;
use v2x_fuser::Method;
use v2x_sim::bench::{self, BenchConfig};
use v2x_sim::noise::NoiseSetting;

/// The options of `bench detection`.
#[derive(clap::Args)]
pub struct DetectionArgs {
    #[command(flatten)]
    pub common: Common,
    /// The detector profiles, comma-separated (e.g. `realistic`: detector faults and pose
    /// errors); --methods 'all' is every method.
    #[arg(long, required = true)]
    pub profile: String,
    /// Every method again after registering each agent to the roadside unit by its boxes
    /// (`v2x-fuser fuse --align`), rows `METHOD --align`.
    #[arg(long)]
    pub align: bool,
}

/// Runs `bench detection`.
pub(super) fn run(args: &DetectionArgs) -> anyhow::Result<()> {
    let c = &args.common;
    let (data, methods, profile) = (&c.data, c.methods.as_str(), args.profile.as_str());
    let (seed, range) = (c.draw.seed, c.draw.range);
    let gt = &data.load()?;
    let cfg = BenchConfig {
        methods: parse_list(methods, Method::all_with_ablations(), Method::parse_any)?,
        settings: parse_list(profile, vec![], |s| NoiseSetting::parse(s, 2))?,
        seed,
        range,
    };
    let start = Instant::now();
    let params = v2x_fuser::time::align::AlignParams::default();
    let rows = bench::run_detection(gt, &cfg, args.align.then_some(&params), &|| {});
    let what = format!("noise seed {seed}; distance matching (nuScenes)");
    c.print(&rows[..], gt, &what, start)
}
