//! `v2x-sim gen`: every agent's noisy detections as a nuScenes results file, each agent
//! capturing at its own rate and phase.
//!
//! An agent at the data's rate with no phase captures on the data's frames, and its samples are
//! keyed by their sample tokens. Any other capture is keyed `t<microseconds>` and sees the ground
//! truth of that instant (interpolated between annotations). Every file's `meta` carries
//! `v2x_timestamps` (each sample's capture time) and `v2x_data_start_us` (the data's first
//! frame), from which `v2x-agent` replays the agents in step and `v2x-fuser fuse` and
//! `v2x-sim eval` align them in time.

use crate::dair::Dair;
use crate::dataset::GroundTruth;
use crate::noise::{detect, place_agents, Capture, NoiseSetting};
use v2x_protocol::nuscenes_json::{default_meta, Results};
use v2x_protocol::InvalidValue;
use v2x_truth::v2v4real::{V2v4real, AGENTS};

/// When an agent captures.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Timing {
    /// Capture rate (Hz); `None` is the data's own.
    pub hz: Option<f64>,
    /// Offset of the first capture after each scene's first frame (ms).
    pub phase_ms: f64,
}

/// A comma-separated list of numbers for `agents` agents: one for all, or one each.
fn per_agent(s: Option<&str>, flag: &str, agents: usize) -> Result<Vec<Option<f64>>, InvalidValue> {
    let Some(s) = s else {
        return Ok(vec![None; agents]);
    };
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().ok())
        .collect::<Option<_>>()
        .ok_or_else(|| InvalidValue::new(flag, "numbers separated by commas", s))?;
    match v.len() {
        1 => Ok(vec![Some(v[0]); agents]),
        n if n == agents => Ok(v.into_iter().map(Some).collect()),
        n => Err(InvalidValue::new(
            flag,
            format!("one value, or one per agent ({agents})"),
            format!("{n} values"),
        )),
    }
}

impl Timing {
    /// Per-agent timings from comma-separated lists (one value applies to every agent).
    pub fn parse(
        hz: Option<&str>,
        phase_ms: Option<&str>,
        agents: usize,
    ) -> Result<Vec<Timing>, InvalidValue> {
        let hz = per_agent(hz, "--agent-hz", agents)?;
        let phase = per_agent(phase_ms, "--phase-ms", agents)?;
        hz.into_iter()
            .zip(phase)
            .enumerate()
            .map(|(i, (hz, phase))| {
                let of = |flag: &str| format!("{flag} of agent {}", i + 1);
                if let Some(h) = hz.filter(|h| !(*h > 0.0 && *h <= 1000.0)) {
                    return Err(InvalidValue::new(of("--agent-hz"), "in (0, 1000]", h));
                }
                let phase_ms = phase.unwrap_or(0.0);
                if !(0.0..60_000.0).contains(&phase_ms) {
                    return Err(InvalidValue::new(
                        of("--phase-ms"),
                        "in [0, 60000)",
                        phase_ms,
                    ));
                }
                Ok(Timing { hz, phase_ms })
            })
            .collect()
    }

    /// The capture times (us) within a scene whose frames are at `frames` (sorted): the frames
    /// shifted by the phase at the data's rate, else every 1/hz from the first frame + phase.
    pub fn captures(&self, frames: &[u64]) -> Vec<u64> {
        let (Some(&first), Some(&last)) = (frames.first(), frames.last()) else {
            return Vec::new();
        };
        let phase_us = (self.phase_ms * 1000.0).round() as u64;
        match self.hz {
            None => frames
                .iter()
                .map(|t| t + phase_us)
                .filter(|t| *t <= last)
                .collect(),
            Some(hz) => {
                let start = (first + phase_us) as f64;
                (0..)
                    .map(|j| start + j as f64 * 1e6 / hz)
                    .take_while(|t| *t <= last as f64 + 0.5)
                    .map(|t| t.round() as u64)
                    .collect()
            }
        }
    }
}

/// Every agent's results file. A capture on a frame draws the noise the synchronous agents and
/// `v2x-sim bench` draw for that frame.
pub fn generate(
    gt: &GroundTruth,
    setting: &NoiseSetting,
    timings: &[Timing],
    seed: u64,
    range: Option<f64>,
) -> Vec<Results> {
    let index = gt.frame_index();
    let data_start = gt.frames.iter().map(|f| f.timestamp_us).min().unwrap_or(0);
    let mut files = Vec::new();
    for (a, noise) in setting.agents.iter().enumerate() {
        let timing = timings.get(a).copied().unwrap_or(Timing {
            hz: None,
            phase_ms: 0.0,
        });
        let mut r = Results::default();
        let mut times = serde_json::Map::new();
        for scene in 0..gt.scenes.len().max(1) {
            let frames: Vec<u64> = gt
                .frames
                .iter()
                .filter(|f| f.scene == scene)
                .map(|f| f.timestamp_us)
                .collect();
            for t in timing.captures(&frames) {
                let Some(near) = gt.nearest_frame(scene, t) else {
                    continue;
                };
                let frame = &gt.frames[near];
                let on_frame = frame.timestamp_us == t;
                let (key, draw) = if on_frame {
                    (
                        frame.sample_token.clone(),
                        index[frame.sample_token.as_str()] as u64,
                    )
                } else {
                    (format!("t{t}"), t)
                };
                let places = place_agents(frame, setting.agents.len(), seed);
                let objects = gt.in_draw_order(gt.objects_at(scene, t));
                let capture = Capture {
                    draw,
                    scene,
                    t_us: t,
                };
                let dets = detect(&objects, capture, a, noise, places[a].position, range, seed);
                times.insert(key.clone(), t.into());
                r.samples.insert(key, dets);
            }
        }
        let mut meta = default_meta();
        meta["v2x_timestamps"] = serde_json::Value::Object(times);
        meta["v2x_data_start_us"] = data_start.into();
        r.meta = meta;
        files.push(r);
    }
    files
}

