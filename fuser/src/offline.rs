//! Offline fusion of nuScenes results files, one file per agent; the output keeps the extension
//! fields.
//!
//! When every file carries its capture times (the `v2x_timestamps` map of its `meta`, as
//! `v2x-sim gen` writes it), frames are grouped the way the fuser node groups them, by capture
//! time in windows of delta t ([`crate::time::window`]), and each window is motion-compensated to its
//! latest capture time ([`crate::time::motion`]) before it is fused; the output sample of a window is
//! the sample of that latest frame, and the output's `v2x_timestamps` gives each sample's
//! reference time. Without capture times, boxes are grouped by sample token and fused as they
//! are. With registration ([`crate::time::align`]), each window's agents are first aligned to the
//! reference agent: pooled over windows when grouping by time, per sample otherwise.

use crate::pipeline::{Pipeline, Prepared, Reference, Steps};
use crate::time::align::Registration;
use crate::time::motion::MotionParams;
use crate::time::window::Windows;
use crate::tracker::{TrackStats, Tracker, TrackerParams};
use crate::uncertainty::detector::DetectorParams;
use crate::uncertainty::learn::AgentReport;
use crate::uncertainty::stdmodel::{ErrorModel, Models};
use crate::Method;
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::PathBuf;
use v2x_protocol::kitti::{self, KittiError};
use v2x_protocol::nuscenes_json::{tracking_json, write_results, JsonError, MissingStd, Results};
use v2x_protocol::{AgentKind, Detection, Frame};

mod inputs;
mod track;
pub use inputs::{from_detector, kitti_default_std, read_inputs, Inputs};
pub use track::{track_files, track_results, track_sequences, Tracks};

/// What went wrong reading, fusing or writing files.
#[derive(Debug, thiserror::Error)]
pub enum FilesError {
    /// A results file.
    #[error(transparent)]
    Json(#[from] JsonError),
    /// A KITTI-layout folder or file.
    #[error(transparent)]
    Kitti(#[from] KittiError),
    /// Files and folders given together.
    #[error(
        "give every input as a results file, or every input as a folder of KITTI rows \
         (NNNN.txt per sequence): not both"
    )]
    MixedInputs,
    /// Tracking of inputs without capture times.
    #[error(
        "tracking needs every input to carry capture times \
         (meta.v2x_timestamps with one entry per sample, as `v2x-sim gen` writes it)"
    )]
    NoCaptureTimes,
    /// The output cannot be written.
    #[error("cannot write {}: {error}", path.display())]
    Write {
        /// The output file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
}

/// The layout the fused or tracked output is written in.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum OutputFormat {
    /// KITTI folders when the inputs are KITTI folders, else a nuScenes results file.
    #[default]
    Auto,
    /// One nuScenes results (or tracking results) JSON file.
    Nuscenes,
    /// A folder of per-sequence `NNNN.txt` rows ([`v2x_protocol::kitti`]).
    Kitti,
}

impl OutputFormat {
    /// The layout for these inputs: `Auto` resolved.
    fn resolve(self, inputs: &Inputs) -> OutputFormat {
        match self {
            OutputFormat::Auto if !inputs.sequences.is_empty() => OutputFormat::Kitti,
            OutputFormat::Auto => OutputFormat::Nuscenes,
            f => f,
        }
    }
}

/// How to fuse files: the per-window steps, and what files add to them.
#[derive(Clone, Debug)]
pub struct OfflineOptions {
    /// The method and the steps around it, as the node runs them; error models are keyed by
    /// input ([`OfflineOptions::set_models`]), and the first input receives a detector's boxes.
    pub steps: Steps,
    /// Window width delta t (ms) when grouping by capture time.
    pub window_ms: f64,
    /// The input registration aligns every other to (an index into the inputs).
    pub reference: usize,
    /// The detector's parameters wherever its treatment applies: given with `steps.detector`,
    /// or for a detector's KITTI rows ([`Inputs::options`]).
    pub detector_params: DetectorParams,
}

impl Default for OfflineOptions {
    fn default() -> Self {
        OfflineOptions {
            steps: Steps {
                motion: Some(MotionParams::default()),
                ..Steps::method(Method::default())
            },
            window_ms: 100.0,
            reference: 0,
            detector_params: DetectorParams::default(),
        }
    }
}

impl OfflineOptions {
    /// The default options, fusing by `method`.
    pub fn method(method: Method) -> Self {
        let mut o = OfflineOptions::default();
        o.steps.method = method;
        o
    }

