//! The node's wiring on its Zenoh session: the worker's start, the fused frames' publishers
//! and the detections' subscribers (per agent or per tile).

use super::*;

/// Starts the worker that fuses, tracks and publishes the closed windows; with the subscriptions
/// to the neighbours' tracks of a regional fuser that hands tracks over.
pub(super) async fn start_worker(
    session: &zenoh::Session,
    cfg: &NodeConfig,
    publisher: zenoh::pubsub::Publisher<'static>,
    clock: Clock,
    jobs: mpsc::Receiver<worker::Job>,
    done: mpsc::UnboundedSender<worker::Done>,
) -> anyhow::Result<(
    tokio::task::JoinHandle<()>,
    Vec<zenoh::pubsub::Subscriber<()>>,
)> {
    let fk = cfg.scope().keys(&cfg.ns);
    let tracks = match cfg.track {
        Some(_) => Some(declare_frames(session, &fk.tracks, "tracks publisher").await?),
        None => None,
    };
    // A regional fuser that tracks hears its neighbours' tracks, to keep ids across borders.
    let (heard, handover) = match (cfg.scope(), cfg.track) {
        (Scope::Tile(r), Some(_)) if cfg.handover => {
            let (heard, subs) = handover::subscribe(session, &cfg.ns, &r).await?;
            (Some(heard), subs)
        }
        _ => (None, Vec::new()),
    };
    let fusion = worker::Fusion {
        steps: cfg.steps.clone(),
        track: cfg.track,
        scope: cfg.scope(),
        heard,
    };
    let worker = tokio::spawn(worker::run(fusion, publisher, tracks, clock, jobs, done));
    Ok((worker, handover))
}

/// Zenoh's errors say what failed, not where: each names its operation and key.
pub(super) fn z(what: &'static str, key: String) -> impl FnOnce(zenoh::Error) -> anyhow::Error {
    move |e| anyhow!("cannot declare the {what} on {key}: {e}")
}

/// A publisher of encoded frames on `key`.
pub(super) async fn declare_frames(
    session: &zenoh::Session,
    key: &str,
    what: &'static str,
) -> anyhow::Result<zenoh::pubsub::Publisher<'static>> {
    session
        .declare_publisher(key.to_owned())
        .encoding(v2x_protocol::net::frame_encoding())
        .await
        .map_err(z(what, key.to_owned()))
}

/// The detections' subscription: every agent's key, or (a region) one per tile within the
/// halo feeding one queue, whose overflow is counted; with the tiles subscribed.
pub(super) async fn subscribe_detections(
    session: &zenoh::Session,
    cfg: &NodeConfig,
    overflow: Arc<std::sync::atomic::AtomicU64>,
) -> anyhow::Result<(Inbox, Vec<v2x_protocol::tiles::Tile>)> {
    let ns = &cfg.ns;
    let Scope::Tile(r) = cfg.scope() else {
        let key = keys::all_detections(ns);
        let sub = session
            .declare_subscriber(key.clone())
            .await
            .map_err(z("detections subscriber", key))?;
        return Ok((Inbox::Whole(sub), Vec::new()));
    };
    let tiles = r.tiling.with_halo(r.tile, r.halo_m);
    let (tx, rx) = mpsc::channel(INBOX);
    let mut subs = Vec::new();
    for t in &tiles {
        let (tx, overflow) = (tx.clone(), overflow.clone());
        let key = keys::tile_detections(ns, *t);
        subs.push(
            session
                .declare_subscriber(key.clone())
                .callback(move |s| {
                    if tx.try_send(s).is_err() {
                        overflow.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    }
                })
                .await
                .map_err(z("detections subscriber", key))?,
        );
    }
    Ok((Inbox::Tiles { rx, _subs: subs }, tiles))
}
