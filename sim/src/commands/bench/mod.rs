//! `v2x-sim bench`: the paper's Table 2 (or a real data set's own tables) without a mode, and
//! each other table as a mode of its own, with the options it takes and no others.

use super::*;
use anyhow::bail;
use std::path::PathBuf;
use v2x_fuser::tracker::{Association, TrackerParams};
use v2x_sim::cli::{DataArgs, DrawArgs, FormatArg};

mod asynchronous;
mod detection;
mod regions;
mod table2;

pub(crate) use table2::run as table2;
mod tracking;

/// The options of `v2x-sim bench`.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    /// A table other than the paper's.
    #[command(subcommand)]
    pub mode: Option<BenchMode>,
    #[command(flatten)]
    pub table: TableArgs,
}

/// The tables other than the paper's Table 2.
#[derive(clap::Subcommand)]
pub enum BenchMode {
    /// Single-frame fusion against tracking: MOTA, MOTP, IDS and FRAG per noise setting.
    ///
    /// Single-frame fusion against tracking (`v2x-fuser track`) of the fused boxes and of each
    /// single agent, with MOTA, MOTP, IDS and FRAG, under each --noise setting; --methods
    /// defaults to the default method and gt-wls. With gt-wls, a row `gt-wls tracked by id`
    /// gives each box to its true object's track (a perfect association of boxes to tracks), and
    /// `gt-state-wls tracked` groups each agent's boxes with the likeliest true object by
    /// centre and velocity (the best grouping the boxes allow a frame at a time).
    Tracking(tracking::TrackingArgs),
    /// The nuScenes detection benchmark under detector profiles (--profile).
    ///
    /// The nuScenes detection benchmark (distance matching: precision, recall, mAP, NDS,
    /// mATE...) for every method and single agent under detector profiles.
    Detection(detection::DetectionArgs),
    /// One fuser against regional fusers of a tile grid (--tile-size), or their tracks.
    ///
    /// Each method as one fuser and as regional fusers, one per tile that some box lies in,
    /// each fusing its tile and a halo around it and keeping the boxes centred in its tile;
    /// the two rows should agree. --methods defaults to the default method and csba-wls.
    Regions(regions::RegionsArgs),
    /// Two agents captured at different instants, with and without motion compensation.
    ///
    /// Two agents captured at different instants (10+10 Hz at offsets 0, 25, 50 and 100 ms,
    /// and a 10+20 Hz pair), each fused with and without motion compensation; --methods
    /// defaults to the default method and gt-wls.
    Async(asynchronous::AsyncArgs),
}

/// What every table takes: the data, the methods, the agents' draw and the format.
#[derive(clap::Args, Clone)]
pub struct Common {
    #[command(flatten)]
    pub data: DataArgs,
    /// Methods, comma-separated, or 'all' (see `v2x-fuser fuse --help`; each mode says what
    /// 'all' is there).
    #[arg(long, default_value = "all")]
    pub methods: String,
    #[command(flatten)]
    pub draw: DrawArgs,
    #[command(flatten)]
    pub format: FormatArg,
}

/// The noise settings a table runs under (`--noise`).
#[derive(clap::Args, Clone)]
pub struct NoiseArg {
    /// Noise settings, comma-separated, or 'all' (the paper's mild, moderate, large and
    /// mild+large; `async` takes one, mild for 'all').
    #[arg(long, default_value = "all")]
    pub noise: String,
}

/// How the tracked rows' boxes reach their tracks (`--association`).
#[derive(clap::Args, Clone, Copy)]
pub struct AssociationArg {
    /// How the tracked rows' boxes reach their tracks, as `v2x-fuser track --association`
    /// (soft or assignment; docs/method.md §8.2); the guided rows are printed beside them
    /// either way.
    #[arg(long, value_name = "soft|assignment", default_value_t = Association::default(), value_parser = fused_association)]
    pub association: Association,
}

