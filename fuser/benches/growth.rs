//! Growth of a fusion step from 2 x 200 to 2 x 1,000 objects (the scenes of the `fusion` bench),
//! measured by alternating the sizes: 400 rounds of five 200-object steps, one 1,000-object
//! step and one step of five copies of the 200-object scene set apart, so that a shared
//! machine's drifting speed weighs on all sides alike.
//!
//! The copies lie side by side with gaps wider than the gate reaches (no eligible pair joins two
//! copies, which is checked), so that scene is exactly five times the 200-object instance: its
//! ratio is what the machine adds to a step five times the size (caches, address translation),
//! and the 1,000-object scene's ratio to it is what that scene adds by being a different
//! instance (its boxes have more partners each, as fewer of them lie near the scene's rim).
//!
//! Prints, per method and noise, the median time per step of each and their ratios to the
//! 200-object step; then this machine's time for a read at a random place in memory blocks of a
//! few sizes, which is what a step's working set outgrowing a cache costs.
//!
//! Run: `cargo bench -p v2x-fuser --bench growth` (a few seconds once built); names filter what
//! runs, a method's and a noise level's (`-- csba-wls+ large`).

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;
use std::time::Instant;
use v2x_fuser::maths::association::eligible_pairs;
use v2x_fuser::Method;
use v2x_protocol::{Detection, NoiseProfile};

mod common;
use common::scene;

/// Rounds of alternation.
const ROUNDS: usize = 400;
/// 200-object steps per round.
const SMALL_PER_ROUND: usize = 5;
/// Copies of the 200-object scene in the scene of copies.
const COPIES: usize = 5;

/// The median of `v` (sorted in place).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// `COPIES` copies of `small` side by side along x, each `step` m from the last.
fn side_by_side(small: &[Vec<Detection>], step: f64) -> Vec<Vec<Detection>> {
    small
        .iter()
        .map(|list| {
            (0..COPIES)
                .flat_map(|t| {
                    list.iter().map(move |d| {
                        let mut d = d.clone();
                        d.center[0] += step * t as f64;
                        d
                    })
                })
                .collect()
        })
        .collect()
}

/// The copies of `small` at the closest spacing (10 m steps past the scene's width) where no
/// eligible pair of `m` joins two of them: `COPIES` times the pairs of one.
fn copies_apart(m: &Method, small: &[Vec<Detection>]) -> (Vec<Vec<Detection>>, f64) {
    let Method::Csba(p) = m else {
        panic!("the growth bench runs CSBA methods");
    };
    let pairs = |s: &[Vec<Detection>]| eligible_pairs(p, &s[0], &s[1]).len();
    let one = pairs(small);
    let (lo, hi) = small
        .iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), d| {
            (lo.min(d.center[0]), hi.max(d.center[0]))
        });
    let mut step = (hi - lo + 10.0).ceil();
    loop {
        let copies = side_by_side(small, step);
        if pairs(&copies) == COPIES * one {
            return (copies, step);
        }
        step += 10.0;
    }
}

/// Nanoseconds per read when each read's place depends on the last one, over a random cycle
/// through every 64-byte line of a block of `bytes`.
fn random_read_ns(bytes: usize) -> f64 {
    const LINE: usize = 64 / std::mem::size_of::<usize>();
    let lines = bytes / 64;
    let mut order: Vec<usize> = (0..lines).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(1));
    let mut next = vec![0usize; lines * LINE];
    for (k, &line) in order.iter().enumerate() {
        next[line * LINE] = order[(k + 1) % lines] * LINE;
    }
    const READS: usize = 10_000_000;
    let mut at = 0;
    let t = Instant::now();
    for _ in 0..READS {
        at = next[at];
    }
    black_box(at);
    t.elapsed().as_secs_f64() * 1e9 / READS as f64
}

/// Median seconds per fuse of the small scene, the large one and the copies, timed round by
/// round in turn.
fn time_three(
    m: &Method,
    small: &[Vec<Detection>],
    large: &[Vec<Detection>],
    copies: &[Vec<Detection>],
) -> (f64, f64, f64) {
    let (mut ts, mut tl, mut tc) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..ROUNDS {
        let t = Instant::now();
        for _ in 0..SMALL_PER_ROUND {
            black_box(m.fuse(black_box(small)));
        }
        ts.push(t.elapsed().as_secs_f64() / SMALL_PER_ROUND as f64);
        let t = Instant::now();
        black_box(m.fuse(black_box(large)));
        tl.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        black_box(m.fuse(black_box(copies)));
        tc.push(t.elapsed().as_secs_f64());
    }
    (median(&mut ts), median(&mut tl), median(&mut tc))
}

fn main() {
    // `cargo bench` passes `--bench`; names filter the methods and noise levels, as criterion's
    // filters do.
    let names: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    const METHODS: [&str; 2] = ["csba-wls", "csba-wls+"];
    let noises: Vec<&str> = NoiseProfile::ALL.iter().map(|n| n.name()).collect();
    if let Some(unknown) = names
        .iter()
        .find(|n| !METHODS.contains(&n.as_str()) && !noises.contains(&n.as_str()))
    {
        eprintln!(
            "growth: unknown name {unknown:?}: give methods ({}) and noise levels ({})",
            METHODS.join(", "),
            noises.join(", ")
        );
        std::process::exit(2);
    }
    let wanted = |known: &[&str], name: &str| {
        let given: Vec<&String> = names
            .iter()
            .filter(|n| known.contains(&n.as_str()))
            .collect();
        given.is_empty() || given.iter().any(|n| *n == name)
    };
    println!(
        "| method | noise | 2 x 200 | 2 x 1000 | 1000 / 200 | {COPIES} copies apart | copies / 200 | 1000 / copies |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    let mut steps = Vec::new();
    for name in METHODS {
        if !wanted(&METHODS, name) {
            continue;
        }
        let m: Method = name.parse().expect("known method");
        for noise in NoiseProfile::ALL {
            if !wanted(&noises, noise.name()) {
                continue;
            }
            let (small, large) = (scene(200, 2, noise, 1), scene(1000, 2, noise, 1));
            let (copies, step) = copies_apart(&m, &small);
            steps.push(format!("{name} {}: {step} m", noise.name()));
            let (s, l, c) = time_three(&m, &small, &large, &copies);
            println!(
                "| {name} | {} | {:.1} µs | {:.1} µs | {:.2}x | {:.1} µs | {:.2}x | {:.2}x |",
                noise.name(),
                s * 1e6,
                l * 1e6,
                l / s,
                c * 1e6,
                c / s,
                l / c
            );
        }
    }
    println!(
        "\ncopies: {COPIES} copies of the 2 x 200 scene along x, no eligible pair between two; \
         spacing {}",
        steps.join(", ")
    );
    let reads: Vec<String> = [16, 64, 256, 1024, 4096]
        .iter()
        .map(|&kib| format!("{kib} KiB {:.1} ns", random_read_ns(kib << 10)))
        .collect();
    println!("random reads in a block of {}", reads.join(", "));
}
