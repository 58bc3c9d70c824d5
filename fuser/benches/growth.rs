//! Growth of a fusion step from 2 x 200 to 2 x 1,000 objects (the scenes of the `fusion` bench),
//! measured by alternating the two sizes: 400 rounds of five 200-object steps and one
//! 1,000-object step, so that a shared machine's drifting speed weighs on both sides alike.
//! Prints, per method and noise, the median time per step of each size and their ratio.
//!
//! Run: `cargo bench -p v2x-fuser --bench growth` (about a minute).

use std::hint::black_box;
use std::time::Instant;
use v2x_fuser::Method;
use v2x_protocol::NoiseProfile;

mod common;
use common::scene;

/// Rounds of alternation.
const ROUNDS: usize = 400;
/// 200-object steps per round.
const SMALL_PER_ROUND: usize = 5;

/// The median of `v` (sorted in place).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    // `cargo bench` passes `--bench`; a name filters the methods, as criterion's filters do.
    let filter = std::env::args().skip(1).find(|a| !a.starts_with("--"));
    println!("| method | noise | 2 x 200 | 2 x 1000 | 1000 / 200 |");
    println!("|---|---|---:|---:|---:|");
    for name in ["csba-wls", "csba-wls+"] {
        if filter.as_deref().is_some_and(|f| f != name) {
            continue;
        }
        let m: Method = name.parse().expect("known method");
        for noise in NoiseProfile::ALL {
            let (small, large) = (scene(200, 2, noise, 1), scene(1000, 2, noise, 1));
            let (mut ts, mut tl) = (Vec::new(), Vec::new());
            for _ in 0..ROUNDS {
                let t = Instant::now();
                for _ in 0..SMALL_PER_ROUND {
                    black_box(m.fuse(black_box(&small)));
                }
                ts.push(t.elapsed().as_secs_f64() / SMALL_PER_ROUND as f64);
                let t = Instant::now();
                black_box(m.fuse(black_box(&large)));
                tl.push(t.elapsed().as_secs_f64());
            }
            let (s, l) = (median(&mut ts), median(&mut tl));
            println!(
                "| {name} | {} | {:.1} µs | {:.1} µs | {:.2}x |",
                noise.name(),
                s * 1e6,
                l * 1e6,
                l / s
            );
        }
    }
}
