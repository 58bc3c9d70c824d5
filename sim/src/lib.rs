//! The v2x-fusion simulator: orchestration around the data and evaluation crates.
//!
//! - Re-exported from `v2x-truth`: the ground truth ([`dataset`], [`town`], [`dair`]) and
//!   synthetic agents ([`noise`], [`faults`], [`seed`]); [`gen`] writes agents' results files.
//! - Re-exported from `v2x-eval`: [`metrics`], [`detection_eval`], [`tracking_eval`] and
//!   [`dair_eval`]; [`cli`] reads files into them.
//! - Offline experiments: [`bench`] (the paper's Table 2, tracking, and its modules: asynchronous
//!   agents, regions, real vehicle and roadside data (DAIR-V2X), real detections of two cars
//!   (V2V4Real))
//!   and [`plot`] (a bird's-eye view).
//! - Over Zenoh: [`scenario`] and [`timeline`] (scenario files and their scripted events),
//!   [`run`] (whole scenarios), [`load`] (the fuser under load) and [`certs`] (certificates and
//!   the access-control policy for the secure mode).
//! - [`table`]: the Markdown tables they print.

pub mod bench;
pub mod certs;
pub mod cli;
pub mod existence_fit;
pub mod gen;
pub mod load;
pub mod plot;
pub mod run;
pub mod scenario;
pub mod table;
pub mod timeline;
pub mod wire_bytes;

pub use v2x_eval::{dair_eval, detection_eval, metrics, tracking_eval, v2v4real_eval};
pub use v2x_truth::{dair, dataset, faults, noise, seed, town, v2v4real};
