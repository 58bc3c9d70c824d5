//! `v2x-sim bench`.

use super::*;
use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;
use v2x_fuser::tracker::Association;
use v2x_fuser::Method;
use v2x_sim::bench::{self, BenchConfig};
use v2x_sim::cli::DataArgs;
use v2x_sim::dataset::GroundTruth;
use v2x_sim::noise::NoiseSetting;
use v2x_sim::table::render;

/// The options of `v2x-sim bench`.
#[derive(clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub data: DataArgs,
    /// Noise settings, comma-separated, or 'all' (mild, moderate, large, mild+large).
    #[arg(long, default_value = "all")]
    pub noise: String,
    /// Methods, comma-separated, or 'all' (see `v2x-fuser fuse --help`).
    #[arg(long, default_value = "all")]
    pub methods: String,
    /// Agents seeing each scene in the paper's table (a noise setting's last profile repeats
    /// for the agents it does not name): 2 as in the paper; up to 64 to score one fuser at a
    /// dense junction.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub agents: u16,
    #[command(flatten)]
    pub draw: v2x_sim::cli::DrawArgs,
    /// With --tracking: several noise seeds, comma-separated (e.g. 1,2,3,4,5,6,7,8), in place
    /// of --seed; each tracked row's AMOTA and identity switches are summarised over them
    /// (mean, lowest, highest) and, seed by seed, against `gt-wls tracked`: the worst ratio.
    #[arg(long, requires = "tracking", value_delimiter = ',', num_args = 1..)]
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
    #[command(flatten)]
    pub format: v2x_sim::cli::FormatArg,
    /// Instead of Table 2: the nuScenes detection benchmark (distance matching: precision,
    /// recall, mAP, NDS, mATE...) for every method and single agent under these noise
    /// settings, comma-separated, e.g. `realistic` (detector faults and pose errors).
    #[arg(long, conflicts_with = "asynchronous")]
    pub profile: Option<String>,
    /// With --profile: every method again after registering each agent to the roadside
    /// unit by its boxes (`v2x-fuser fuse --align`), rows `METHOD --align`.
    #[arg(long, requires = "profile")]
    pub align: bool,
    /// Instead of Table 2: single-frame fusion against tracking (`v2x-fuser track`) of the
    /// fused boxes and of each single agent, with MOTA, MOTP, IDS and FRAG, under each
    /// --noise setting; --methods defaults to csba-wls+ and gt-wls. With gt-wls, a row
    /// `gt-wls tracked by id` gives each box to its true object's track: what a perfect
    /// association of boxes to tracks gives; and a row `gt-state-wls tracked` groups each
    /// agent's boxes with the likeliest true object by centre and velocity: the best grouping
    /// the boxes allow a frame at a time.
    #[arg(long, conflicts_with_all = ["asynchronous", "profile"])]
    pub tracking: bool,
    /// With --tracking (also with --tile-size, and --dataset v2v4real): how the tracked rows'
    /// boxes reach their tracks, as `v2x-fuser track --association` (assignment or soft;
    /// docs/method.md §8.2); the guided rows are printed beside them either way.
    #[arg(long, value_name = "assignment|soft", default_value_t = Association::default(), value_parser = fused_association)]
    pub association: Association,
    /// Instead of Table 2: each method as one fuser and as regional fusers, one per tile of
    /// this side (m) that some box lies in, each fusing its tile and a --halo around it and
    /// keeping the boxes centred in its tile; the two rows should agree. With --tracking:
    /// each method's tracks by one fuser, by regional fusers that never hear each other and by
    /// regional fusers handing tracks over at the borders (rows `METHOD tracked regions`,
    /// `... hand-over`, and the same guided); --methods defaults to csba-wls+.
    #[arg(long, conflicts_with_all = ["asynchronous", "profile"])]
    pub tile_size: Option<f64>,
    /// With --tile-size: how far beyond its tile a regional fuser takes boxes (m).
    #[arg(long, requires = "tile_size", default_value_t = v2x_fuser::intake::region::DEFAULT_HALO_M)]
    pub halo: f64,
    /// Instead of Table 2: two agents captured at different instants (10+10 Hz at offsets
    /// 0, 25, 50 and 100 ms, and a 10+20 Hz pair), each fused with and without motion
    /// compensation. --noise is then one setting (default mild); --methods defaults to
    /// csba-wls+ and gt-wls.
    #[arg(long = "async")]
    pub asynchronous: bool,
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

