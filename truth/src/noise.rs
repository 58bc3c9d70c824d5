//! Noisy agents (`docs/method.md` §5): each agent sees every ground-truth object (the paper's setting; an
//! optional sensing range restricts that) through zero-mean Gaussian noise of its profile,
//! independent per axis; sizes are clamped to >= 0.05 m, yaws wrapped; each detection reports the
//! profile's stds and a confidence of base + N(0, 0.05), clamped to [0.01, 1], which does not
//! depend on the box's own error. An agent's [`Faults`] (misses, false positives, flipped headings,
//! confused classes, a pose error) come on top, from a stream of their own. Every draw comes from
//! a generator seeded by (seed, agent, frame), so output is reproducible byte for byte and
//! independent of evaluation order or threads.

use crate::dataset::{GroundTruth, GtFrame, GtObject, Recorded};
use crate::faults::{false_positive_class, hidden, look_alike, Faults};
use crate::faults::{FALSE_POSITIVE_RADIUS, FALSE_POSITIVE_SCORE_DROP};
pub use crate::seed::mix;
use crate::spec::SpecError;
use crate::stated::Stated;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};
use std::fmt;
use std::str::FromStr;
use v2x_protocol::{
    wrap_angle, AgentKind, Detection, InvalidValue, NoiseProfile, Uncertainty, Velocity, NO_ID,
};

/// How one agent perceives.
#[derive(Clone, Debug, PartialEq)]
pub struct AgentNoise {
    /// The stds of the injected noise, reported with each detection.
    pub std: Uncertainty,
    /// The std of the injected velocity noise (m/s per axis), reported with each velocity.
    pub velocity_std: f64,
    /// Base confidence.
    pub base_confidence: f64,
    /// What the agent's detector does wrong besides the Gaussian noise.
    pub faults: Faults,
    /// The profile name, or "custom".
    pub label: String,
    /// Report each object exactly as it is labelled (score 1), stating `std`: what a data
    /// set's own labels are as an agent's detections (profile `labels`).
    pub exact: bool,
    /// The stds it states with each box (by default its noise's own).
    pub stated: Stated,
}

impl AgentNoise {
    /// The noise of a named profile.
    pub fn profile(p: NoiseProfile) -> Self {
        AgentNoise {
            std: p.std(),
            velocity_std: p.velocity_std(),
            base_confidence: p.base_confidence(),
            faults: Faults::NONE,
            label: p.name().into(),
            exact: false,
            stated: Stated::Honest,
        }
    }

    /// The `realistic` profile: a lidar detector's errors (0.2 m, 0.1 m, 6 degrees, 0.25 m/s,
    /// confidence 0.8) with [`Faults::REALISTIC`]; docs/guide.md ("Detector faults") gives the
    /// published figures.
    pub fn realistic() -> Self {
        AgentNoise {
            std: Uncertainty::uniform(0.2, 0.1, 6f64.to_radians()),
            velocity_std: 0.25,
            base_confidence: 0.8,
            faults: Faults::REALISTIC,
            label: "realistic".into(),
            exact: false,
            stated: Stated::Honest,
        }
    }

    /// `realistic-rsu`: [`AgentNoise::realistic`] for a roadside unit, whose pose is surveyed once
    /// and does not move: no pose error.
    pub fn realistic_rsu() -> Self {
        AgentNoise {
            faults: Faults {
                pose_m: 0.0,
                pose_yaw: 0.0,
                drift_s: None,
                ..Faults::REALISTIC
            },
            label: "realistic-rsu".into(),
            ..AgentNoise::realistic()
        }
    }

    /// Custom stds (confidence base 0.7, velocity std 0.5 m/s).
    pub fn custom(std: Uncertainty) -> Self {
        AgentNoise {
            std,
            velocity_std: 0.5,
            base_confidence: 0.7,
            faults: Faults::NONE,
            label: "custom".into(),
            exact: false,
            stated: Stated::Honest,
        }
    }

    /// `labels`: every object exactly as labelled, score 1, stating 0.5 m in x and y, 0.25 m
    /// in z, 0.2 m in size and 0.1 rad in yaw (on DAIR-V2X-C the vehicle's and the roadside's
    /// labels of one object lie about 0.8 m apart once calibrated).
    pub fn labels() -> Self {
        AgentNoise {
            std: Uncertainty {
                pos: [0.5, 0.5, 0.25],
                size: [0.2, 0.2, 0.2],
                yaw: 0.1,
            },
            velocity_std: 0.5,
            base_confidence: 1.0,
            faults: Faults::NONE,
            label: "labels".into(),
            exact: true,
            stated: Stated::Honest,
        }
    }
}

