//! The v2x-fusion simulator.
//!
//! Sans-IO cores: [`dataset`] (ground truth: nuScenes tables or the synthetic [`town`]),
//! [`noise`] (agents' noisy detections), [`metrics`] (`docs/method.md` §6) and [`bench`] (the paper's
//! Table 2). [`plot`] draws a bird's-eye view; [`scenario`] and [`run`] drive whole scenarios
//! over Zenoh.

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
pub mod timeline;
pub mod town;
pub mod tracking_eval;
