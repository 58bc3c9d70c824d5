//! `v2x-sim bench`.

use super::*;
use anyhow::bail;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;
use v2x_fuser::Method;
use v2x_sim::bench::{self, BenchConfig};
use v2x_sim::cli::DataArgs;
use v2x_sim::noise::NoiseSetting;

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
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sensing range of each agent in metres (default: every agent sees every object).
    #[arg(long)]
    pub range: Option<f64>,
    /// Output format.
    #[arg(long, value_enum, default_value = "table")]
    pub format: Format,
    /// Also draw frame N (index over all frames) as an SVG into --out, for each noise setting.
    #[arg(long, requires = "out")]
    pub plot: Option<usize>,
    /// Directory for --plot.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Instead of Table 2: the nuScenes detection benchmark (distance matching: precision,
    /// recall, mAP, NDS, mATE...) for every method and single agent under these noise
    /// settings, comma-separated, e.g. `realistic` (detector faults and pose errors).
    #[arg(long, conflicts_with_all = ["asynchronous", "plot"])]
    pub profile: Option<String>,
    /// With --profile: every method again after registering each agent to the roadside
    /// unit by its boxes (`v2x-fuser fuse --align`), rows `METHOD --align`.
    #[arg(long, requires = "profile")]
    pub align: bool,
    /// Instead of Table 2: single-frame fusion against tracking (`v2x-fuser track`) of the
    /// fused boxes and of each single agent, with MOTA, MOTP, IDS and FRAG, under each
    /// --noise setting; --methods defaults to csba-wls+ and gt-wls. With gt-wls, a row
    /// `gt-wls tracked by id` gives each box to its true object's track: what a perfect
    /// association of boxes to tracks gives.
    #[arg(long, conflicts_with_all = ["asynchronous", "plot", "profile"])]
    pub tracking: bool,
    /// Instead of Table 2: each method as one fuser and as regional fusers, one per tile of
    /// this side (m) that some box lies in, each fusing its tile and a --halo around it and
    /// keeping the boxes centred in its tile; the two rows should agree.
    #[arg(long, conflicts_with_all = ["asynchronous", "plot", "profile", "tracking"])]
    pub tile_size: Option<f64>,
    /// With --tile-size: how far beyond its tile a regional fuser takes boxes (m).
    #[arg(long, requires = "tile_size", default_value_t = v2x_fuser::region::DEFAULT_HALO_M)]
    pub halo: f64,
    /// Instead of Table 2: two agents captured at different instants (10+10 Hz at offsets
    /// 0, 25, 50 and 100 ms, and a 10+20 Hz pair), each fused with and without motion
    /// compensation. --noise is then one setting (default mild); --methods defaults to
    /// csba-wls+ and gt-wls.
    #[arg(long = "async")]
    pub asynchronous: bool,
}

/// Runs `v2x-sim bench`.
pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    let BenchArgs {
        data,
        noise,
        methods,
        seed,
        range,
        format,
        plot: plot_frame,
        out,
        profile,
        align,
        tracking,
        tile_size,
        halo,
        asynchronous,
    } = args;
    let gt = data.load()?;
    if let Some(size) = tile_size {
        let tiling = v2x_fuser::region::Tiling::new(size)
            .map_err(|e| anyhow::anyhow!("--tile-size: {e}"))?;
        if !(halo.is_finite() && halo >= 0.0) {
            bail!("--halo {halo}: expected a finite distance of at least 0 m");
        }
        let cfg = paper_settings(&methods, "csba-wls+,csba-wls", &noise, seed, range)?;
        let start = Instant::now();
        let rows = bench::run_regions(&gt, &cfg, tiling, halo);
        match format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&rows)?),
            Format::Csv => print!("{}", bench::csv(&rows)),
            Format::Table => {
                println!(
                    "{} ; noise seed {seed}; tiles of {size} m, halo {halo} m; {:.1} s\n",
                    data.describe(&gt),
                    start.elapsed().as_secs_f64()
                );
                print!("{}", bench::table(&rows));
            }
        }
        return Ok(());
    }
    if tracking {
        let cfg = paper_settings(&methods, "csba-wls+,gt-wls", &noise, seed, range)?;
        let start = Instant::now();
        let rows = bench::run_tracking(&gt, &cfg, Default::default());
        match format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&rows)?),
            Format::Table | Format::Csv => {
                println!(
                    "{} ; noise seed {seed}; id matching for the boxes, 2 m for tracking; {:.1} s\n",
                    data.describe(&gt),
                    start.elapsed().as_secs_f64()
                );
                print!("{}", bench::tracking_table(&rows));
            }
        }
        return Ok(());
    }
    if let Some(profile) = profile {
        let cfg = BenchConfig {
            methods: parse_list(&methods, Method::all(), |s| s.parse())?,
            settings: parse_list(&profile, vec![], |s| NoiseSetting::parse(s, 2))?,
            seed,
            range,
        };
        let start = Instant::now();
        let params = v2x_fuser::align::AlignParams::default();
        let rows = bench::run_detection(&gt, &cfg, align.then_some(&params), &|| {});
        let named: Vec<(String, &v2x_sim::detection_eval::DetectionMetrics)> = rows
            .iter()
            .map(|r| (format!("{} {}", r.noise, r.method), &r.metrics))
            .collect();
        match format {
            Format::Table => {
                println!(
                    "{} ; noise seed {seed}; distance matching (nuScenes); {:.1} s\n",
                    data.describe(&gt),
                    start.elapsed().as_secs_f64()
                );
                print!("{}", bench::detection_table(&named));
            }
            Format::Json => println!("{}", serde_json::to_string_pretty(&rows)?),
            Format::Csv => print!("{}", bench::detection_csv(&named)),
        }
        return Ok(());
    }
    if asynchronous {
        let noise = if noise == "all" { "mild".into() } else { noise };
        let setting = NoiseSetting::parse(&noise, 2).map_err(anyhow::Error::msg)?;
        let methods = if methods == "all" {
            "csba-wls+,gt-wls".into()
        } else {
            methods
        };
        let cfg = BenchConfig {
            methods: parse_list(&methods, vec![], |s| s.parse())?,
            settings: vec![],
            seed,
            range,
        };
        let start = Instant::now();
        let rows = v2x_sim::asyncbench::run(&gt, &cfg, &setting);
        match format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&rows)?),
            Format::Table | Format::Csv => {
                println!(
                    "{} ; noise {setting}, seed {seed}; {:.1} s\n",
                    data.describe(&gt),
                    start.elapsed().as_secs_f64()
                );
                print!("{}", v2x_sim::asyncbench::table(&rows));
            }
        }
        return Ok(());
    }
    let settings = parse_list(&noise, NoiseSetting::paper(), |s| NoiseSetting::parse(s, 2))?;
    let methods = parse_list(&methods, Method::all(), |s| s.parse())?;
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
    let rows = bench::run(&gt, &cfg, &|| bar.inc(1));
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    match format {
        Format::Table => {
            println!(
                "{} ; noise seed {seed}; {:.1} s\n",
                data.describe(&gt),
                secs
            );
            print!("{}", bench::table(&rows));
        }
        Format::Json => println!("{}", serde_json::to_string_pretty(&rows)?),
        Format::Csv => print!("{}", bench::csv(&rows)),
    }
    if let (Some(frame), Some(out)) = (plot_frame, out) {
        let best: Method = "csba-wls+".parse().map_err(anyhow::Error::msg)?;
        for s in &cfg.settings {
            eprintln!("drew {}", plot(&gt, frame, s, &best, seed, &out)?.display());
        }
    }
    Ok(())
}
