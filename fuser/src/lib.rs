//! Late fusion of 3D boxes from several V2X agents.
//!
//! The modules read as the pipeline a window goes through, all of it sans-IO but the shells:
//! - [`intake`]: admission of agents' frames, the fuser's scope (a region's tile) and the
//!   reassembly of per-tile parts;
//! - [`time`]: windows of frames, motion to the window's time, registration of wrong poses;
//! - [`uncertainty`]: the boxes' stds, from a detector's score, learned online or calibrated;
//! - [`maths`]: CSBA-3D association, WLS-3D fusion, the baselines and the [`Method`] that runs
//!   one of them;
//! - [`tracker`]: tracks over windows;
//! - [`pipeline`]: one closed window through all of the above, the one way every shell fuses;
//! - [`settings`]: every setting of the fuser, for the command line and scenario files alike;
//! - the shells: [`offline`] fuses nuScenes results files, `node` (feature `node`, on by
//!   default) is the Zenoh shell the `v2x-fuser` binary runs and `viz` draws a frame;
//!   [`fuzzing`] holds the fuzz targets' entry points.
//!
//! With `default-features = false` the crate is the fusion library alone, without zenoh, tokio,
//! clap or tracing.

pub mod fuzzing;
pub mod intake;
pub mod maths;
#[cfg(feature = "node")]
pub mod node;
pub mod offline;
pub mod pipeline;
pub mod settings;
pub mod time;
pub mod tracker;
pub mod uncertainty;
#[cfg(feature = "node")]
pub mod viz;

pub use maths::method::{Method, Named, Sourced, METHODS};
