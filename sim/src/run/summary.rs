//! The summary of a run: metrics of the fused output and of each agent alone, bandwidth, frame
//! counts and latencies, as one JSON object (fields in docs/guide.md) or as tables.

use super::roles::{agent_captures, agent_view, FuserOutcome};
use super::schedule::Schedule;
use crate::dataset::{GroundTruth, GtObject};
use crate::metrics::{Accumulator, Metrics};
use crate::scenario::Scenario;
use crate::tracking_eval::{TrackBox, TrackingEval, TrackingMetrics};
use serde::Serialize;
use std::collections::BTreeMap;
use v2x_agent::AgentTotals;
use v2x_fuser::intake::ingest::AgentStats;
use v2x_fuser::node::Latency;
use v2x_protocol::nuscenes_json::Results;
use v2x_protocol::traffic::{Flow, Traffic};
use v2x_protocol::Detection;

/// Bandwidth of one agent: its own side (what its session sent, when the agent ran in this
/// process) and the fuser's (what arrived, when the fuser ran here), from Zenoh's statistics.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Bandwidth {
    /// Frames published (or, when the agent ran elsewhere, received).
    pub frames: u64,
    /// Mean objects per frame.
    pub objects_per_frame: f64,
    /// Mean payload bytes per frame.
    pub payload_bytes_per_frame: f64,
    /// Mean payload bytes per object.
    pub payload_bytes_per_object: f64,
    /// The same boxes as ETSI CPMs: mean bytes per frame (docs/cpm.md), when the agent ran in
    /// this process.
    pub cpm_bytes_per_frame: Option<f64>,
    /// Frames Zenoh put on the wire for the agent (frames published while no fuser subscribed
    /// never leave the host); when the agent ran here.
    pub zenoh_frames: Option<u64>,
    /// Mean bytes the agent's session wrote to the wire per frame Zenoh sent, as Zenoh counts
    /// them, over the transports that carried its detections (to the fuser, or to the router):
    /// framing, declarations, keep-alives and payload (no TCP/IP headers, TLS records or the
    /// opening handshake).
    pub wire_bytes_per_frame: Option<f64>,
    /// Zenoh's count of the payload put on the agent's key, per frame Zenoh sent.
    pub zenoh_payload_bytes_per_frame: Option<f64>,
    /// Zenoh's overhead per message: wire bytes beyond the payload, per put.
    pub overhead_bytes_per_message: Option<f64>,
    /// At the fuser: payload received on the agent's key per frame received.
    pub received_payload_bytes_per_frame: Option<f64>,
    /// Wire bytes received per frame over the agent's own transport: at the fuser in peer mode;
    /// through a router, at the router when it ran in the fuser's process (else null).
    pub received_wire_bytes_per_frame: Option<f64>,
    /// TCP bytes per frame between the agent and the hub, TLS records and handshakes included
    /// (one-process runs, which route each agent through a counting relay).
    pub socket_bytes_per_frame: Option<f64>,
    /// Wire rate in kbit/s over the run: sent, else received, else payload.
    pub kbit_s: f64,
}

/// What an agent role measured of its own sending.
#[derive(Clone, Debug, Default)]
pub struct AgentSide {
    /// The agent's counters.
    pub totals: AgentTotals,
    /// Its session's traffic at the end, from Zenoh's statistics.
    pub sent: Option<Traffic>,
    /// Bytes its TCP connection carried towards the hub (the relay of a one-process run).
    pub socket_bytes: Option<u64>,
}

/// The run's length in seconds of wall time.
fn run_seconds(scenario: &Scenario, schedule: &Schedule) -> f64 {
    (schedule.frames.len() as f64 * schedule.period_us as f64 / 1e6 / scenario.speed).max(1e-9)
}

fn per(x: u64, n: u64) -> f64 {
    if n > 0 {
        x as f64 / n as f64
    } else {
        0.0
    }
}

