//! `v2x-agent`: replays a nuScenes results file (any detector's output) as one agent over Zenoh.

use anyhow::{anyhow, bail, Context};
use clap::Parser;
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Duration;
use v2x_agent::{now_us, replay, Agent, Link, ReplayClock};
use v2x_protocol::net::{open_session, ZenohArgs};
use v2x_protocol::nuscenes_json::{read_results, MissingStd, Results, TokenTable};
use v2x_protocol::{AgentKind, Frame, Uncertainty};

#[derive(Parser)]
#[command(
    name = "v2x-agent",
    version,
    about = "Replay a nuScenes results file, or forward a ROS 2 detector's topic, as one V2X agent over Zenoh",
    long_about = "Replay a nuScenes results file, or forward a ROS 2 detector's topic, as one V2X agent over Zenoh: each frame on v2x/NS/det/AGENT for a single fuser, or with --tile-size as one part per tile its boxes lie in, on v2x/NS/det/TILE/AGENT, for regional fusers."
)]
struct Cli {
    /// The results file to replay (one agent's detections per sample token); not with
    /// --ros-topic.
    #[arg(required_unless_present = "ros_topic", conflicts_with = "ros_topic")]
    results: Option<PathBuf>,
    /// The agent's name (last segment of v2x/NS/det/AGENT).
    #[arg(long)]
    name: String,
    /// vehicle or infrastructure.
    #[arg(long, default_value = "vehicle")]
    kind: AgentKind,
    #[command(flatten)]
    ns: v2x_protocol::net::Namespace,
    /// nuScenes sample table (sample.json) giving each sample's timestamp; without it, samples
    /// are sent in token order at --replay's hz (or at the `v2x_timestamps` map in the file's
    /// meta).
    #[arg(long)]
    sample_table: Option<PathBuf>,
    #[command(flatten)]
    replay: v2x_protocol::cli::ReplayArg,
    /// Stds for boxes without std fields: mild, moderate, large or POS,SIZE,YAW_DEG.
    #[arg(long, value_parser = v2x_protocol::parse_std)]
    default_std: Option<Uncertainty>,
    /// The simulated link and sensor clock, KEY=VALUE,... as a scenario's `link` table has
    /// them: latency_ms (one-way latency), jitter_ms (uniform in [0, J] ms), drop_rate (the
    /// chance a frame is lost), clock_offset_ms (added to every capture time, may be negative),
    /// each left out 0; and seed, the simulation's (1). E.g. latency_ms=20,jitter_ms=10,drop_rate=0.05.
    #[arg(long, value_name = "KEY=VALUE,...", default_value = "", hide_default_value = true, value_parser = parse_link, allow_hyphen_values = true)]
    link: LinkArg,
    /// Wait at most this long for a fuser to subscribe before sending (s).
    #[arg(long, default_value_t = 30.0)]
    wait_s: f64,
    #[command(flatten)]
    tiles: v2x_protocol::tiles::TileSize,
    /// What goes on the air: the project's frames, or ETSI Collective Perception Messages
    /// (UPER, docs/cpm.md), which the fuser reads as frames.
    #[arg(long, value_enum, default_value = "frame")]
    wire: Wire,
    #[command(flatten)]
    map_origin: v2x_cpm::MapOrigin,
    /// Instead of a results file, send what a ROS 2 detector publishes on this topic (heard
    /// over Zenoh), until Ctrl-C or SIGTERM.
    #[arg(long, value_name = "TOPIC")]
    ros_topic: Option<String>,
    /// The topic's message type.
    #[arg(long, value_enum, default_value = "vision", requires = "ros_topic")]
    ros_type: v2x_agent::ros_in::RosType,
    #[command(flatten)]
    ros: v2x_ros::keys::RosNet,
    /// The pose of the messages' frame in the map, as a static transform: X,Y,Z in metres and
    /// the yaw in degrees, or a JSON file as a static transform states it: {"translation": [x,
    /// y, z], "rotation": [x, y, z, w]} (only the rotation about z is used).
    #[arg(
        long,
        value_name = "X,Y,Z,YAW_DEG|FILE",
        default_value = "0,0,0,0",
        value_parser = parse_tf,
        requires = "ros_topic"
    )]
    tf: v2x_ros::convert::Transform,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

/// What an agent sends.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Wire {
    /// The project's frames (docs/wire-format.md).
    Frame,
    /// ETSI Collective Perception Messages, UPER (docs/cpm.md).
    Cpm,
}

fn timestamps(path: &PathBuf) -> anyhow::Result<HashMap<String, u64>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let rows: Vec<serde_json::Value> = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a JSON array of samples", path.display()))?;
    let mut out = HashMap::new();
    for (i, r) in rows.iter().enumerate() {
        let token = r
            .get("token")
            .and_then(|v| v.as_str())
            .ok_or_else(|| anyhow!("{}: record {i}: field 'token' missing", path.display()))?;
        let ts = r
            .get("timestamp")
            .and_then(|v| v.as_u64())
            .ok_or_else(|| anyhow!("{}: record {i}: field 'timestamp' missing", path.display()))?;
        out.insert(token.to_string(), ts);
    }
    Ok(out)
}

