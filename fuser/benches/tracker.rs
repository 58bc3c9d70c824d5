//! Time per tracker step: 200 confirmed tracks of cars moving at constant velocity, one fused
//! box each per window (0.5 m noise, with velocities), in steady state, by the best assignment
//! and by soft association (`--association soft`); and through the tracks
//! (`step_agents`), two agents' boxes of the same cars.
//!
//! Run: `cargo bench -p v2x-fuser --bench tracker`.

#![allow(missing_docs)] // criterion_group! generates an undocumented function

use criterion::{criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::hint::black_box;
use std::time::Duration;
use v2x_fuser::tracker::{Association, Tracker, TrackerParams};
use v2x_protocol::{Class, Detection, Uncertainty, Velocity, NO_ID};

/// Windows of `n` cars on a 400 m square at 10 Hz, each moving at its own velocity, seen with
/// the noise of `seed`.
fn windows(n: usize, steps: usize, seed: u64) -> Vec<Vec<Detection>> {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let cars: Vec<([f64; 2], [f64; 2])> = (0..n)
        .map(|_| {
            (
                [rng.gen_range(-200.0..200.0), rng.gen_range(-200.0..200.0)],
                [rng.gen_range(-10.0..10.0), rng.gen_range(-10.0..10.0)],
            )
        })
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..steps)
        .map(|k| {
            let t = k as f64 * 0.1;
            cars.iter()
                .map(|(p, v)| {
                    let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
                    Detection {
                        class: Class::Car,
                        center: [
                            p[0] + v[0] * t + 0.5 * g(),
                            p[1] + v[1] * t + 0.5 * g(),
                            1.0,
                        ],
                        size: [4.5, 1.9, 1.6],
                        yaw: v[1].atan2(v[0]),
                        score: 0.8,
                        std: Uncertainty::uniform(0.5, 0.1, 0.1),
                        pos_cov: None,
                        velocity: Some(Velocity {
                            v: [v[0] + 0.3 * g(), v[1] + 0.3 * g()],
                            std: [0.3, 0.3],
                        }),
                        id: NO_ID,
                    }
                })
                .collect()
        })
        .collect()
}

fn bench_step(c: &mut Criterion) {
    let w = windows(200, 40, 1);
    let mut group = c.benchmark_group("tracker");
    group
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .sample_size(30);
    for (name, soft) in [("step/200-tracks", false), ("step-soft/200-tracks", true)] {
        let mut tracker = Tracker::new(TrackerParams::with_mode(if soft {
            Association::Soft
        } else {
            Association::Assignment
        }));
        for (k, boxes) in w.iter().take(20).enumerate() {
            tracker.step(k as u64 * 100_000, boxes);
        }
        assert_eq!(tracker.stats().live, 200, "steady state: every car tracked");
        group.bench_function(name, |b| {
            b.iter_batched(
                || tracker.clone(),
                |mut t| black_box(t.step(2_000_000, black_box(&w[20]))),
                criterion::BatchSize::SmallInput,
            )
        });
    }
    let agents: Vec<Vec<Vec<Detection>>> = (0..40)
        .map(|k| vec![w[k].clone(), windows(200, 40, 2)[k].clone()])
        .collect();
    let method = v2x_fuser::Method::default();
    let mut guided = Tracker::new(TrackerParams::default());
    for (k, a) in agents.iter().take(20).enumerate() {
        guided.step_agents(k as u64 * 100_000, a, &method);
    }
    assert_eq!(guided.stats().live, 200, "steady state: every car tracked");
    group.bench_function("guided/200-tracks-2-agents", |b| {
        b.iter_batched(
            || guided.clone(),
            |mut t| black_box(t.step_agents(2_000_000, black_box(&agents[20]), &method)),
            criterion::BatchSize::SmallInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench_step);
criterion_main!(benches);