/// What one `v2x-sim bench` run measures, told from its flags once.
#[derive(Clone, Debug, PartialEq)]
pub enum Mode {
    /// `--dataset dair-v2x`: the vehicle, the roadside and every method.
    Dair,
    /// `--dataset v2v4real`: each car, the dataset's references and every method.
    V2v4real,
    /// A table over ground truth with simulated agents.
    Truth(TruthMode),
}

/// The tables over ground truth with simulated agents.
#[derive(Clone, Debug, PartialEq)]
pub enum TruthMode {
    /// `--tile-size`: one fuser against regional fusers of tiles of this side (m).
    Regions(f64),
    /// `--tile-size --tracking`: the same, tracked.
    RegionTracking(f64),
    /// `--tracking --seeds`: the tracking table per seed, summarised.
    TrackingSeeds,
    /// `--tracking`: single-frame fusion against tracking.
    Tracking,
    /// `--profile`: the nuScenes detection benchmark under these noise settings.
    Detection(String),
    /// `--async`: agents captured at different instants.
    Asynchronous,
    /// The paper's Table 2 (no mode flag).
    Table2,
}

impl Mode {
    /// The mode the flags select, or why they select none.
    pub fn of(args: &BenchArgs) -> anyhow::Result<Mode> {
        if (args.data.is_dair() || args.data.is_v2v4real()) && args.agents != 2 {
            bail!("--agents is for simulated agents: the real data sets have their own two");
        }
        if args.data.is_dair() {
            if args.tile_size.is_some()
                || args.tracking
                || args.profile.is_some()
                || args.asynchronous
            {
                bail!("--dataset dair-v2x runs its own table: leave out --tile-size, --tracking, --profile and --async");
            }
            return Ok(Mode::Dair);
        }
        if args.data.is_v2v4real() {
            if args.tile_size.is_some()
                || args.profile.is_some()
                || args.asynchronous
                || !args.seeds.is_empty()
                || args.parts != 1
                || !args.more_dataroot.is_empty()
            {
                bail!("--dataset v2v4real runs its own tables: leave out --tile-size, --profile, --async, --seeds, --parts and --more-dataroot");
            }
            return Ok(Mode::V2v4real);
        }
        let mode = match (args.tile_size, args.tracking, &args.profile) {
            (Some(size), true, _) => TruthMode::RegionTracking(size),
            (Some(size), false, _) => TruthMode::Regions(size),
            (None, true, _) if !args.seeds.is_empty() => TruthMode::TrackingSeeds,
            (None, true, _) => TruthMode::Tracking,
            (None, false, Some(profile)) => TruthMode::Detection(profile.clone()),
            (None, false, None) if args.asynchronous => TruthMode::Asynchronous,
            (None, false, None) => TruthMode::Table2,
        };
        if args.agents != 2 && mode != TruthMode::Table2 {
            bail!("--agents sets the agents of the paper's table: leave it out with --tile-size, --tracking, --profile and --async");
        }
        Ok(Mode::Truth(mode))
    }
}

/// Runs `v2x-sim bench`: the mode its flags select.
pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    let mode = match Mode::of(&args)? {
        Mode::Dair => return dair(&args),
        Mode::V2v4real => return v2v4real(&args),
        Mode::Truth(mode) => mode,
    };
    // Every mode but the one over several logs reads the one data set it is given.
    let gt = || args.data.load();
    match mode {
        TruthMode::Regions(size) => regions(&args, &gt()?, size),
        TruthMode::RegionTracking(size) => region_tracking(&args, &gt()?, size),
        TruthMode::TrackingSeeds => tracking_seeds(&args),
        TruthMode::Tracking => tracking(&args, &gt()?),
        TruthMode::Detection(profile) => detection(&args, &gt()?, &profile),
        TruthMode::Asynchronous => asynchronous(&args, &gt()?),
        TruthMode::Table2 => table2(&args, &gt()?),
    }
}

