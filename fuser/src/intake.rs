//! What comes in: [`ingest`] admits each agent's frames (checks, roster, area of interest),
//! [`region`] is a fuser's scope (the whole namespace or a tile with its halo) and [`parts`]
//! reassembles a capture sent per tile.

pub mod ingest;
pub mod parts;
pub mod region;
