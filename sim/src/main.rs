//! `v2x-sim`: generate noisy agents from ground truth, score results files, reproduce the
//! paper's Table 2, draw a frame, and run scripted scenarios over Zenoh.

use clap::{Parser, Subcommand};

mod commands;
mod sources;

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

#[derive(Subcommand)]
enum Command {
    /// Write each agent's noisy detections as nuScenes results files (agent1.json, ...) into
    /// the folder -o names.
    #[command(after_help = commands::faults_help())]
    Gen(commands::gen::GenArgs),
    /// Score a results file against the ground truth.
    Eval(commands::eval::EvalArgs),
    /// Fit an agent's error model against the ground truth: the bias and std of its boxes'
    /// centre, size, yaw and velocity per class and score bin, with counts and 95% intervals,
    /// written as JSON to -o for `v2x-fuser fuse/track/node --std-model AGENT=FILE`.
    Calibrate(commands::calibrate::CalibrateArgs),
    /// Fit the existence model of a detector's fused boxes (their score: the chance each is a
    /// real object) against a split's labels, written as JSON to -o for `v2x-fuser fuse/track
    /// --existence-model FILE`.
    FitScore(commands::fit_score::FitScoreArgs),
    /// Reproduce the paper's Table 2 (every method under each noise setting, with the single
    /// agents and the lower bound), a real data set's own tables with --dataset, or another
    /// table: tracking, detection, regions, async.
    Bench(Box<commands::bench::BenchArgs>),
    /// Draw one frame as an SVG into the folder -o names: ground truth, each agent's boxes, the
    /// fused boxes (with --timeline: a run's timeline, into the SVG file -o names).
    Plot(commands::plot::PlotArgs),
    #[command(flatten)]
    Run(v2x_sim::run::RunCommand),
    /// Make a certificate authority, certificates for every role (common name = agent name,
    /// `fuser`, `observer`, and a server certificate for the router) and the Zenoh
    /// configuration of each role: the router with mutual TLS and the access-control policy,
    /// the others as its clients, all into the folder -o names. Give each command its file with
    /// --zenoh-config.
    Certs(commands::certs::CertsArgs),
    /// Load test: N agents x M objects at a fixed rate to one fuser over loopback; reports
    /// fusion latency, backlog, CPU and memory.
    Load(v2x_sim::load::LoadArgs),
    /// Convert a results file into an MCAP file for Foxglove (-o): its boxes on `/boxes` and
    /// the ground truth on `/ground_truth`, each sample at its time (as `eval` finds it).
    Mcap(commands::mcap::McapArgs),
    /// Write a results file's frames as ETSI Collective Perception Messages (UPER) or as the
    /// project's own frames, one file per agent and sample, and print the bytes per frame of
    /// both; or read CPM files back as boxes (--read).
    Wire(commands::wire::WireArgs),
}

fn main() -> std::process::ExitCode {
    v2x_protocol::cli::quiet_on_closed_stdout();
    v2x_protocol::net::exit_code(run(Cli::parse()))
}

fn run(cli: Cli) -> anyhow::Result<()> {
    v2x_protocol::net::init_logging("warn,zenoh=error");
    match cli.command {
        Command::Gen(args) => sources::open(&args.data).gen(&args)?,
        Command::Eval(args) => sources::eval(&args)?,
        Command::Calibrate(args) => commands::calibrate::run(args)?,
        Command::FitScore(args) => commands::fit_score::run(args)?,
        Command::Bench(args) => sources::bench(*args)?,
        Command::Mcap(args) => commands::mcap::run(args)?,
        Command::Wire(args) => commands::wire::run(args)?,
        Command::Load(args) => commands::load::run(args)?,
        Command::Run(cmd) => {
            let rt = v2x_protocol::net::runtime()?;
            rt.block_on(v2x_sim::run::run_command(cmd))?;
        }
        Command::Certs(args) => commands::certs::run(args)?,
        Command::Plot(args) => commands::plot::run(args)?,
    }
    Ok(())
}