/// What the hub saw of the agents: the fuser's counters and the samples of its session's
/// traffic, and the router's traffic when a router ran in this process.
pub struct HubView<'a> {
    /// The fuser's counters of the agent.
    pub stats: &'a AgentStats,
    /// The fuser session's traffic, sampled over the run.
    pub samples: &'a [(u64, Traffic)],
    /// The router's traffic, sampled over the run, if the router ran here.
    pub router: &'a [(u64, Traffic)],
}

/// One agent's bandwidth from its own side and, if the fuser ran here, the hub's.
pub fn agent_bandwidth(
    scenario: &Scenario,
    schedule: &Schedule,
    name: &str,
    side: &AgentSide,
    hub: Option<HubView>,
) -> Bandwidth {
    let t = &side.totals;
    let st = hub.as_ref().map(|h| h.stats.clone()).unwrap_or_default();
    let frames = if t.published > 0 {
        t.published
    } else {
        st.frames_in
    };
    let payload = if t.payload_bytes > 0 {
        t.payload_bytes
    } else {
        st.payload_bytes
    };
    let objects = if t.objects > 0 { t.objects } else { st.objects };
    let key = super::meter::agent_key(scenario, name);
    let sent = side
        .sent
        .as_ref()
        .map(|tr| (tr.sent_with(&key), tr.key(&key).tx));
    let samples = hub.as_ref().map_or(&[][..], |h| h.samples);
    // Received payload: the key's counters outlive the agent's transport; received wire: the
    // agent's own transport, in the last sample that still had it, per put it had carried (at
    // the fuser, or, when agents reach it through a router, at the router).
    let received = samples.last().map(|(_, tr)| tr.key(&key).rx);
    let own_transport = |tr: &Traffic| {
        let p = tr.sole_sender(&key)?;
        let puts = p.keys.get(&key)?.rx.put_msgs;
        Some((p.total.rx.bytes, puts))
    };
    let received_wire = samples
        .iter()
        .rev()
        .find_map(|(_, tr)| own_transport(tr))
        .or_else(|| {
            let router = hub.as_ref().map_or(&[][..], |h| h.router);
            router.iter().rev().find_map(|(_, tr)| own_transport(tr))
        });
    let secs = run_seconds(scenario, schedule);
    // In a city an agent sends each frame as one put per tile: Zenoh's per-put figures, brought
    // to per-frame ones.
    let puts_per_frame = if t.published > 0 && t.parts > t.published {
        t.parts as f64 / t.published as f64
    } else {
        1.0
    };
    let rate = sent
        .map(|(all, _)| all.bytes as f64)
        .or(received_wire.map(|(b, puts)| per(b, puts) * st.frames_in as f64))
        .unwrap_or(payload as f64);
    Bandwidth {
        frames,
        objects_per_frame: per(objects, frames),
        payload_bytes_per_frame: per(payload, frames),
        payload_bytes_per_object: per(payload, objects),
        cpm_bytes_per_frame: (t.cpm_bytes > 0).then(|| per(t.cpm_bytes, t.published)),
        zenoh_frames: sent.map(|(_, k)| (k.put_msgs as f64 / puts_per_frame).round() as u64),
        wire_bytes_per_frame: sent.map(|(all, k)| per(all.bytes, k.put_msgs) * puts_per_frame),
        zenoh_payload_bytes_per_frame: sent
            .map(|(_, k)| per(k.put_payload_bytes, k.put_msgs) * puts_per_frame),
        overhead_bytes_per_message: sent.and_then(|(all, _)| all.overhead_per_put()),
        received_payload_bytes_per_frame: received.map(|k| per(k.put_payload_bytes, st.frames_in)),
        received_wire_bytes_per_frame: received_wire.map(|(b, puts)| per(b, puts)),
        socket_bytes_per_frame: side
            .socket_bytes
            .zip(sent)
            .map(|(w, (_, k))| per(w, k.put_msgs) * puts_per_frame),
        kbit_s: rate * 8.0 / 1000.0 / secs,
    }
}

