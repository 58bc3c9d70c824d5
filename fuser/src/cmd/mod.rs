//! The subcommands of `v2x-fuser`, one module each, and the option groups they share.

pub(crate) mod admin;
pub(crate) mod files;
pub(crate) mod node;
pub(crate) mod settings;
