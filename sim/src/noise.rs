//! Noisy agents (`docs/method.md` §5): each agent sees every ground-truth object (the paper's setting; an
//! optional sensing range restricts that) through zero-mean Gaussian noise of its profile,
//! independent per axis; sizes are clamped to >= 0.05 m, yaws wrapped; each detection reports the
//! profile's stds and a confidence of base + N(0, 0.05), clamped to [0.01, 1], which does not
//! depend on the box's own error. Every draw comes from a generator seeded by (seed, agent, frame),
//! so output is reproducible byte for byte and independent of evaluation order or threads.

use crate::dataset::{GtFrame, GtObject};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::fmt;
use std::str::FromStr;
use v2x_protocol::{wrap_angle, AgentKind, Detection, NoiseProfile, Uncertainty, Velocity};

/// How one agent perceives.
#[derive(Clone, Debug, PartialEq)]
pub struct AgentNoise {
    /// The stds of the injected noise, reported with each detection.
    pub std: Uncertainty,
    /// The std of the injected velocity noise (m/s per axis), reported with each velocity.
    pub velocity_std: f64,
    /// Base confidence.
    pub base_confidence: f64,
    /// The profile name, or "custom".
    pub label: String,
}

impl AgentNoise {
    /// The noise of a named profile.
    pub fn profile(p: NoiseProfile) -> Self {
        AgentNoise {
            std: p.std(),
            velocity_std: p.velocity_std(),
            base_confidence: p.base_confidence(),
            label: p.name().into(),
        }
    }

    /// Custom stds (confidence base 0.7, velocity std 0.5 m/s).
    pub fn custom(std: Uncertainty) -> Self {
        AgentNoise {
            std,
            velocity_std: 0.5,
            base_confidence: 0.7,
            label: "custom".into(),
        }
    }
}

impl FromStr for AgentNoise {
    type Err = String;
    /// A profile name, `POS,SIZE,YAW_DEG`, or `POS,SIZE,YAW_DEG,VEL` (VEL in m/s).
    fn from_str(s: &str) -> Result<Self, String> {
        if let Ok(p) = s.parse::<NoiseProfile>() {
            return Ok(AgentNoise::profile(p));
        }
        let parts: Vec<&str> = s.split(',').collect();
        let (stds, vel) = match parts.len() {
            4 => {
                let v: f64 = parts[3].trim().parse().map_err(|_| {
                    format!(
                        "invalid noise '{s}': the velocity std '{}' is not a number",
                        parts[3]
                    )
                })?;
                if !v2x_protocol::limits::std_in_range(v) {
                    return Err(format!("invalid noise '{s}': the velocity std must be > 0"));
                }
                (parts[..3].join(","), Some(v))
            }
            _ => (s.to_string(), None),
        };
        let std = v2x_protocol::parse_std(&stds)
            .map_err(|e| format!("{e} (or POS,SIZE,YAW_DEG,VEL with a velocity std in m/s)"))?;
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
    /// Parses `PROFILE` (repeated for `n_agents`) or `P1+P2+...` (one per agent).
    pub fn parse(s: &str, n_agents: usize) -> Result<Self, String> {
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

    /// The four settings of the paper's Table 2.
    pub fn paper() -> Vec<NoiseSetting> {
        ["mild", "moderate", "large", "mild+large"]
            .iter()
            .map(|s| NoiseSetting::parse(s, 2).expect("valid"))
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

/// Mixes seed parts into one 64-bit seed (splitmix64 steps).
pub fn mix(a: u64, b: u64, c: u64) -> u64 {
    let mut z = a ^ b.rotate_left(21) ^ c.rotate_left(42);
    for _ in 0..2 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
    }
    z
}

/// One agent's detections of `objects` (the ground truth at its capture time). `draw` numbers
/// the capture (the frame index for an agent that captures on the data's frames), so that every
/// capture draws its own noise. `range` (m) limits what the agent sees around `position`; `None`
/// means every object (the paper's setting). Velocity noise comes from a stream of its own, so
/// that the position, size and yaw noise are the same with or without velocities.
pub fn detect(
    objects: &[GtObject],
    draw: u64,
    agent: usize,
    noise: &AgentNoise,
    position: [f64; 3],
    range: Option<f64>,
    seed: u64,
) -> Vec<Detection> {
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed, agent as u64 + 1, draw));
    let mut vrng = ChaCha8Rng::seed_from_u64(mix(seed ^ VELOCITY_STREAM, agent as u64 + 1, draw));
    let s = &noise.std;
    let mut g = move || -> f64 { StandardNormal.sample(&mut rng) };
    let mut gv = move || -> f64 { StandardNormal.sample(&mut vrng) };
    let mut out = Vec::with_capacity(objects.len());
    for o in objects {
        // Draw for every object, seen or not, so that the range does not shift the stream.
        let e: [f64; 8] = std::array::from_fn(|_| g());
        let ev: [f64; 2] = std::array::from_fn(|_| gv());
        if let Some(r) = range {
            if (o.center[0] - position[0]).hypot(o.center[1] - position[1]) > r {
                continue;
            }
        }
        let sv = noise.velocity_std;
        out.push(Detection {
            class: o.class,
            center: std::array::from_fn(|k| o.center[k] + s.pos[k] * e[k]),
            size: std::array::from_fn(|k| (o.size[k] + s.size[k] * e[3 + k]).max(0.05)),
            yaw: wrap_angle(o.yaw + s.yaw * e[6]),
            score: (noise.base_confidence + 0.05 * e[7]).clamp(0.01, 1.0),
            std: *s,
            pos_cov: None,
            velocity: o.velocity.map(|v| Velocity {
                v: [v[0] + sv * ev[0], v[1] + sv * ev[1]],
                std: [sv, sv],
            }),
            id: o.id,
        });
    }
    out
}

/// Salt of the velocity noise stream.
const VELOCITY_STREAM: u64 = 0x7E10_C17E;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::GtObject;
    use v2x_protocol::Class;

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
            let d = detect(&f.objects, 0, 0, &noise, [0.0; 3], None, 42);
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
        let a = detect(&f.objects, 3, 1, &noise, [0.0; 3], None, 9);
        let b = detect(&f.objects, 3, 1, &noise, [0.0; 3], None, 9);
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        assert_ne!(a, detect(&f.objects, 3, 1, &noise, [0.0; 3], None, 10));
        assert_ne!(
            a,
            detect(&f.objects, 3, 0, &noise, [0.0; 3], None, 9),
            "agents draw independently"
        );
    }

    #[test]
    fn range_limits_what_an_agent_sees() {
        let f = frame(100);
        let d = detect(
            &f.objects,
            0,
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
        assert!(NoiseSetting::parse("huge", 2).unwrap_err().contains("mild"));
        let c = NoiseSetting::parse("0.2,0.1,3", 2).unwrap();
        assert!((c.agents[1].std.yaw - 3f64.to_radians()).abs() < 1e-12);
        assert_eq!(c.agents[1].velocity_std, 0.5);
        let c = NoiseSetting::parse("0.2,0.1,3,0.8", 1).unwrap();
        assert_eq!(c.agents[0].velocity_std, 0.8);
        assert!(NoiseSetting::parse("0.2,0.1,3,x", 1).is_err());
    }
}