/// Frame counts of one agent.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Counts {
    /// Frames the agent produced.
    pub sent: u64,
    /// Frames its link dropped.
    pub dropped_by_link: u64,
    /// Frames the fuser received.
    pub received: u64,
    /// Frames fused.
    pub fused: u64,
    /// Late frames (window already closed).
    pub late: u64,
    /// Duplicate frames.
    pub duplicate: u64,
    /// Invalid frames (including frames naming another agent).
    pub invalid: u64,
    /// Frames stamped too far from the fuser's clock (ahead or behind).
    pub clock_rejected: u64,
    /// Frames dropped for a frame of the same agent closer to a window's anchor.
    pub replaced: u64,
}

/// The summary of a run (`--format json`).
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Namespace.
    pub namespace: String,
    /// Method.
    pub method: String,
    /// Agents' noise, in order.
    pub noise: String,
    /// Ground-truth frames scheduled.
    pub frames_scheduled: usize,
    /// Fused windows published.
    pub windows: u64,
    /// Windows closed by deadline with a live agent missing.
    pub windows_incomplete: u64,
    /// Wall-clock length of the run (s).
    pub wall_s: f64,
    /// Metrics of the fused output over the fused frames.
    pub fused: Metrics,
    /// With `[fuser] track`: the tracks scored as the nuScenes tracking benchmark does
    /// (AMOTA, MOTA, IDS...), over the same frames.
    pub tracking: Option<TrackingMetrics>,
    /// With `[fuser] track` and `[regions]`: the identity switches whose object stood within
    /// [`BORDER_M`] of a tile border.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub border_switches: Option<usize>,
    /// Metrics of each agent alone over the same frames.
    pub agents: BTreeMap<String, Metrics>,
    /// Bandwidth per agent.
    pub bandwidth: BTreeMap<String, Bandwidth>,
    /// Frame counts per agent.
    pub counts: BTreeMap<String, Counts>,
    /// Everything the fuser's session sent and received over the run, from Zenoh's statistics.
    pub fuser_traffic: Option<Flow>,
    /// The fuser's puts per key (each agent's detections received, fused output and tracks
    /// sent), from Zenoh's statistics.
    pub fuser_keys: BTreeMap<String, Flow>,
    /// Capture to fused publish (ms).
    pub e2e_latency_ms: Latency,
    /// Window close to fused publish (ms).
    pub fusion_latency_ms: Latency,
    /// How the roles talked.
    pub security: SecurityReport,
    /// A city's regions, each with its own figures (absent for one fuser).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub regions: Vec<RegionReport>,
    /// With learned stds (`fuser.learn_std`): what the fuser learned of each agent by the end.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub learned_std: BTreeMap<String, v2x_fuser::uncertainty::learn::AgentReport>,
    /// With learned stds: each agent flagged as stating inconsistent stds, and how long after
    /// the first fused window (s of data) it was first flagged.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub std_flagged_after_s: BTreeMap<String, f64>,
}

/// The security mode of a run and what it cost to connect.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct SecurityReport {
    /// `plain` or `mtls`.
    pub mode: String,
    /// Mean time to open an agent's Zenoh session, connection and handshakes included (ms),
    /// when measured.
    pub session_setup_ms: Option<f64>,
}

