//! A city in one process (`[regions]` in the scenario): meshed Zenoh routers, one regional fuser
//! per tile as a client of its router, and the agents, publishing per tile, each a client of the
//! router of the tile it starts in (of the first router when that tile has no fuser). Every
//! router listens on a free local port and meshes with the first. The regions' fused windows are
//! joined by reference time into one outcome, scored like a single fuser's, and each region's
//! own figures are reported beside it ([`RegionReport`]).

use super::meter;
use super::roles::{absorb, agent_role, agent_view, regional_fuser_role, FuserOutcome};
use super::summary::{summarize, AgentSide, RegionReport, Summary};
use super::{free_port, stopped, Schedule};
use crate::dataset::GroundTruth;
use crate::scenario::{RegionFuserSpec, RegionsSpec, Scenario};
use anyhow::Context;
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::sync::watch;
use v2x_agent::now_us;
use v2x_fuser::intake::region::Region;
use v2x_fuser::node::Latency;
use v2x_protocol::keys::FuserKeys;
use v2x_protocol::net::{open_session, ZenohArgs};

/// The router each agent is a client of: the router of the fuser of the tile it starts in, or
/// the first router.
pub fn agent_routers(
    scenario: &Scenario,
    regions: &RegionsSpec,
    gt: &GroundTruth,
    schedule: &Schedule,
) -> Vec<usize> {
    let tiling = regions.tiling();
    (0..scenario.agents.len())
        .map(|idx| {
            let first = super::agent_captures(scenario, gt, schedule, idx)
                .first()
                .copied();
            let home = first.map(|t| {
                let noise = scenario.agents[idx].agent_noise();
                tiling.tile_of(agent_view(scenario, gt, schedule, idx, 0, t, &noise).1)
            });
            regions
                .regions()
                .iter()
                .zip(&regions.fusers)
                .find(|(r, _)| Some(r.tile) == home)
                .and_then(|(_, f)| regions.router(&f.router))
                .unwrap_or(0)
        })
        .collect()
}

/// Joins the regions' outcomes: fused boxes, tracks and windows by reference time, counters
/// added.
pub fn join(outcomes: Vec<FuserOutcome>) -> FuserOutcome {
    let mut it = outcomes.into_iter();
    let mut all = it.next().unwrap_or_default();
    for o in it {
        for (t, dets) in o.fused {
            all.fused.entry(t).or_default().extend(dets);
        }
        for (t, dets) in o.tracks {
            all.tracks.entry(t).or_default().extend(dets);
        }
        for (t, w) in o.windows {
            match all.windows.get_mut(&t) {
                None => {
                    all.windows.insert(t, w);
                }
                Some(e) => {
                    for (a, n) in w.agents.iter().zip(&w.objects) {
                        match e.agents.iter().position(|x| x == a) {
                            Some(i) => e.objects[i] += n,
                            None => {
                                e.agents.push(a.clone());
                                e.objects.push(*n);
                            }
                        }
                    }
                    e.complete &= w.complete;
                    e.e2e_ms = e.e2e_ms.max(w.e2e_ms);
                }
            }
        }
        all.reached_us = all.reached_us.min(o.reached_us);
        all.stats.captures_incomplete += o.stats.captures_incomplete;
        all.stats.inbox_overflow += o.stats.inbox_overflow;
        absorb(&mut all.stats, o.stats);
    }
    // The windows of the city: one per reference time, whichever regions fused it.
    all.stats.windows = all.windows.len() as u64;
    all.stats.windows_incomplete = all.windows.values().filter(|w| !w.complete).count() as u64;
    let e2e: Vec<f64> = all.windows.values().map(|w| w.e2e_ms).collect();
    all.stats.e2e_latency_ms = Latency::of(&e2e);
    all.stats.fusion_latency_ms = Latency::of(&all.stats.fusion_samples);
    all
}

