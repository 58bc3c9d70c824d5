//! `v2x-fuser node`: the fuser on the network, its options and its run.

use std::path::PathBuf;
use v2x_fuser::node;
use v2x_protocol::nuscenes_json::{
    default_meta, provenance_json, write_results, Results, TokenTable,
};

use super::settings::*;

/// The options of `v2x-fuser node`.
#[derive(clap::Args)]
pub(crate) struct NodeArgs {
    #[command(flatten)]
    pub(crate) ns: v2x_protocol::net::Namespace,
    #[command(flatten)]
    pub(crate) settings: Box<v2x_fuser::settings::FuserSettings>,
    #[command(flatten)]
    pub(crate) region: RegionArgs,
    /// With --track and --tile: do not hear the neighbouring regions' tracks, so that an object
    /// crossing into this tile starts a track of this region's own (by default it keeps the id
    /// its neighbour gave it; docs/method.md §9.1).
    #[arg(long, requires_all = ["track", "tile"])]
    pub(crate) no_track_handover: bool,
    #[command(flatten)]
    pub(crate) map_origin: v2x_cpm::MapOrigin,
    #[command(flatten)]
    pub(crate) ros: node::ros_out::RosOutArgs,
    /// Record the fused output as a nuScenes results file (keys t<capture us>), scorable by
    /// `v2x-sim eval` against the same ground truth; each frame's provenance (window agents,
    /// completeness, every box's source agents) goes in meta.v2x_provenance.
    #[arg(long)]
    pub(crate) record: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) viz: v2x_fuser::viz::VizArgs,
    /// Stop after this many seconds (default: run until Ctrl-C or SIGTERM, which both write
    /// the recording and print the final statistics).
    #[arg(long)]
    pub(crate) duration_s: Option<f64>,
    #[command(flatten)]
    pub(crate) zenoh: v2x_protocol::net::ZenohArgs,
}

/// `v2x-fuser node`.
pub(crate) fn run_node(args: NodeArgs) -> anyhow::Result<()> {
    let NodeArgs {
        ns,
        settings,
        region,
        no_track_handover,
        map_origin,
        ros,
        record,
        viz,
        duration_s,
        zenoh,
    } = args;
    let rt = v2x_protocol::net::runtime()?;
    rt.block_on(async move {
        if let Some(s) = duration_s {
            if !(s > 0.0 && s.is_finite()) {
                anyhow::bail!("--duration-s must be > 0");
            }
        }
        let mut cfg = settings.node_config(&ns.ns).map_err(flag_error)?;
        cfg.region = region.region()?;
        cfg.handover = !no_track_handover;
        cfg.map_origin = map_origin.geo;
        cfg.viz = viz.open().await?;
        let shown = cfg.viz.clone();
        let session = v2x_protocol::net::open_session(&zenoh).await?;
        let mut recorded = Results::default();
        let mut provenance = serde_json::Map::new();
        let stop = async move {
            match duration_s {
                Some(s) => tokio::select! {
                    _ = tokio::time::sleep(std::time::Duration::from_secs_f64(s)) => {}
                    _ = node::shutdown_signal() => {}
                },
                None => node::shutdown_signal().await,
            }
        };
        let mut ros_out = ros.open(&session).await?;
        let stats = node::run(
            &session,
            cfg,
            |f| {
                if let Some(r) = ros_out.as_mut() {
                    r.publish(f);
                }
                if record.is_some() {
                    let sample = format!("t{}", f.frame.capture_us);
                    provenance.insert(sample.clone(), provenance_json(&f.provenance));
                    recorded.samples.insert(sample, f.frame.detections.clone());
                }
            },
            stop,
        )
        .await?;
        if let Some(v) = shown {
            v.close()?;
        }
        if let Some(path) = &record {
            let mut meta = default_meta();
            meta["v2x_provenance"] = serde_json::Value::Object(provenance);
            if !stats.learned_std.is_empty() {
                meta["v2x_learned_std"] = serde_json::to_value(&stats.learned_std)?;
            }
            recorded.meta = meta;
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