impl FromStr for AgentNoise {
    type Err = SpecError;
    /// A profile name (`realistic` and `labels` included), `POS,SIZE,YAW_DEG`, or
    /// `POS,SIZE,YAW_DEG,VEL` (VEL in m/s).
    fn from_str(s: &str) -> Result<Self, SpecError> {
        if let Ok(p) = s.parse::<NoiseProfile>() {
            return Ok(AgentNoise::profile(p));
        }
        match s {
            "labels" => return Ok(AgentNoise::labels()),
            "realistic" => return Ok(AgentNoise::realistic()),
            "realistic-rsu" => return Ok(AgentNoise::realistic_rsu()),
            _ => {}
        }
        let parts: Vec<&str> = s.split(',').collect();
        let (stds, vel) = match parts.len() {
            4 => {
                let v = parts[3]
                    .trim()
                    .parse()
                    .ok()
                    .filter(|v| v2x_protocol::limits::std_in_range(*v))
                    .ok_or_else(|| {
                        let e = InvalidValue::new("the velocity std", "a number > 0", parts[3]);
                        SpecError::new("noise", s, e)
                    })?;
                (parts[..3].join(","), Some(v))
            }
            _ => (s.to_string(), None),
        };
        let std = v2x_protocol::parse_std(&stds).map_err(|e| {
            let forms = "mild, moderate, large, realistic, labels, POS,SIZE,YAW_DEG or \
                         POS,SIZE,YAW_DEG,VEL with a velocity std in m/s";
            SpecError::std("noise", s, e, forms)
        })?;
        let mut n = AgentNoise::custom(std);
        n.label = s.to_string();
        if let Some(v) = vel {
            n.velocity_std = v;
        }
        Ok(n)
    }
}

/// A noise setting: one noise per agent, e.g. `mild` (every agent mild) or `mild+large`.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseSetting {
    /// The setting's name as given.
    pub name: String,
    /// One entry per agent.
    pub agents: Vec<AgentNoise>,
}

impl NoiseSetting {
    /// Parses `PROFILE` (repeated for `n_agents`) or `P1+P2+...` (one per agent). `realistic`
    /// alone gives agent 2, the roadside unit of [`place_agents`], `realistic-rsu`.
    pub fn parse(s: &str, n_agents: usize) -> Result<Self, SpecError> {
        if s == "realistic" {
            let mut agents = vec![AgentNoise::realistic(); n_agents.max(1)];
            if n_agents >= 2 {
                agents[1] = AgentNoise::realistic_rsu();
            }
            return Ok(NoiseSetting {
                name: s.to_string(),
                agents,
            });
        }
        let parts: Vec<&str> = s.split('+').collect();
        let agents: Vec<AgentNoise> = if parts.len() == 1 {
            vec![parts[0].parse()?; n_agents.max(1)]
        } else {
            let mut v: Vec<AgentNoise> =
                parts.iter().map(|p| p.parse()).collect::<Result<_, _>>()?;
            // more agents than named: the last profile repeats
            while v.len() < n_agents {
                v.push(v.last().expect("non-empty").clone());
            }
            v
        };
        Ok(NoiseSetting {
            name: s.to_string(),
            agents,
        })
    }

    /// Replaces the agents' faults: one spec for all, or one per agent joined by '+' (the last
    /// repeats).
    pub fn set_faults(&mut self, spec: &str) -> Result<(), SpecError> {
        self.set_each(spec, |agent, f| agent.faults = f)?;
        self.name = format!("{} faults {spec}", self.name);
        Ok(())
    }

    /// Sets the stds the agents state ([`Stated`]): one for all, or one per agent joined by
    /// '+' (the last repeats).
    pub fn set_stated(&mut self, spec: &str) -> Result<(), SpecError> {
        self.set_each(spec, |agent, s: Stated| agent.stated = s)?;
        self.name = format!("{} stating {spec}", self.name);
        Ok(())
    }

    /// Parses one value for all agents, or one per agent joined by '+' (the last repeats), and
    /// sets each agent's.
    fn set_each<T: FromStr<Err = SpecError> + Copy>(
        &mut self,
        spec: &str,
        set: impl Fn(&mut AgentNoise, T),
    ) -> Result<(), SpecError> {
        let parts: Vec<T> = spec.split('+').map(str::parse).collect::<Result<_, _>>()?;
        for (a, agent) in self.agents.iter_mut().enumerate() {
            set(agent, parts[a.min(parts.len() - 1)]);
        }
        Ok(())
    }

