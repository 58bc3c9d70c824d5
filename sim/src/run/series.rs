//! The time series of a run as the fuser saw it (`v2x-sim run --timeline FILE`): per second of
//! the scenario, the windows fused and how many closed incomplete, the end-to-end latency, the
//! fused metrics, and each agent's frames in the windows; written as CSV or JSON and drawn by
//! `v2x-sim plot --timeline`.

use super::roles::FuserOutcome;
use super::schedule::Schedule;
use crate::dataset::GroundTruth;
use crate::metrics::Accumulator;
use crate::scenario::Scenario;
use crate::timeline::EventSpec;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One second of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Second {
    /// Seconds from the run's start (data time): this row covers [second, second + 1).
    pub second: u64,
    /// Windows fused.
    pub windows: u64,
    /// Of which closed by deadline with a live agent missing.
    pub incomplete: u64,
    /// End-to-end latency, median and 95th percentile (ms).
    pub e2e_p50_ms: Option<f64>,
    /// See `e2e_p50_ms`.
    pub e2e_p95_ms: Option<f64>,
    /// Precision of the fused boxes (id matching).
    pub precision: Option<f64>,
    /// Recall of the fused boxes.
    pub recall: Option<f64>,
    /// mATE of the fused boxes (m).
    pub mate_m: Option<f64>,
    /// Frames of each agent in the windows fused.
    pub frames: BTreeMap<String, u64>,
    /// Objects of each agent in the windows fused.
    #[serde(default)]
    pub objects: BTreeMap<String, u64>,
    /// Payload bytes received from each agent (Zenoh's statistics at the fuser).
    #[serde(default)]
    pub payload_bytes: BTreeMap<String, u64>,
    /// Wire bytes received over each agent's own transport (peer mode; absent through a router).
    #[serde(default)]
    pub wire_bytes: BTreeMap<String, u64>,
}

/// A run's series and the events that shaped it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Timeline {
    /// The scenario's namespace.
    pub namespace: String,
    /// The agents, in order.
    pub agents: Vec<String>,
    /// The scripted events.
    pub events: Vec<EventMark>,
    /// One row per second.
    pub seconds: Vec<Second>,
}

/// An event as the plot marks it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventMark {
    /// When (s from the start).
    pub at_s: f64,
    /// `target action`, e.g. `rsu leave`.
    pub label: String,
}

impl EventMark {
    fn of(e: &EventSpec) -> Self {
        let action = serde_json::to_value(e.action)
            .ok()
            .and_then(|v| v.as_str().map(String::from))
            .unwrap_or_default();
        EventMark {
            at_s: e.at_s,
            label: format!("{} {action}", e.target),
        }
    }
}

/// Nearest-rank percentile of sorted values.
fn percentile(sorted: &[f64], q: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let k = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    Some(sorted[k - 1])
}

/// The series of a run from what the fuser role recorded.
pub fn timeline(
    scenario: &Scenario,
    gt: &GroundTruth,
    schedule: &Schedule,
    outcome: &FuserOutcome,
) -> Timeline {
    let agents: Vec<String> = scenario.agents.iter().map(|a| a.name.clone()).collect();
    let seconds = (schedule.duration_us() as f64 / 1e6).ceil() as u64;
    let mut rows: Vec<Second> = (0..seconds.max(1))
        .map(|s| Second::empty(s, &agents))
        .collect();
    let mut e2e: Vec<Vec<f64>> = vec![Vec::new(); rows.len()];
    let mut acc: Vec<Accumulator> = vec![Accumulator::new(); rows.len()];
    for (&t, w) in &outcome.windows {
        let s = ((t.saturating_sub(schedule.t0_us)) / 1_000_000) as usize;
        let Some(row) = rows.get_mut(s) else {
            continue;
        };
        row.windows += 1;
        row.incomplete += u64::from(!w.complete);
        for (i, a) in w.agents.iter().enumerate() {
            *row.frames.entry(a.clone()).or_default() += 1;
            *row.objects.entry(a.clone()).or_default() += w.objects.get(i).copied().unwrap_or(0);
        }
        e2e[s].push(w.e2e_ms);
        if let Some(dets) = outcome.fused.get(&t) {
            acc[s].add_frame(&gt.objects_at(schedule.scene, t), dets);
        }
    }
    // Bytes between consecutive samples of the fuser's traffic, in the second of their midpoint.
    for pair in outcome.traffic.windows(2) {
        let ((w0, before), (w1, after)) = (&pair[0], &pair[1]);
        let mid = schedule.data_us(outcome.epoch_us, (w0 + w1) / 2, scenario.speed);
        let Some(row) = rows.get_mut((mid.saturating_sub(schedule.t0_us) / 1_000_000) as usize)
        else {
            continue;
        };
        for a in &agents {
            let key = super::meter::agent_key(scenario, a);
            let payload = after.key(&key).rx.since(&before.key(&key).rx);
            *row.payload_bytes.entry(a.clone()).or_default() += payload.put_payload_bytes;
            if let Some(p) = after.sole_sender(&key) {
                let was = before
                    .peers
                    .iter()
                    .find(|q| q.zid == p.zid)
                    .map(|q| q.total.rx)
                    .unwrap_or_default();
                *row.wire_bytes.entry(a.clone()).or_default() += p.total.rx.since(&was).bytes;
            }
        }
    }
    for ((row, mut lat), acc) in rows.iter_mut().zip(e2e).zip(acc) {
        lat.sort_by(f64::total_cmp);
        row.e2e_p50_ms = percentile(&lat, 0.5);
        row.e2e_p95_ms = percentile(&lat, 0.95);
        let m = acc.summary();
        row.precision = m.precision;
        row.recall = m.recall;
        row.mate_m = m.all.m_ate;
    }
    Timeline {
        namespace: scenario.namespace.clone(),
        agents,
        events: scenario.events.iter().map(EventMark::of).collect(),
        seconds: rows,
    }
}

