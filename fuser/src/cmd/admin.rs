//! `v2x-fuser router` and `stats`: a Zenoh router for the secure mode, and a running node's
//! statistics.

use v2x_fuser::node;

/// The options of `v2x-fuser router`.
#[derive(clap::Args)]
pub(crate) struct RouterArgs {
    #[command(flatten)]
    pub(crate) zenoh: v2x_protocol::net::ZenohArgs,
}

/// The options of `v2x-fuser stats`.
#[derive(clap::Args)]
pub(crate) struct StatsArgs {
    #[command(flatten)]
    pub(crate) ns: v2x_protocol::net::Namespace,
    /// Ask the regional fuser of this tile (COLUMN_ROW) instead of the single fuser.
    #[arg(long)]
    pub(crate) tile: Option<v2x_protocol::tiles::Tile>,
    /// How long to wait for an answer (s).
    #[arg(long, default_value_t = 5.0)]
    pub(crate) timeout_s: f64,
    #[command(flatten)]
    pub(crate) zenoh: v2x_protocol::net::ZenohArgs,
}

/// `v2x-fuser router`.
pub(crate) fn router(args: RouterArgs) -> anyhow::Result<()> {
    let RouterArgs { mut zenoh } = args;
    if zenoh.mode.is_none() {
        zenoh.mode = Some("router".into());
    }
    let rt = v2x_protocol::net::runtime()?;
    rt.block_on(async move {
        let config = v2x_protocol::net::config(&zenoh)?;
        let secure = config
            .get_json("access_control/enabled")
            .is_ok_and(|v| v == "true");
        let session = zenoh::open(config)
            .await
            .map_err(|e| anyhow::anyhow!("cannot start the router: {e}"))?;
        eprintln!(
            "router {} running ({}); Ctrl-C or SIGTERM stops it",
            session.zid(),
            if secure {
                "access control on"
            } else {
                "no access control: any client may publish anything"
            }
        );
        v2x_protocol::net::shutdown_signal().await;
        session
            .close()
            .await
            .map_err(|e| anyhow::anyhow!("closing the router: {e}"))?;
        Ok(())
    })
}

/// `v2x-fuser stats`.
pub(crate) fn stats(args: StatsArgs) -> anyhow::Result<()> {
    let StatsArgs {
        ns,
        tile,
        timeout_s,
        zenoh,
    } = args;
    let rt = v2x_protocol::net::runtime()?;
    rt.block_on(async move {
        let session = v2x_protocol::net::open_session(&zenoh).await?;
        let key = v2x_protocol::keys::FuserKeys::of(&ns.ns, tile).stats;
        let v = node::query_stats_at(
            &session,
            &key,
            std::time::Duration::from_secs_f64(timeout_s),
        )
        .await?;
        println!("{}", serde_json::to_string_pretty(&v)?);
        Ok(())
    })
}