    /// The four settings of the paper's Table 2.
    pub fn paper() -> Vec<NoiseSetting> {
        NoiseSetting::paper_with(2)
    }

    /// The paper's settings seen by `n_agents` agents (the last profile repeating).
    pub fn paper_with(n_agents: usize) -> Vec<NoiseSetting> {
        ["mild", "moderate", "large", "mild+large"]
            .iter()
            .map(|s| NoiseSetting::parse(s, n_agents).expect("valid"))
            .collect()
    }

    /// The lower bound on the mean 2D centre error after fusing every agent:
    /// sqrt(pi/2) x (sum 1/sigma_n^2)^(-1/2), for the x/y stds of the agents.
    pub fn error_bound(&self) -> f64 {
        let info: f64 = self.agents.iter().map(|a| 1.0 / a.std.pos[0].powi(2)).sum();
        (std::f64::consts::PI / 2.0).sqrt() / info.sqrt()
    }
}

impl fmt::Display for NoiseSetting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name)
    }
}

/// An agent's place in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// Vehicle or infrastructure.
    pub kind: AgentKind,
    /// Position in the map frame (m).
    pub position: [f64; 3],
}

/// Places agents for one frame: agent 0 is the vehicle (at the ego pose when the data has one),
/// agent 1 the infrastructure unit a random 20-80 m away, further agents vehicles 20-80 m from it.
/// The draw depends only on (seed, scene), so agents stay put within a scene.
pub fn place_agents(frame: &GtFrame, n_agents: usize, seed: u64) -> Vec<Placement> {
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed, 0x00A1_1CE5, frame.scene as u64));
    let centroid = {
        let n = frame.objects.len().max(1) as f64;
        let mut c = [0.0; 3];
        for o in &frame.objects {
            for k in 0..3 {
                c[k] += o.center[k] / n;
            }
        }
        c
    };
    let vehicle = frame.ego.unwrap_or(centroid);
    let mut out = Vec::with_capacity(n_agents);
    let around = |rng: &mut ChaCha8Rng, from: [f64; 3]| {
        let r: f64 = rng.gen_range(20.0..80.0);
        let a: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
        [from[0] + r * a.cos(), from[1] + r * a.sin(), from[2]]
    };
    let infra = around(&mut rng, vehicle);
    for i in 0..n_agents {
        let (kind, position) = match i {
            0 => (AgentKind::Vehicle, vehicle),
            1 => (AgentKind::Infrastructure, infra),
            _ => (AgentKind::Vehicle, around(&mut rng, infra)),
        };
        out.push(Placement { kind, position });
    }
    out
}

/// One capture of an agent: which draw it is and when.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Capture {
    /// Numbers the capture (the frame index for an agent that captures on the data's frames),
    /// so that every capture draws its own noise.
    pub draw: u64,
    /// The scene.
    pub scene: usize,
    /// Data time of the capture (us), which the pose error drifts with.
    pub t_us: u64,
}

impl Capture {
    /// The capture of frame number `draw` of `frame`.
    pub fn of(frame: &GtFrame, draw: u64) -> Self {
        Capture {
            draw,
            scene: frame.scene,
            t_us: frame.timestamp_us,
        }
    }
}

