//! Late fusion of 3D boxes from several V2X agents.
//!
//! The sans-IO core: [`association`] (CSBA-3D), [`fusion`] (WLS-3D), [`align`] (box-level
//! registration of agents with a wrong pose), [`geometry`] and
//! [`baselines`] (the comparison methods), [`method`] (the `Fuser` API: a [`Method`] value fuses
//! one time step), [`window`] (time alignment of frames) and [`ingest`] (admission of frames:
//! validation, clock tolerance, bounded agent table), [`region`] (tiles and regional fusers) and
//! [`parts`] (reassembly of a capture sent per tile),
//! [`tracker`] (tracks over windows), [`learn`] (each agent's stds learned from its boxes, and
//! the consistency monitor) and [`stdmodel`] (an agent's calibrated error model).
//! [`detector`] readies a real detector's boxes (stds from score and range, group scores,
//! duplicates and tail). [`motion`] predicts boxes to a window's time, [`ratelog`] bounds the node's warnings and
//! [`fuzzing`] holds the fuzz targets' entry points. [`settings`] is every setting of the fuser,
//! for the command line and scenario files alike. [`offline`] fuses nuScenes results files,
//! and `node` (feature `node`, on by default) is the thin Zenoh shell the `v2x-fuser` binary
//! runs. With `default-features = false` the crate is the fusion library alone, without zenoh,
//! tokio, clap or tracing.

pub mod align;
pub mod association;
pub mod baselines;
pub mod detector;
pub mod fusion;
pub mod fuzzing;
pub mod geometry;
pub mod ingest;
pub mod learn;
pub mod method;
pub mod motion;
#[cfg(feature = "node")]
pub mod node;
pub mod offline;
pub mod parts;
pub mod pipeline;
pub mod ratelog;
pub mod region;
pub mod settings;
pub mod stdmodel;
pub mod tracker;
#[cfg(feature = "node")]
pub mod viz;
pub mod window;

pub use method::{Method, Named, Sourced, METHODS};
