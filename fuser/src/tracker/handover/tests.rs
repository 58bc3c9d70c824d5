use super::*;
use crate::tracker::tests::car;
use crate::tracker::TrackerParams;
use std::collections::HashSet;
use v2x_protocol::Velocity;

fn tiling() -> Tiling {
    Tiling::new(100.0).unwrap()
}

fn region(x: i32) -> Region {
    Region {
        tiling: tiling(),
        tile: Tile { x, y: 0 },
        halo_m: 30.0,
    }
}

fn method() -> Method {
    "csba-wls+".parse().unwrap()
}

#[test]
fn id_blocks_are_disjoint_never_hold_no_id_and_pack_the_tile() {
    assert_eq!(id_block(Tile { x: 0, y: 0 }), 1..0xffff);
    assert_eq!(id_block(Tile { x: -1, y: 0 }), 0x0100_0001..0x0100_ffff);
    assert_eq!(id_block(Tile { x: 1, y: 2 }), 0x0204_0001..0x0204_ffff);
    assert_eq!(id_block(Tile { x: -128, y: -128 }).end, NO_ID);
    let mut starts = HashSet::new();
    for x in -128..128 {
        for y in -128..128 {
            let b = id_block(Tile { x, y });
            assert!(!b.contains(&NO_ID) && b.len() == 65534);
            starts.insert(b.start);
        }
    }
    assert_eq!(starts.len(), 256 * 256);
}

#[test]
fn a_tracker_cycles_through_its_ids() {
    let mut tr = Tracker::with_ids(TrackerParams::default(), 5..7);
    let ids: Vec<u32> = (0..3)
        .map(|k| {
            let (_, ids) = tr.step_ids(0, &[car(50.0 * k as f64, 0.0, 0.0)]);
            ids[0]
        })
        .collect();
    // Each step at t = 0 restarts nothing: three boxes far apart, three tentative tracks.
    assert_eq!(ids, [5, 6, 5]);
}

/// A region's tracker with one confirmed car at (95, 50) and (96, 50), in its neighbour's tile.
fn tracker_of_tile_1() -> Tracker {
    let mut tr = Tracker::with_ids(TrackerParams::default(), id_block(Tile { x: 1, y: 0 }));
    tr.step(0, &[car(95.0, 50.0, 0.0)]);
    let out = tr.step(100_000, &[car(96.0, 50.0, 0.0)]);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].tracking_id, 0x0200_0001);
    tr
}

fn theirs(x: f64, y: f64, id: u32, v: f64) -> Detection {
    Detection {
        id,
        velocity: Some(Velocity {
            v: [v, 0.0],
            std: [0.3, 0.3],
        }),
        ..car(x, y, 0.0)
    }
}

#[test]
fn a_track_in_a_neighbours_tile_takes_the_nearest_of_its_ids_and_surer_velocity() {
    let mut tr = tracker_of_tile_1();
    let mut h = Handover::new(region(1));
    // Heard a window late: at 0 ms car 7 at 95.2 (10 m/s, so 96.2 at 100 ms), car 8 further.
    h.hear(
        Tile { x: 0, y: 0 },
        0,
        vec![theirs(97.0, 54.0, 8, 10.0), theirs(95.2, 50.1, 7, 10.0)],
    );
    assert_eq!(h.adopt(&mut tr), 1);
    assert_eq!(tr.tracks[0].id, 7);
    assert_eq!([tr.tracks[0].x[2], tr.tracks[0].x[3]], [10.0, 0.0]);
    assert!((tr.tracks[0].p[(2, 2)] - 0.09).abs() < 1e-12);
    assert_eq!(tr.tracks[0].p[(0, 2)], 0.0);
    // Taking it again changes nothing; the next window shows the car under id 7.
    assert_eq!(h.adopt(&mut tr), 0);
    let out = tr.step(200_000, &[car(97.0, 50.0, 0.0)]);
    assert_eq!(out[0].tracking_id, 7);
}

