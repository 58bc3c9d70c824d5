//! `v2x-fuser`: the roadside fuser. `fuse` fuses nuScenes results files offline; `node` runs the
//! fuser on the network.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use v2x_fuser::{Method, METHODS};
use v2x_protocol::nuscenes_json::MissingStd;

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
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
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
    }
}
