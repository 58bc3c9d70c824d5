//! End-to-end tests of v2x-fusion, one module per subject, in one test binary (a release link of
//! Zenoh and tokio costs about a minute, once instead of once per file). Run one subject with
//! `cargo test --release -p v2x-tests --test e2e SUBJECT::`, e.g. `ingest::`.

mod city;
mod cli;
mod cpm;
mod dair;
mod docs;
mod ingest;
mod learn;
mod loopback;
mod motion;
mod processes;
mod regions;
mod resilience;
mod security;
mod timeline;
mod traffic;
mod v2v4real;