/// Runs a city scenario in this process; returns the joined summary and outcome, and each
/// region's report.
pub async fn run_city_local(
    scenario: &Scenario,
    gt: &GroundTruth,
    stop: watch::Receiver<bool>,
) -> anyhow::Result<(Summary, FuserOutcome, Vec<RegionReport>)> {
    let regions = scenario.regions.as_ref().context("not a city scenario")?;
    let schedule = Schedule::of(gt, scenario.duration_s);
    let start = std::time::Instant::now();
    let (routers, endpoints) = open_routers(regions).await?;
    let client = |router: usize| ZenohArgs {
        mode: Some("client".into()),
        connect: vec![endpoints[router].clone()],
        ..Default::default()
    };
    let epoch = now_us() + 1_500_000;
    let (done_tx, done_rx) = watch::channel(false);
    let max_wait = scenario.fuser.settings.max_wait_ms;
    let mut fusers = Vec::new();
    for (k, (f, region)) in regions.fusers.iter().zip(regions.regions()).enumerate() {
        let router = regions.router(&f.router).expect("checked");
        let session = open_session(&client(router)).await?;
        let (done, stop) = (done_rx.clone(), stop.clone());
        let until = async move {
            tokio::select! {
                _ = stopped(done) => {}
                _ = stopped(stop) => {}
            }
            tokio::time::sleep(Duration::from_secs_f64(max_wait / 1000.0 + 0.3)).await;
        };
        let (scenario, schedule) = (scenario.clone(), schedule.clone());
        fusers.push(tokio::spawn(async move {
            let first = k == 0;
            let o = regional_fuser_role(
                &session,
                &scenario,
                &schedule,
                epoch,
                Some(region),
                first,
                None,
                until,
            )
            .await;
            let _ = session.close().await;
            o
        }));
    }
    wait_for_fusers(&routers[0], scenario, regions).await?;
    let homes = agent_routers(scenario, regions, gt, &schedule);
    let sessions = agent_sessions(scenario, &homes, &endpoints).await?;
    let results = super::roles::all_agents(&sessions, scenario, gt, &schedule, epoch, &stop).await;
    let _ = done_tx.send(true);
    let mut outcomes = Vec::new();
    let mut reports = Vec::new();
    for (task, f) in fusers.into_iter().zip(&regions.fusers) {
        let o = task
            .await
            .context("a regional fuser panicked")?
            .with_context(|| format!("the fuser of tile {}", f.tile))?;
        reports.push(RegionReport::of(&f.tile, &f.router, &o));
        outcomes.push(o);
    }
    let totals = agent_sides(scenario, results, &sessions).await?;
    for s in sessions {
        let _ = s.close().await;
    }
    for r in routers.into_iter().rev() {
        let _ = r.close().await;
    }
    let outcome = join(outcomes);
    let wall_s = start.elapsed().as_secs_f64();
    let mut summary = summarize(scenario, gt, &schedule, &outcome, &totals, wall_s);
    summary.regions = reports.clone();
    Ok((summary, outcome, reports))
}

/// Each agent's session, a client of its home router (of those listening on `endpoints`).
async fn agent_sessions(
    scenario: &Scenario,
    homes: &[usize],
    endpoints: &[String],
) -> anyhow::Result<Vec<zenoh::Session>> {
    let mut sessions = Vec::new();
    for (a, &r) in scenario.agents.iter().zip(homes) {
        let args = ZenohArgs {
            mode: Some("client".into()),
            connect: vec![endpoints[r].clone()],
            ..Default::default()
        };
        let role = super::secure::Role::Agent(&a.name);
        sessions.push(meter::open_role_session(&args, scenario, role).await?);
    }
    Ok(sessions)
}

/// Each agent's totals and what its session sent, by name.
async fn agent_sides(
    scenario: &Scenario,
    results: Vec<anyhow::Result<v2x_agent::AgentTotals>>,
    sessions: &[zenoh::Session],
) -> anyhow::Result<BTreeMap<String, AgentSide>> {
    let mut totals = BTreeMap::new();
    for ((a, r), session) in scenario.agents.iter().zip(results).zip(sessions) {
        totals.insert(
            a.name.clone(),
            AgentSide {
                totals: r.with_context(|| format!("agent {}", a.name))?,
                sent: meter::snapshot(session, &a.name).await,
                socket_bytes: None,
            },
        );
    }
    Ok(totals)
}

