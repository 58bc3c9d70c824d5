//! `v2x-sim`: generate noisy agents from ground truth, score results files, reproduce the
//! paper's Table 2, draw a frame, and run scripted scenarios over Zenoh.

use anyhow::{bail, Context};
use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;
use v2x_fuser::Method;
use v2x_protocol::nuscenes_json::write_results;
use v2x_sim::bench::{self, BenchConfig};
use v2x_sim::cli::{evaluate_file, DataArgs, EvalOptions, Evaluation};
use v2x_sim::noise::{place_agents, NoiseSetting};

#[derive(Parser)]
#[command(
    name = "v2x-sim",
    version,
    about = "Simulator for v2x-fusion: noisy agents from ground truth, metrics, the paper's comparison, scenario runs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Copy, Clone, Debug, ValueEnum, PartialEq)]
enum Format {
    Table,
    Json,
    Csv,
}

#[derive(Subcommand)]
enum Command {
    /// Write each agent's noisy detections as nuScenes results files (agent1.json, ...).
    #[command(after_help = faults_help())]
    Gen {
        #[command(flatten)]
        data: DataArgs,
        /// Noise: mild, moderate, large, realistic, a mix such as mild+large (one per agent), or
        /// POS,SIZE,YAW_DEG.
        #[arg(long, default_value = "mild+large")]
        noise: String,
        /// Detector faults, replacing the noise profile's own (none, except for `realistic`):
        /// `none`, `realistic`, or KEY=VALUE,... (keys below); one for all agents or one per
        /// agent joined by '+'.
        #[arg(long)]
        faults: Option<String>,
        /// Number of agents.
        #[arg(long, default_value_t = 2)]
        agents: usize,
        /// Noise seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Sensing range of each agent in metres (default: every agent sees every object).
        #[arg(long)]
        range: Option<f64>,
        /// Capture rate of each agent in Hz, comma-separated, or one for all (default: the
        /// data's rate, on its frames).
        #[arg(long)]
        agent_hz: Option<String>,
        /// Phase of each agent in ms after each scene's first frame, comma-separated, or one
        /// for all (default 0).
        #[arg(long)]
        phase_ms: Option<String>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
    },
    /// Score a results file against the ground truth.
    Eval {
        #[command(flatten)]
        data: DataArgs,
        /// Count ground-truth frames absent from the file as all missed (default: score only the
        /// frames the file has).
        #[arg(long)]
        all_frames: bool,
        /// How predictions are matched to ground truth: `id` (the paper's protocol: by
        /// ground-truth id, precision, recall, mATE...), `distance` (the nuScenes detection
        /// benchmark: by centre distance, AP at 0.5/1/2/4 m, TP errors at 2 m, NDS), or `auto`:
        /// by id when the file's boxes carry ground-truth ids, else by distance (a detector's own
        /// output has none).
        #[arg(long = "match", value_enum, default_value = "auto")]
        matching: v2x_sim::cli::Match,
        /// Score a tracking results file (`v2x-fuser track`) as the nuScenes tracking benchmark
        /// does: AMOTA, AMOTP, and MOTA, MOTP, IDS, FRAG at each class's best score threshold,
        /// 2 m centre distance, the seven tracking classes. The same file without --tracking
        /// scores its boxes as detections.
        #[arg(long, conflicts_with_all = ["replay_start_at", "at", "classes"])]
        tracking: bool,
        /// Output format.
        #[arg(long, value_enum, default_value = "table")]
        format: Format,
        /// For a fuser recording of `v2x-agent --clock real` replays: the agents' --start-at
        /// (Unix seconds), so that capture times map back to the data's frames.
        #[arg(long)]
        replay_start_at: Option<f64>,
        /// With --replay-start-at: the agents' --speed.
        #[arg(long, default_value_t = 1.0, requires = "replay_start_at")]
        replay_speed: f64,
        /// When a sample is scored: `frame` (a sample token at its own frame, whatever the
        /// file's meta.v2x_timestamps say) or `capture` (at its capture time from
        /// meta.v2x_timestamps, the ground truth interpolated along its tracks; only for ground
        /// truth tracked across frames). Keys that are no sample token (t<us>) use their time.
        #[arg(long, value_enum, default_value = "frame")]
        at: v2x_sim::cli::Timing,
        /// The classes to score, comma-separated nuScenes names (e.g. car,truck,bus): other
        /// classes' boxes, ground truth and predictions, are left out. Default: every class, the
        /// benchmark's headline averaged over the classes the ground truth holds.
        #[arg(long, value_parser = v2x_sim::cli::parse_classes)]
        classes: Option<Vec<v2x_protocol::Class>>,
        /// The results file to score.
        pred: PathBuf,
    },
    /// Reproduce the paper's Table 2: every method under each noise setting, with the single
    /// agents and the lower bound.
    Bench {
        #[command(flatten)]
        data: DataArgs,
        /// Noise settings, comma-separated, or 'all' (mild, moderate, large, mild+large).
        #[arg(long, default_value = "all")]
        noise: String,
        /// Methods, comma-separated, or 'all' (see `v2x-fuser fuse --help`).
        #[arg(long, default_value = "all")]
        methods: String,
        /// Noise seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Sensing range of each agent in metres (default: every agent sees every object).
        #[arg(long)]
        range: Option<f64>,
        /// Output format.
        #[arg(long, value_enum, default_value = "table")]
        format: Format,
        /// Also draw frame N (index over all frames) as an SVG into --out, for each noise setting.
        #[arg(long, requires = "out")]
        plot: Option<usize>,
        /// Directory for --plot.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Instead of Table 2: the nuScenes detection benchmark (distance matching: precision,
        /// recall, mAP, NDS, mATE...) for every method and single agent under these noise
        /// settings, comma-separated, e.g. `realistic` (detector faults and pose errors).
        #[arg(long, conflicts_with_all = ["asynchronous", "plot"])]
        profile: Option<String>,
        /// With --profile: every method again after registering each agent to the roadside
        /// unit by its boxes (`v2x-fuser fuse --align`), rows `METHOD --align`.
        #[arg(long, requires = "profile")]
        align: bool,
        /// Instead of Table 2: single-frame fusion against tracking (`v2x-fuser track`) of the
        /// fused boxes and of each single agent, with MOTA, MOTP, IDS and FRAG, under each
        /// --noise setting; --methods defaults to csba-wls+ and gt-wls. With gt-wls, a row
        /// `gt-wls tracked by id` gives each box to its true object's track: what a perfect
        /// association of boxes to tracks gives.
        #[arg(long, conflicts_with_all = ["asynchronous", "plot", "profile"])]
        tracking: bool,
        /// Instead of Table 2: each method as one fuser and as regional fusers, one per tile of
        /// this side (m) that some box lies in, each fusing its tile and a --halo around it and
        /// keeping the boxes centred in its tile; the two rows should agree.
        #[arg(long, conflicts_with_all = ["asynchronous", "plot", "profile", "tracking"])]
        tile_size: Option<f64>,
        /// With --tile-size: how far beyond its tile a regional fuser takes boxes (m).
        #[arg(long, requires = "tile_size", default_value_t = v2x_fuser::region::DEFAULT_HALO_M)]
        halo: f64,
        /// Instead of Table 2: two agents captured at different instants (10+10 Hz at offsets
        /// 0, 25, 50 and 100 ms, and a 10+20 Hz pair), each fused with and without motion
        /// compensation. --noise is then one setting (default mild); --methods defaults to
        /// csba-wls+ and gt-wls.
        #[arg(long = "async")]
        asynchronous: bool,
    },
    /// Draw one frame as an SVG: ground truth, each agent's boxes, the fused boxes.
    Plot {
        #[command(flatten)]
        data: DataArgs,
        /// Frame index over all frames.
        #[arg(long, default_value_t = 0)]
        frame: usize,
        /// Noise setting.
        #[arg(long, default_value = "mild+large")]
        noise: String,
        /// Method for the fused boxes.
        #[arg(long, default_value = "csba-wls+")]
        method: Method,
        /// Noise seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output directory (with --timeline: the SVG file to write).
        #[arg(long)]
        out: PathBuf,
        /// Instead of a frame: draw a run's per-second series (`v2x-sim run --timeline
        /// FILE.json`), one panel per measure, the scripted events marked.
        #[arg(long)]
        timeline: Option<PathBuf>,
    },
    #[command(flatten)]
    Run(v2x_sim::run::RunCommand),
    /// Make a certificate authority, certificates for every role (common name = agent name,
    /// `fuser`, `observer`, and a server certificate for the router) and the Zenoh
    /// configuration of each role: the router with mutual TLS and the access-control policy,
    /// the others as its clients. Give each command its file with --zenoh-config.
    Certs {
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Namespace the access-control policy covers.
        #[arg(long, default_value = "default")]
        ns: String,
        /// Endpoints the router listens on.
        #[arg(long, default_value = "tls/0.0.0.0:7447")]
        listen: Vec<String>,
        /// Endpoints the clients connect to; their hosts are written into the router's
        /// certificate (with localhost and 127.0.0.1).
        #[arg(long, default_value = "tls/localhost:7447")]
        router: Vec<String>,
        /// Days the certificates are valid.
        #[arg(long, default_value_t = 365)]
        days: u32,
        /// The agents' names, one certificate each.
        #[arg(required = true)]
        agents: Vec<String>,
    },
    /// Load test: N agents x M objects at a fixed rate to one fuser over loopback; reports
    /// fusion latency, backlog, CPU and memory.
    Load(v2x_sim::load::LoadArgs),
    /// Convert a results file into an MCAP for Foxglove: its boxes on `/boxes` and the ground
    /// truth on `/ground_truth`, each sample at its time (as `eval` finds it).
    Mcap {
        #[command(flatten)]
        data: DataArgs,
        /// The results file (from `v2x-fuser fuse`, `node --record`, `v2x-sim gen` or `run --record`).
        pred: PathBuf,
        /// The MCAP file to write.
        #[arg(long)]
        out: PathBuf,
    },
}