/// Builds the summary from what the roles produced.
pub fn summarize(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    outcome: &FuserOutcome,
    totals: &BTreeMap<String, AgentSide>,
    wall_s: f64,
) -> Summary {
    let (fused, covered) = fused_metrics(scenario, gt, schedule, outcome);
    let tracks = scenario
        .fuser
        .settings
        .track
        .then(|| tracking_metrics(gt, schedule, outcome, &covered));
    let border_switches = scenario.regions.as_ref().and_then(|r| {
        let tiling = r.tiling();
        let (_, at) = tracks.as_ref()?;
        Some(
            at.iter()
                .filter(|p| tiling.border_distance(**p) <= BORDER_M)
                .count(),
        )
    });
    let tracking = tracks.map(|(m, _)| m);
    let (bandwidth, counts) = agent_traffic(scenario, schedule, outcome, totals);
    Summary {
        namespace: scenario.namespace.clone(),
        method: scenario.method().name(),
        noise: scenario.noise().name,
        frames_scheduled: schedule.frames.len(),
        windows: outcome.stats.windows,
        windows_incomplete: outcome.stats.windows_incomplete,
        wall_s,
        fused,
        tracking,
        border_switches,
        agents: agent_metrics(scenario, gt, schedule, outcome.reached_us),
        bandwidth,
        counts,
        fuser_traffic: outcome.traffic.last().map(|(_, tr)| tr.total),
        fuser_keys: outcome
            .traffic
            .last()
            .map(|(_, tr)| tr.keys.clone())
            .unwrap_or_default(),
        e2e_latency_ms: outcome.stats.e2e_latency_ms.clone(),
        fusion_latency_ms: outcome.stats.fusion_latency_ms.clone(),
        security: SecurityReport {
            mode: scenario.security.mode.name().into(),
            session_setup_ms: None,
        },
        regions: Vec::new(),
        learned_std: outcome.stats.learned_std.clone(),
        std_flagged_after_s: first_flagged(outcome),
    }
}

/// Each agent ever flagged, with how long after the first window (s of data) it first was.
fn first_flagged(outcome: &FuserOutcome) -> BTreeMap<String, f64> {
    let Some(&start) = outcome.windows.keys().next() else {
        return BTreeMap::new();
    };
    let mut out = BTreeMap::new();
    for (t, w) in &outcome.windows {
        for a in &w.flagged {
            out.entry(a.clone()).or_insert((t - start) as f64 / 1e6);
        }
    }
    out
}

/// Scores one frame; boxes of recorded agents (DAIR-V2X) carry no ground-truth ids, and those
/// that crossed the air as CPMs only their low 16 bits (docs/cpm.md): they match by distance.
fn score(
    scenario: &Scenario,
    gt: &GroundTruth,
    acc: &mut Accumulator,
    objects: &[GtObject],
    dets: &[Detection],
) {
    if gt.recorded.is_some() || scenario.agents.iter().any(|a| a.cpm) {
        let unnamed: Vec<Detection> = dets
            .iter()
            .map(|d| Detection {
                id: v2x_protocol::NO_ID,
                ..d.clone()
            })
            .collect();
        acc.add_frame(
            objects,
            &crate::metrics::ids_by_distance(objects, &unnamed, 2.0),
        );
    } else {
        acc.add_frame(objects, dets);
    }
}

/// The fused output scored at its reference times against the ground truth of those instants;
/// a scheduled frame the run reached but no fused window came near counts as missed. Also which
/// scheduled frames a window came near.
fn fused_metrics(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    outcome: &FuserOutcome,
) -> (Metrics, Vec<bool>) {
    let mut acc = Accumulator::new();
    let mut covered = vec![false; schedule.frames.len()];
    for (&t, dets) in &outcome.fused {
        score(
            scenario,
            gt,
            &mut acc,
            &gt.objects_at(schedule.scene, t),
            dets,
        );
        if let Some(k) = schedule.frame_near(t) {
            covered[k] = true;
        }
    }
    for (k, &gi) in schedule.frames.iter().enumerate() {
        let f = &gt.frames[gi];
        if !covered[k] && f.timestamp_us <= outcome.reached_us {
            acc.add_frame(&f.objects, &[]);
        }
    }
    (acc.summary(), covered)
}

/// Identity switches whose object stood within this distance (m) of a tile border are the
/// border's: a window or two of an object's motion, and the hand-over's reach.
pub const BORDER_M: f64 = 10.0;

