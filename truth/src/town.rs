//! The synthetic town: the embedded default ground truth, seeded and nuScenes-like.
//!
//! Each scene is a four-arm intersection (two roads of four 3.5 m lanes, sidewalks beside them).
//! Cars, trucks, buses, trailers and construction vehicles drive in lanes at a per-lane speed
//! (spaced so they never overlap) or stand parked along the kerb; pedestrians walk the sidewalks
//! or cross at the crosswalks; cyclists and motorcyclists ride the outer lanes; barriers and cones
//! mark a work zone. Sizes follow per-class nuScenes-like means with about 8% spread; a scene
//! holds 8 to 80 objects (about 24 on average, like the nuScenes validation split), and the
//! class mix follows nuScenes. [`TownConfig::validation`] matches the nuScenes validation split's
//! size: 150 scenes of 20 s at 2 Hz, 6,000 frames, about 145,000 boxes.

use crate::dataset::{Continuous, GroundTruth, GtFrame, GtObject, Motion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use v2x_protocol::nuscenes_json::TokenTable;
use v2x_protocol::{wrap_angle, Class};

/// What town to build.
#[derive(Clone, Debug, PartialEq)]
pub struct TownConfig {
    /// Number of scenes.
    pub scenes: usize,
    /// Length of a scene (s).
    pub seconds: f64,
    /// Frames per second.
    pub hz: f64,
    /// Seed of everything.
    pub seed: u64,
}

impl Default for TownConfig {
    fn default() -> Self {
        TownConfig {
            scenes: 1,
            seconds: 20.0,
            hz: 10.0,
            seed: 7,
        }
    }
}

impl TownConfig {
    /// The nuScenes-validation-sized set: 150 scenes x 20 s at 2 Hz.
    pub fn validation(seed: u64) -> Self {
        TownConfig {
            scenes: 150,
            seconds: 20.0,
            hz: 2.0,
            seed,
        }
    }
}

const HALF_SPAN: f64 = 90.0;
const LANES: [f64; 4] = [-5.25, -1.75, 1.75, 5.25];
const KERB: f64 = 8.6;
const SIDEWALK: f64 = 10.5;

/// Class mix (nuScenes validation proportions, roughly).
const MIX: [(Class, f64); 10] = [
    (Class::Car, 0.45),
    (Class::Pedestrian, 0.20),
    (Class::Barrier, 0.12),
    (Class::TrafficCone, 0.09),
    (Class::Truck, 0.06),
    (Class::Trailer, 0.02),
    (Class::Bus, 0.015),
    (Class::ConstructionVehicle, 0.015),
    (Class::Motorcycle, 0.015),
    (Class::Bicycle, 0.015),
];

/// A moving or static object: its path is p(t) = start + dir * wrap(s0 + v t).
#[derive(Clone, Debug)]
struct Actor {
    class: Class,
    size: [f64; 3],
    /// Point on the path at s = 0.
    origin: [f64; 2],
    /// Unit direction of travel.
    dir: [f64; 2],
    s0: f64,
    speed: f64,
    /// Whether s wraps to stay within the scene.
    wraps: bool,
    yaw: f64,
}

impl Actor {
    /// An actor heading along its path: from `origin`, `s0` m along `dir` at t = 0, at `speed`.
    fn heading(
        (class, size): (Class, [f64; 3]),
        origin: [f64; 2],
        dir: [f64; 2],
        s0: f64,
        speed: f64,
        wraps: bool,
    ) -> Actor {
        Actor {
            class,
            size,
            origin,
            dir,
            s0,
            speed,
            wraps,
            yaw: dir[1].atan2(dir[0]),
        }
    }

    /// Velocity over ground (m/s): constant along the path.
    fn velocity(&self) -> [f64; 2] {
        [self.dir[0] * self.speed, self.dir[1] * self.speed]
    }

    /// How many times the path has wrapped at `t` (0 at t = 0): a wrapped actor leaves the scene
    /// and comes back as another object, with an id of its own.
    fn lap(&self, t: f64) -> i64 {
        if self.wraps {
            ((self.s0 + self.speed * t + HALF_SPAN) / (2.0 * HALF_SPAN)).floor() as i64
        } else {
            0
        }
    }

    fn at(&self, t: f64) -> ([f64; 3], f64) {
        let mut s = self.s0 + self.speed * t;
        if self.wraps {
            s = (s + HALF_SPAN).rem_euclid(2.0 * HALF_SPAN) - HALF_SPAN;
        }
        let c = [
            self.origin[0] + self.dir[0] * s,
            self.origin[1] + self.dir[1] * s,
            self.size[2] / 2.0,
        ];
        (c, self.yaw)
    }
}

fn pick_class(rng: &mut ChaCha8Rng) -> Class {
    let mut u: f64 = rng.gen();
    for (c, p) in MIX {
        if u < p {
            return c;
        }
        u -= p;
    }
    Class::Car
}

fn sample_size(rng: &mut ChaCha8Rng, class: Class) -> [f64; 3] {
    let n = Normal::new(1.0, 0.08).expect("valid normal");
    class.typical_size().map(|s| (s * n.sample(rng)).max(0.1))
}

/// Builds one scene's actors.
fn scene_actors(rng: &mut ChaCha8Rng) -> Vec<Actor> {
    let count = (Normal::new(22f64.ln(), 0.45)
        .expect("valid")
        .sample(rng)
        .exp()
        .round() as usize)
        .clamp(8, 80);
    let mut layout = Layout::draw(rng);
    let mut actors = Vec::with_capacity(count);
    for _ in 0..count {
        let class = pick_class(rng);
        let size = sample_size(rng, class);
        let road = rng.gen_range(0..2);
        let (along, across) = road_frame(road);
        let actor = match class {
            Class::Car
            | Class::Truck
            | Class::Bus
            | Class::Trailer
            | Class::ConstructionVehicle => match layout.vehicle(rng, class, size) {
                Some(a) => a,
                None => continue,
            },
            Class::Pedestrian => pedestrian(rng, size, along, across),
            Class::Bicycle | Class::Motorcycle => two_wheeler(rng, class, size, along, across),
            Class::Barrier | Class::TrafficCone => layout.work_zone(rng, class, size),
        };
        actors.push(actor);
    }
    actors
}

/// A road's (along, across) unit vectors.
fn road_frame(road: usize) -> ([f64; 2], [f64; 2]) {
    if road == 0 {
        ([1.0, 0.0], [0.0, 1.0])
    } else {
        ([0.0, 1.0], [-1.0, 0.0])
    }
}

/// Where a scene's vehicles and work zone go: lane slots, parking bays and the work zone.
struct Layout {
    /// A speed per lane (8 lanes: two roads x four lanes).
    lane_speed: Vec<f64>,
    /// Free slots per lane, 12 m apart.
    lane_slots: Vec<Vec<f64>>,
    /// Free parking bays: (road, side, s).
    parking: Vec<(usize, f64, f64)>,
    zone_road: usize,
    zone_side: f64,
    zone_s: f64,
    /// Work-zone objects placed so far.
    zone_k: usize,
}

impl Layout {
    /// The lanes' speeds and the work zone (on one road's kerb, away from the intersection).
    fn draw(rng: &mut ChaCha8Rng) -> Layout {
        let lane_speed: Vec<f64> = (0..8).map(|_| rng.gen_range(5.0..12.0)).collect();
        let lane_slots: Vec<Vec<f64>> = (0..8)
            .map(|_| (0..15).map(|k| -HALF_SPAN + 12.0 * k as f64).collect())
            .collect();
        let mut parking: Vec<(usize, f64, f64)> = Vec::new();
        for road in 0..2 {
            for side in [-1.0, 1.0] {
                for k in 0..24 {
                    let s = -HALF_SPAN + 7.0 * k as f64 + 3.5;
                    if s.abs() > 16.0 {
                        parking.push((road, side, s));
                    }
                }
            }
        }
        let zone_road = rng.gen_range(0..2);
        let zone_side = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        let zone_s = rng.gen_range(25.0..70.0) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        Layout {
            lane_speed,
            lane_slots,
            parking,
            zone_road,
            zone_side,
            zone_s,
            zone_k: 0,
        }
    }

    /// A vehicle: parked in a free bay, or driving in a free lane slot; none when neither is
    /// left.
    fn vehicle(&mut self, rng: &mut ChaCha8Rng, class: Class, size: [f64; 3]) -> Option<Actor> {
        let (lane_slots, parking, lane_speed) =
            (&mut self.lane_slots, &mut self.parking, &self.lane_speed);
        let parked = class == Class::Car && rng.gen_bool(0.4)
            || class == Class::ConstructionVehicle
            || class == Class::Trailer && rng.gen_bool(0.5);
        let mut free_lanes: Vec<usize> = (0..8).filter(|&l| !lane_slots[l].is_empty()).collect();
        let actor = if parked || free_lanes.is_empty() {
            if parking.is_empty() {
                return None;
            }
            let (road, side, s) = parking.swap_remove(rng.gen_range(0..parking.len()));
            let (along, across) = road_frame(road);
            let off = side * KERB;
            let heading = if side > 0.0 {
                0.0
            } else {
                std::f64::consts::PI
            };
            let yaw = wrap_angle(along[1].atan2(along[0]) + heading + rng.gen_range(-0.05..0.05));
            standing(class, size, [across, along], off, s, yaw)
        } else {
            let lane = free_lanes.swap_remove(rng.gen_range(0..free_lanes.len()));
            let slots = &mut lane_slots[lane];
            let s0 = slots.swap_remove(rng.gen_range(0..slots.len()));
            let (along, across) = road_frame(lane / 4);
            let off = LANES[lane % 4];
            // right-hand traffic: lanes on the positive side drive against `along`
            let sign = if off > 0.0 { -1.0 } else { 1.0 };
            let dir = [along[0] * sign, along[1] * sign];
            let origin = [across[0] * off, across[1] * off];
            Actor::heading((class, size), origin, dir, s0, lane_speed[lane], true)
        };
        Some(actor)
    }

    /// A barrier or cone of the work zone, each the next along it.
    fn work_zone(&mut self, rng: &mut ChaCha8Rng, class: Class, size: [f64; 3]) -> Actor {
        let (zone_road, zone_side, zone_s) = (self.zone_road, self.zone_side, self.zone_s);
        let zone_k = &mut self.zone_k;
        let (along, across) = road_frame(zone_road);
        let s = zone_s + 1.2 * *zone_k as f64 * if class == Class::Barrier { 2.2 } else { 1.0 };
        let off = zone_side
            * (KERB - 1.5
                + if class == Class::TrafficCone {
                    -1.0
                } else {
                    0.0
                });
        *zone_k += 1;
        let yaw = along[1].atan2(along[0]) + rng.gen_range(-0.1..0.1);
        standing(class, size, [across, along], off, s, yaw)
    }
}

/// A pedestrian: crossing at a crosswalk, or on a sidewalk, walking or standing.
fn pedestrian(rng: &mut ChaCha8Rng, size: [f64; 3], along: [f64; 2], across: [f64; 2]) -> Actor {
    let class = Class::Pedestrian;
    if rng.gen_bool(0.3) {
        // crossing at a crosswalk, back and forth over the road width
        let at = if rng.gen_bool(0.5) { 13.0 } else { -13.0 };
        let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        let dir = [across[0] * sign, across[1] * sign];
        Actor::heading(
            (class, size),
            [along[0] * at, along[1] * at],
            dir,
            rng.gen_range(-9.0..9.0),
            rng.gen_range(1.0..1.6),
            false,
        )
    } else {
        let side = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        let off = side * (SIDEWALK + rng.gen_range(-1.0..1.0));
        let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        let dir = [along[0] * sign, along[1] * sign];
        let standing = rng.gen_bool(0.2);
        Actor::heading(
            (class, size),
            [across[0] * off, across[1] * off],
            dir,
            rng.gen_range(-HALF_SPAN..HALF_SPAN),
            if standing {
                0.0
            } else {
                rng.gen_range(1.0..1.7)
            },
            true,
        )
    }
}

/// A bicycle or motorcycle: parked at the sidewalk, or riding at the road's edge.
fn two_wheeler(
    rng: &mut ChaCha8Rng,
    class: Class,
    size: [f64; 3],
    along: [f64; 2],
    across: [f64; 2],
) -> Actor {
    let parked = rng.gen_bool(0.3);
    let side = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
    let off = side * if parked { SIDEWALK - 1.2 } else { 6.6 };
    let sign = -side;
    let dir = [along[0] * sign, along[1] * sign];
    let speed = match (parked, class) {
        (true, _) => 0.0,
        (false, Class::Bicycle) => rng.gen_range(3.0..7.0),
        _ => rng.gen_range(6.0..12.0),
    };
    let origin = [across[0] * off, across[1] * off];
    let s0 = rng.gen_range(-HALF_SPAN..HALF_SPAN);
    Actor::heading((class, size), origin, dir, s0, speed, true)
}

/// One scene of the town in continuous time: its actors, their ids, where the scene sits on the
/// map and when its clock starts.
#[derive(Clone, Debug)]
pub struct TownScene {
    actors: Vec<Actor>,
    /// Per actor: its first lap and the ids of its laps from there.
    ids: Vec<(i64, Vec<u32>)>,
    offset: [f64; 2],
    start_us: u64,
}

impl Continuous for TownScene {
    /// Every object of the scene at `t_us`, with its velocity.
    fn objects_at(&self, t_us: u64) -> Vec<GtObject> {
        let t = (t_us as f64 - self.start_us as f64) / 1e6;
        self.actors
            .iter()
            .zip(&self.ids)
            .map(|(a, (first, laps))| {
                let (c, yaw) = a.at(t);
                let lap = (a.lap(t) - first).clamp(0, laps.len() as i64 - 1);
                GtObject {
                    id: laps[lap as usize],
                    class: a.class,
                    center: [c[0] + self.offset[0], c[1] + self.offset[1], c[2]],
                    size: a.size,
                    yaw,
                    velocity: Some(a.velocity()),
                }
            })
            .collect()
    }
}

/// Builds the synthetic town's ground truth.
pub fn generate(cfg: &TownConfig) -> GroundTruth {
    let mut tokens = TokenTable::new();
    let mut frames = Vec::new();
    let mut scenes = Vec::new();
    let mut town_scenes = Vec::new();
    let steps = (cfg.seconds * cfg.hz).round().max(1.0) as usize;
    for sc in 0..cfg.scenes {
        let mut rng = ChaCha8Rng::seed_from_u64(
            cfg.seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(sc as u64),
        );
        let actors = scene_actors(&mut rng);
        let ids = lap_ids(&actors, cfg, sc, &mut tokens);
        // Each scene sits at its own place on the map and time on the clock.
        let offset = [2000.0 * sc as f64, 0.0];
        let start_us = 1_600_000_000_000_000u64 + sc as u64 * 3_600_000_000;
        let ego_speed = rng.gen_range(4.0..9.0);
        let ego_s0 = rng.gen_range(-60.0..-20.0);
        scenes.push(format!("synthetic-{sc:03}"));
        let scene = TownScene {
            actors,
            ids,
            offset,
            start_us,
        };
        for k in 0..steps {
            let t_us = start_us + (k as f64 * 1e6 / cfg.hz).round() as u64;
            let t = k as f64 / cfg.hz;
            let ego_x =
                ((ego_s0 + ego_speed * t) + HALF_SPAN).rem_euclid(2.0 * HALF_SPAN) - HALF_SPAN;
            frames.push(GtFrame {
                sample_token: format!("syn-{sc:03}-{k:04}"),
                scene: sc,
                timestamp_us: t_us,
                ego: Some([offset[0] + ego_x, offset[1] - 1.75, 0.0]),
                objects: scene.objects_at(t_us),
            });
        }
        town_scenes.push(scene);
    }
    GroundTruth {
        scenes,
        frames,
        tokens,
        skipped: Default::default(),
        motion: Motion::Continuous(
            town_scenes
                .into_iter()
                .map(|s| std::sync::Arc::new(s) as std::sync::Arc<dyn Continuous>)
                .collect(),
        ),
        recorded: None,
    }
}

/// Each actor's object ids, per lap from 10 s before scene `sc` to 10 s after it, so that
/// captures off the frames (phases, offsets) find them: (first lap, id per lap). They are
/// numbered in the order the laps first appear in the frames, then the others: the order in
/// which a reader of the scene's results files meets their tokens.
fn lap_ids(
    actors: &[Actor],
    cfg: &TownConfig,
    sc: usize,
    tokens: &mut TokenTable,
) -> Vec<(i64, Vec<u32>)> {
    let steps = (cfg.seconds * cfg.hz).round().max(1.0) as usize;
    let spans: Vec<(i64, i64)> = actors
        .iter()
        .map(|a| (a.lap(-10.0), a.lap(cfg.seconds + 10.0)))
        .collect();
    let mut order: Vec<(usize, i64)> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for k in 0..steps {
        let t = k as f64 / cfg.hz;
        for (j, a) in actors.iter().enumerate() {
            if seen.insert((j, a.lap(t))) {
                order.push((j, a.lap(t)));
            }
        }
    }
    for (j, &(first, last)) in spans.iter().enumerate() {
        for lap in first..=last {
            if seen.insert((j, lap)) {
                order.push((j, lap));
            }
        }
    }
    let mut ids: Vec<(i64, Vec<u32>)> = spans
        .iter()
        .map(|&(first, last)| (first, vec![0; (last - first + 1) as usize]))
        .collect();
    for (j, lap) in order {
        let token = if lap == 0 {
            format!("syn-{sc:03}-obj{j:03}")
        } else {
            format!("syn-{sc:03}-obj{j:03}-lap{lap}")
        };
        let (first, laps) = &mut ids[j];
        laps[(lap - *first) as usize] = tokens.intern(&token);
    }
    ids
}

/// An actor that stands still, `off` m across and `s` m along a street with directions
/// `[across, along]`.
fn standing(
    class: Class,
    size: [f64; 3],
    [across, along]: [[f64; 2]; 2],
    off: f64,
    s: f64,
    yaw: f64,
) -> Actor {
    Actor {
        class,
        size,
        origin: [
            across[0] * off + along[0] * s,
            across[1] * off + along[1] * s,
        ],
        dir: along,
        s0: 0.0,
        speed: 0.0,
        wraps: false,
        yaw,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_nuscenes_like() {
        let cfg = TownConfig {
            scenes: 20,
            seconds: 4.0,
            hz: 2.0,
            seed: 3,
        };
        let a = generate(&cfg);
        let b = generate(&cfg);
        assert_eq!(a.frames, b.frames);
        assert_eq!(a.frames.len(), 20 * 8);
        let per_frame = a.boxes() as f64 / a.frames.len() as f64;
        assert!((15.0..40.0).contains(&per_frame), "{per_frame}");
        assert!(a.frames.iter().all(|f| (8..=80).contains(&f.objects.len())));
        let cars = a
            .frames
            .iter()
            .flat_map(|f| &f.objects)
            .filter(|o| o.class == Class::Car)
            .count();
        assert!(cars as f64 / a.boxes() as f64 > 0.3);
        // another seed, another town
        let c = generate(&TownConfig { seed: 4, ..cfg });
        assert_ne!(a.frames[0].objects, c.frames[0].objects);
    }

    #[test]
    fn moving_vehicles_never_overlap_in_a_lane() {
        let g = generate(&TownConfig {
            scenes: 5,
            seconds: 10.0,
            hz: 2.0,
            seed: 11,
        });
        for f in &g.frames {
            for (i, a) in f.objects.iter().enumerate() {
                for b in &f.objects[i + 1..] {
                    let same_lane = (a.center[1] - b.center[1]).abs() < 0.1
                        && (a.yaw - b.yaw).abs() < 1e-9
                        && a.center[1].abs() < 6.0;
                    if same_lane && a.class != Class::Pedestrian && b.class != Class::Pedestrian {
                        assert!((a.center[0] - b.center[0]).abs() > 2.0, "{a:?} {b:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn objects_move_at_their_velocity_and_come_back_as_others() {
        let g = generate(&TownConfig {
            scenes: 1,
            seconds: 20.0,
            hz: 10.0,
            seed: 7,
        });
        let Motion::Continuous(scenes) = &g.motion else {
            panic!("the town moves continuously")
        };
        let t0 = g.frames[0].timestamp_us;
        let (mut same, mut wrapped) = (0, 0);
        for k in 0..199 {
            let t = t0 + k * 100_000 + 37_000;
            let now = scenes[0].objects_at(t);
            let later = scenes[0].objects_at(t + 50_000);
            for (a, b) in now.iter().zip(&later) {
                if a.id == b.id {
                    // constant velocity: 50 ms later it is v x 50 ms further
                    let v = a.velocity.unwrap();
                    for i in 0..2 {
                        assert!((b.center[i] - a.center[i] - 0.05 * v[i]).abs() < 1e-9);
                    }
                    same += 1;
                } else {
                    // a jump across the scene is another object
                    assert!((b.center[0] - a.center[0]).hypot(b.center[1] - a.center[1]) > 100.0);
                    wrapped += 1;
                }
            }
        }
        assert!(same > 1000 && wrapped >= 1, "{same} {wrapped}");
        // on the frames, the continuous model is the frames' ground truth
        assert_eq!(
            scenes[0].objects_at(g.frames[5].timestamp_us),
            g.frames[5].objects
        );
    }
}
