//! How a scenario's roles are deployed: the security mode, and a city of regional fusers
//! behind meshed routers.

use anyhow::{anyhow, bail};
use serde::Deserialize;
use std::path::PathBuf;
use v2x_fuser::intake::region::Region;
use v2x_protocol::keys;
use v2x_protocol::net::ZenohArgs;
use v2x_protocol::tiles::{Tile, Tiling};

/// How the roles talk to each other.
#[derive(Copy, Clone, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum SecurityMode {
    /// Plain TCP between peers, no access control.
    #[default]
    Plain,
    /// Mutual TLS through a Zenoh router that holds the access-control policy; every role is a
    /// client of the router.
    Mtls,
}

impl SecurityMode {
    /// The mode's name.
    pub fn name(self) -> &'static str {
        match self {
            SecurityMode::Plain => "plain",
            SecurityMode::Mtls => "mtls",
        }
    }
}

/// Security of a run.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct SecuritySpec {
    /// `plain` or `mtls`.
    pub mode: SecurityMode,
    /// A directory written by `v2x-sim certs` (relative to the scenario file); required when
    /// roles run on separate hosts. A one-process run without it makes its own certificates.
    pub certs: Option<PathBuf>,
    /// The router role's Zenoh options (used with `--role router`).
    pub router: ZenohArgs,
}

/// A Zenoh router of a city deployment.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RouterSpec {
    /// Name (the role is `router-NAME`).
    pub name: String,
    /// Its Zenoh options with `--role router-NAME` (listen, and connect to the routers it
    /// meshes with); a one-process run listens on a free local port and meshes every router
    /// with the first.
    #[serde(default)]
    pub zenoh: ZenohArgs,
}

/// The regional fuser of one tile.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RegionFuserSpec {
    /// Its tile, `COLUMN_ROW` (the role is `fuser-COLUMN_ROW`).
    pub tile: String,
    /// The router it is a client of.
    pub router: String,
    /// Its Zenoh options with `--role fuser-TILE` (a client of its router).
    #[serde(default)]
    pub zenoh: ZenohArgs,
}

/// A city: regional fusers, one per tile, as clients of meshed Zenoh routers; agents publish
/// per tile, each a client of the router of the tile it starts in.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RegionsSpec {
    /// Tile side (m).
    #[serde(default = "default_tile")]
    pub tile_m: f64,
    /// How far beyond its tile a regional fuser takes boxes (m).
    #[serde(default = "default_halo")]
    pub halo_m: f64,
    /// The routers (`[[regions.routers]]`), meshed.
    pub routers: Vec<RouterSpec>,
    /// The regional fusers (`[[regions.fusers]]`); tiles without one are not fused.
    pub fusers: Vec<RegionFuserSpec>,
    /// With `[fuser] track`: the regional fusers hear each other's tracks, so an object keeps
    /// its tracking id across tile borders (`v2x-fuser node --no-track-handover` when false).
    #[serde(default = "yes")]
    pub track_handover: bool,
}

fn yes() -> bool {
    true
}

fn default_tile() -> f64 {
    v2x_fuser::intake::region::DEFAULT_TILE_M
}
fn default_halo() -> f64 {
    v2x_fuser::intake::region::DEFAULT_HALO_M
}

impl RegionsSpec {
    /// The tile grid.
    pub fn tiling(&self) -> Tiling {
        Tiling::new(self.tile_m).expect("checked when the scenario loaded")
    }

    /// Each regional fuser's region, in order.
    pub fn regions(&self) -> Vec<Region> {
        self.fusers
            .iter()
            .map(|f| Region {
                tiling: self.tiling(),
                tile: f.tile.parse().expect("checked when the scenario loaded"),
                halo_m: self.halo_m,
            })
            .collect()
    }

    /// The index of a router by name.
    pub fn router(&self, name: &str) -> Option<usize> {
        self.routers.iter().position(|r| r.name == name)
    }

    pub(super) fn check(&self, security: SecurityMode) -> anyhow::Result<()> {
        Tiling::new(self.tile_m).map_err(|e| anyhow!("regions.tile_m: {e}"))?;
        if !(self.halo_m >= 0.0 && self.halo_m.is_finite()) {
            bail!("regions.halo_m must be >= 0 (got {})", self.halo_m);
        }
        if security != SecurityMode::Plain {
            bail!("regions: a city runs plain for now (mutual TLS needs a certificate per router)");
        }
        if self.routers.is_empty() || self.fusers.is_empty() {
            bail!(
                "regions: a city needs at least one [[regions.routers]] and one [[regions.fusers]]"
            );
        }
        let mut names = std::collections::BTreeSet::new();
        for r in &self.routers {
            keys::validate_chunk("regions.routers: name", &r.name).map_err(anyhow::Error::msg)?;
            if !names.insert(&r.name) {
                bail!("regions.routers: the name '{}' is used twice", r.name);
            }
        }
        let mut tiles = std::collections::BTreeSet::new();
        for f in &self.fusers {
            let t: Tile = f.tile.parse().map_err(|e| anyhow!("regions.fusers: {e}"))?;
            if !tiles.insert(t) {
                bail!("regions.fusers: tile {t} has two fusers");
            }
            if self.router(&f.router).is_none() {
                bail!("regions.fusers: tile {t}: no router named '{}'", f.router);
            }
        }
        Ok(())
    }
}
