//! Ground truth and synthetic agents for v2x-fusion, sans-IO except for reading tables.
//!
//! - [`dataset`]: the ground truth every other crate scores against, read from nuScenes-format
//!   tables (the types all modules share live here).
//! - [`dair`]: DAIR-V2X-C and V2X-Seq-SPD cooperative data: its ground truth and its two real
//!   agents.
//! - [`v2v4real`]: V2V4Real's real detections of two cars, their labels and the dataset's references.
//! - [`town`]: a synthetic town whose actors move continuously.
//! - [`noise`] and [`faults`]: agents' noisy detections and detector faults drawn from the
//!   ground truth; [`stated`]: the stds they state; [`seed`]: their independent random streams.

pub mod dair;
pub mod dataset;
pub mod faults;
pub mod noise;
pub mod seed;
pub mod spec;
pub mod stated;
pub mod town;
pub mod v2v4real;