/// Scores a tracking results file over the ground truth's frames in time order: only the frames
/// the file has, or with `all_frames` every frame (absent ones all missed).
fn evaluate_tracking(
    gt: &v2x_sim::dataset::GroundTruth,
    path: &std::path::Path,
    all_frames: bool,
) -> anyhow::Result<v2x_sim::tracking_eval::TrackingMetrics> {
    let tracks = v2x_sim::tracking_eval::read_tracking(path).map_err(anyhow::Error::msg)?;
    let known: std::collections::HashSet<&str> =
        gt.frames.iter().map(|f| f.sample_token.as_str()).collect();
    if let Some(s) = tracks.keys().find(|s| !known.contains(s.as_str())) {
        bail!(
            "{}: sample {s} is not in the ground truth: score the file against the data it was made from (--dataroot/--version, or the same town flags)",
            path.display()
        );
    }
    let mut other: std::collections::BTreeMap<&str, usize> = Default::default();
    for b in tracks.values().flatten() {
        if !b.class.is_tracking() {
            *other.entry(b.class.name()).or_default() += 1;
        }
    }
    if !other.is_empty() {
        let list: Vec<String> = other.iter().map(|(c, n)| format!("{c} {n}")).collect();
        eprintln!(
            "{}: boxes of classes the tracking benchmark does not score were left out ({}); the official devkit refuses a file with them",
            path.display(),
            list.join(", ")
        );
    }
    let mut eval = v2x_sim::tracking_eval::TrackingEval::new();
    for f in &gt.frames {
        match tracks.get(&f.sample_token) {
            Some(boxes) => eval.add_frame(f.scene, f.timestamp_us, &f.objects, boxes),
            None if all_frames => eval.add_frame(f.scene, f.timestamp_us, &f.objects, &[]),
            None => {}
        }
    }
    Ok(eval.summary())
}