/// `--dataset dair-v2x`: the vehicle, the roadside and every method on real cooperative data.
fn dair(args: &BenchArgs) -> anyhow::Result<()> {
    let d = args.data.load_dair()?;
    let methods = real_data_methods(&args.methods)?;
    if methods.contains(&Method::GtWls) {
        bail!("gt-wls groups boxes by ground-truth id, which DAIR-V2X's own labels do not carry");
    }
    let noise = if args.noise == "all" {
        "labels"
    } else {
        args.noise.as_str()
    };
    let setting = NoiseSetting::parse(noise, 2).map_err(anyhow::Error::msg)?;
    let start = Instant::now();
    let rows = v2x_sim::bench::dair::run(&d, &methods, &setting, args.draw.seed, args.draw.range);
    let what = format!(
        "noise {setting} over each side's own labels, seed {}",
        args.draw.seed
    );
    let heading = format!(
        "{} ; {what}; devkit-style over the ground truth's classes, AP in % (DAIR-V2X protocol, vehicle frame); {:.1} s",
        args.data.describe(&d.gt),
        start.elapsed().as_secs_f64()
    );
    print!("{}", render(&rows[..], args.format.format, &heading)?);
    Ok(())
}

/// `--methods` on real data: `all` is every method but the oracle, which needs ground-truth
/// ids the data's own boxes do not carry.
fn real_data_methods(list: &str) -> anyhow::Result<Vec<Method>> {
    Ok(if list == "all" {
        Method::all_with_ablations()
            .into_iter()
            .filter(|m| *m != Method::GtWls)
            .collect()
    } else {
        parse_list(list, vec![], Method::parse_any)?
    })
}

/// `--dataset v2v4real`: each car, the dataset's references and every method on real
/// detections of two cars, by V2V4Real's protocol.
fn v2v4real(args: &BenchArgs) -> anyhow::Result<()> {
    let mut d = args
        .data
        .load_v2v4real(v2x_fuser::offline::kitti_default_std())?;
    for dir in &args.results {
        d.add_reference(dir.display().to_string(), dir)?;
    }
    let methods = real_data_methods(&args.methods)?;
    let start = Instant::now();
    let sources = v2x_sim::bench::v2v4real::sources(&d, &methods);
    let rows = v2x_sim::bench::v2v4real::run(&d, &sources);
    let detection_s = start.elapsed().as_secs_f64();
    if let Some(dir) = &args.plots {
        let written = v2x_sim::bench::v2v4real::write_plots(&rows, dir)
            .with_context(|| format!("--plots: cannot write into {}", dir.display()))?;
        eprintln!("{}: {} plots", dir.display(), written.len());
    }
    if let Some(dir) = &args.write_rows {
        for (dir, n) in v2x_sim::bench::v2v4real::write_rows(&d, &sources, dir)? {
            eprintln!("{}: {n} rows", dir.display());
        }
    }
    let start = Instant::now();
    let root = args
        .data
        .dataroot
        .as_deref()
        .expect("checked by load_v2v4real");
    let cars = v2x_truth::v2v4real::Paths::new(root, d.split).cars;
    let track_methods: Vec<Method> = if args.methods == "all" {
        vec![Method::default()]
    } else {
        methods.clone()
    };
    let mut tracked = Vec::new();
    for m in &track_methods {
        for guided in [false, true] {
            let params = tracker_params(args).with_guided(guided);
            tracked.push(v2x_sim::bench::v2v4real::tracked(&d, &cars, m, params)?);
        }
    }
    tracked.push(v2x_sim::bench::v2v4real::ceiling(&d));
    let report = v2x_sim::bench::v2v4real::Report {
        detection: rows,
        tracking: tracked,
        tracking_heading: format!(
            "Tracked as `v2x-fuser track` tracks the two cars' folders, scored by AB3DMOT's KITTI evaluation (3D IoU 0.25, percent); {:.1} s",
            start.elapsed().as_secs_f64()
        ),
    };
    let heading = format!(
        "V2V4Real {} split: {} frames, {} labelled cars; AP of cars by V2V4Real's protocol (frames in order, VOC 2010); {detection_s:.1} s",
        d.split,
        d.frames.len(),
        d.boxes(),
    );
    print!("{}", render(&report, args.format.format, &heading)?);
    Ok(())
}