fn main() -> std::process::ExitCode {
    v2x_protocol::cli::quiet_on_closed_stdout();
    let cli = Cli::parse();
    v2x_protocol::net::exit_code(
        v2x_protocol::net::runtime()
            .map_err(anyhow::Error::from)
            .and_then(|rt| rt.block_on(run(cli))),
    )
}

async fn run(cli: Cli) -> anyhow::Result<()> {
    v2x_protocol::net::init_logging("info,zenoh=warn");
    if !(cli.wait_s >= 0.0 && cli.wait_s.is_finite()) {
        bail!("--wait-s must be >= 0");
    }
    if let Some(topic) = &cli.ros_topic {
        return run_ros(&cli, topic).await;
    }
    let clock = replay_clock(&cli);
    let missing = cli
        .default_std
        .map_or(MissingStd::Error, MissingStd::Default);
    let path = cli
        .results
        .clone()
        .expect("clap requires a results file without --ros-topic");
    let results = read_results(&path, &mut TokenTable::new(), missing)?;
    // Files of agents with their own phases (`v2x-sim gen --phase-ms`) name the data time their
    // replay starts from, so that every agent keeps its offset.
    let clock = match clock {
        ReplayClock::Real { start_us, .. } => ReplayClock::Real {
            start_us,
            data_start_us: results
                .meta
                .get("v2x_data_start_us")
                .and_then(|v| v.as_u64()),
        },
        c => c,
    };
    let frames = frames_of(&cli, results)?;
    let (session, mut agent) = start(&cli).await?;
    let wait = Duration::from_secs_f64(cli.wait_s);
    match cli.tiles.tiling {
        None => agent.wait_for_subscriber(wait).await?,
        Some(tiling) => {
            // Wait for the fuser of the tile the first frame's boxes are centred on.
            let home = frames.first().map_or([0.0; 3], |f| f.origin);
            agent = agent.with_tiling(tiling);
            agent
                .wait_for_subscriber_in(tiling.tile_of(home), wait)
                .await?;
        }
    }
    let n = frames.len();
    let report = replay(
        &mut agent,
        frames,
        cli.replay.replay.speed,
        clock,
        v2x_protocol::net::shutdown_signal(),
    )
    .await?;
    // Let delayed publications leave before closing.
    tokio::time::sleep(Duration::from_millis(
        (cli.link.link.latency_ms + cli.link.link.jitter_ms) as u64 + 200,
    ))
    .await;
    let t = agent.counters().totals();
    eprintln!(
        "{}: sent {} of {n} frames ({} skipped: their time had passed; {} dropped by the link), {} payload bytes",
        cli.name, report.sent, report.skipped, t.dropped, t.payload_bytes
    );
    close(session, agent).await
}

/// `--link`: the simulated link and the seed it is drawn with.
#[derive(Clone, Debug)]
struct LinkArg {
    link: Link,
    seed: u64,
}

/// `--link`: the link's table (its `seed` key apart, 1 when left out), checked.
fn parse_link(s: &str) -> Result<LinkArg, String> {
    let mut seed = None;
    let mut rest = Vec::new();
    for part in s.split(',') {
        match part.trim().strip_prefix("seed=") {
            Some(v) if seed.is_none() => {
                seed = Some(
                    v.trim()
                        .parse()
                        .map_err(|_| format!("seed: expected a whole number, got '{v}'"))?,
                )
            }
            Some(_) => return Err("'seed' is given twice".into()),
            None => rest.push(part),
        }
    }
    let link: Link = v2x_protocol::pairs::from_pairs(&rest.join(","))?;
    link.validate().map_err(|e| e.to_string())?;
    Ok(LinkArg {
        link,
        seed: seed.unwrap_or(1),
    })
}

/// Withdraws the agent, then closes its session.
async fn close(session: zenoh::Session, agent: Agent) -> anyhow::Result<()> {
    drop(agent);
    session
        .close()
        .await
        .map_err(|e| anyhow!("closing the session: {e}"))
}

/// The agent's session and the agent on it, with its simulated link and its wire.
async fn start(cli: &Cli) -> anyhow::Result<(zenoh::Session, Agent)> {
    let link = cli.link.link.clone();
    let session = open_session(&cli.zenoh).await?;
    let mut agent = Agent::start(
        &session,
        &cli.ns.ns,
        &cli.name,
        cli.kind,
        link,
        cli.link.seed,
    )
    .await?;
    if cli.wire == Wire::Cpm {
        agent = agent.sending_cpm(cli.map_origin.geo);
    }
    Ok((session, agent))
}

