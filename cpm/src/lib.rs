//! The ETSI Collective Perception Message (TS 103 324 Release 2, UPER-encoded ASN.1): a frame
//! of boxes as the standard message that V2X stacks exchange, and a received CPM back as boxes.
//!
//! The message types ([`asn`]) are compiled from the official ASN.1 modules in `cpm/asn1` by
//! rasn-compiler (`cpm/codegen`; CI checks that they match). This crate maps the project's
//! [`Frame`] to them ([`encode`]) and back ([`decode`]), sans-IO; what the message's resolution
//! loses on the way is listed in docs/wire-format.md ("ETSI CPM") and tested here.
//!
//! Positions: the map frame's x axis points East and y North (as the CPM's own axes); the CPM's
//! reference position is the frame's origin in WGS84, through [`Geo`], the map origin's
//! latitude and longitude.

#[rustfmt::skip]
#[allow(missing_docs, clippy::all, clippy::pedantic)]
mod generated;

mod classes;
mod decode;
mod encode;
mod units;

pub mod fuzzing;

/// The CPM's types, as compiled from the ETSI modules.
pub mod asn {
    pub use crate::generated::cpm_originating_station_containers::*;
    pub use crate::generated::cpm_pdu_descriptions::*;
    pub use crate::generated::cpm_perceived_object_container::*;
    pub use crate::generated::etsi_its_cdd::*;
}

pub use decode::{decode, Cpm, DecodeError, Skipped};
pub use encode::{encode, message_bytes, EncodeError};
pub use units::{station_id, Geo};

/// The map origin CPMs are written and read against, a command-line option (`--map-origin`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct MapOrigin {
    /// WGS84 latitude and longitude (degrees) of the map frame's origin (x East, y North), for
    /// ETSI CPMs (docs/cpm.md): their positions are geographic, so sender and receiver give
    /// the same.
    #[cfg_attr(
        feature = "cli",
        arg(long = "map-origin", value_name = "LAT,LON", default_value = "0,0")
    )]
    pub geo: Geo,
}
pub use v2x_protocol::Frame;

/// The ItsPduHeader's protocol version of a Release 2 CPM.
pub const PROTOCOL_VERSION: u8 = 2;
/// The ItsPduHeader's message id of a CPM.
pub const MESSAGE_ID: u8 = 14;
/// Most perceived objects one CPM carries (`numberOfPerceivedObjects` is one byte).
pub const MAX_OBJECTS: usize = 255;

#[cfg(test)]
mod tests;
