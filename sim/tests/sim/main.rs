//! The simulator's command line and evaluation against the devkits' own figures, in one test
//! binary. Run one subject with `cargo test --release -p v2x-sim --test sim SUBJECT::`.

mod cli;
mod eval_real;
mod faults;
mod tracking_devkit;
