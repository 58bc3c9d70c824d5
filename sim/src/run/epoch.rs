//! The shared start of a run across hosts: the fuser role fixes an epoch and answers it on
//! `v2x/NS/sim/epoch`; agent roles ask for it before they replay.

use anyhow::{anyhow, bail};
use std::time::Duration;

/// Answers `v2x/NS/sim/epoch` with `epoch_us` until the returned task is aborted.
pub async fn serve_epoch(
    session: &zenoh::Session,
    ns: &str,
    epoch_us: u64,
) -> anyhow::Result<tokio::task::JoinHandle<()>> {
    let key = v2x_protocol::keys::sim_epoch(ns);
    let queryable = session
        .declare_queryable(&key)
        .await
        .map_err(|e| anyhow!("cannot declare the epoch queryable on {key}: {e}"))?;
    Ok(tokio::spawn(async move {
        while let Ok(q) = queryable.recv_async().await {
            let _ = q
                .reply(&key, epoch_us.to_string())
                .encoding(zenoh::bytes::Encoding::TEXT_PLAIN)
                .await;
        }
    }))
}

/// Asks the fuser role for the epoch, retrying until `timeout`.
pub async fn query_epoch(
    session: &zenoh::Session,
    ns: &str,
    timeout: Duration,
) -> anyhow::Result<u64> {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        if let Ok(replies) = session
            .get(v2x_protocol::keys::sim_epoch(ns))
            .timeout(Duration::from_secs(1))
            .await
        {
            while let Ok(r) = replies.recv_async().await {
                if let Ok(s) = r.result() {
                    if let Ok(t) = String::from_utf8_lossy(&s.payload().to_bytes()).parse::<u64>() {
                        return Ok(t);
                    }
                }
            }
        }
        if tokio::time::Instant::now() > deadline {
            bail!(
                "no fuser answered {} within {timeout:?}: is the fuser role running and reachable?",
                v2x_protocol::keys::sim_epoch(ns)
            );
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}
