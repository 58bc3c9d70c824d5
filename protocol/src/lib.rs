//! The formats v2x-fusion speaks.
//!
//! Everything that crosses a process boundary is defined here, once: the domain types
//! ([`Class`], [`Detection`], [`Uncertainty`], [`Frame`]), the compact quantized wire encoding of a
//! frame ([`wire`]), the Zenoh key expressions ([`keys`]) and the nuScenes detection-results JSON
//! files with their uncertainty extension fields ([`nuscenes_json`]), the KITTI tracking text layouts
//! V2V4Real's detections and labels come in ([`kitti`]), the validity domain
//! ([`limits`]), the access-control policy ([`acl`]) and the Zenoh session options ([`net`]).
//! Without the `session` feature this crate has no network or clock dependencies, and it touches
//! files only to read and write JSON and KITTI text; with it, [`net`] opens Zenoh sessions.

pub mod acl;
#[cfg(feature = "cli")]
pub mod cli;
#[cfg(feature = "fixtures")]
pub mod fixtures;
pub mod fuzzing;
mod invalid;
pub mod keys;
pub mod kitti;
pub mod limits;
pub mod net;
pub mod nuscenes_json;
pub mod pairs;
mod provenance;
pub mod tiles;
pub mod traffic;
mod types;
pub mod wire;

pub use invalid::{InvalidValue, UnknownName};
pub use provenance::{AgentSet, Provenance, ProvenanceError};
pub use types::*;