impl Second {
    /// Second `second` before anything is counted: no frame of any of `agents`.
    fn empty(second: u64, agents: &[String]) -> Second {
        Second {
            second,
            windows: 0,
            incomplete: 0,
            e2e_p50_ms: None,
            e2e_p95_ms: None,
            precision: None,
            recall: None,
            mate_m: None,
            frames: agents.iter().map(|a| (a.clone(), 0)).collect(),
            objects: agents.iter().map(|a| (a.clone(), 0)).collect(),
            payload_bytes: BTreeMap::new(),
            wire_bytes: BTreeMap::new(),
        }
    }
}

impl Timeline {
    /// The series as CSV: one row per second; per agent, `frames_A`, `objects_A`,
    /// `payload_bytes_A` and `wire_bytes_A` columns (empty where not measured).
    pub fn csv(&self) -> String {
        let mut s =
            String::from("second,windows,incomplete,e2e_p50_ms,e2e_p95_ms,precision,recall,mate_m");
        for a in &self.agents {
            s.push_str(&format!(
                ",frames_{a},objects_{a},payload_bytes_{a},wire_bytes_{a}"
            ));
        }
        s.push('\n');
        let f = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.4}"));
        for r in &self.seconds {
            s.push_str(&format!(
                "{},{},{},{},{},{},{},{}",
                r.second,
                r.windows,
                r.incomplete,
                f(r.e2e_p50_ms),
                f(r.e2e_p95_ms),
                f(r.precision),
                f(r.recall),
                f(r.mate_m)
            ));
            let n = |m: &BTreeMap<String, u64>, a: &String| {
                m.get(a).map_or(String::new(), u64::to_string)
            };
            for a in &self.agents {
                s.push_str(&format!(
                    ",{},{},{},{}",
                    r.frames.get(a).copied().unwrap_or(0),
                    r.objects.get(a).copied().unwrap_or(0),
                    n(&r.payload_bytes, a),
                    n(&r.wire_bytes, a)
                ));
            }
            s.push('\n');
        }
        s
    }

    /// Writes the series: CSV when the file name ends in `.csv`, else JSON.
    pub fn write(&self, path: &std::path::Path) -> anyhow::Result<()> {
        let text = if path.extension().is_some_and(|e| e == "csv") {
            self.csv()
        } else {
            serde_json::to_string_pretty(self)?
        };
        std::fs::write(path, text)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
    }

    /// Reads a series written as JSON, naming the file when it is not one.
    pub fn read(path: &std::path::Path) -> anyhow::Result<Timeline> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
        serde_json::from_str(&text).map_err(|e| {
            anyhow::anyhow!(
                "{}: not a timeline JSON file (write one with v2x-sim run --timeline FILE.json): {e}",
                path.display()
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::super::roles::WindowRecord;
    use crate::town::{generate, TownConfig};

    #[test]
    fn windows_are_counted_in_their_second() {
        let gt = generate(&TownConfig {
            scenes: 1,
            seconds: 3.0,
            hz: 10.0,
            seed: 5,
        });
        let schedule = Schedule::of(&gt, 3.0);
        let mut scenario = Scenario::parse(crate::scenario::DEFAULT, "default", None).unwrap();
        scenario.events.clear();
        let mut outcome = FuserOutcome::default();
        // 30 frames: the exact ground truth fused; the second second's windows lack "rsu",
        // close incomplete and take 100 ms longer.
        for (k, &gi) in schedule.frames.iter().enumerate() {
            let f = &gt.frames[gi];
            let second = k / 10;
            let agents: Vec<String> = if second == 1 {
                vec!["veh".into()]
            } else {
                vec!["rsu".into(), "veh".into()]
            };
            outcome.windows.insert(
                f.timestamp_us,
                WindowRecord {
                    objects: vec![3; agents.len()],
                    agents,
                    complete: second != 1,
                    e2e_ms: 10.0 + k as f64 % 10.0 + if second == 1 { 100.0 } else { 0.0 },
                    flagged: Vec::new(),
                },
            );
            let boxes = f.objects.iter().map(|o| o.as_detection()).collect();
            outcome.fused.insert(f.timestamp_us, boxes);
        }
        // The fuser's traffic sampled at 0, 1 and 2 s: veh over a transport of its own.
        use v2x_protocol::traffic::{Counters, Flow, Peer, Traffic};
        outcome.epoch_us = 5_000_000;
        let rx = |bytes: u64, put_msgs: u64, put_payload_bytes: u64| Flow {
            rx: Counters {
                bytes,
                put_msgs,
                put_payload_bytes,
                ..Default::default()
            },
            ..Default::default()
        };
        let key = v2x_protocol::keys::detections("default", "veh");
        for (s, (wire, payload)) in [(0, 0), (1300, 1000), (3200, 2500)].into_iter().enumerate() {
            let keys: BTreeMap<String, Flow> = [(key.clone(), rx(0, s as u64, payload))].into();
            let t = Traffic {
                total: rx(wire, s as u64, payload),
                keys: keys.clone(),
                peers: vec![Peer {
                    zid: "p1".into(),
                    whatami: "peer".into(),
                    total: rx(wire, s as u64, payload),
                    keys,
                }],
            };
            outcome.traffic.push((5_000_000 + s as u64 * 1_000_000, t));
        }
        let tl = timeline(&scenario, &gt, &schedule, &outcome);
        assert_eq!(tl.seconds.len(), 3);
        let s = &tl.seconds;
        assert_eq!(
            (s[0].windows, s[0].incomplete, s[1].incomplete),
            (10, 0, 10)
        );
        assert_eq!(
            (s[0].frames["rsu"], s[1].frames["rsu"], s[1].frames["veh"]),
            (10, 0, 10)
        );
        // latencies 10..19 ms: nearest-rank median 14, p95 19
        assert_eq!((s[0].e2e_p50_ms, s[0].e2e_p95_ms), (Some(14.0), Some(19.0)));
        assert_eq!(s[1].e2e_p50_ms, Some(114.0));
        assert_eq!(
            (s[2].precision, s[2].recall, s[2].mate_m),
            (Some(1.0), Some(1.0), Some(0.0))
        );
        let csv = tl.csv();
        let mut lines = csv.lines();
        assert_eq!(
            lines.next(),
            Some("second,windows,incomplete,e2e_p50_ms,e2e_p95_ms,precision,recall,mate_m,frames_veh,objects_veh,payload_bytes_veh,wire_bytes_veh,frames_rsu,objects_rsu,payload_bytes_rsu,wire_bytes_rsu")
        );
        assert_eq!(
            lines.next(),
            Some("0,10,0,14.0000,19.0000,1.0000,1.0000,0.0000,10,30,1000,1300,10,30,0,")
        );
        assert_eq!(
            lines.next(),
            Some("1,10,10,114.0000,119.0000,1.0000,1.0000,0.0000,10,30,1500,1900,0,0,0,")
        );
        assert_eq!(
            lines.next(),
            Some("2,10,0,14.0000,19.0000,1.0000,1.0000,0.0000,10,30,,,10,30,,")
        );
        // JSON round trip, as the plot reads it
        let dir = std::env::temp_dir().join(format!("v2x-series-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.json");
        tl.write(&path).unwrap();
        assert_eq!(Timeline::read(&path).unwrap(), tl);
        std::fs::write(&path, "[]").unwrap();
        assert!(Timeline::read(&path)
            .unwrap_err()
            .to_string()
            .contains("not a timeline"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn percentiles_are_nearest_rank() {
        let v = [1.0, 2.0, 3.0, 4.0, 10.0];
        assert_eq!(percentile(&v, 0.5), Some(3.0));
        assert_eq!(percentile(&v, 0.95), Some(10.0));
        assert_eq!(percentile(&[], 0.5), None);
    }
}
