//! Time to write and read a frame of cars with stds and velocities as an ETSI CPM, beside the
//! project's own frame encoding of the same frame, at 24 and 200 boxes.
//!
//! Run: `cargo bench -p v2x-cpm --bench codec`.

#![allow(missing_docs)] // criterion_group! generates an undocumented function

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use std::hint::black_box;
use v2x_cpm::Geo;
use v2x_protocol::{wire, AgentKind, Detection, Frame, Velocity};

/// A frame of `n` moving cars on a 100 m grid, each with its id.
fn frame(n: usize) -> Frame {
    Frame {
        agent: "car1".into(),
        kind: AgentKind::Vehicle,
        seq: 0,
        capture_us: 1_700_000_000_000_000,
        origin: [0.0; 3],
        detections: (0..n)
            .map(|i| Detection {
                velocity: Some(Velocity {
                    v: [5.0, -1.0],
                    std: [0.3, 0.3],
                }),
                id: i as u32,
                ..v2x_protocol::fixtures::car((i % 20) as f64 * 5.0, (i / 20) as f64 * 5.0, 0.3)
            })
            .collect(),
    }
    .with_centroid_origin()
}

fn codec(c: &mut Criterion) {
    let geo = Geo {
        lat_deg: 48.1,
        lon_deg: 11.6,
    };
    let mut g = c.benchmark_group("codec");
    for n in [24, 200] {
        let f = frame(n);
        let cpm = v2x_cpm::encode(&f, &geo).unwrap();
        let own = wire::encode(&f).unwrap();
        g.bench_with_input(BenchmarkId::new("cpm_encode", n), &f, |b, f| {
            b.iter(|| v2x_cpm::encode(black_box(f), &geo).unwrap())
        });
        g.bench_with_input(BenchmarkId::new("cpm_decode", n), &cpm, |b, m| {
            b.iter(|| v2x_cpm::decode(black_box(m), &geo).unwrap())
        });
        g.bench_with_input(BenchmarkId::new("frame_encode", n), &f, |b, f| {
            b.iter(|| wire::encode(black_box(f)).unwrap())
        });
        g.bench_with_input(BenchmarkId::new("frame_decode", n), &own, |b, m| {
            b.iter(|| wire::decode(black_box(m)).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, codec);
criterion_main!(benches);