    /// Sets the replay speed of motion compensation and the learner at once
    /// ([`crate::pipeline::set_time_scale`]); a tracker's is its own parameter.
    pub fn set_time_scale(&mut self, s: f64) {
        let steps = &mut self.steps;
        crate::pipeline::set_time_scale(s, steps.motion.as_mut(), steps.learn.as_mut(), None);
    }

    /// Calibrated error models by input (an index into the inputs), applied to that input's
    /// boxes before anything else ([`crate::uncertainty::stdmodel`]).
    pub fn set_models(&mut self, by_input: BTreeMap<usize, ErrorModel>) {
        let named = by_input.into_iter().map(|(a, m)| (name(a), m)).collect();
        self.steps.models = std::sync::Arc::new(Models(named));
    }
}

/// The capture time of each sample of a file, when its meta gives one for every sample.
pub fn capture_times(r: &Results) -> Option<HashMap<String, u64>> {
    let map = r.meta.get("v2x_timestamps")?.as_object()?;
    let times: HashMap<String, u64> = map
        .iter()
        .filter_map(|(k, v)| Some((k.clone(), v.as_u64()?)))
        .collect();
    r.samples
        .keys()
        .all(|s| times.contains_key(s))
        .then_some(times)
}

/// The name input `a` goes by in windows and in the pipeline (`a00000`, ...: name order is
/// input order).
fn name(a: usize) -> String {
    format!("a{a:05}")
}

impl OfflineOptions {
    /// The per-window pipeline of these options over inputs named by [`name`]: the first input
    /// receives a detector's boxes, and registration aligns to [`OfflineOptions::reference`].
    pub fn pipeline(&self) -> Pipeline {
        let reference = Reference::Agent(name(self.reference));
        Pipeline::new(self.steps.clone(), reference, Some(name(0)))
    }
}

/// One time step of every input's boxes (`per_agent[k]`, input k's), each box as it was
/// captured, through the pipeline's detector and fusion steps (no registration, no history).
pub fn fuse_step(opts: &OfflineOptions, per_agent: &[Vec<Detection>]) -> Vec<Detection> {
    let mut once = opts.clone();
    once.steps.align = None;
    let mut p = once.pipeline();
    let names: Vec<String> = (0..per_agent.len()).map(name).collect();
    let kinds = vec![AgentKind::Vehicle; per_agent.len()];
    p.fuse_frame(None, &names, &kinds, per_agent)
}

/// Fuses the agents' files: by capture-time windows when every file has capture times, else by
/// sample token.
pub fn fuse_results(agents: &[Results], opts: &OfflineOptions) -> Results {
    let times: Option<Vec<HashMap<String, u64>>> = agents.iter().map(capture_times).collect();
    match times {
        Some(times) if !agents.is_empty() => fuse_by_time(agents, &times, opts),
        _ => fuse_by_token(agents, opts),
    }
}

/// The input's name in reports: `agentN`, N its position among the inputs from 1.
fn input_name(internal: &str) -> String {
    let n: usize = internal[1..].parse().expect("internal names are a00000...");
    format!("agent{}", n + 1)
}

/// A window's registrations as `meta.v2x_registration` holds them per sample: each registered
/// input's estimate, its stds, its matches and whether it was applied.
fn registration_json(names: &[String], regs: &[Option<Registration>]) -> Option<Value> {
    let m: serde_json::Map<String, Value> = names
        .iter()
        .zip(regs)
        .filter_map(|(n, r)| {
            let r = r.as_ref()?;
            Some((
                input_name(n),
                serde_json::json!({
                    "shift_m": r.shift_m,
                    "turn_deg": r.turn_rad.to_degrees(),
                    "std_m": [r.std[0], r.std[1]],
                    "std_turn_deg": r.std[2].to_degrees(),
                    "pivot": r.pivot,
                    "matches": r.matches,
                    "chi2": r.chi2,
                    "turn_chi2": r.turn_chi2,
                    "applied": r.applied,
                    "turn_applied": r.turn_applied,
                }),
            ))
        })
        .collect();
    (!m.is_empty()).then_some(Value::Object(m))
}

/// Puts `key` into a results file's meta (made if there is none).
fn set_meta(out: &mut Results, key: &str, value: Value) {
    if !matches!(out.meta, Value::Object(_)) {
        out.meta = v2x_protocol::nuscenes_json::default_meta();
    }
    out.meta[key] = value;
}

