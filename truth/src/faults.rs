//! Detector faults (`docs/method.md` §5.1): what a real agent does besides Gaussian jitter. It
//! misses objects, more often far away and behind nearer ones; it sees objects that are not
//! there; it turns headings by pi; it confuses similar classes; and its own pose is wrong, which
//! shifts and turns all of its boxes together. [`Faults`] holds the rates, parsed from a spec
//! such as `detect=0.95,half_range=60,fp=1,flip=0.03` or the name `realistic`; `noise.rs` draws
//! them from a random stream of their own, so the Gaussian noise is the same with or without.

use crate::seed::mix;
use crate::spec::{Problem, SpecError};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::fmt;
use std::str::FromStr;
use v2x_protocol::{wrap_angle, Class, InvalidValue};

/// One agent's fault rates. [`Faults::NONE`] is the paper's ideal detector.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Faults {
    /// Probability of detecting an unoccluded object next to the agent, in [0, 1].
    pub detect: f64,
    /// Range (m) at which the detection probability has fallen to half of `detect`:
    /// p(r) = detect / (1 + (r / half_range)^4). `None`: no fall with range.
    pub half_range_m: Option<f64>,
    /// Probability of missing an object hidden behind a nearer one (the occlusion proxy), in [0, 1].
    pub occlusion: f64,
    /// Mean number of false positives per capture (Poisson), near the agent.
    pub false_positives: f64,
    /// Probability of reporting a heading turned by pi, in [0, 1].
    pub flip: f64,
    /// Probability of reporting the class's look-alike ([`look_alike`]), in [0, 1].
    pub confusion: f64,
    /// Std (m) of the agent's pose error per horizontal axis.
    pub pose_m: f64,
    /// Std (rad) of the agent's heading error.
    pub pose_yaw: f64,
    /// Seconds between independent pose errors, linearly blended between (a slow drift);
    /// `None`: one constant error per scene.
    pub drift_s: Option<f64>,
}

/// Radius (m) around the agent within which false positives appear (or its range, if smaller).
pub const FALSE_POSITIVE_RADIUS: f64 = 50.0;

/// How much lower a false positive's confidence is than the agent's base confidence.
pub const FALSE_POSITIVE_SCORE_DROP: f64 = 0.2;

impl Faults {
    /// No faults: every object seen, nothing invented, perfect pose.
    pub const NONE: Faults = Faults {
        detect: 1.0,
        half_range_m: None,
        occlusion: 0.0,
        false_positives: 0.0,
        flip: 0.0,
        confusion: 0.0,
        pose_m: 0.0,
        pose_yaw: 0.0,
        drift_s: None,
    };

    /// The `realistic` faults; docs/guide.md ("Detector faults") gives the published figures
    /// behind each value.
    pub const REALISTIC: Faults = Faults {
        detect: 0.95,
        half_range_m: Some(60.0),
        occlusion: 0.5,
        false_positives: 1.0,
        flip: 0.03,
        confusion: 0.02,
        pose_m: 0.2,
        pose_yaw: 0.2 * std::f64::consts::PI / 180.0,
        drift_s: Some(20.0),
    };

    /// Whether any fault is active.
    pub fn any(&self) -> bool {
        *self != Faults::NONE
    }

    /// Detection probability of an unoccluded object at range `r` (m).
    pub fn detection_probability(&self, r: f64) -> f64 {
        match self.half_range_m {
            Some(h) => self.detect / (1.0 + (r / h).powi(4)),
            None => self.detect,
        }
    }

