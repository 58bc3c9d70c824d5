//! The statistics key: the node's answer to a query, and a client's question to a running
//! fuser.

use super::NodeStats;
use anyhow::anyhow;
use std::time::Duration;
use v2x_protocol::keys;
use zenoh::bytes::Encoding;

/// Answers a statistics query with `stats` as JSON.
pub(super) async fn reply_stats(q: &zenoh::query::Query, key: &str, stats: &NodeStats) {
    match serde_json::to_vec(stats) {
        Ok(body) => {
            if let Err(e) = q
                .reply(key.to_owned(), body)
                .encoding(Encoding::APPLICATION_JSON)
                .await
            {
                tracing::warn!("stats reply failed: {e}");
            }
        }
        Err(e) => tracing::warn!("stats do not serialize: {e}"),
    }
}

/// Asks a running fuser for its statistics.
pub async fn query_stats(
    session: &zenoh::Session,
    ns: &str,
    timeout: Duration,
) -> anyhow::Result<serde_json::Value> {
    query_stats_at(session, &keys::fuser_stats(ns), timeout).await
}

/// Asks the fuser answering on `key` (a [`keys::FuserKeys::stats`]) for its statistics.
pub async fn query_stats_at(
    session: &zenoh::Session,
    key: &str,
    timeout: Duration,
) -> anyhow::Result<serde_json::Value> {
    let replies = session
        .get(key)
        .timeout(timeout)
        .await
        .map_err(|e| anyhow!("cannot query {key}: {e}"))?;
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            return Ok(serde_json::from_slice(&sample.payload().to_bytes())?);
        }
    }
    anyhow::bail!("no fuser answered on {key} within {timeout:?}")
}
