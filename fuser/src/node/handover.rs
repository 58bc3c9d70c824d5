//! The network side of the tracks' hand-over between regions (`crate::tracker::handover`): a
//! regional fuser that tracks subscribes to the tracks its neighbours publish
//! (`v2x/NS/tracks/TILE` for every other tile reaching into its halo) and keeps the latest
//! frame of each for the worker, which hands them to its [`Handover`] before each window.
//!
//! [`Handover`]: crate::tracker::handover::Handover

use crate::intake::region::Region;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use v2x_protocol::tiles::Tile;
use v2x_protocol::{keys, wire, Detection};

/// The latest tracks heard from each neighbour: its window's time and its tracks.
pub(super) type Heard = Arc<Mutex<BTreeMap<Tile, (u64, Vec<Detection>)>>>;

/// The neighbours' tracks subscriptions (held for the node's life) and what they hear.
pub(super) type Subscriptions = (Heard, Vec<zenoh::pubsub::Subscriber<()>>);

/// Subscribes to the tracks of every tile but `region`'s own that reaches into its halo.
pub(super) async fn subscribe(
    session: &zenoh::Session,
    ns: &str,
    region: &Region,
) -> anyhow::Result<Subscriptions> {
    let heard: Heard = Arc::default();
    let mut subs = Vec::new();
    for tile in region.tiling.with_halo(region.tile, region.halo_m) {
        if tile == region.tile {
            continue;
        }
        let key = keys::FuserKeys::of(ns, Some(tile)).tracks;
        let into = heard.clone();
        let sub = session
            .declare_subscriber(key.clone())
            .callback(move |s| {
                // Only fusers may publish tracks; a frame that does not decode is dropped.
                match wire::decode(&s.payload().to_bytes()) {
                    Ok(f) => {
                        let mut heard = into.lock().unwrap_or_else(|e| e.into_inner());
                        heard.insert(tile, (f.capture_us, f.detections));
                    }
                    Err(e) => tracing::debug!("tracks of tile {tile} do not decode: {e}"),
                }
            })
            .await
            .map_err(|e| {
                anyhow::anyhow!("cannot subscribe to the neighbours' tracks on {key}: {e}")
            })?;
        subs.push(sub);
    }
    Ok((heard, subs))
}

/// Takes what was heard since the last window.
pub(super) fn drain(heard: &Heard) -> Vec<(Tile, u64, Vec<Detection>)> {
    let mut heard = heard.lock().unwrap_or_else(|e| e.into_inner());
    std::mem::take(&mut *heard)
        .into_iter()
        .map(|(tile, (t, tracks))| (tile, t, tracks))
        .collect()
}