/// The tracks scored as the tracking benchmark does: each window's tracks at its time, and
/// every reached frame no window came near as empty; and where each identity switch happened.
fn tracking_metrics(
    gt: &GroundTruth,
    schedule: &Schedule,
    outcome: &FuserOutcome,
    covered: &[bool],
) -> (TrackingMetrics, Vec<[f64; 2]>) {
    let mut frames: BTreeMap<u64, (Vec<GtObject>, Vec<TrackBox>)> = outcome
        .tracks
        .iter()
        .map(|(&t, dets)| {
            let boxes = dets
                .iter()
                .map(|d| TrackBox {
                    track: d.id.to_string(),
                    class: d.class,
                    center: [d.center[0], d.center[1]],
                    score: d.score,
                })
                .collect();
            (t, (gt.objects_at(schedule.scene, t), boxes))
        })
        .collect();
    for (k, &gi) in schedule.frames.iter().enumerate() {
        let f = &gt.frames[gi];
        if !covered[k] && f.timestamp_us <= outcome.reached_us {
            frames.insert(f.timestamp_us, (f.objects.clone(), Vec::new()));
        }
    }
    let mut eval = TrackingEval::new();
    for (t, (objects, boxes)) in &frames {
        eval.add_frame(schedule.scene, *t, objects, boxes);
    }
    eval.summary_with_switches()
}

/// Each agent alone, at its own capture times up to `reached`, as it saw them: absent while it
/// had left, with the noise of the moment.
fn agent_metrics(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    reached: u64,
) -> BTreeMap<String, Metrics> {
    let mut out = BTreeMap::new();
    for (idx, a) in scenario.agents.iter().enumerate() {
        let mut acc = Accumulator::new();
        let mut timeline = a.timeline(&scenario.events);
        for (j, t) in agent_captures(scenario, gt, schedule, idx)
            .into_iter()
            .enumerate()
        {
            if t > reached {
                break;
            }
            let state = timeline.at(t.saturating_sub(schedule.t0_us));
            if !state.present {
                continue;
            }
            let objects = gt.objects_at(schedule.scene, t);
            let view = agent_view(scenario, gt, schedule, idx, j, t, &state.noise).0;
            score(scenario, gt, &mut acc, &objects, &view);
        }
        out.insert(a.name.clone(), acc.summary());
    }
    out
}

/// Each agent's bandwidth and frame counts, from its own side and the fuser's.
fn agent_traffic(
    scenario: &Scenario,
    schedule: &Schedule,
    outcome: &FuserOutcome,
    totals: &BTreeMap<String, AgentSide>,
) -> (BTreeMap<String, Bandwidth>, BTreeMap<String, Counts>) {
    let mut bandwidth = BTreeMap::new();
    let mut counts = BTreeMap::new();
    for a in &scenario.agents {
        let st = outcome
            .stats
            .agents
            .get(&a.name)
            .cloned()
            .unwrap_or_default();
        let side = totals.get(&a.name).cloned().unwrap_or_default();
        let t = side.totals;
        bandwidth.insert(
            a.name.clone(),
            agent_bandwidth(
                scenario,
                schedule,
                &a.name,
                &side,
                Some(HubView {
                    stats: &st,
                    samples: &outcome.traffic,
                    router: &outcome.router_traffic,
                }),
            ),
        );
        counts.insert(
            a.name.clone(),
            Counts {
                sent: t.frames,
                dropped_by_link: t.dropped,
                received: st.frames_in,
                fused: st.fused,
                late: st.late,
                duplicate: st.duplicate,
                invalid: st.invalid + st.wrong_agent,
                clock_rejected: st.future + st.stale,
                replaced: st.replaced,
            },
        );
    }
    (bandwidth, counts)
}