/// A bench configuration over the paper's noise settings (or those named), with `methods`, or
/// `default_methods` when it is `all`.
fn paper_settings(
    methods: &str,
    default_methods: &str,
    noise: &str,
    seed: u64,
    range: Option<f64>,
) -> anyhow::Result<BenchConfig> {
    let methods = if methods == "all" {
        default_methods
    } else {
        methods
    };
    Ok(BenchConfig {
        methods: parse_list(methods, vec![], |s| s.parse())?,
        settings: parse_list(noise, NoiseSetting::paper(), |s| NoiseSetting::parse(s, 2))?,
        seed,
        range,
    })
}

fn faults_help() -> String {
    let mut s = String::from("Fault keys (--faults KEY=VALUE,...; default in brackets):\n");
    for (k, what) in v2x_sim::faults::FAULT_KEYS {
        s.push_str(&format!("  {k:<11} {what}\n"));
    }
    s.push_str(&format!(
        "  realistic = {}\n",
        v2x_sim::faults::Faults::REALISTIC
    ));
    s
}

fn parse_list<T>(
    s: &str,
    all: Vec<T>,
    parse: impl Fn(&str) -> Result<T, String>,
) -> anyhow::Result<Vec<T>> {
    if s == "all" {
        return Ok(all);
    }
    s.split(',')
        .map(|x| parse(x.trim()).map_err(anyhow::Error::msg))
        .collect()
}