/// One agent's detections of `objects` (the ground truth at its capture time). `range` (m)
/// limits what the agent sees around `position`; `None` means every object (the paper's
/// setting). Velocity noise and faults come from streams of their own, so that the position,
/// size and yaw noise are the same with or without velocities and faults.
pub fn detect(
    objects: &[GtObject],
    capture: Capture,
    agent: usize,
    noise: &AgentNoise,
    position: [f64; 3],
    range: Option<f64>,
    seed: u64,
) -> Vec<Detection> {
    let draw = capture.draw;
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed, agent as u64 + 1, draw));
    let mut vrng = ChaCha8Rng::seed_from_u64(mix(seed ^ VELOCITY_STREAM, agent as u64 + 1, draw));
    let mut frng = ChaCha8Rng::seed_from_u64(mix(seed ^ FAULT_STREAM, agent as u64 + 1, draw));
    let s = &noise.std;
    let f = &noise.faults;
    let mut g = move || -> f64 { StandardNormal.sample(&mut rng) };
    let mut gv = move || -> f64 { StandardNormal.sample(&mut vrng) };
    let hidden = occluded(objects, f, position);
    let sv = noise.velocity_std;
    let (stated, stated_v) = noise.stated.apply(*s, sv);
    // The noise drawn is scaled by 0 for an exact agent, so that the streams stay the same.
    let k = if noise.exact { 0.0 } else { 1.0 };
    let mut out = Vec::with_capacity(objects.len());
    for (o, hidden) in objects.iter().zip(hidden) {
        // Draw for every object, seen or not, so that the range does not shift the streams.
        let e: [f64; 8] = std::array::from_fn(|_| g());
        let ev: [f64; 2] = std::array::from_fn(|_| gv());
        let u: [f64; 4] = std::array::from_fn(|_| frng.gen::<f64>());
        let r = (o.center[0] - position[0]).hypot(o.center[1] - position[1]);
        if range.is_some_and(|max| r > max) {
            continue;
        }
        let missed = u[0] >= f.detection_probability(r) || (hidden && u[1] < f.occlusion);
        if missed {
            continue;
        }
        let flip = if u[2] < f.flip {
            std::f64::consts::PI
        } else {
            0.0
        };
        let class = if u[3] < f.confusion {
            look_alike(o.class)
        } else {
            o.class
        };
        out.push(Detection {
            class,
            center: std::array::from_fn(|i| o.center[i] + k * s.pos[i] * e[i]),
            size: std::array::from_fn(|i| (o.size[i] + k * s.size[i] * e[3 + i]).max(0.05)),
            yaw: wrap_angle(o.yaw + k * s.yaw * e[6] + flip),
            score: (noise.base_confidence + k * 0.05 * e[7]).clamp(0.01, 1.0),
            std: stated,
            pos_cov: None,
            velocity: o.velocity.map(|v| Velocity {
                v: [v[0] + k * sv * ev[0], v[1] + k * sv * ev[1]],
                std: [stated_v; 2],
            }),
            id: o.id,
        });
    }
    if f.false_positives > 0.0 {
        let with_velocity = objects.iter().any(|o| o.velocity.is_some());
        out.extend(false_positives(
            noise,
            position,
            range,
            with_velocity,
            &mut frng,
        ));
    }
    let error = f.pose_error(seed, agent, capture.scene, capture.t_us);
    if error != [0.0; 3] {
        for d in &mut out {
            mislocate(d, position, error);
        }
    }
    out
}

/// Per object, whether another hides it from `position` (none without occlusion faults).
fn occluded(objects: &[GtObject], f: &Faults, position: [f64; 3]) -> Vec<bool> {
    if f.occlusion > 0.0 {
        let boxes: Vec<_> = objects.iter().map(|o| (o.center, o.size)).collect();
        hidden(&boxes, position)
    } else {
        vec![false; objects.len()]
    }
}

/// An agent's false positives of one capture (a Poisson count at its faults' rate): classes as
/// detectors confuse them, placed uniformly over the disc around the agent within its range.
fn false_positives(
    noise: &AgentNoise,
    position: [f64; 3],
    range: Option<f64>,
    with_velocity: bool,
    frng: &mut ChaCha8Rng,
) -> Vec<Detection> {
    let f = &noise.faults;
    let (s, sv) = noise.stated.apply(noise.std, noise.velocity_std);
    let mut out = Vec::new();
    let radius = range.map_or(FALSE_POSITIVE_RADIUS, |r| r.min(FALSE_POSITIVE_RADIUS));
    let n = Poisson::new(f.false_positives).map_or(0.0, |p| p.sample(frng)) as usize;
    for _ in 0..n {
        let class = false_positive_class(frng.gen());
        // uniform over the disc's area
        let r = radius * frng.gen::<f64>().sqrt();
        let a = frng.gen_range(0.0..std::f64::consts::TAU);
        let e: [f64; 4] = std::array::from_fn(|_| StandardNormal.sample(frng));
        let size = class.typical_size();
        out.push(Detection {
            class,
            center: [
                position[0] + r * a.cos(),
                position[1] + r * a.sin(),
                position[2] + size[2] / 2.0,
            ],
            size: std::array::from_fn(|k| (size[k] * (1.0 + 0.1 * e[k])).max(0.05)),
            yaw: wrap_angle(frng.gen_range(-std::f64::consts::PI..std::f64::consts::PI)),
            score: (noise.base_confidence - FALSE_POSITIVE_SCORE_DROP + 0.05 * e[3])
                .clamp(0.01, 1.0),
            std: s,
            pos_cov: None,
            velocity: with_velocity.then_some(Velocity {
                v: [0.0, 0.0],
                std: [sv, sv],
            }),
            id: NO_ID,
        });
    }
    out
}