/// The fused output as a results file keyed by the ground truth's sample tokens.
/// Keys are the ground truth's sample token when a window's reference time is a frame's time,
/// else `t<microseconds>` of the data's clock; the `v2x_timestamps` map of the meta gives every
/// key's reference time, so `v2x-sim eval` scores each at its instant.
pub fn recorded(gt: &GroundTruth, schedule: &Schedule, outcome: &FuserOutcome) -> Results {
    let mut r = Results::default();
    let mut stamps = serde_json::Map::new();
    for (&t, dets) in &outcome.fused {
        let key = gt
            .nearest_frame(schedule.scene, t)
            .map(|i| &gt.frames[i])
            .filter(|f| f.timestamp_us == t)
            .map_or_else(|| format!("t{t}"), |f| f.sample_token.clone());
        stamps.insert(key.clone(), t.into());
        r.samples.insert(key, dets.clone());
    }
    let mut meta = v2x_protocol::nuscenes_json::default_meta();
    meta["v2x_timestamps"] = serde_json::Value::Object(stamps);
    r.meta = meta;
    r
}

/// One region's own figures.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RegionReport {
    /// Its tile.
    pub tile: String,
    /// The router its fuser is a client of.
    pub router: String,
    /// Windows fused.
    pub windows: u64,
    /// Of those, closed with an awaited agent missing.
    pub windows_incomplete: u64,
    /// Captures fused without every part.
    pub captures_incomplete: u64,
    /// Fused boxes it published (those whose centre lies in its tile).
    pub fused_objects: u64,
    /// Agents that sent it parts.
    pub agents_heard: Vec<String>,
    /// Window close to publish.
    pub fusion_latency_ms: Latency,
}

