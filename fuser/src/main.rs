//! `v2x-fuser`: the roadside fuser. `fuse` fuses nuScenes results files offline; `node` runs the
//! fuser on the network.

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use v2x_fuser::{node, Method, METHODS};
use v2x_protocol::nuscenes_json::MissingStd;
use v2x_protocol::nuscenes_json::{write_results, Results, TokenTable};

fn methods_help() -> String {
    let mut s = String::from("Methods:\n");
    for (name, about) in METHODS {
        s.push_str(&format!("  {name:<16} {about}\n"));
    }
    s
}

#[derive(Parser)]
#[command(
    name = "v2x-fuser",
    version,
    about = "Late fusion of V2X agents' 3D boxes (CSBA-3D + WLS-3D and baselines)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fuse nuScenes detection-results files offline, one file per agent.
    #[command(after_help = methods_help())]
    Fuse {
        /// Fusion method (see the list below).
        #[arg(long, short, default_value = "csba-wls")]
        method: Method,
        /// Stds for boxes that carry no translation_std/size_std/yaw_std: mild, moderate, large,
        /// or POS,SIZE,YAW_DEG (metres, metres, degrees). Without it, a missing std is an error.
        #[arg(long, value_parser = v2x_protocol::parse_std)]
        default_std: Option<v2x_protocol::Uncertainty>,
        /// Where to write the fused results file.
        #[arg(long, short)]
        output: PathBuf,
        /// Input results files, one per agent, in agent order.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
    },
    /// Run the fuser on the network: subscribe to every agent, fuse each time window, publish.
    #[command(after_help = methods_help())]
    Node {
        /// Scenario namespace (keys v2x/NS/...).
        #[arg(long, default_value = "default")]
        ns: String,
        /// Fusion method.
        #[arg(long, short, default_value = "csba-wls+")]
        method: Method,
        /// Window width delta t (ms).
        #[arg(long, default_value_t = 100.0)]
        window_ms: f64,
        /// Longest wait for missing live agents after a window's first frame (ms).
        #[arg(long, default_value_t = 150.0)]
        max_wait_ms: f64,
        /// Record the fused output as a nuScenes results file (keys t<capture us>), scorable by
        /// `v2x-sim eval` against the same ground truth.
        #[arg(long)]
        record: Option<PathBuf>,
        /// Stop after this many seconds (default: run until Ctrl-C).
        #[arg(long)]
        duration_s: Option<f64>,
        #[command(flatten)]
        zenoh: v2x_protocol::net::ZenohArgs,
    },
    /// Ask a running fuser for its statistics (JSON).
    Stats {
        /// Scenario namespace.
        #[arg(long, default_value = "default")]
        ns: String,
        /// How long to wait for an answer (s).
        #[arg(long, default_value_t = 5.0)]
        timeout_s: f64,
        #[command(flatten)]
        zenoh: v2x_protocol::net::ZenohArgs,
    },
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
                .unwrap_or_else(|_| "info,zenoh=warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match cli.command {
        Command::Fuse {
            method,
            default_std,
            output,
            inputs,
        } => {
            let missing = default_std.map_or(MissingStd::Error, MissingStd::Default);
            let (samples, n_in, n_out) =
                v2x_fuser::offline::fuse_files(&method, &inputs, &output, missing)?;
            eprintln!(
                "{method}: fused {n_in} boxes from {} agents over {samples} samples into {n_out} boxes -> {}",
                inputs.len(),
                output.display()
            );
            Ok(())
        }
        Command::Node {
            ns,
            method,
            window_ms,
            max_wait_ms,
            record,
            duration_s,
            zenoh,
        } => {
            let rt = tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .build()
                .context("starting the async runtime")?;
            rt.block_on(async move {
                let session = node::open_session(&zenoh).await?;
                let cfg = node::NodeConfig {
                    ns,
                    method,
                    window_ms,
                    max_wait_ms,
                };
                let mut recorded = Results::default();
                let stop = async move {
                    match duration_s {
                        Some(s) => tokio::time::sleep(std::time::Duration::from_secs_f64(s)).await,
                        None => {
                            let _ = tokio::signal::ctrl_c().await;
                        }
                    }
                };
                let stats = node::run(
                    &session,
                    cfg,
                    |f| {
                        if record.is_some() {
                            recorded.samples.insert(
                                format!("t{}", f.frame.capture_us),
                                f.frame.detections.clone(),
                            );
                        }
                    },
                    stop,
                )
                .await?;
                if let Some(path) = &record {
                    write_results(path, &recorded, &TokenTable::new())?;
                    eprintln!(
                        "recorded {} fused frames -> {}",
                        recorded.samples.len(),
                        path.display()
                    );
                }
                println!("{}", serde_json::to_string_pretty(&stats)?);
                session
                    .close()
                    .await
                    .map_err(|e| anyhow::anyhow!("closing the session: {e}"))?;
                Ok(())
            })
        }
        Command::Stats {
            ns,
            timeout_s,
            zenoh,
        } => {
            let rt = tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .build()
                .context("starting the async runtime")?;
            rt.block_on(async move {
                let session = node::open_session(&zenoh).await?;
                let v =
                    node::query_stats(&session, &ns, std::time::Duration::from_secs_f64(timeout_s))
                        .await?;
                println!("{}", serde_json::to_string_pretty(&v)?);
                Ok(())
            })
        }
    }
}