/// A recorded agent's detections at frame `i` of `gt`: its labels as `noise` sees them.
pub fn recorded_view(
    gt: &GroundTruth,
    rec: &dyn Recorded,
    agent: usize,
    i: usize,
    noise: &AgentNoise,
    seed: u64,
    range: Option<f64>,
) -> Vec<Detection> {
    let capture = Capture {
        draw: i as u64,
        scene: gt.frames[i].scene,
        t_us: rec.capture_us(agent, i),
    };
    detect(
        rec.labels(agent, i),
        capture,
        agent,
        noise,
        rec.position(agent, i),
        range,
        seed,
    )
}

/// Moves a box as an agent at `position` with pose error (dx, dy, dyaw) reports it: turned by
/// dyaw about the agent, then shifted by (dx, dy); heading and velocity turn with it.
pub fn mislocate(d: &mut Detection, position: [f64; 3], [dx, dy, dyaw]: [f64; 3]) {
    let (sin, cos) = dyaw.sin_cos();
    [d.center[0], d.center[1]] = mislocate_point(d.center, position, [dx, dy, dyaw]);
    d.yaw = wrap_angle(d.yaw + dyaw);
    if let Some(v) = &mut d.velocity {
        v.v = [cos * v.v[0] - sin * v.v[1], sin * v.v[0] + cos * v.v[1]];
    }
}

/// Where a point at `p` appears to an agent at `position` with pose error (dx, dy, dyaw).
pub fn mislocate_point(p: [f64; 3], position: [f64; 3], [dx, dy, dyaw]: [f64; 3]) -> [f64; 2] {
    let (sin, cos) = dyaw.sin_cos();
    let (x, y) = (p[0] - position[0], p[1] - position[1]);
    [
        position[0] + cos * x - sin * y + dx,
        position[1] + sin * x + cos * y + dy,
    ]
}

/// Salt of the fault stream.
const FAULT_STREAM: u64 = 0xFA17_5EED;