impl RegionReport {
    /// The report of one regional fuser's outcome.
    pub fn of(tile: &str, router: &str, o: &FuserOutcome) -> Self {
        RegionReport {
            tile: tile.to_string(),
            router: router.to_string(),
            windows: o.stats.windows,
            windows_incomplete: o.stats.windows_incomplete,
            captures_incomplete: o.stats.captures_incomplete,
            fused_objects: o.stats.fused_objects,
            agents_heard: o
                .stats
                .agents
                .iter()
                .filter(|(_, a)| a.frames_in > 0)
                .map(|(n, _)| n.clone())
                .collect(),
            fusion_latency_ms: o.stats.fusion_latency_ms.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::town::{generate, TownConfig};

    /// A 2 s town at 10 Hz and its schedule.
    fn town() -> (GroundTruth, Schedule) {
        let gt = generate(&TownConfig {
            scenes: 1,
            seconds: 2.0,
            hz: 10.0,
            seed: 5,
        });
        let schedule = Schedule::of(&gt, 2.0);
        (gt, schedule)
    }

    /// A run of the town's 20 frames whose fuser published the exact ground truth for the frames
    /// `fused` says, and nothing for the others; it stopped after `reached_frames`.
    fn run_with(fused: impl Fn(usize) -> bool, reached_frames: usize) -> Summary {
        let scenario = Scenario::parse(crate::scenario::DEFAULT, "default", None).unwrap();
        let (gt, schedule) = town();
        let mut outcome = FuserOutcome::default();
        for (k, &gi) in schedule.frames.iter().enumerate() {
            let f = &gt.frames[gi];
            if fused(k) {
                let boxes = f.objects.iter().map(|o| o.as_detection()).collect();
                outcome.fused.insert(f.timestamp_us, boxes);
            }
            if k < reached_frames {
                outcome.reached_us = f.timestamp_us;
            }
        }
        summarize(&scenario, &gt, &schedule, &outcome, &BTreeMap::new(), 2.0)
    }

    #[test]
    fn windows_never_fused_count_their_objects_as_missed() {
        let all = run_with(|_| true, 20);
        assert_eq!(
            (all.fused.precision, all.fused.recall),
            (Some(1.0), Some(1.0))
        );
        let n = all.fused.tp;
        // Every other frame lost: the even frames' objects are found, the odd ones' missed.
        let half = run_with(|k| k % 2 == 0, 20);
        assert_eq!(half.fused.precision, Some(1.0));
        assert_eq!(
            half.fused.tp + half.fused.fn_,
            n,
            "every scheduled frame scored"
        );
        let even: usize = (0..20).step_by(2).map(frame_objects).sum();
        assert_eq!(half.fused.tp, even);
        assert!(half.fused.recall.unwrap() < 0.6 && half.fused.recall.unwrap() > 0.4);
        // Frames after the fuser stopped are not held against it.
        let early = run_with(|k| k < 10, 10);
        assert_eq!(early.fused.recall, Some(1.0));
    }

    /// The town's 20 frames fused and tracked exactly: ids from `id(object, frame)`.
    fn tracked_with(id: impl Fn(u32, usize) -> u32) -> Summary {
        tracked_in(crate::scenario::DEFAULT, id)
    }

    /// [`tracked_with`] in the scenario `toml`.
    fn tracked_in(toml: &str, id: impl Fn(u32, usize) -> u32) -> Summary {
        let mut scenario = Scenario::parse(toml, "scenario", None).unwrap();
        scenario.fuser.settings.track = true;
        let (gt, schedule) = town();
        let mut outcome = FuserOutcome::default();
        for (k, &gi) in schedule.frames.iter().enumerate() {
            let f = &gt.frames[gi];
            let boxes: Vec<_> = f.objects.iter().map(|o| o.as_detection()).collect();
            let tracks = boxes
                .iter()
                .zip(&f.objects)
                .map(|(b, o)| v2x_protocol::Detection {
                    id: id(o.id, k),
                    ..b.clone()
                })
                .collect();
            outcome.fused.insert(f.timestamp_us, boxes);
            outcome.tracks.insert(f.timestamp_us, tracks);
            outcome.reached_us = f.timestamp_us;
        }
        summarize(&scenario, &gt, &schedule, &outcome, &BTreeMap::new(), 2.0)
    }

    #[test]
    fn tracks_are_scored_when_the_fuser_tracks() {
        assert!(run_with(|_| true, 20).tracking.is_none());
        let stable = tracked_with(|o, _| o).tracking.unwrap();
        assert_eq!((stable.amota, stable.mota, stable.ids), (1.0, 1.0, 0));
        // A new id for every object at frame 10: one switch per object present then and before.
        let (gt, schedule) = town();
        let before = &gt.frames[schedule.frames[9]].objects;
        let at = &gt.frames[schedule.frames[10]].objects;
        let both = at
            .iter()
            .filter(|o| before.iter().any(|b| b.id == o.id))
            .filter(|o| o.class.is_tracking())
            .count();
        assert!(both > 0);
        let renamed = tracked_with(|o, k| if k < 10 { o } else { o + 1000 })
            .tracking
            .unwrap();
        assert_eq!(renamed.ids, both);
        assert_eq!(
            tracked_with(|o, k| if k < 10 { o } else { o + 1000 }).border_switches,
            None,
            "no tiles, no border"
        );
        // In the city's 100 m tiles: the switches of objects within 10 m of a tile border.
        let city = include_str!("../../../scenarios/city.toml");
        let tiling = v2x_protocol::tiles::Tiling::new(100.0).unwrap();
        let near: usize = at
            .iter()
            .filter(|o| before.iter().any(|b| b.id == o.id) && o.class.is_tracking())
            .filter(|o| tiling.border_distance([o.center[0], o.center[1]]) <= BORDER_M)
            .count();
        assert!(near > 0 && near < both, "{near} of {both}");
        let s = tracked_in(city, |o, k| if k < 10 { o } else { o + 1000 });
        assert_eq!(s.tracking.unwrap().ids, both);
        assert_eq!(s.border_switches, Some(near));
        assert_eq!(tracked_in(city, |o, _| o).border_switches, Some(0));
    }

    fn frame_objects(k: usize) -> usize {
        let (gt, schedule) = town();
        gt.frames[schedule.frames[k]].objects.len()
    }
}