fn fuse_by_token(agents: &[Results], opts: &OfflineOptions) -> Results {
    // Sample tokens carry no order, so each sample is registered on its own evidence.
    let mut pipeline = opts.pipeline();
    let mut registered = serde_json::Map::new();
    let names: Vec<String> = (0..agents.len()).map(name).collect();
    let kinds = vec![AgentKind::Vehicle; agents.len()];
    let samples: BTreeSet<&String> = agents.iter().flat_map(|r| r.samples.keys()).collect();
    let mut out = Results {
        meta: agents.first().map(|r| r.meta.clone()).unwrap_or_default(),
        ..Default::default()
    };
    for s in samples {
        let per_agent: Vec<Vec<_>> = agents
            .iter()
            .enumerate()
            .map(|(a, r)| {
                let mut dets = r.samples.get(s).cloned().unwrap_or_default();
                pipeline.steps().models.apply(&name(a), &mut dets);
                dets
            })
            .collect();
        let (per_agent, regs) = pipeline.register(None, &names, &kinds, per_agent);
        registered.extend(registration_json(&names, &regs).map(|r| (s.clone(), r)));
        let receiver = pipeline.receiver_in(&names);
        out.samples
            .insert(s.clone(), pipeline.steps().fuse_boxes(&per_agent, receiver));
    }
    if opts.steps.align.is_some() {
        set_meta(&mut out, "v2x_registration", Value::Object(registered));
    }
    out
}

fn fuse_by_time(
    agents: &[Results],
    times: &[HashMap<String, u64>],
    opts: &OfflineOptions,
) -> Results {
    let mut out = Results {
        meta: agents[0].meta.clone(),
        ..Default::default()
    };
    let mut samples = BTreeMap::new();
    let meta = by_time(agents, times, opts, |steps, sample, prepared| {
        samples.insert(
            sample.clone(),
            steps.fuse_boxes(&prepared.lists, prepared.receiver),
        );
    });
    out.samples = samples;
    meta.set(&mut out);
    out
}

/// What grouping by time adds to a results file's meta: each sample's reference time, and with
/// registration or learned stds their reports.
struct TimeMeta {
    stamps: serde_json::Map<String, Value>,
    registered: Option<serde_json::Map<String, Value>>,
    learned: Option<BTreeMap<String, AgentReport>>,
}

impl TimeMeta {
    fn set(self, out: &mut Results) {
        set_meta(out, "v2x_timestamps", Value::Object(self.stamps));
        if let Some(r) = self.registered {
            set_meta(out, "v2x_registration", Value::Object(r));
        }
        if let Some(learned) = self.learned {
            set_meta(
                out,
                "v2x_learned_std",
                serde_json::to_value(learned).expect("reports serialize"),
            );
        }
    }
}

/// Every frame of every agent, in capture order, through the node's window state machine: each
/// window prepared by the options' pipeline ([`OfflineOptions::pipeline`]) goes to `each` with the
/// pipeline's steps and the window's sample (that of its latest frame), in time order.
fn by_time(
    agents: &[Results],
    times: &[HashMap<String, u64>],
    opts: &OfflineOptions,
    mut each: impl FnMut(&Steps, &String, &Prepared),
) -> TimeMeta {
    let mut frames: Vec<(u64, usize, &String, &Vec<Detection>)> = Vec::new();
    for (a, r) in agents.iter().enumerate() {
        for (token, dets) in &r.samples {
            frames.push((times[a][token], a, token, dets));
        }
    }
    frames.sort_by_key(|f| (f.0, f.1));
    let mut windows = Windows::new((opts.window_ms * 1000.0) as u64, 0);
    let mut token_of: HashMap<(String, u32), &String> = HashMap::new();
    for (seq, (t, a, token, dets)) in frames.iter().enumerate() {
        token_of.insert((name(*a), seq as u32), token);
        let frame = Frame {
            agent: name(*a),
            kind: AgentKind::Vehicle,
            seq: seq as u32,
            capture_us: *t,
            origin: [0.0; 3],
            detections: (*dets).clone(),
        };
        windows.insert(frame, *t);
    }
    let all: BTreeSet<String> = (0..agents.len()).map(name).collect();
    let mut stamps = serde_json::Map::new();
    let mut pipeline = opts.pipeline();
    let mut registered = serde_json::Map::new();
    for closed in windows.flush(|_| all.clone()) {
        let captured: Vec<(String, u32, u64)> = closed
            .frames
            .values()
            .map(|f| (f.agent.clone(), f.seq, f.capture_us))
            .collect();
        let prepared = pipeline.prepare(closed);
        let latest = captured
            .iter()
            .find(|f| f.2 == prepared.t_ref)
            .map(|(agent, seq, _)| token_of[&(agent.clone(), *seq)].clone())
            .unwrap_or_default();
        if opts.steps.align.is_some() {
            registered.extend(
                registration_json(&prepared.agents, &prepared.registration)
                    .map(|r| (latest.clone(), r)),
            );
        }
        each(pipeline.steps(), &latest, &prepared);
        stamps.insert(latest, prepared.t_ref.into());
    }
    TimeMeta {
        stamps,
        registered: opts.steps.align.is_some().then_some(registered),
        learned: opts.steps.learn.map(|_| {
            pipeline
                .learned()
                .into_iter()
                .map(|(name, r)| (input_name(&name), r))
                .collect()
        }),
    }
}

