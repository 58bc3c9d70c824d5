//! Regional fusion, sans-IO: a fixed grid of square tiles in the map frame splits a city between
//! several fusers (`docs/method.md` §9).
//!
//! - An agent sends each box to the tile its centre lies in ([`split`]).
//! - A regional fuser takes its own tile and a halo around it ([`Region::input`]), fuses, and
//!   keeps only the fused boxes whose centre lies in its own tile ([`Region::owns`]).
//!
//! Tiles are half-open squares, [x0, x0 + size) x [y0, y0 + size), so every point lies in exactly
//! one tile and every fused box is published by exactly one region. A group whose members all
//! lie within the halo of the owner's tile is fused there exactly as one fuser would fuse it; a
//! halo at least as wide as the association's reach (the gate's radius) makes that every group.

use std::collections::BTreeMap;
pub use v2x_protocol::tiles::{Tile, Tiling, DEFAULT_HALO_M, DEFAULT_TILE_M};
use v2x_protocol::Detection;

/// An agent's boxes by the tile their centre lies in (one frame per tile it sees).
pub fn split(tiling: &Tiling, dets: &[Detection]) -> BTreeMap<Tile, Vec<Detection>> {
    let mut out: BTreeMap<Tile, Vec<Detection>> = BTreeMap::new();
    for d in dets {
        out.entry(tiling.tile_of(d.center))
            .or_default()
            .push(d.clone());
    }
    out
}

/// One regional fuser's share of the map.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Region {
    /// The grid.
    pub tiling: Tiling,
    /// The tile it publishes.
    pub tile: Tile,
    /// How far beyond its tile it takes boxes (m).
    pub halo_m: f64,
}

impl Region {
    /// The boxes of each agent the region fuses: those within its tile and halo.
    pub fn input(&self, agents: &[Vec<Detection>]) -> Vec<Vec<Detection>> {
        agents
            .iter()
            .map(|list| {
                list.iter()
                    .filter(|d| self.tiling.within(self.tile, d.center, self.halo_m))
                    .cloned()
                    .collect()
            })
            .collect()
    }

    /// Whether a fused box is this region's to publish: its centre lies in the region's tile.
    pub fn owns(&self, d: &Detection) -> bool {
        self.tiling.tile_of(d.center) == self.tile
    }

    /// Fuses the region's input with `fuse` (its fuser's pipeline, or a method) and keeps the
    /// boxes it owns.
    pub fn fuse(
        &self,
        fuse: impl FnOnce(&[Vec<Detection>]) -> Vec<Detection>,
        agents: &[Vec<Detection>],
    ) -> Vec<Detection> {
        let mut out = fuse(&self.input(agents));
        out.retain(|d| self.owns(d));
        out
    }
}

/// What one fuser serves: every agent's boxes, or one tile and its halo.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Scope {
    /// The single fuser of a namespace.
    Whole,
    /// A regional fuser.
    Tile(Region),
}

impl From<Option<Region>> for Scope {
    fn from(r: Option<Region>) -> Scope {
        r.map_or(Scope::Whole, Scope::Tile)
    }
}

impl Scope {
    /// The region, for a regional fuser.
    pub fn region(&self) -> Option<&Region> {
        match self {
            Scope::Whole => None,
            Scope::Tile(r) => Some(r),
        }
    }

    /// The tile it publishes, for a regional fuser.
    pub fn tile(&self) -> Option<Tile> {
        self.region().map(|r| r.tile)
    }

    /// Whether a box is the fuser's input: within its tile and halo (every box, for the whole).
    pub fn takes(&self, d: &Detection) -> bool {
        self.region()
            .is_none_or(|r| r.tiling.within(r.tile, d.center, r.halo_m))
    }

    /// Whether a fused box is the fuser's to publish: its centre lies in its tile (every box,
    /// for the whole).
    pub fn owns(&self, d: &Detection) -> bool {
        self.region().is_none_or(|r| r.owns(d))
    }

    /// The keys it publishes and answers on.
    pub fn keys(&self, ns: &str) -> v2x_protocol::keys::FuserKeys {
        v2x_protocol::keys::FuserKeys::of(ns, self.tile())
    }
}

/// The regions a window needs: every tile some box of `agents` lies in, and the tiles around
/// those (a fused centre lies between its members, so it can fall in a corner tile none of them
/// is in).
pub fn tiles_of(tiling: &Tiling, agents: &[Vec<Detection>]) -> Vec<Tile> {
    let mut tiles: Vec<Tile> = agents
        .iter()
        .flatten()
        .flat_map(|d| tiling.with_halo(tiling.tile_of(d.center), 1.0))
        .collect();
    tiles.sort_unstable();
    tiles.dedup();
    tiles
}

/// What the regional fusers of every tile [`tiles_of`] names publish together for one window,
/// each region fusing its input with `fuse`.
pub fn fuse_regions(
    tiling: Tiling,
    halo_m: f64,
    mut fuse: impl FnMut(&[Vec<Detection>]) -> Vec<Detection>,
    agents: &[Vec<Detection>],
) -> Vec<Detection> {
    tiles_of(&tiling, agents)
        .into_iter()
        .flat_map(|tile| {
            Region {
                tiling,
                tile,
                halo_m,
            }
            .fuse(&mut fuse, agents)
        })
        .collect()
}

#[cfg(test)]
mod tests;
