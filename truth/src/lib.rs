//! Ground truth and synthetic agents for v2x-fusion, sans-IO except for reading tables.
//!
//! - [`dataset`]: the ground truth every other crate scores against, read from nuScenes-format
//!   tables (the types all modules share live here).
//! - [`town`]: a synthetic town whose actors move continuously.
//! - [`noise`] and [`faults`]: agents' noisy detections and detector faults drawn from the
//!   ground truth; [`seed`]: their independent random streams.

pub mod dataset;
pub mod faults;
pub mod noise;
pub mod seed;
pub mod town;