/// The tiles and halo of `--tile-size` and `--halo`.
fn tiling(size: f64, halo: f64) -> anyhow::Result<v2x_fuser::intake::region::Tiling> {
    if !(halo.is_finite() && halo >= 0.0) {
        bail!("--halo {halo}: expected a finite distance of at least 0 m");
    }
    v2x_fuser::intake::region::Tiling::new(size).map_err(|e| anyhow::anyhow!("--tile-size: {e}"))
}

/// `--tile-size --tracking`: tracks of one fuser against regional fusers', with and without
/// the hand-over at the borders.
fn region_tracking(args: &BenchArgs, gt: &GroundTruth, size: f64) -> anyhow::Result<()> {
    let (noise, methods) = (args.noise.as_str(), args.methods.as_str());
    let tiling = tiling(size, args.halo)?;
    let cfg = paper_settings(
        methods,
        &[Method::default()],
        noise,
        args.draw.seed,
        args.draw.range,
    )?;
    let start = Instant::now();
    let rows = v2x_sim::bench::regions::run_region_tracking(
        gt,
        &cfg,
        tiling,
        args.halo,
        tracker_params(args),
    );
    let heading = format!(
        "{} ; noise seed {}; tiles of {size} m, halo {} m; id matching for the boxes, 2 m for tracking; {:.1} s",
        args.data.describe(gt),
        args.draw.seed,
        args.halo,
        start.elapsed().as_secs_f64()
    );
    print!("{}", render(&rows[..], args.format.format, &heading)?);
    Ok(())
}

/// `--tile-size`: one fuser against regional fusers.
fn regions(args: &BenchArgs, gt: &GroundTruth, size: f64) -> anyhow::Result<()> {
    let (data, noise, methods) = (&args.data, args.noise.as_str(), args.methods.as_str());
    let (seed, range, format) = (args.draw.seed, args.draw.range, args.format.format);
    let halo = args.halo;
    let tiling = tiling(size, halo)?;
    let cfg = paper_settings(methods, &beside_paper(), noise, seed, range)?;
    let start = Instant::now();
    let rows = bench::run_regions(gt, &cfg, tiling, halo);
    let heading = format!(
        "{} ; noise seed {seed}; tiles of {size} m, halo {halo} m; {:.1} s",
        data.describe(gt),
        start.elapsed().as_secs_f64()
    );
    print!("{}", render(&rows[..], format, &heading)?);
    Ok(())
}