/// The city's routers: each listens on a free port and every other one meshes with the first;
/// with their endpoints.
async fn open_routers(regions: &RegionsSpec) -> anyhow::Result<(Vec<zenoh::Session>, Vec<String>)> {
    // Routers: each listens on a free port; every other router meshes with the first.
    let mut endpoints = Vec::new();
    let mut routers = Vec::new();
    for i in 0..regions.routers.len() {
        let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
        let args = ZenohArgs {
            mode: Some("router".into()),
            listen: vec![endpoint.clone()],
            connect: endpoints.first().cloned().into_iter().collect(),
            no_multicast_scouting: true,
            zenoh_config: None,
        };
        let name = &regions.routers[i].name;
        routers.push(
            open_session(&args)
                .await
                .with_context(|| format!("router {name}"))?,
        );
        endpoints.push(endpoint);
    }
    Ok((routers, endpoints))
}

/// Waits until every regional fuser is up (its liveliness token reaches `router`), 20 s at most
/// each.
async fn wait_for_fusers(
    router: &zenoh::Session,
    scenario: &Scenario,
    regions: &RegionsSpec,
) -> anyhow::Result<()> {
    // Every regional fuser is up (its liveliness token reaches the first router) before the
    // agents start.
    for f in &regions.fusers {
        let tile = f.tile.parse().expect("checked");
        let key = FuserKeys::of(&scenario.namespace, Some(tile)).alive;
        let up = async {
            loop {
                let replies = router
                    .liveliness()
                    .get(&key)
                    .timeout(Duration::from_secs(1))
                    .await;
                if let Ok(r) = replies {
                    if r.recv_async().await.is_ok() {
                        return;
                    }
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        };
        tokio::time::timeout(Duration::from_secs(20), up)
            .await
            .with_context(|| format!("the fuser of tile {tile} did not come up within 20 s"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;

/// How long a role on its own host keeps trying to reach its router.
const CONNECT_FOR: Duration = Duration::from_secs(30);

/// Opens a session, retrying for [`CONNECT_FOR`] while its router is not up yet.
async fn open_retrying(args: &ZenohArgs) -> anyhow::Result<zenoh::Session> {
    let deadline = tokio::time::Instant::now() + CONNECT_FOR;
    loop {
        match open_session(args).await {
            Ok(s) => return Ok(s),
            Err(e) if tokio::time::Instant::now() >= deadline => return Err(e.into()),
            Err(_) => tokio::time::sleep(Duration::from_millis(200)).await,
        }
    }
}

/// What the roles of a city run on this host did: each regional fuser's report and outcome.
pub struct CityRoles {
    /// The regional fusers run here, in scenario order: tile, report, outcome.
    pub fusers: Vec<(String, RegionReport, FuserOutcome)>,
    /// The agents run here.
    pub agents: BTreeMap<String, AgentSide>,
}

/// The role names of a city: `router-NAME`, `fuser-TILE` and the agents'.
pub fn city_roles(scenario: &Scenario, regions: &RegionsSpec) -> Vec<String> {
    let mut names: Vec<String> = regions
        .routers
        .iter()
        .map(|r| format!("router-{}", r.name))
        .collect();
    names.extend(regions.fusers.iter().map(|f| format!("fuser-{}", f.tile)));
    names.extend(scenario.agents.iter().map(|a| a.name.clone()));
    names
}

/// Runs the named roles of a city with the scenario's endpoints: routers until the other roles
/// here end (a router alone until stopped), regional fusers (the first of the scenario fixes
/// and answers the shared start, the others ask for it), agents.
pub async fn run_city_roles(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    roles: &[String],
    stop: watch::Receiver<bool>,
) -> anyhow::Result<CityRoles> {
    let regions = scenario.regions.as_ref().context("not a city scenario")?;
    let mut routers = Vec::new();
    for r in &regions.routers {
        if roles.contains(&format!("router-{}", r.name)) {
            let args = ZenohArgs {
                mode: Some(r.zenoh.mode.clone().unwrap_or_else(|| "router".into())),
                ..r.zenoh.clone()
            };
            let s = open_session(&args)
                .await
                .with_context(|| format!("router {}", r.name))?;
            eprintln!("router {}: running", r.name);
            routers.push(s);
        }
    }
    let fusers = regions
        .fusers
        .iter()
        .zip(regions.regions())
        .enumerate()
        .filter(|(_, (f, _))| roles.contains(&format!("fuser-{}", f.tile)))
        .map(|(k, (f, region))| city_fuser(scenario, schedule, k, f, region, stop.clone()));
    let agents = scenario
        .agents
        .iter()
        .enumerate()
        .filter(|(_, a)| roles.contains(&a.name))
        .map(|(idx, _)| city_agent(scenario, gt, schedule, idx, stop.clone()));
    let (fusers, agents) = tokio::join!(
        futures::future::join_all(fusers),
        futures::future::join_all(agents)
    );
    let only_routers = roles.iter().all(|r| r.starts_with("router-"));
    if only_routers {
        stopped(stop).await;
    }
    for r in routers {
        let _ = r.close().await;
    }
    Ok(CityRoles {
        fusers: fusers.into_iter().collect::<anyhow::Result<_>>()?,
        agents: agents.into_iter().collect::<anyhow::Result<_>>()?,
    })
}

/// The `k`th regional fuser of a city on its own host: it connects (retrying), fixes the shared
/// start (the first) or asks for it, and runs until the schedule's end or a stop.
async fn city_fuser(
    scenario: &Scenario,
    schedule: &Schedule,
    k: usize,
    f: &RegionFuserSpec,
    region: Region,
    stop: watch::Receiver<bool>,
) -> anyhow::Result<(String, RegionReport, FuserOutcome)> {
    let ns = &scenario.namespace;
    let args = ZenohArgs {
        mode: Some(f.zenoh.mode.clone().unwrap_or_else(|| "client".into())),
        ..f.zenoh.clone()
    };
    let session = open_retrying(&args)
        .await
        .with_context(|| format!("the fuser of tile {}", f.tile))?;
    let epoch = match k {
        0 => now_us() + 3_000_000,
        _ => super::epoch::query_epoch(&session, ns, Duration::from_secs(60)).await?,
    };
    let end = super::fuser_end_us(scenario, schedule, epoch);
    eprintln!(
        "fuser of tile {}: running for {:.1} s",
        f.tile,
        end.saturating_sub(now_us()) as f64 / 1e6
    );
    let until = async move {
        tokio::select! {
            _ = tokio::time::sleep(Duration::from_micros(end.saturating_sub(now_us()))) => {}
            _ = stopped(stop) => {}
        }
    };
    let o = regional_fuser_role(
        &session,
        scenario,
        schedule,
        epoch,
        Some(region),
        k == 0,
        None,
        until,
    )
    .await?;
    let _ = session.close().await;
    Ok((f.tile.clone(), RegionReport::of(&f.tile, &f.router, &o), o))
}

/// Agent `idx` of a city on its own host: it connects to its router (retrying, the router may
/// start after it), asks for the shared start and sends until the schedule's end or a stop.
async fn city_agent(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    idx: usize,
    stop: watch::Receiver<bool>,
) -> anyhow::Result<(String, AgentSide)> {
    let a = &scenario.agents[idx];
    let role = || super::secure::Role::Agent(&a.name);
    let args = super::secure::role_args(scenario, role())?;
    let deadline = tokio::time::Instant::now() + CONNECT_FOR;
    let session = loop {
        match meter::open_role_session(&args, scenario, role()).await {
            Ok(s) => break s,
            Err(e) if tokio::time::Instant::now() >= deadline => {
                return Err(e.context(format!("agent {}", a.name)))
            }
            Err(_) => tokio::time::sleep(Duration::from_millis(200)).await,
        }
    };
    let ns = &scenario.namespace;
    let epoch = super::epoch::query_epoch(&session, ns, Duration::from_secs(60)).await?;
    let totals = agent_role(&session, scenario, gt, schedule, idx, epoch, stop).await?;
    let sent = meter::snapshot(&session, &a.name).await;
    let _ = session.close().await;
    eprintln!(
        "agent {}: sent {} frames in {} parts ({} dropped by the link), {} payload bytes",
        a.name, totals.frames, totals.parts, totals.dropped, totals.payload_bytes
    );
    let side = AgentSide {
        totals,
        sent,
        socket_bytes: None,
    };
    Ok((a.name.clone(), side))
}
