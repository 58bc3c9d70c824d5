//! Runs fusion steps on one of the benches' scenes and nothing else, for a profiler to count
//! what a step costs at each size (`perf record`, `valgrind --tool=cachegrind`):
//!
//! `cargo run --release -p v2x-fuser --example steps -- METHOD NOISE OBJECTS STEPS [SEED]`
//!
//! e.g. `csba-wls+ large 1000 60`: 60 steps of 2 x 1,000 objects at large noise (seed 1);
//! OBJECTS may name the agents too, `64x200` for 64 agents of 200 objects.

use std::hint::black_box;
use std::process::ExitCode;
use v2x_fuser::Method;
use v2x_protocol::NoiseProfile;

#[path = "../benches/common/mod.rs"]
mod common;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: steps METHOD NOISE OBJECTS STEPS [SEED]";
    let [method, noise, objects, steps, rest @ ..] = &args[..] else {
        eprintln!("{usage}");
        return ExitCode::FAILURE;
    };
    let parsed = (
        method.parse::<Method>().ok(),
        NoiseProfile::ALL.into_iter().find(|p| p.name() == noise),
        parse_size(objects),
        steps.parse::<usize>().ok(),
        rest.first().map_or(Some(1), |s| s.parse::<u64>().ok()),
    );
    let (Some(method), Some(noise), Some((agents, objects)), Some(steps), Some(seed)) = parsed
    else {
        eprintln!("{usage}\n  METHOD a fusion method (csba-wls+, ...), NOISE one of mild, moderate, large, OBJECTS N or AGENTSxN");
        return ExitCode::FAILURE;
    };
    let scene = common::scene(objects, agents, noise, seed);
    let mut fused = 0;
    for _ in 0..steps {
        fused += black_box(method.fuse(black_box(&scene))).len();
    }
    println!("{steps} steps, {} fused boxes each", fused / steps.max(1));
    ExitCode::SUCCESS
}

/// `N` (two agents) or `AxN`: the agents and the objects.
fn parse_size(s: &str) -> Option<(usize, usize)> {
    match s.split_once('x') {
        Some((a, n)) => Some((a.parse().ok()?, n.parse().ok()?)),
        None => Some((2, s.parse().ok()?)),
    }
}