/// The two agents of DAIR-V2X data (vehicle, then roadside) as results files: each pair keyed
/// by its vehicle frame id, holding that side's labels as `setting` sees them
/// ([`Dair::detections`]; `labels`: exactly) and stamped with that side's own capture time.
pub fn generate_dair(
    d: &Dair,
    setting: &NoiseSetting,
    seed: u64,
    range: Option<f64>,
) -> Vec<Results> {
    let data_start =
        d.gt.frames
            .iter()
            .map(|f| f.timestamp_us)
            .min()
            .unwrap_or(0);
    (0..2)
        .map(|a| {
            let mut r = Results::default();
            let mut times = serde_json::Map::new();
            for (i, f) in d.gt.frames.iter().enumerate() {
                let dets = d.detections(a, i, &setting.agents[a], seed, range);
                times.insert(f.sample_token.clone(), d.capture_us(a, i).into());
                r.order.push(f.sample_token.clone());
                r.samples.insert(f.sample_token.clone(), dets);
            }
            let mut meta = default_meta();
            meta["v2x_timestamps"] = serde_json::Value::Object(times);
            meta["v2x_data_start_us"] = data_start.into();
            meta["v2x_agent"] = v2x_truth::dair::AGENTS[a].into();
            r.meta = meta;
            r
        })
        .collect()
}

/// V2V4Real's two cars' boxes per frame with the stds a detector's boxes are given
/// (`docs/method.md` §11): the ego car is the receiver, car 1's add its pose.
pub fn ready_cars(
    cars: &[Vec<Vec<v2x_protocol::Detection>>; 2],
    p: &v2x_fuser::uncertainty::detector::DetectorParams,
) -> [Vec<Vec<v2x_protocol::Detection>>; 2] {
    let mut cars = cars.clone();
    for (k, car) in cars.iter_mut().enumerate() {
        for dets in car.iter_mut() {
            v2x_fuser::uncertainty::detector::ready(p, dets, k == 0);
        }
    }
    cars
}

