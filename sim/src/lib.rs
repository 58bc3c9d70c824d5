//! The v2x-fusion simulator.
//!
//! - Ground truth: [`dataset`] (nuScenes tables read from files, and the types every other module
//!   shares) and the synthetic [`town`].
//! - Synthetic agents, sans-IO: [`noise`], [`faults`] and [`seed`] (their random streams); [`gen`]
//!   writes their results files.
//! - Evaluation, sans-IO: [`metrics`] (`docs/method.md` §6), [`detection_eval`] and
//!   [`tracking_eval`] (the nuScenes devkit's protocols); [`cli`] reads files into them.
//! - Offline experiments: [`bench`] (the paper's Table 2), [`asyncbench`] (asynchronous agents)
//!   and [`plot`] (a bird's-eye view).
//! - Over Zenoh: [`scenario`] and [`timeline`] (scenario files and their scripted events),
//!   [`run`] (whole scenarios), [`load`] (the fuser under load) and [`certs`] (certificates and
//!   the access-control policy for the secure mode).

pub mod asyncbench;
pub mod bench;
pub mod certs;
pub mod cli;
pub mod dataset;
pub mod detection_eval;
pub mod faults;
pub mod gen;
pub mod load;
pub mod metrics;
pub mod noise;
pub mod plot;
pub mod run;
pub mod scenario;
pub mod seed;
pub mod timeline;
pub mod town;
pub mod tracking_eval;