impl AssociationArg {
    /// The tracker of the tracked rows.
    pub fn tracker(&self) -> TrackerParams {
        TrackerParams::with_mode(self.association)
    }
}

/// A mode of the fused boxes' tracks: the bench prints the guided rows beside them.
fn fused_association(s: &str) -> Result<Association, String> {
    match s.parse::<Association>().map_err(|e| e.to_string())? {
        Association::Guided => Err(
            "the guided rows are printed beside the tracked ones: give assignment or soft".into(),
        ),
        mode => Ok(mode),
    }
}

/// The paper's Table 2 over simulated agents, or with --dataset dair-v2x or v2v4real, the data
/// set's own tables.
#[derive(clap::Args)]
pub struct TableArgs {
    #[command(flatten)]
    pub common: Common,
    #[command(flatten)]
    pub noise: NoiseArg,
    /// Agents seeing each scene (a noise setting's last profile repeats for the agents it does
    /// not name): 2 as in the paper; up to 64 to score one fuser at a dense junction.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub agents: u16,
    /// With --dataset v2v4real: its tracked rows' association.
    #[command(flatten)]
    pub association: AssociationArg,
    /// With --dataset v2v4real: also score these folders of KITTI detection rows (one NNNN.txt
    /// per sequence, e.g. `v2x-fuser fuse --output-format kitti`'s output), a row each.
    #[arg(long, value_name = "DIR")]
    pub results: Vec<PathBuf>,
    /// With --dataset v2v4real: write each detection row's boxes into DIR/ROW/ (a folder of
    /// KITTI detection rows per sequence, as AB3DMOT's trackers read them; ROW the row's name
    /// in lower case, `+` spelled `plus`, every other run of characters but letters and digits
    /// one `-`: `csba-wls-plus`).
    #[arg(long, value_name = "DIR")]
    pub write_rows: Option<PathBuf>,
    /// With --dataset v2v4real: write each detection row's precision-recall curves (BEV at 0.5
    /// and 0.7, frame order and global sort) as DIR/ROW.svg.
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
}

impl Common {
    /// Prints a table's rows under the line that says what ran: the data `gt`, `what`, and the
    /// seconds since `start`.
    fn print<R: v2x_sim::table::Rows + ?Sized>(
        &self,
        rows: &R,
        gt: &v2x_sim::dataset::GroundTruth,
        what: &str,
        start: std::time::Instant,
    ) -> anyhow::Result<()> {
        let secs = start.elapsed().as_secs_f64();
        let heading = format!("{} ; {what}; {secs:.1} s", self.data.describe(gt));
        print!(
            "{}",
            v2x_sim::table::render(rows, self.format.format, &heading)?
        );
        Ok(())
    }
}

impl BenchMode {
    /// The options every mode takes.
    pub(crate) fn common(&self) -> &Common {
        match self {
            BenchMode::Tracking(a) => &a.common,
            BenchMode::Detection(a) => &a.common,
            BenchMode::Regions(a) => &a.common,
            BenchMode::Async(a) => &a.common,
        }
    }
}

/// Runs a bench mode over agents simulated on the data (`sources::bench` checks they are).
pub fn run_mode(mode: BenchMode) -> anyhow::Result<()> {
    match mode {
        BenchMode::Tracking(a) => tracking::run(&a),
        BenchMode::Detection(a) => detection::run(&a),
        BenchMode::Regions(a) => regions::run(&a),
        BenchMode::Async(a) => asynchronous::run(&a),
    }
}

/// `--methods` on real data: `all` is every method but the oracle, which needs ground-truth
/// ids the data's own boxes do not carry.
pub(crate) fn real_data_methods(list: &str) -> anyhow::Result<Vec<v2x_fuser::Method>> {
    let mut all = v2x_fuser::Method::all_with_ablations();
    all.retain(|m| *m != v2x_fuser::Method::GtWls);
    parse_list(list, all, v2x_fuser::Method::parse_any)
}

#[cfg(test)]
mod tests;
