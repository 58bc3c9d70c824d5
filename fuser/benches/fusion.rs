//! Time per fusion step: csba-wls (and csba-wls+) for 2 agents x {10, 25, 80, 200, 1000} objects
//! at mild, moderate and large noise, {2, 4, 8} agents x 80 objects, every method at 2 x 80, and
//! the registration of `--align` at 2 x 80.
//! Scenes have nuScenes-like density (80 objects within 50 m, the area grows with the count)
//! and class mix.
//!
//! Run: `cargo bench -p v2x-fuser --bench fusion` (add a filter such as `csba-wls/2x80` to pick).

#![allow(missing_docs)] // criterion_group! generates an undocumented function

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use std::hint::black_box;
use std::time::Duration;
use v2x_fuser::Method;
use v2x_protocol::NoiseProfile;

mod common;
use common::scene;

fn bench_objects(c: &mut Criterion) {
    for method in ["csba-wls", "csba-wls+"] {
        let m: Method = method.parse().expect("known method");
        let mut group = c.benchmark_group(format!("{method}/2-agents"));
        group
            .warm_up_time(Duration::from_millis(500))
            .measurement_time(Duration::from_secs(2))
            .sample_size(30);
        for noise in NoiseProfile::ALL {
            for n in [10usize, 25, 80, 200, 1000] {
                let s = scene(n, 2, noise, 1);
                group.bench_with_input(BenchmarkId::new(noise.name(), n), &s, |b, s| {
                    b.iter(|| black_box(m.fuse(black_box(s))))
                });
            }
        }
        group.finish();
    }
}

fn bench_agents(c: &mut Criterion) {
    let m: Method = "csba-wls".parse().expect("known method");
    let mut group = c.benchmark_group("csba-wls/80-objects");
    group
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30);
    for noise in NoiseProfile::ALL {
        for agents in [2usize, 4, 8] {
            let s = scene(80, agents, noise, 2);
            group.bench_with_input(BenchmarkId::new(noise.name(), agents), &s, |b, s| {
                b.iter(|| black_box(m.fuse(black_box(s))))
            });
        }
    }
    group.finish();
}

fn bench_methods(c: &mut Criterion) {
    let mut group = c.benchmark_group("methods/2x80");
    group
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30);
    for noise in [NoiseProfile::Mild, NoiseProfile::Large] {
        let s = scene(80, 2, noise, 3);
        for m in Method::all_with_ablations() {
            group.bench_with_input(BenchmarkId::new(m.name(), noise.name()), &s, |b, s| {
                b.iter(|| black_box(m.fuse(black_box(s))))
            });
        }
    }
    group.finish();
}

/// Registration of agent 1 to agent 2 at 2 x 80 objects (per window, and filtered in steady
/// state), beside the csba-wls+ step it precedes.
fn bench_align(c: &mut Criterion) {
    use v2x_fuser::time::align::{align, AlignParams, Aligner};
    let mut group = c.benchmark_group("align/2x80");
    group
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30);
    let p = AlignParams::default();
    for noise in [NoiseProfile::Mild, NoiseProfile::Moderate] {
        let s = scene(80, 2, noise, 4);
        group.bench_with_input(BenchmarkId::new("per-window", noise.name()), &s, |b, s| {
            b.iter(|| black_box(align(black_box(s), 1, &p)))
        });
        let mut filtered = Aligner::new(p);
        let mut t = 0u64;
        for _ in 0..10 {
            t += 100_000;
            filtered.align(Some(t), &["a", "b"], &s, 1);
        }
        group.bench_with_input(BenchmarkId::new("filtered", noise.name()), &s, |b, s| {
            b.iter(|| {
                t += 100_000;
                black_box(filtered.align(Some(t), &["a", "b"], black_box(s), 1))
            })
        });
    }
    group.finish();
}

criterion_group!(
    benches,
    bench_objects,
    bench_agents,
    bench_methods,
    bench_align
);
criterion_main!(benches);