/// Writes a JSON document to a file.
fn write_json(output: &std::path::Path, doc: &Value) -> Result<(), FilesError> {
    std::fs::write(
        output,
        serde_json::to_string(doc).expect("JSON values always serialize"),
    )
    .map_err(|error| FilesError::Write {
        path: output.to_path_buf(),
        error,
    })
}

/// What `v2x-fuser fuse` did.
#[derive(Clone, Debug, PartialEq)]
pub struct FuseReport {
    /// Samples (windows) written.
    pub samples: usize,
    /// Boxes read, over every input.
    pub boxes_in: usize,
    /// Fused boxes written.
    pub boxes_out: usize,
    /// Whether frames were grouped by capture time (else by sample token).
    pub by_time: bool,
    /// With registration, per input registered: `agentN`, the windows it was measured in,
    /// the windows its correction was applied in, and its last estimate.
    pub registration: Vec<(String, usize, usize, Option<Registration>)>,
    /// With learned stds, what was learned of each input (`agentN`) by the end.
    pub learned: BTreeMap<String, AgentReport>,
}

/// Reads, fuses and writes (a nuScenes results file, or KITTI detection rows per sequence):
/// the `v2x-fuser fuse` command.
pub fn fuse_files(
    inputs: &[PathBuf],
    output: &std::path::Path,
    missing: MissingStd,
    opts: &OfflineOptions,
    format: OutputFormat,
) -> Result<FuseReport, FilesError> {
    let read = read_inputs(inputs, missing)?;
    let (fused, report) = fuse_agents(&read.agents, inputs, &read.options(opts))?;
    match format.resolve(&read) {
        OutputFormat::Kitti => {
            kitti::write_detection_dir(output, &fused, read.sequences)?;
        }
        _ => write_results(output, &fused, &read.tokens)?,
    }
    Ok(report)
}

/// Fuses the agents' results as [`fuse_files`] fuses files (`names[k]` names agent k's in
/// errors): the fused results and what was done.
pub fn fuse_agents(
    agents: &[Results],
    names: &[PathBuf],
    opts: &OfflineOptions,
) -> Result<(Results, FuseReport), JsonError> {
    let by_time = !agents.is_empty() && agents.iter().all(|r| capture_times(r).is_some());
    if opts.steps.learn.is_some() && !by_time {
        let without = agents.iter().position(|r| capture_times(r).is_none());
        return Err(JsonError {
            file: without.map(|k| names[k].clone()).unwrap_or_default(),
            sample: None,
            index: None,
            field: Some("meta.v2x_timestamps".into()),
            message: "learning stds needs every sample's capture time \
                      (meta.v2x_timestamps, as `v2x-sim gen` writes it)"
                .into(),
        });
    }
    let fused = fuse_results(agents, opts);
    let boxes_in = agents
        .iter()
        .flat_map(|r| r.samples.values())
        .map(Vec::len)
        .sum();
    let report = FuseReport {
        samples: fused.samples.len(),
        boxes_in,
        boxes_out: fused.samples.values().map(Vec::len).sum(),
        by_time,
        registration: registration_summary(&fused),
        learned: fused
            .meta
            .get("v2x_learned_std")
            .and_then(|v| serde_json::from_value(v.clone()).ok())
            .unwrap_or_default(),
    };
    Ok((fused, report))
}