/// Salt of the velocity noise stream.
const VELOCITY_STREAM: u64 = 0x7E10_C17E;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::GtObject;
    use crate::spec::Problem;
    use v2x_protocol::Class;

    fn cap(draw: u64) -> Capture {
        Capture {
            draw,
            scene: 0,
            t_us: 0,
        }
    }

    fn frame(n: usize) -> GtFrame {
        GtFrame {
            sample_token: "t".into(),
            scene: 0,
            timestamp_us: 0,
            ego: None,
            objects: (0..n)
                .map(|i| GtObject {
                    id: i as u32,
                    class: Class::Car,
                    center: [i as f64, 2.0 * i as f64, 1.0],
                    size: [4.5, 1.9, 1.6],
                    yaw: 3.0,
                    velocity: Some([i as f64 * 0.001, -1.0]),
                })
                .collect(),
        }
    }

    #[test]
    fn injected_errors_have_the_profile_statistics() {
        let f = frame(20_000);
        for p in NoiseProfile::ALL {
            let noise = AgentNoise::profile(p);
            let d = detect(&f.objects, cap(0), 0, &noise, [0.0; 3], None, 42);
            let n = d.len() as f64;
            let ex: Vec<f64> = d
                .iter()
                .zip(&f.objects)
                .map(|(d, o)| d.center[0] - o.center[0])
                .collect();
            let mean = ex.iter().sum::<f64>() / n;
            let sd = (ex.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
            let s = p.std().pos[0];
            // the std of the sample mean is s / sqrt(n) = s / 141: allow 4 of them
            assert!(mean.abs() < 4.0 * s / n.sqrt(), "{p}: mean {mean}");
            assert!((sd / s - 1.0).abs() < 0.03, "{p}: sd {sd}");
            let ey: Vec<f64> = d
                .iter()
                .zip(&f.objects)
                .map(|(d, o)| wrap_angle(d.yaw - o.yaw))
                .collect();
            let sy = (ey.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
            assert!((sy / p.std().yaw - 1.0).abs() < 0.03, "{p}: yaw sd {sy}");
            let ev: Vec<f64> = d
                .iter()
                .zip(&f.objects)
                .map(|(d, o)| d.velocity.unwrap().v[1] - o.velocity.unwrap()[1])
                .collect();
            let sv = (ev.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
            assert!(
                (sv / p.velocity_std() - 1.0).abs() < 0.03,
                "{p}: velocity sd {sv}"
            );
            assert!(d
                .iter()
                .all(|d| d.velocity.unwrap().std == [p.velocity_std(); 2]));
            let conf = d.iter().map(|d| d.score).sum::<f64>() / n;
            assert!(
                (conf - p.base_confidence()).abs() < 0.003,
                "{p}: confidence {conf}"
            );
            assert!(d
                .iter()
                .all(|d| d.size.iter().all(|s| *s >= 0.05) && d.std == p.std()));
        }
    }

    #[test]
    fn same_seed_same_bytes_other_seed_other_bytes() {
        let f = frame(50);
        let noise = AgentNoise::profile(NoiseProfile::Moderate);
        let a = detect(&f.objects, cap(3), 1, &noise, [0.0; 3], None, 9);
        let b = detect(&f.objects, cap(3), 1, &noise, [0.0; 3], None, 9);
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        assert_ne!(a, detect(&f.objects, cap(3), 1, &noise, [0.0; 3], None, 10));
        assert_ne!(
            a,
            detect(&f.objects, cap(3), 0, &noise, [0.0; 3], None, 9),
            "agents draw independently"
        );
    }

    #[test]
    fn range_limits_what_an_agent_sees() {
        let f = frame(100);
        let d = detect(
            &f.objects,
            cap(0),
            0,
            &AgentNoise::profile(NoiseProfile::Mild),
            [0.0; 3],
            Some(50.0),
            1,
        );
        // object i is at distance i sqrt(5): 50 / 2.236 = 22.4, so ids 0..=22 (mild noise may move one)
        assert!((21..=24).contains(&d.len()), "{}", d.len());
    }

    #[test]
    fn settings_and_bound() {
        let s = NoiseSetting::parse("mild+large", 2).unwrap();
        assert_eq!(s.agents[0].std.pos[0], 0.5);
        assert_eq!(s.agents[1].std.pos[0], 3.0);
        // (1/0.25 + 1/9)^(-1/2) x sqrt(pi/2)
        let expect = (std::f64::consts::PI / 2.0).sqrt() / (4.0f64 + 1.0 / 9.0).sqrt();
        assert!((s.error_bound() - expect).abs() < 1e-12);
        let m = NoiseSetting::parse("moderate", 4).unwrap();
        assert_eq!(m.agents.len(), 4);
        let e = NoiseSetting::parse("huge", 2).unwrap_err();
        assert!(matches!(e.problem, Problem::Form(f) if f.starts_with("mild, moderate, large")));
        let e = NoiseSetting::parse("0.1,0.1,5,-1", 2).unwrap_err();
        assert!(matches!(e.problem, Problem::Value(v) if v.field == "the velocity std"));
        let c = NoiseSetting::parse("0.2,0.1,3", 2).unwrap();
        assert!((c.agents[1].std.yaw - 3f64.to_radians()).abs() < 1e-12);
        assert_eq!(c.agents[1].velocity_std, 0.5);
        let c = NoiseSetting::parse("0.2,0.1,3,0.8", 1).unwrap();
        assert_eq!(c.agents[0].velocity_std, 0.8);
        assert!(NoiseSetting::parse("0.2,0.1,3,x", 1).is_err());
        // `realistic`: the roadside unit (agent 2) has no pose error; faults can be replaced
        let mut r = NoiseSetting::parse("realistic", 3).unwrap();
        let labels: Vec<&str> = r.agents.iter().map(|a| a.label.as_str()).collect();
        assert_eq!(labels, ["realistic", "realistic-rsu", "realistic"]);
        assert_eq!(r.agents[1].faults.pose_m, 0.0);
        assert_eq!(r.agents[1].faults.flip, Faults::REALISTIC.flip);
        r.set_faults("none+fp=3").unwrap();
        assert_eq!(r.agents[0].faults, Faults::NONE);
        assert_eq!(r.agents[2].faults.false_positives, 3.0);
        let e = r.set_faults("flip=9").unwrap_err();
        assert!(matches!(e.problem, Problem::Value(v) if v.field == "flip"));
        let e = NoiseSetting::parse("huge", 1).unwrap_err().to_string();
        assert!(e.starts_with("invalid noise 'huge': expected mild, moderate, large, realistic"));
    }
}
