//! Bandwidth as Zenoh itself counts it, on every host: each role's session is opened with Zenoh's
//! transport statistics on (counting puts per key of interest: an agent its own detections, the
//! fuser and the router every agent's detections and the fuser's outputs), and the fuser role
//! samples its own once a second for the timeline.

use super::secure::Role;
use crate::scenario::Scenario;
use std::time::Duration;
use tokio::sync::watch;
use v2x_agent::now_us;
use v2x_protocol::keys;
use v2x_protocol::net::{open_counted_session, ZenohArgs};
use v2x_protocol::traffic::{traffic, Traffic};

/// How long a statistics query may take.
pub const QUERY_TIMEOUT: Duration = Duration::from_secs(2);

/// The keys whose puts a role's session counts.
pub fn role_keys(scenario: &Scenario, role: Role) -> Vec<String> {
    let ns = &scenario.namespace;
    match role {
        Role::Agent(a) => vec![agent_key(scenario, a)],
        Role::Fuser | Role::Router => {
            let mut k: Vec<String> = scenario
                .agents
                .iter()
                .map(|a| agent_key(scenario, &a.name))
                .collect();
            let out = keys::FuserKeys::of(ns, None);
            match scenario.regions {
                None => k.extend([out.fused, out.tracks]),
                Some(_) => {
                    let any = keys::FuserKeys::any_region(ns);
                    k.extend([any.fused, any.tracks]);
                }
            }
            k
        }
    }
}

/// The key (expression) an agent's detections go out on: `v2x/NS/det/AGENT`, or in a city
/// every tile's, `v2x/NS/det/*/AGENT`.
pub fn agent_key(scenario: &Scenario, agent: &str) -> String {
    match scenario.regions {
        None => keys::detections(&scenario.namespace, agent),
        Some(_) => format!("{}/{}/det/*/{agent}", keys::ROOT, scenario.namespace),
    }
}

/// Opens a role's session with its statistics on.
pub async fn open_role_session(
    args: &ZenohArgs,
    scenario: &Scenario,
    role: Role<'_>,
) -> anyhow::Result<zenoh::Session> {
    Ok(open_counted_session(args, &role_keys(scenario, role)).await?)
}

/// The session's traffic now, or `None` (with a warning) if Zenoh did not say.
pub async fn snapshot(session: &zenoh::Session, who: &str) -> Option<Traffic> {
    match traffic(session, QUERY_TIMEOUT).await {
        Ok(t) => Some(t),
        Err(e) => {
            tracing::warn!("{who}: {e}");
            None
        }
    }
}

/// Samples a session's traffic every second (wall clock, us) until `stop` turns true.
pub fn sample_every_second(
    session: zenoh::Session,
    mut stop: watch::Receiver<bool>,
) -> tokio::task::JoinHandle<Vec<(u64, Traffic)>> {
    tokio::spawn(async move {
        let mut out = Vec::new();
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        loop {
            tokio::select! {
                _ = tick.tick() => {}
                _ = stop.wait_for(|s| *s) => break,
            }
            if let Ok(t) = traffic(&session, QUERY_TIMEOUT).await {
                out.push((now_us(), t));
            }
        }
        if let Ok(t) = traffic(&session, QUERY_TIMEOUT).await {
            out.push((now_us(), t));
        }
        out
    })
}
