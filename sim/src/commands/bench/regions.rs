//! `v2x-sim bench regions`: one fuser against regional fusers of a tile grid, single-frame or
//! tracked.

use super::*;
use std::time::Instant;
use v2x_fuser::intake::region::Tiling;
use v2x_sim::bench;
use v2x_sim::dataset::GroundTruth;

/// The options of `bench regions`.
#[derive(clap::Args)]
pub struct RegionsArgs {
    #[command(flatten)]
    pub common: Common,
    #[command(flatten)]
    pub noise: NoiseArg,
    /// The tiles (--tile-size required).
    #[command(flatten)]
    pub tiles: v2x_protocol::tiles::TileSize,
    #[command(flatten)]
    pub halo: v2x_protocol::tiles::Halo,
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
    let Some(tiling) = args.tiles.tiling else {
        bail!("bench regions cuts the map into tiles: give --tile-size METRES");
    };
    let gt = args.common.data.load()?;
    if args.tracking {
        region_tracking(args, &gt, tiling)
    } else {
        regions(args, &gt, tiling)
    }
}

/// With --tracking: tracks of one fuser against regional fusers', with and without
/// the hand-over at the borders.
fn region_tracking(args: &RegionsArgs, gt: &GroundTruth, tiling: Tiling) -> anyhow::Result<()> {
    let (noise, methods) = (args.noise.noise.as_str(), args.common.methods.as_str());
    let (size, halo) = (tiling.size_m(), args.halo.halo_m());
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
        halo,
        args.association.tracker(),
    );
    let what = format!(
        "noise seed {}; tiles of {size} m, halo {halo} m; id matching for the boxes, 2 m for tracking",
        args.common.draw.seed
    );
    args.common.print(&rows[..], gt, &what, start)
}

/// One fuser against regional fusers.
fn regions(args: &RegionsArgs, gt: &GroundTruth, tiling: Tiling) -> anyhow::Result<()> {
    let c = &args.common;
    let (noise, methods) = (args.noise.noise.as_str(), c.methods.as_str());
    let (seed, range) = (c.draw.seed, c.draw.range);
    let (size, halo) = (tiling.size_m(), args.halo.halo_m());
    let cfg = paper_settings(methods, &beside_paper(), noise, seed, range)?;
    let start = Instant::now();
    let rows = bench::run_regions(gt, &cfg, tiling, halo);
    let what = format!("noise seed {seed}; tiles of {size} m, halo {halo} m");
    c.print(&rows[..], gt, &what, start)
}