/// V2V4Real's two cars (ego, then car 1) as results files: every frame of the split keyed by
/// its sample token (`SSSS_FFFFFF`), each car's detections with the stds a detector's boxes are
/// given (`docs/method.md` §11; the ego car is the receiver), at the split's replay times
/// ([`V2v4real::replay_times`]: 100 ms apart, sequences 3 s apart), so that `v2x-agent`
/// replays the split in one go and `v2x-fuser fuse --detector` fuses it as the bench does.
pub fn generate_v2v4real(
    d: &V2v4real,
    p: &v2x_fuser::uncertainty::detector::DetectorParams,
) -> Vec<Results> {
    let times = d.replay_times();
    let cars = ready_cars(&d.cars, p);
    (0..2)
        .map(|k| {
            let mut r = Results::default();
            let mut stamps = serde_json::Map::new();
            for (i, f) in d.frames.iter().enumerate() {
                let token = f.token();
                stamps.insert(token.clone(), times[i].into());
                r.order.push(token.clone());
                r.samples.insert(token, cars[k][i].clone());
            }
            let mut meta = default_meta();
            meta["v2x_timestamps"] = serde_json::Value::Object(stamps);
            meta["v2x_data_start_us"] = times.first().copied().unwrap_or(0).into();
            meta["v2x_agent"] = AGENTS[k].into();
            r.meta = meta;
            r
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::agent_detections;
    use crate::town::{generate as town, TownConfig};
    use v2x_protocol::Uncertainty;

    #[test]
    fn agents_capture_at_their_own_rates_and_phases() {
        let gt = town(&TownConfig {
            scenes: 2,
            seconds: 2.0,
            hz: 10.0,
            seed: 1,
        });
        let setting = NoiseSetting::parse("mild+large", 2).unwrap();
        let timings = Timing::parse(Some("10,20"), Some("0,25"), 2).unwrap();
        let files = generate(&gt, &setting, &timings, 5, None);
        // on the frames: the frames' tokens, and the noise `bench` draws
        assert_eq!(files[0].samples.len(), 40);
        let k = 13;
        let token = &gt.frames[k].sample_token;
        assert_eq!(
            files[0].samples[token],
            agent_detections(&gt, k, &setting, 5, None)[0]
        );
        // 20 Hz from 25 ms: 2 x 38 captures within the two 1.9 s scenes, none on a frame
        assert_eq!(files[1].samples.len(), 2 * 38);
        let t0 = gt.frames[0].timestamp_us;
        let first = &files[1].samples[&format!("t{}", t0 + 25_000)];
        let times = &files[1].meta["v2x_timestamps"];
        assert_eq!(times[format!("t{}", t0 + 75_000)], t0 + 75_000);
        assert_eq!(files[1].meta["v2x_data_start_us"], t0);
        assert_eq!(first.len(), gt.objects_at(0, t0 + 25_000).len());
        // the boxes are where the objects are at 25 ms, not at the frame
        let exact = NoiseSetting::parse("0.001,0.001,0.01", 2).unwrap();
        let files = generate(&gt, &exact, &timings, 5, None);
        let boxes = &files[1].samples[&format!("t{}", t0 + 25_000)];
        let gap = |truth: &[crate::dataset::GtObject]| {
            boxes
                .iter()
                .zip(truth)
                .map(|(d, o)| (d.center[0] - o.center[0]).hypot(d.center[1] - o.center[1]))
                .fold(0.0, f64::max)
        };
        assert!(gap(&gt.objects_at(0, t0 + 25_000)) < 0.01);
        assert!(gap(&gt.frames[0].objects) > 0.1);
        let e = Timing::parse(Some("10,20,30"), None, 2).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--agent-hz must be one value, or one per agent (2) (got 3 values)"
        );
        let e = Timing::parse(None, Some("-5"), 2).unwrap_err();
        assert_eq!(
            (e.field.as_str(), e.got.as_str()),
            ("--phase-ms of agent 1", "-5")
        );
        let e = Timing::parse(Some("10,x"), None, 2).unwrap_err();
        assert_eq!((e.field.as_str(), e.got.as_str()), ("--agent-hz", "10,x"));
    }

    #[test]
    fn v2v4real_cars_become_files_that_fuse_as_their_folders_do() {
        use v2x_fuser::offline::{fuse_results, read_inputs, OfflineOptions};
        use v2x_fuser::uncertainty::detector::{stds, DetectorParams};
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../truth/fixtures/v2v4real/AB3DMOT");
        let split = v2x_truth::v2v4real::Split::Train;
        let d =
            v2x_truth::v2v4real::load(&root, split, Uncertainty::uniform(0.5, 0.1, 0.1)).unwrap();
        let p = DetectorParams::default();
        let files = generate_v2v4real(&d, &p);
        // Sequence 0 has frames 0-2, sequence 1 frames 0-1: every frame, empty ones too.
        let tokens = [
            "0000_000000",
            "0000_000001",
            "0000_000002",
            "0001_000000",
            "0001_000001",
        ];
        assert_eq!(files[0].order, tokens);
        let t: Vec<u64> = tokens
            .iter()
            .map(|k| files[1].meta["v2x_timestamps"][k].as_u64().unwrap())
            .collect();
        assert_eq!(t, [1_000_000, 1_100_000, 1_200_000, 4_200_000, 4_300_000]);
        assert_eq!(files[0].meta["v2x_data_start_us"], 1_000_000);
        assert_eq!(files[1].meta["v2x_agent"], "car1");
        // Each box keeps its score; the ego car's stds are its detector's, car 1's add the pose.
        let (ego, car1) = (
            &files[0].samples["0000_000000"],
            &files[1].samples["0000_000000"],
        );
        assert_eq!((ego.len(), car1.len()), (2, 2));
        assert_eq!((ego[0].score, car1[1].score), (0.9, 0.6));
        assert_eq!(ego[0].std, stds(&p, &ego[0], true));
        assert_eq!(car1[1].std, stds(&p, &car1[1], false));
        assert!(car1[1].std.pos[0] > ego[0].std.pos[0]);
        // Fused with the detector's treatment, the files give what the folders give.
        let csba = "csba-wls+".parse::<v2x_fuser::Method>().unwrap();
        let mut opts = OfflineOptions::method(csba);
        opts.steps.detector = Some(p);
        let folders = read_inputs(
            &v2x_truth::v2v4real::Paths::new(&root, split).cars,
            v2x_protocol::nuscenes_json::MissingStd::Error,
        )
        .unwrap();
        let from_folders = fuse_results(
            &folders.agents,
            &folders.options(&OfflineOptions::method(csba)),
        );
        let from_files = fuse_results(&files, &opts);
        let boxes = |r: &Results| -> Vec<(String, Vec<[f64; 3]>, Vec<f64>)> {
            r.samples
                .iter()
                .filter(|(_, v)| !v.is_empty())
                .map(|(k, v)| {
                    (
                        k.clone(),
                        v.iter().map(|d| d.center).collect(),
                        v.iter().map(|d| d.score).collect(),
                    )
                })
                .collect()
        };
        assert_eq!(boxes(&from_files), boxes(&from_folders));
        assert_eq!(boxes(&from_files).len(), 5);
    }
}