/// Sends what a ROS 2 detector publishes on `topic` until Ctrl-C or SIGTERM.
async fn run_ros(cli: &Cli, topic: &str) -> anyhow::Result<()> {
    let input = v2x_agent::ros_in::RosInput {
        topic: topic.to_string(),
        kind: cli.ros_type,
        layout: cli.ros.layout,
        domain: cli.ros.domain,
        transform: cli.tf,
        // A detector's message without a covariance: its boxes take --default-std, else mild.
        default_std: cli
            .default_std
            .unwrap_or(v2x_protocol::NoiseProfile::Mild.std()),
    };
    let key = input.key()?;
    let (session, mut agent) = start(cli).await?;
    agent
        .wait_for_subscriber(Duration::from_secs_f64(cli.wait_s))
        .await?;
    tracing::info!("{}: forwarding {key}", cli.name);
    let r = v2x_agent::ros_in::forward(
        &mut agent,
        &session,
        &input,
        v2x_protocol::net::shutdown_signal(),
    )
    .await?;
    tokio::time::sleep(Duration::from_millis(200)).await;
    eprintln!(
        "{}: {} messages heard on {key}, {} not the type expected; {} frames sent; {} boxes left out",
        cli.name, r.messages, r.undecodable, r.sent, r.skipped
    );
    close(session, agent).await
}

/// A static transform from a JSON file: `translation` [x, y, z] and `rotation` [x, y, z, w].
/// `--tf`: four numbers, else the JSON file of that name.
fn parse_tf(s: &str) -> anyhow::Result<v2x_ros::convert::Transform> {
    if s.contains(',') {
        return s.parse().map_err(|e| anyhow!("{e}"));
    }
    transform_file(std::path::Path::new(s))
}

fn transform_file(path: &std::path::Path) -> anyhow::Result<v2x_ros::convert::Transform> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    let numbers = |field: &str, n: usize| -> anyhow::Result<Vec<f64>> {
        let list = v[field].as_array().filter(|a| a.len() == n).and_then(|a| {
            a.iter()
                .map(|x| x.as_f64().filter(|x| x.is_finite()))
                .collect::<Option<Vec<_>>>()
        });
        list.ok_or_else(|| anyhow!("{}: `{field}` must be {n} numbers", path.display()))
    };
    let t = numbers("translation", 3)?;
    let q = numbers("rotation", 4)?;
    Ok(v2x_ros::convert::Transform {
        translation: [t[0], t[1], t[2]],
        yaw: v2x_protocol::nuscenes_json::quaternion_yaw([q[3], q[0], q[1], q[2]]),
    })
}

/// The clock a replay runs on, from --replay's clock and start_at (checked when parsed).
fn replay_clock(cli: &Cli) -> ReplayClock {
    let r = cli.replay.replay;
    match r.clock {
        v2x_protocol::cli::ReplayClock::Data => ReplayClock::Data,
        v2x_protocol::cli::ReplayClock::Real => ReplayClock::Real {
            start_us: r.start_at.map_or_else(now_us, |t| (t * 1e6) as u64),
            data_start_us: None,
        },
    }
}

/// The file's samples as frames in capture order, each at its time: from --sample-table, else
/// the file's meta.v2x_timestamps, else in token order at --hz.
fn frames_of(cli: &Cli, results: Results) -> anyhow::Result<Vec<Frame>> {
    let mut times: HashMap<String, u64> = match &cli.sample_table {
        Some(p) => timestamps(p)?,
        None => results
            .meta
            .get("v2x_timestamps")
            .and_then(|m| m.as_object())
            .map(|m| {
                m.iter()
                    .filter_map(|(k, v)| Some((k.clone(), v.as_u64()?)))
                    .collect()
            })
            .unwrap_or_default(),
    };
    if times.is_empty() {
        let hz = cli.replay.replay.hz;
        tracing::warn!("no timestamps known: sending samples in token order at {hz} Hz");
        for (i, s) in results.samples.keys().enumerate() {
            times.insert(s.clone(), (i as f64 * 1e6 / hz) as u64);
        }
    }
    let mut frames = Vec::new();
    for (token, dets) in results.samples {
        let t = *times.get(&token).ok_or_else(|| {
            anyhow!(
                "{}: sample '{token}' has no timestamp in the sample table",
                cli.results
                    .as_deref()
                    .unwrap_or(std::path::Path::new(""))
                    .display()
            )
        })?;
        frames.push(
            Frame {
                agent: cli.name.clone(),
                kind: cli.kind,
                seq: 0,
                capture_us: t,
                origin: [0.0; 3],
                detections: dets,
            }
            .with_centroid_origin(),
        );
    }
    frames.sort_by_key(|f| f.capture_us);
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_link_takes_its_seed_and_refuses_a_bad_key() {
        let l = parse_link("latency_ms=20,seed=3,drop_rate=0.1").unwrap();
        assert_eq!(
            (l.link.latency_ms, l.link.drop_rate, l.seed),
            (20.0, 0.1, 3)
        );
        assert_eq!(parse_link("").unwrap().seed, 1);
        assert!(parse_link("seed=x").unwrap_err().starts_with("seed:"));
        assert!(parse_link("seed=1,seed=2").unwrap_err().contains("twice"));
        assert!(parse_link("sed=3").unwrap_err().contains("sed"));
        assert!(parse_link("drop_rate=2").unwrap_err().contains("drop_rate"));
    }
}