    /// The agent's pose error (dx, dy, dyaw) at data time `t_us` of `scene`: zero-mean Gaussian
    /// with the configured stds at every instant. With a drift period T, independent errors sit
    /// at multiples of T and are blended linearly, rescaled so the std stays the configured one.
    pub fn pose_error(&self, seed: u64, agent: usize, scene: usize, t_us: u64) -> [f64; 3] {
        if self.pose_m == 0.0 && self.pose_yaw == 0.0 {
            return [0.0; 3];
        }
        let knot = |k: u64| -> [f64; 3] {
            let stream = mix(
                seed ^ POSE_STREAM,
                agent as u64 + 1,
                (scene as u64) << 40 | k,
            );
            let mut rng = ChaCha8Rng::seed_from_u64(stream);
            let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
            [self.pose_m * g(), self.pose_m * g(), self.pose_yaw * g()]
        };
        let Some(period) = self.drift_s else {
            return knot(0);
        };
        let t = t_us as f64 / (period * 1e6);
        let k = t.floor();
        let f = t - k;
        let (a, b) = (knot(k as u64), knot(k as u64 + 1));
        let norm = ((1.0 - f).powi(2) + f * f).sqrt();
        std::array::from_fn(|i| ((1.0 - f) * a[i] + f * b[i]) / norm)
    }

    /// Checks every rate and std, naming the first bad one.
    pub fn check(&self) -> Result<(), InvalidValue> {
        let unit = [
            ("detect", self.detect),
            ("occlusion", self.occlusion),
            ("flip", self.flip),
            ("confuse", self.confusion),
        ];
        for (name, v) in unit {
            if !(0.0..=1.0).contains(&v) {
                return Err(InvalidValue::new(name, "a probability in [0, 1]", v));
            }
        }
        let bounded = [
            ("fp", self.false_positives, 1000.0),
            ("pose", self.pose_m, 100.0),
            ("pose_yaw", self.pose_yaw, std::f64::consts::PI),
        ];
        for (name, v, max) in bounded {
            if !(0.0..=max).contains(&v) {
                return Err(InvalidValue::new(name, format!("in [0, {max}]"), v));
            }
        }
        for (name, v) in [("half_range", self.half_range_m), ("drift", self.drift_s)] {
            if let Some(v) = v {
                if !(v > 0.0 && v <= 1e6) {
                    return Err(InvalidValue::new(name, "> 0 (and at most 1e6)", v));
                }
            }
        }
        Ok(())
    }
}

impl Default for Faults {
    fn default() -> Self {
        Faults::NONE
    }
}

impl FromStr for Faults {
    type Err = SpecError;
    /// `none`, `realistic`, or `KEY=VALUE,...` over the keys of [`FAULT_KEYS`] (unnamed keys
    /// keep the values of `none`).
    fn from_str(s: &str) -> Result<Self, SpecError> {
        match s.trim() {
            "none" | "" => return Ok(Faults::NONE),
            "realistic" => return Ok(Faults::REALISTIC),
            _ => {}
        }
        let bad = |problem: Problem| SpecError::new("faults", s, problem);
        let mut f = Faults::NONE;
        for part in s.split(',') {
            let (key, value) = part.split_once('=').ok_or_else(|| {
                let (part, keys) = (part.to_string(), keys());
                bad(Problem::NotKeyValue { part, keys })
            })?;
            let (key, value) = (key.trim(), value.trim());
            let v: f64 = value
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| bad(InvalidValue::new(key, "a number", value).into()))?;
            match key {
                "detect" => f.detect = v,
                "half_range" => f.half_range_m = Some(v),
                "occlusion" => f.occlusion = v,
                "fp" => f.false_positives = v,
                "flip" => f.flip = v,
                "confuse" => f.confusion = v,
                "pose" => f.pose_m = v,
                "pose_yaw" => f.pose_yaw = v.to_radians(),
                "drift" => f.drift_s = Some(v),
                _ => {
                    let (key, keys) = (key.to_string(), keys());
                    return Err(bad(Problem::UnknownKey { key, keys }));
                }
            }
        }
        f.check().map_err(|e| bad(e.into()))?;
        Ok(f)
    }
}