#[test]
fn the_owners_id_stays_and_far_stale_or_taken_ids_are_not_adopted() {
    let near = |id| theirs(96.2, 50.0, id, 0.0);
    // Its own tile's track keeps its id, whatever a neighbour says of the place.
    let mut own = Tracker::new(TrackerParams::default());
    own.step(0, &[car(105.0, 50.0, 0.0)]);
    own.step(100_000, &[car(105.0, 50.0, 0.0)]);
    let mut h = Handover::new(region(1));
    h.hear(
        Tile { x: 1, y: 0 },
        100_000,
        vec![theirs(105.0, 50.0, 9, 0.0)],
    );
    h.hear(
        Tile { x: 3, y: 0 },
        100_000,
        vec![theirs(105.0, 50.0, 9, 0.0)],
    );
    assert!(
        h.heard.is_empty(),
        "its own tile, and a tile beyond its halo"
    );
    assert_eq!(h.adopt(&mut own), 0);
    // Beyond the gate: 4 m off at 0.5 m stds on both sides.
    let mut tr = tracker_of_tile_1();
    let mut h = Handover::new(region(1));
    h.hear(
        Tile { x: 0, y: 0 },
        100_000,
        vec![theirs(96.0, 54.0, 8, 0.0)],
    );
    assert_eq!(h.adopt(&mut tr), 0);
    // Heard 3 s before: too old.
    let mut late = tracker_of_tile_1();
    late.step(3_100_000, &[car(96.0, 50.0, 0.0)]);
    h.hear(Tile { x: 0, y: 0 }, 100_000, vec![near(7)]);
    assert_eq!(h.adopt(&mut late), 0);
    // An id one of its tracks already holds is not given to another.
    let mut two = tracker_of_tile_1();
    two.tracks.push(Track {
        id: 7,
        ..two.tracks[0].clone()
    });
    two.tracks[1].x[1] = 80.0;
    let mut h = Handover::new(region(1));
    h.hear(Tile { x: 0, y: 0 }, 100_000, vec![near(7)]);
    assert_eq!(h.adopt(&mut two), 0);
    assert_eq!(two.tracks[0].id, 0x0200_0001);
}

use super::super::Track;

/// The ids each car was published under, and whether any window showed a car twice, over
/// `cars` crossing the border x = 100 between tiles 0_0 and 1_0 (half each way, lanes 4 m
/// apart, 10 m/s from 40 m before it), seen by two agents at 0.5 m of noise for 8 s at 10 Hz.
fn crossing(handover: bool, guided: bool, seed: u64) -> (Vec<BTreeSet<u32>>, bool) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let cars = 6;
    let params = TrackerParams::default().with_guided(guided);
    let mut regions = RegionalTrackers::new(tiling(), 30.0, params, handover);
    let mut ids = vec![BTreeSet::new(); cars];
    let mut twice = false;
    for k in 0..80u64 {
        let t = k as f64 * 0.1;
        let agents: Vec<Vec<Detection>> = (0..2)
            .map(|_| {
                (0..cars)
                    .map(|c| {
                        let way = if c % 2 == 0 { 1.0 } else { -1.0 };
                        let x = 100.0 - way * 40.0 + way * 10.0 * t;
                        let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
                        let mut b = car(x + 0.5 * g(), 20.0 + 4.0 * c as f64 + 0.5 * g(), 0.0);
                        b.id = c as u32;
                        b
                    })
                    .collect()
            })
            .collect();
        let out = regions.step(k * 100_000, &agents, &method(), |l| method().fuse(l));
        let mut seen = vec![0; cars];
        for tr in out {
            ids[tr.det.id as usize].insert(tr.tracking_id);
            seen[tr.det.id as usize] += 1;
        }
        twice |= seen.iter().any(|&n| n > 1);
    }
    (ids, twice)
}

#[test]
fn cars_crossing_a_border_keep_their_ids_with_hand_over_and_change_them_without() {
    for guided in [false, true] {
        for seed in 1..=3 {
            let (with, twice) = crossing(true, guided, seed);
            assert!(!twice, "a car published by two regions at once");
            assert!(
                with.iter().all(|ids| ids.len() == 1),
                "guided {guided}, seed {seed}: {with:?}"
            );
            let all: BTreeSet<u32> = with.iter().flatten().copied().collect();
            assert_eq!(all.len(), 6, "one id per car");
            let (without, _) = crossing(false, guided, seed);
            assert!(
                without.iter().all(|ids| ids.len() >= 2),
                "without hand-over each car changes id at the border: {without:?}"
            );
        }
    }
}