fn plot(
    data: &v2x_sim::dataset::GroundTruth,
    frame: usize,
    setting: &NoiseSetting,
    method: &Method,
    seed: u64,
    out: &std::path::Path,
) -> anyhow::Result<PathBuf> {
    let Some(f) = data.frames.get(frame) else {
        bail!(
            "--plot/--frame {frame} is out of range: the data has {} frames",
            data.frames.len()
        );
    };
    let agents = bench::agent_detections(data, frame, setting, seed, None);
    let fused = method.fuse(&agents);
    let places = place_agents(f, agents.len(), seed);
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

fn main() -> std::process::ExitCode {
    // Errors are for people: one line with its causes, no backtrace.
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "warn,zenoh=error".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match cli.command {
        Command::Gen {
            data,
            noise,
            faults,
            agents,
            seed,
            range,
            agent_hz,
            phase_ms,
            out,
        } => {
            let gt = data.load()?;
            let mut setting = NoiseSetting::parse(&noise, agents).map_err(anyhow::Error::msg)?;
            if let Some(f) = &faults {
                setting
                    .set_faults(f)
                    .map_err(|e| anyhow::anyhow!("--faults: {e}"))?;
            }
            let timings = v2x_sim::gen::Timing::parse(
                agent_hz.as_deref(),
                phase_ms.as_deref(),
                setting.agents.len(),
            )
            .map_err(anyhow::Error::msg)?;
            std::fs::create_dir_all(&out)
                .with_context(|| format!("cannot create {}", out.display()))?;
            let files = v2x_sim::gen::generate(&gt, &setting, &timings, seed, range);
            for (a, r) in files.iter().enumerate() {
                let p = out.join(format!("agent{}.json", a + 1));
                write_results(&p, r, &gt.tokens)?;
                eprintln!("wrote {} ({} noise)", p.display(), setting.agents[a].label);
            }
            eprintln!("{}", data.describe(&gt));
        }
        Command::Eval {
            data,
            all_frames,
            matching,
            format,
            replay_start_at,
            replay_speed,
            at,
            classes,
            tracking,
            pred,
        } => {
            if tracking {
                let gt = data.load()?;
                let m = evaluate_tracking(&gt, &pred, all_frames)?;
                match format {
                    Format::Json => println!("{}", serde_json::to_string_pretty(&m)?),
                    Format::Table | Format::Csv => {
                        println!("| predictions | AMOTA | AMOTP (m) | MOTA | MOTP (m) | IDS | IDS / 100 objects | FRAG | TP | FP | FN | objects |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
                        println!(
                            "| {} | {:.4} | {:.3} | {:.4} | {:.3} | {} | {:.2} | {} | {} | {} | {} | {} |",
                            pred.display(),
                            m.amota,
                            m.amotp,
                            m.mota,
                            m.motp,
                            m.ids,
                            m.ids_per_100_tracks,
                            m.frag,
                            m.tp,
                            m.fp,
                            m.fn_,
                            m.gt_tracks
                        );
                    }
                }
                return Ok(());
            }
            let replay = match replay_start_at {
                None => None,
                Some(t)
                    if t > 0.0
                        && t.is_finite()
                        && replay_speed > 0.0
                        && replay_speed.is_finite() =>
                {
                    Some(v2x_sim::cli::ReplayMap {
                        start_us: (t * 1e6) as u64,
                        speed: replay_speed,
                    })
                }
                Some(_) => {
                    bail!("--replay-start-at must be a positive Unix time and --replay-speed > 0")
                }
            };
            let gt = data.load()?;
            let opts = EvalOptions {
                all_frames,
                replay,
                how: matching,
                timing: at,
                classes,
            };
            let (evaluation, note) = evaluate_file(&gt, &pred, &opts)?;
            eprintln!("{note}");
            let csv = format == Format::Csv;
            match evaluation {
                e if format == Format::Json => println!("{}", serde_json::to_string_pretty(&e)?),
                Evaluation::Distance(d) => {
                    let rows = [(pred.display().to_string(), &d)];
                    print!(
                        "{}",
                        if csv {
                            bench::detection_csv(&rows)
                        } else {
                            bench::detection_table(&rows)
                        }
                    );
                }
                Evaluation::Id(m) => {
                    let rows = [bench::Row {
                        noise: "-".into(),
                        method: pred.display().to_string(),
                        metrics: m,
                    }];
                    print!(
                        "{}",
                        if csv {
                            bench::csv(&rows)
                        } else {
                            bench::table(&rows)
                        }
                    );
                }
            }
        }
        Command::Bench {
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
        } => {
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
            let settings =
                parse_list(&noise, NoiseSetting::paper(), |s| NoiseSetting::parse(s, 2))?;
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
        }
        Command::Mcap { data, pred, out } => {
            let gt = data.load()?;
            let mut tokens = gt.tokens.clone();
            let results = v2x_protocol::nuscenes_json::read_results(
                &pred,
                &mut tokens,
                v2x_protocol::nuscenes_json::MissingStd::Default(
                    v2x_protocol::Uncertainty::uniform(1.0, 1.0, 1.0),
                ),
            )?;
            let (samples, unknown) =
                v2x_sim::cli::sample_times(&gt, &results, None, v2x_sim::cli::Timing::Capture);
            if let Some(k) = unknown.first() {
                bail!(
                    "{}: {} sample(s) have no time within the ground truth, e.g. '{k}' (is this the right --dataroot/--version?)",
                    pred.display(),
                    unknown.len()
                );
            }
            let rt = tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .build()
                .context("starting the async runtime")?;
            let viz = rt.block_on(v2x_fuser::viz::Viz::open(Some(&out), None))?;
            for v2x_sim::cli::SampleTime {
                key,
                t_us: t,
                scene,
                ..
            } in &samples
            {
                let truth: Vec<_> = gt
                    .objects_at(*scene, *t)
                    .iter()
                    .map(v2x_sim::dataset::GtObject::as_detection)
                    .collect();
                viz.boxes(
                    "/ground_truth",
                    "gt",
                    *t,
                    &truth,
                    v2x_fuser::viz::GROUND_TRUTH,
                );
                viz.boxes(
                    "/boxes",
                    "boxes",
                    *t,
                    &results.samples[key],
                    v2x_fuser::viz::FUSED,
                );
            }
            viz.close()?;
            eprintln!("wrote {} ({} samples)", out.display(), samples.len());
        }
        Command::Load(args) => {
            let rt = tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .build()
                .context("starting the async runtime")?;
            if args.regions.is_some() {
                let rows = rt.block_on(v2x_sim::load::run_regions(&args))?;
                if args.json {
                    println!("{}", serde_json::to_string_pretty(&rows)?);
                } else {
                    println!("{} agents x {} objects at {} Hz over four sites of {} m, {} s per configuration", args.agents, args.objects, args.hz, v2x_sim::load::BLOCK_M, args.seconds);
                    println!("| fusers | tile (m) | boxes in/s | boxes fused/s | windows (incomplete) | captures incomplete | windows lost | fusion p50 / p99 (ms) | e2e p99 (ms), worst fuser | CPU % |\n|---|---|---|---|---|---|---|---|---|---|");
                    for r in &rows {
                        println!(
                            "| {} | {} | {:.0} | {:.0} | {} ({}) | {} | {} | {:.3} / {:.3} | {:.1} | {:.0} |",
                            r.fusers,
                            r.tile_m,
                            r.input_boxes_per_s,
                            r.fused_boxes_per_s,
                            r.windows,
                            r.windows_incomplete,
                            r.captures_incomplete,
                            r.windows_lost,
                            r.fusion_latency_ms.p50_ms.unwrap_or(f64::NAN),
                            r.fusion_latency_ms.p99_ms.unwrap_or(f64::NAN),
                            r.e2e_p99_ms.unwrap_or(f64::NAN),
                            r.cpu_percent
                        );
                    }
                }
                return Ok(());
            }
            if args.max_load {
                let (runs, stopped) = rt.block_on(v2x_sim::load::run_max_load(&args))?;
                if let Some(why) = &stopped {
                    eprintln!("the search stopped early: {why}");
                }
                if args.json {
                    let v: Vec<_> = runs
                        .iter()
                        .map(|(r, held)| serde_json::json!({"held": held, "report": r}))
                        .collect();
                    let v = serde_json::json!({"runs": v, "stopped_early": stopped});
                    println!("{}", serde_json::to_string_pretty(&v)?);
                } else {
                    println!("| agents | objects | boxes/s | windows | fusion p99 (ms) | held (p99 < {} ms) |\n|---|---|---|---|---|---|", v2x_sim::load::HOLD_P99_MS);
                    for (r, held) in &runs {
                        println!(
                            "| {} | {} | {:.0} | {} of {} | {:.3} | {} |",
                            r.agents,
                            r.objects,
                            (r.agents * r.objects) as f64 * r.hz,
                            r.windows,
                            r.frames_per_agent,
                            r.fusion_latency_ms.p99_ms.unwrap_or(f64::NAN),
                            if *held { "yes" } else { "no" }
                        );
                    }
                    match runs.iter().rev().find(|(_, held)| *held) {
                        Some((r, _)) => println!(
                            "largest load held: {} agents x {} objects at {} Hz",
                            r.agents, r.objects, r.hz
                        ),
                        None => println!("no load held: lower --agents"),
                    }
                }
                return Ok(());
            }
            let r = rt.block_on(v2x_sim::load::run(&args))?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&r)?);
            } else {
                let l = |x: &v2x_fuser::node::Latency| {
                    format!(
                        "{:.3} / {:.3} / {:.3} / {:.3}",
                        x.p50_ms.unwrap_or(f64::NAN),
                        x.p95_ms.unwrap_or(f64::NAN),
                        x.p99_ms.unwrap_or(f64::NAN),
                        x.max_ms.unwrap_or(f64::NAN)
                    )
                };
                println!("{} agents x {} objects at {} Hz: {} frames per agent, {} windows fused ({} incomplete), {} open at the end", r.agents, r.objects, r.hz, r.frames_per_agent, r.windows, r.windows_incomplete, r.open_windows_at_end);
                println!("| latency (ms) | p50 / p95 / p99 / max |\n|---|---|");
                println!(
                    "| fusion (window close to publish) | {} |",
                    l(&r.fusion_latency_ms)
                );
                println!(
                    "| fusion, first half | {} |",
                    l(&r.fusion_latency_first_half_ms)
                );
                println!(
                    "| fusion, second half | {} |",
                    l(&r.fusion_latency_second_half_ms)
                );
                println!(
                    "| end to end (capture to publish) | {} |",
                    l(&r.e2e_latency_ms)
                );
                println!("CPU {:.0}% of one core (whole process: agents, Zenoh and fuser); RSS {:.1} MiB at start, {:.1} MiB at the end", r.cpu_percent, r.rss_start_mib, r.rss_end_mib);
            }
        }
        Command::Run(cmd) => {
            let rt = tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .build()
                .context("starting the async runtime")?;
            rt.block_on(v2x_sim::run::run_command(cmd))?;
        }
        Command::Certs {
            out,
            ns,
            listen,
            router,
            days,
            agents,
        } => {
            let issued = v2x_sim::certs::issue(&v2x_sim::certs::CertsConfig {
                out,
                ns,
                agents,
                listen,
                connect: router,
                days,
            })?;
            println!(
                "wrote certificates and Zenoh configurations to {}:",
                issued.dir.display()
            );
            println!(
                "  router:   v2x-fuser router --zenoh-config {}",
                issued.router.display()
            );
            println!(
                "  fuser:    v2x-fuser node --zenoh-config {} ...",
                issued.fuser.display()
            );
            for (a, p) in &issued.agents {
                println!(
                    "  agent {a}: v2x-agent FILE --name {a} --zenoh-config {} ...",
                    p.display()
                );
            }
            println!(
                "  observer: v2x-fuser stats --zenoh-config {}",
                issued.observer.display()
            );
            println!("keep ca-key.pem and the *-key.pem files private");
        }
        Command::Plot {
            data,
            frame,
            noise,
            method,
            seed,
            out,
            timeline,
        } => {
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
        }
    }
    Ok(())
}