impl fmt::Display for Faults {
    /// The spec that parses back to these faults.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if *self == Faults::NONE {
            return f.write_str("none");
        }
        let mut parts = vec![
            format!("detect={}", self.detect),
            format!("occlusion={}", self.occlusion),
            format!("fp={}", self.false_positives),
            format!("flip={}", self.flip),
            format!("confuse={}", self.confusion),
            format!("pose={}", self.pose_m),
            format!("pose_yaw={}", self.pose_yaw.to_degrees()),
        ];
        if let Some(h) = self.half_range_m {
            parts.push(format!("half_range={h}"));
        }
        if let Some(d) = self.drift_s {
            parts.push(format!("drift={d}"));
        }
        f.write_str(&parts.join(","))
    }
}

/// The keys of a faults spec with what each sets, as `--help` lists them.
pub const FAULT_KEYS: &[(&str, &str)] = &[
    (
        "detect",
        "probability of detecting a near, unoccluded object (1)",
    ),
    (
        "half_range",
        "range in m where that probability has halved (none)",
    ),
    (
        "occlusion",
        "probability of missing an object behind a nearer one (0)",
    ),
    ("fp", "false positives per capture, near the agent (0)"),
    ("flip", "probability of a heading turned by pi (0)"),
    ("confuse", "probability of the look-alike class (0)"),
    ("pose", "pose error std per axis, m (0)"),
    ("pose_yaw", "heading error std, degrees (0)"),
    (
        "drift",
        "seconds between independent pose errors (constant per scene)",
    ),
];

/// The names of [`FAULT_KEYS`].
fn keys() -> Vec<&'static str> {
    FAULT_KEYS.iter().map(|(k, _)| *k).collect()
}

/// The class a detector confuses `c` with: car and truck, pedestrian and bicycle, bicycle and
/// motorcycle, bus and truck, trailer and truck, construction vehicle and truck, cone and barrier.
pub fn look_alike(c: Class) -> Class {
    match c {
        Class::Car => Class::Truck,
        Class::Truck => Class::Car,
        Class::Bus | Class::Trailer | Class::ConstructionVehicle => Class::Truck,
        Class::Pedestrian => Class::Bicycle,
        Class::Bicycle => Class::Pedestrian,
        Class::Motorcycle => Class::Bicycle,
        Class::TrafficCone => Class::Barrier,
        Class::Barrier => Class::TrafficCone,
    }
}

/// The class of a false positive: cars half the time, then pedestrians, trucks, barriers, cones.
pub fn false_positive_class(u: f64) -> Class {
    match u {
        u if u < 0.5 => Class::Car,
        u if u < 0.8 => Class::Pedestrian,
        u if u < 0.9 => Class::Truck,
        u if u < 0.95 => Class::Barrier,
        _ => Class::TrafficCone,
    }
}

/// For each object (centre and size) seen from `from`, whether a nearer object covers its
/// bearing: the nearer box's half-width max(l, w) / 2 subtends atan(half / distance) either side.
/// A proxy for occlusion: no heights, no partial cover.
pub fn hidden(objects: &[([f64; 3], [f64; 3])], from: [f64; 3]) -> Vec<bool> {
    let polar: Vec<(f64, f64, f64)> = objects
        .iter()
        .map(|(c, s)| {
            let (dx, dy) = (c[0] - from[0], c[1] - from[1]);
            let d = dx.hypot(dy);
            let half = 0.5 * s[0].max(s[1]);
            (d, dy.atan2(dx), half.atan2(d))
        })
        .collect();
    polar
        .iter()
        .enumerate()
        .map(|(j, &(dj, bj, _))| {
            polar
                .iter()
                .enumerate()
                .any(|(i, &(di, bi, wi))| i != j && di < dj && wrap_angle(bj - bi).abs() < wi)
        })
        .collect()
}