/// The logs of `--tracking --seeds`: --dataroot and each --more-dataroot, or the town under
/// each --town-seeds (--town-seed without), each cut into --parts.
fn tracking_logs(args: &BenchArgs) -> anyhow::Result<Vec<(String, GroundTruth)>> {
    let mut whole = Vec::new();
    if args.town_seeds.is_empty() {
        whole.push((args.data.source(), args.data.load()?));
    }
    for &seed in &args.town_seeds {
        let data = DataArgs {
            town_seed: seed,
            ..args.data.clone()
        };
        whole.push((data.source(), data.load()?));
    }
    for root in &args.more_dataroot {
        let data = DataArgs {
            dataroot: Some(root.clone()),
            ..args.data.clone()
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

/// `--tracking --seeds`: the tracking table of each log under each seed, summarised per log and
/// over them all.
fn tracking_seeds(args: &BenchArgs) -> anyhow::Result<()> {
    let (noise, methods) = (args.noise.as_str(), args.methods.as_str());
    let logs = tracking_logs(args)?;
    let start = Instant::now();
    let mut runs = Vec::with_capacity(logs.len());
    for (name, gt) in &logs {
        let mut per_seed = Vec::with_capacity(args.seeds.len());
        for &seed in &args.seeds {
            let cfg = paper_settings(methods, &beside_oracle(), noise, seed, args.draw.range)?;
            per_seed.push(bench::run_tracking(gt, &cfg, tracker_params(args)));
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
    print!("{}", render(&report, args.format.format, &heading)?);
    Ok(())
}

/// The tracker of the tracking tables (`--association`).
fn tracker_params(args: &BenchArgs) -> v2x_fuser::tracker::TrackerParams {
    v2x_fuser::tracker::TrackerParams::with_mode(args.association)
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

/// `--tracking`: single-frame fusion against tracking.
fn tracking(args: &BenchArgs, gt: &GroundTruth) -> anyhow::Result<()> {
    let (data, noise, methods) = (&args.data, args.noise.as_str(), args.methods.as_str());
    let (seed, range, format) = (args.draw.seed, args.draw.range, args.format.format);
    let cfg = paper_settings(methods, &beside_oracle(), noise, seed, range)?;
    let start = Instant::now();
    let rows = bench::run_tracking(gt, &cfg, tracker_params(args));
    let heading = format!(
        "{} ; noise seed {seed}; id matching for the boxes, 2 m for tracking; {:.1} s",
        data.describe(gt),
        start.elapsed().as_secs_f64()
    );
    print!("{}", render(&rows[..], format, &heading)?);
    Ok(())
}

/// `--profile`: the nuScenes detection benchmark under detector profiles.
fn detection(args: &BenchArgs, gt: &GroundTruth, profile: &str) -> anyhow::Result<()> {
    let (data, methods) = (&args.data, args.methods.as_str());
    let (seed, range, format) = (args.draw.seed, args.draw.range, args.format.format);
    let cfg = BenchConfig {
        methods: parse_list(methods, Method::all_with_ablations(), Method::parse_any)?,
        settings: parse_list(profile, vec![], |s| NoiseSetting::parse(s, 2))?,
        seed,
        range,
    };
    let start = Instant::now();
    let params = v2x_fuser::time::align::AlignParams::default();
    let rows = bench::run_detection(gt, &cfg, args.align.then_some(&params), &|| {});
    let heading = format!(
        "{} ; noise seed {seed}; distance matching (nuScenes); {:.1} s",
        data.describe(gt),
        start.elapsed().as_secs_f64()
    );
    print!("{}", render(&rows[..], format, &heading)?);
    Ok(())
}

/// `--async`: agents captured at different instants.
fn asynchronous(args: &BenchArgs, gt: &GroundTruth) -> anyhow::Result<()> {
    let (data, noise, methods) = (&args.data, args.noise.as_str(), args.methods.as_str());
    let (seed, range, format) = (args.draw.seed, args.draw.range, args.format.format);
    let noise = if noise == "all" { "mild" } else { noise };
    let setting = NoiseSetting::parse(noise, 2).map_err(anyhow::Error::msg)?;
    let cfg = BenchConfig {
        methods: methods_or(methods, &beside_oracle())?,
        settings: vec![],
        seed,
        range,
    };
    let start = Instant::now();
    let rows = v2x_sim::bench::asynchronous::run(gt, &cfg, &setting);
    let heading = format!(
        "{} ; noise {setting}, seed {seed}; {:.1} s",
        data.describe(gt),
        start.elapsed().as_secs_f64()
    );
    print!("{}", render(&rows[..], format, &heading)?);
    Ok(())
}

/// The paper's Table 2.
fn table2(args: &BenchArgs, gt: &GroundTruth) -> anyhow::Result<()> {
    let (data, noise, methods) = (&args.data, args.noise.as_str(), args.methods.as_str());
    let (seed, range, format) = (args.draw.seed, args.draw.range, args.format.format);
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
    let secs = start.elapsed().as_secs_f64();
    let heading = format!("{} ; noise seed {seed}; {:.1} s", data.describe(gt), secs);
    print!("{}", render(&rows[..], format, &heading)?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        bench: BenchArgs,
    }

    fn mode(flags: &[&str]) -> anyhow::Result<Mode> {
        let cli = Cli::try_parse_from(std::iter::once("bench").chain(flags.iter().copied()))?;
        Mode::of(&cli.bench)
    }

    #[test]
    fn each_flag_selects_its_mode_and_real_data_refuses_the_others() {
        let truth = |m| Mode::Truth(m);
        assert_eq!(mode(&[]).unwrap(), truth(TruthMode::Table2));
        assert_eq!(mode(&["--async"]).unwrap(), truth(TruthMode::Asynchronous));
        assert_eq!(
            mode(&["--profile", "realistic"]).unwrap(),
            truth(TruthMode::Detection("realistic".into()))
        );
        assert_eq!(mode(&["--tracking"]).unwrap(), truth(TruthMode::Tracking));
        assert_eq!(
            mode(&["--tracking", "--seeds", "1,2"]).unwrap(),
            truth(TruthMode::TrackingSeeds)
        );
        assert_eq!(
            mode(&["--tile-size", "50"]).unwrap(),
            truth(TruthMode::Regions(50.0))
        );
        assert_eq!(
            mode(&["--tile-size", "50", "--tracking"]).unwrap(),
            truth(TruthMode::RegionTracking(50.0))
        );
        let v2v = ["--dataset", "v2v4real", "--dataroot", "x"];
        assert_eq!(mode(&v2v).unwrap(), Mode::V2v4real);
        for extra in [
            &["--tile-size", "50"][..],
            &["--tracking", "--seeds", "1,2"],
            &["--tracking", "--seeds", "1", "--parts", "2"],
        ] {
            let err = mode(&[&v2v[..], extra].concat()).unwrap_err();
            assert!(err.to_string().contains("leave out --tile-size"), "{err}");
        }
        let dair = ["--dataset", "dair-v2x", "--dataroot", "x", "--tracking"];
        assert!(mode(&dair)
            .unwrap_err()
            .to_string()
            .contains("dair-v2x runs its own table"));
        // --agents sets the paper's table alone, 1 to 64 agents.
        assert_eq!(mode(&["--agents", "64"]).unwrap(), truth(TruthMode::Table2));
        for bad in [
            &["--agents", "64", "--tracking"][..],
            &["--agents", "3", "--async"],
        ] {
            let err = mode(bad).unwrap_err().to_string();
            assert!(err.contains("--agents sets the agents"), "{err}");
        }
        assert!(mode(&["--agents", "65"]).is_err());
        assert!(mode(&["--agents", "0"]).is_err());
        let err = mode(&[&v2v[..], &["--agents", "4"]].concat()).unwrap_err();
        assert!(err.to_string().contains("real data sets"), "{err}");
    }

    #[test]
    fn logs_and_parts_go_with_the_seeds_and_the_town_seeds_with_the_town() {
        let seeds = ["--tracking", "--seeds", "1,2"];
        for extra in [
            &["--parts", "2"][..],
            &["--town-seeds", "7,8"],
            &[
                "--dataroot",
                "a",
                "--more-dataroot",
                "b",
                "--more-dataroot",
                "c",
            ],
        ] {
            let flags = [&seeds[..], extra].concat();
            assert_eq!(mode(&flags).unwrap(), Mode::Truth(TruthMode::TrackingSeeds));
        }
        for bad in [
            &["--tracking", "--parts", "2"][..],
            &["--tracking", "--town-seeds", "7"],
            &["--tracking", "--seeds", "1", "--parts", "0"],
            &["--tracking", "--seeds", "1", "--parts", "17"],
            &["--tracking", "--seeds", "1", "--more-dataroot", "b"],
            &[
                "--tracking",
                "--seeds",
                "1",
                "--dataroot",
                "a",
                "--town-seeds",
                "7",
            ],
        ] {
            assert!(mode(bad).is_err(), "{bad:?}");
        }
        let cli = Cli::try_parse_from([
            "bench",
            "--tracking",
            "--seeds",
            "1",
            "--town-seeds",
            "7,9",
            "--parts",
            "2",
        ])
        .unwrap();
        let logs = tracking_logs(&BenchArgs {
            data: DataArgs {
                seconds: 2.0,
                ..cli.bench.data.clone()
            },
            ..cli.bench
        })
        .unwrap();
        let names: Vec<&str> = logs.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names.len(), 4);
        assert!(names[0].starts_with("synthetic town (seed 7,"), "{names:?}");
        assert!(names[1].contains("part 2 of 2: 10 frames"), "{names:?}");
        assert!(names[3].starts_with("synthetic town (seed 9,"), "{names:?}");
    }
}
