//! `v2x-sim bench regions`: one fuser against regional fusers of a tile grid, single-frame or
//! tracked.

use super::*;
use std::time::Instant;
use v2x_sim::bench;
use v2x_sim::dataset::GroundTruth;

/// The options of `bench regions`.
#[derive(clap::Args)]
pub struct RegionsArgs {
    #[command(flatten)]
    pub common: Common,
    #[command(flatten)]
    pub noise: NoiseArg,
    /// The tiles' side (m).
    #[arg(long, required = true)]
    pub tile_size: f64,
    /// How far beyond its tile a regional fuser takes boxes (m).
    #[arg(long, default_value_t = v2x_fuser::intake::region::DEFAULT_HALO_M)]
    pub halo: f64,
    /// Each method's tracks by one fuser, by regional fusers that never hear each other and by
    /// regional fusers handing tracks over at the borders (rows `METHOD tracked regions`,
    /// `... hand-over`, and the same guided); --methods defaults to the default method.
    #[arg(long)]
    pub tracking: bool,
    /// With --tracking: the tracked rows' association.
    #[command(flatten)]
    pub association: AssociationArg,
}

/// Runs `bench regions`.
pub(super) fn run(args: &RegionsArgs) -> anyhow::Result<()> {
    let gt = args.common.data.load()?;
    if args.tracking {
        region_tracking(args, &gt, args.tile_size)
    } else {
        regions(args, &gt, args.tile_size)
    }
}

/// The tiles and halo of `--tile-size` and `--halo`.
fn tiling(size: f64, halo: f64) -> anyhow::Result<v2x_fuser::intake::region::Tiling> {
    if !(halo.is_finite() && halo >= 0.0) {
        bail!("--halo {halo}: expected a finite distance of at least 0 m");
    }
    v2x_fuser::intake::region::Tiling::new(size).map_err(|e| anyhow::anyhow!("--tile-size: {e}"))
}

/// With --tracking: tracks of one fuser against regional fusers', with and without
/// the hand-over at the borders.
fn region_tracking(args: &RegionsArgs, gt: &GroundTruth, size: f64) -> anyhow::Result<()> {
    let (noise, methods) = (args.noise.noise.as_str(), args.common.methods.as_str());
    let tiling = tiling(size, args.halo)?;
    let cfg = paper_settings(
        methods,
        &[Method::default()],
        noise,
        args.common.draw.seed,
        args.common.draw.range,
    )?;
    let start = Instant::now();
    let rows = v2x_sim::bench::regions::run_region_tracking(
        gt,
        &cfg,
        tiling,
        args.halo,
        args.association.tracker(),
    );
    let what = format!(
        "noise seed {}; tiles of {size} m, halo {} m; id matching for the boxes, 2 m for tracking",
        args.common.draw.seed, args.halo
    );
    args.common.print(&rows[..], gt, &what, start)
}

/// One fuser against regional fusers.
fn regions(args: &RegionsArgs, gt: &GroundTruth, size: f64) -> anyhow::Result<()> {
    let c = &args.common;
    let (noise, methods) = (args.noise.noise.as_str(), c.methods.as_str());
    let (seed, range) = (c.draw.seed, c.draw.range);
    let halo = args.halo;
    let tiling = tiling(size, halo)?;
    let cfg = paper_settings(methods, &beside_paper(), noise, seed, range)?;
    let start = Instant::now();
    let rows = bench::run_regions(gt, &cfg, tiling, halo);
    let what = format!("noise seed {seed}; tiles of {size} m, halo {halo} m");
    c.print(&rows[..], gt, &what, start)
}