/// Salt of the pose error stream.
const POSE_STREAM: u64 = 0x9053_E770;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_check_and_print_back() {
        assert_eq!("none".parse::<Faults>().unwrap(), Faults::NONE);
        assert_eq!("realistic".parse::<Faults>().unwrap(), Faults::REALISTIC);
        let f: Faults = "fp=2,flip=0.1,pose=0.5,pose_yaw=1,drift=5,half_range=40"
            .parse()
            .unwrap();
        assert_eq!(f.false_positives, 2.0);
        assert_eq!(f.half_range_m, Some(40.0));
        assert!((f.pose_yaw - 1f64.to_radians()).abs() < 1e-15);
        assert_eq!(f.to_string().parse::<Faults>().unwrap(), f);
        assert_eq!(
            Faults::REALISTIC.to_string().parse::<Faults>().unwrap(),
            Faults::REALISTIC
        );
        let err = |s: &str| s.parse::<Faults>().unwrap_err().problem;
        let value = |field: &str, expected: &str, got: &str| {
            Problem::Value(InvalidValue::new(field, expected, got))
        };
        assert_eq!(err("flip=2"), value("flip", "a probability in [0, 1]", "2"));
        assert_eq!(err("flip=x"), value("flip", "a number", "x"));
        let keys = keys();
        let key = "speed".to_string();
        assert_eq!(err("speed=1"), Problem::UnknownKey { key, keys });
        assert!(matches!(err("fp"), Problem::NotKeyValue { part, .. } if part == "fp"));
        let e = value("half_range", "> 0 (and at most 1e6)", "0");
        assert_eq!(err("half_range=0"), e);
        assert_eq!(err("fp=nan"), value("fp", "a number", "nan"));
        assert_eq!(
            "flip=2".parse::<Faults>().unwrap_err().to_string(),
            "invalid faults 'flip=2': flip must be a probability in [0, 1] (got 2)"
        );
    }

    #[test]
    fn detection_probability_halves_at_half_range() {
        let f = Faults::REALISTIC;
        assert_eq!(f.detection_probability(0.0), 0.95);
        assert!((f.detection_probability(60.0) - 0.475).abs() < 1e-12);
        // (30 / 60)^4 = 1/16
        assert!((f.detection_probability(30.0) - 0.95 / (1.0 + 1.0 / 16.0)).abs() < 1e-12);
        assert_eq!(Faults::NONE.detection_probability(1e4), 1.0);
    }

    #[test]
    fn pose_error_has_its_std_and_drifts_slowly() {
        let f: Faults = "pose=0.5,pose_yaw=2,drift=10".parse().unwrap();
        // The std over many scenes, sampled between knots, is the configured one.
        let n = 4000;
        let (mut sx, mut syaw) = (0.0, 0.0);
        for scene in 0..n {
            let e = f.pose_error(7, 1, scene, 3_700_000);
            sx += e[0] * e[0];
            syaw += e[2] * e[2];
        }
        let (sx, syaw) = ((sx / n as f64).sqrt(), (syaw / n as f64).sqrt());
        // the relative std of a sample std over 4000 draws is 1.1%: allow 4 of them
        assert!((sx / 0.5 - 1.0).abs() < 0.045, "{sx}");
        assert!((syaw / 2f64.to_radians() - 1.0).abs() < 0.045, "{syaw}");
        // 100 ms apart it barely moves; constant errors do not move at all.
        let (a, b) = (
            f.pose_error(7, 1, 0, 3_700_000),
            f.pose_error(7, 1, 0, 3_800_000),
        );
        assert!((a[0] - b[0]).abs() < 0.1 * 0.5 && a != b);
        let c: Faults = "pose=0.5".parse().unwrap();
        assert_eq!(c.pose_error(7, 1, 0, 0), c.pose_error(7, 1, 0, 9_000_000));
        assert_ne!(c.pose_error(7, 1, 0, 0), c.pose_error(7, 2, 0, 0));
    }

    #[test]
    fn nearer_boxes_hide_what_is_behind_them() {
        let car = [4.0, 2.0, 1.5];
        let objects = [
            ([10.0, 0.0, 0.0], car),  // in front
            ([30.0, 0.5, 0.0], car),  // behind it: bearing 0.95 deg < atan(2 / 10) = 11.3 deg
            ([30.0, 10.0, 0.0], car), // bearing 18.4 deg: visible
            ([-20.0, 0.0, 0.0], car), // the other way
        ];
        assert_eq!(hidden(&objects, [0.0; 3]), vec![false, true, false, false]);
    }
}
