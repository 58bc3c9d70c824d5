//! `v2x-fuser`: the roadside fuser. `fuse` fuses nuScenes results files offline and `track`
//! tracks a fused one; `node` runs the fuser on the network, `router` a Zenoh router for the
//! secure mode, and `stats` asks a running node for its statistics.

mod cmd;

use clap::{Parser, Subcommand};
use cmd::admin::{router, stats, RouterArgs, StatsArgs};
use cmd::files::{fuse, track, FuseArgs, TrackArgs};
use cmd::node::{run_node, NodeArgs};
use v2x_fuser::METHODS;

fn methods_help() -> String {
    let mut s = String::from("Methods:\n");
    for m in METHODS.iter().filter(|m| !m.ablation) {
        s.push_str(&format!("  {:<16} {}\n", m.name, m.about));
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
    /// Fuse nuScenes detection-results files offline, one file per agent, into the results file
    /// -o names (a folder of KITTI rows with --output-format kitti).
    #[command(after_help = methods_help())]
    Fuse(FuseArgs),
    /// Fuse results files, one per agent, then follow the fused boxes over time with a
    /// constant-velocity Kalman tracker, and write nuScenes tracking results (`tracking_id`,
    /// `tracking_name`, `tracking_score`, beside the detection fields). The files must carry
    /// capture times (meta.v2x_timestamps, as `v2x-sim gen` writes them). -o names the file (a
    /// folder with --output-format kitti).
    #[command(after_help = methods_help())]
    Track(TrackArgs),
    /// Run the fuser on the network: subscribe to every agent, fuse each time window, publish.
    #[command(after_help = methods_help())]
    Node(Box<NodeArgs>),
    /// Run a Zenoh router: the access-control point of a secure deployment (mutual TLS and the
    /// ACL come from its --zenoh-config, as `v2x-sim certs` writes it), until Ctrl-C or SIGTERM.
    /// Agents, fuser and observers connect to it as clients. Access control holds only through
    /// a router: in peer mode sessions talk to each other directly.
    Router(RouterArgs),
    /// Ask a running fuser for its statistics (JSON).
    Stats(StatsArgs),
}

fn main() -> std::process::ExitCode {
    v2x_protocol::cli::quiet_on_closed_stdout();
    v2x_protocol::net::exit_code(run(Cli::parse()))
}

fn run(cli: Cli) -> anyhow::Result<()> {
    v2x_protocol::net::init_logging("info,zenoh=warn");
    match cli.command {
        Command::Fuse(args) => fuse(args),
        Command::Track(args) => track(args),
        Command::Node(args) => run_node(*args),
        Command::Router(args) => router(args),
        Command::Stats(args) => stats(args),
    }
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;
    use v2x_fuser::settings::{keys_of, AdmissionSettings, FusionSettings, TrackSettings};

    /// The long flags of a subcommand.
    fn flags(sub: &str) -> Vec<String> {
        Cli::command()
            .find_subcommand(sub)
            .unwrap()
            .get_arguments()
            .filter_map(|a| a.get_long().map(String::from))
            .collect()
    }

    /// A setting's flag: its key's, but where the key reads better otherwise.
    fn flag(key: &str) -> String {
        match key {
            "compensation" => "no-compensation".into(),
            "std_models" => "std-model".into(),
            k => k.replace('_', "-"),
        }
    }

    #[test]
    fn every_setting_is_declared_once_and_reaches_each_command_that_takes_it() {
        let (fuse, track, node) = (flags("fuse"), flags("track"), flags("node"));
        for key in keys_of::<FusionSettings>() {
            for (name, flags) in [("fuse", &fuse), ("track", &track), ("node", &node)] {
                assert!(flags.contains(&flag(&key)), "{name} lacks {key}");
            }
        }
        for key in keys_of::<TrackSettings>() {
            assert!(track.contains(&flag(&key)), "track lacks {key}");
            assert!(node.contains(&flag(&key)), "node lacks {key}");
            assert!(!fuse.contains(&flag(&key)), "fuse takes {key}");
        }
        for key in keys_of::<AdmissionSettings>() {
            assert!(node.contains(&flag(&key)), "node lacks {key}");
        }
        // No command declares a flag twice.
        for flags in [&fuse, &track, &node] {
            let mut sorted = flags.clone();
            sorted.sort();
            sorted.dedup();
            assert_eq!(sorted.len(), flags.len());
        }
        Cli::command().debug_assert();
    }

    #[test]
    fn a_regional_fusers_tiles_are_checked_and_need_its_tile() {
        use clap::Parser;
        let region = |flags: &[&str]| {
            let cli = Cli::try_parse_from(["v2x-fuser", "node"].iter().chain(flags))?;
            match cli.command {
                super::Command::Node(n) => Ok::<_, clap::Error>(n.region.region()),
                _ => unreachable!("parsed as node"),
            }
        };
        assert!(region(&[]).unwrap().unwrap().is_none());
        let r = region(&["--tile", "0_-1", "--halo", "10"])
            .unwrap()
            .unwrap()
            .unwrap();
        assert_eq!((r.tiling.size_m(), r.halo_m), (200.0, 10.0));
        let r = region(&["--tile", "1_1", "--tile-size", "50"])
            .unwrap()
            .unwrap()
            .unwrap();
        assert_eq!((r.tiling.size_m(), r.halo_m), (50.0, 30.0));
        let e = region(&["--tile-size", "50"])
            .unwrap()
            .unwrap_err()
            .to_string();
        assert!(e.contains("give --tile too"), "{e}");
        assert!(region(&["--tile", "0_0", "--tile-size", "0"]).is_err());
        assert!(region(&["--tile", "0_0", "--halo", "nan"]).is_err());
    }
}