/// Per registered input, from `meta.v2x_registration` in time (else token) order: the windows
/// measured, the windows applied, the last estimate.
fn registration_summary(fused: &Results) -> Vec<(String, usize, usize, Option<Registration>)> {
    let Some(Value::Object(per_sample)) = fused.meta.get("v2x_registration") else {
        return Vec::new();
    };
    let times = capture_times(fused);
    let mut keys: Vec<&String> = per_sample.keys().collect();
    keys.sort_by_key(|k| (times.as_ref().and_then(|t| t.get(*k).copied()), *k));
    let mut out: BTreeMap<String, (usize, usize, Option<Registration>)> = BTreeMap::new();
    for k in keys {
        for (agent, r) in per_sample[k].as_object().into_iter().flatten() {
            let e = out.entry(agent.clone()).or_default();
            let num = |f: &str| r[f].as_f64().unwrap_or(f64::NAN);
            let pair = |f: &str| {
                [
                    r[f][0].as_f64().unwrap_or(f64::NAN),
                    r[f][1].as_f64().unwrap_or(f64::NAN),
                ]
            };
            let reg = Registration {
                pivot: pair("pivot"),
                shift_m: pair("shift_m"),
                turn_rad: num("turn_deg").to_radians(),
                std: [
                    pair("std_m")[0],
                    pair("std_m")[1],
                    num("std_turn_deg").to_radians(),
                ],
                matches: r["matches"].as_u64().unwrap_or(0) as usize,
                chi2: num("chi2"),
                turn_chi2: num("turn_chi2"),
                applied: r["applied"].as_bool().unwrap_or(false),
                turn_applied: r["turn_applied"].as_bool().unwrap_or(false),
            };
            e.0 += usize::from(reg.matches > 0);
            e.1 += usize::from(reg.applied);
            e.2 = Some(reg);
        }
    }
    out.into_iter()
        .map(|(a, (m, ap, r))| (a, m, ap, r))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::align::AlignParams;
    use v2x_protocol::{Class, Uncertainty, NO_ID};

    /// Two agents over `n` samples seeing the same 6 cars; agent 1 reports them 1.8 m east and
    /// 0.9 m south of where agent 2 does. With `times`, each file carries capture times.
    fn files(n: usize, times: bool) -> Vec<Results> {
        let cars = |dx: f64, dy: f64| -> Vec<Detection> {
            (0..6)
                .map(|i| Detection {
                    class: Class::Car,
                    center: [10.0 * i as f64 + dx, 7.0 * (i % 3) as f64 + dy, 0.0],
                    size: [4.5, 1.9, 1.6],
                    yaw: 0.2,
                    score: 0.8,
                    std: Uncertainty::uniform(0.2, 0.1, 0.1),
                    pos_cov: None,
                    velocity: None,
                    id: NO_ID,
                })
                .collect()
        };
        [(1.8, -0.9), (0.0, 0.0)]
            .iter()
            .map(|&(dx, dy)| {
                let mut r = Results::default();
                let mut stamps = serde_json::Map::new();
                for s in 0..n {
                    let token = format!("s{s}");
                    stamps.insert(token.clone(), (s as u64 * 100_000).into());
                    r.samples.insert(token, cars(dx, dy));
                }
                if times {
                    r.meta = serde_json::json!({ "v2x_timestamps": stamps });
                }
                r
            })
            .collect()
    }

    #[test]
    fn align_registers_the_agent_to_the_reference_before_fusion() {
        let method: Method = "csba-wls+".parse().unwrap();
        for times in [false, true] {
            let agents = files(20, times);
            let plain = fuse_results(&agents, &OfflineOptions::method(method));
            let mut opts = OfflineOptions::method(method);
            opts.steps.align = Some(AlignParams::default());
            opts.reference = 1;
            let aligned = fuse_results(&agents, &opts);
            // each sample's registration of input 1 is reported; without times each sample
            // stands alone and is significant at once, with times the filter needs a few
            // windows of evidence (measurements 0.1 s apart are not independent)
            let reports = aligned.meta["v2x_registration"].as_object().unwrap();
            assert_eq!(reports.len(), 20, "times {times}");
            let applied = |s: &str| reports[s]["agent1"]["applied"].as_bool().unwrap();
            let first = if times { 5 } else { 0 };
            let mut keys: Vec<&String> = aligned.samples.keys().collect();
            keys.sort_by_key(|k| k[1..].parse::<u32>().unwrap());
            assert!(keys[first..].iter().all(|k| applied(k)), "times {times}");
            for key in &keys[first..] {
                let out = &aligned.samples[*key];
                let shift = &reports[key.as_str()]["agent1"]["shift_m"];
                assert!((shift[0].as_f64().unwrap() + 1.8).abs() < 0.01, "{shift}");
                // every car once, where the reference sees it
                assert_eq!(out.len(), 6, "times {times}");
                for (i, d) in out.iter().enumerate() {
                    let want = [10.0 * i as f64, 7.0 * (i % 3) as f64];
                    assert!((d.center[0] - want[0]).abs() < 0.01, "{:?}", d.center);
                    assert!((d.center[1] - want[1]).abs() < 0.01, "{:?}", d.center);
                }
            }
            // without registration the pairs are 2.0 m apart: 7.1 combined stds, beyond the gate of 6
            assert!(
                plain.samples.values().all(|s| s.len() == 12),
                "times {times}"
            );
        }
    }
}
