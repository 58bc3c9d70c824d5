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

use crate::Method;
use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;
use v2x_protocol::Detection;

/// Default tile side (m).
pub const DEFAULT_TILE_M: f64 = 200.0;
/// Default halo (m): beyond csba-wls+'s reach at large noise (6 Mahalanobis units of two 3 m
/// stds, 25.5 m, per axis).
pub const DEFAULT_HALO_M: f64 = 30.0;

/// One tile of the grid: column `x`, row `y` (tile (0, 0) starts at the map origin).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Tile {
    /// Column: floor(x / size).
    pub x: i32,
    /// Row: floor(y / size).
    pub y: i32,
}

impl fmt::Display for Tile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}_{}", self.x, self.y)
    }
}

impl FromStr for Tile {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("tile '{s}': expected COLUMN_ROW, e.g. 0_0 or -1_2");
        let (x, y) = s.split_once('_').ok_or_else(bad)?;
        Ok(Tile {
            x: x.parse().map_err(|_| bad())?,
            y: y.parse().map_err(|_| bad())?,
        })
    }
}

/// The grid: square tiles of one side, aligned on the map origin.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Tiling {
    size_m: f64,
}

impl Tiling {
    /// A grid of `size_m` tiles (positive and finite, at least 1 m).
    pub fn new(size_m: f64) -> Result<Self, String> {
        if !(size_m.is_finite() && size_m >= 1.0) {
            return Err(format!(
                "tile size {size_m} m: expected a finite size of at least 1 m"
            ));
        }
        Ok(Tiling { size_m })
    }

    /// The tile side (m).
    pub fn size_m(&self) -> f64 {
        self.size_m
    }

    /// The tile a point lies in (far points saturate at the grid's outermost tiles).
    pub fn tile_of(&self, p: [f64; 3]) -> Tile {
        let cell = |v: f64| {
            (v / self.size_m)
                .floor()
                .clamp(i32::MIN as f64, i32::MAX as f64) as i32
        };
        Tile {
            x: cell(p[0]),
            y: cell(p[1]),
        }
    }

    /// The tile's lower corner and upper corner (exclusive).
    pub fn bounds(&self, t: Tile) -> ([f64; 2], [f64; 2]) {
        let lo = [t.x as f64 * self.size_m, t.y as f64 * self.size_m];
        (lo, [lo[0] + self.size_m, lo[1] + self.size_m])
    }

    /// Whether a point lies in the tile grown by `halo_m` on every side.
    pub fn within(&self, t: Tile, p: [f64; 3], halo_m: f64) -> bool {
        let (lo, hi) = self.bounds(t);
        (0..2).all(|k| p[k] >= lo[k] - halo_m && p[k] < hi[k] + halo_m)
    }

    /// The tiles a region of tile `t` with a `halo_m` halo needs boxes from: `t` and every tile
    /// that reaches into its halo.
    pub fn with_halo(&self, t: Tile, halo_m: f64) -> Vec<Tile> {
        let k = (halo_m / self.size_m).ceil().max(0.0) as i32;
        let mut out = Vec::new();
        for dx in -k..=k {
            for dy in -k..=k {
                out.push(Tile {
                    x: t.x.saturating_add(dx),
                    y: t.y.saturating_add(dy),
                });
            }
        }
        out.dedup();
        out
    }
}

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

    /// Fuses the region's input and keeps the boxes it owns.
    pub fn fuse(&self, method: &Method, agents: &[Vec<Detection>]) -> Vec<Detection> {
        let mut out = method.fuse(&self.input(agents));
        out.retain(|d| self.owns(d));
        out
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

/// What the regional fusers of every tile [`tiles_of`] names publish together for one window.
pub fn fuse_regions(
    tiling: Tiling,
    halo_m: f64,
    method: &Method,
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
            .fuse(method, agents)
        })
        .collect()
}

#[cfg(test)]
mod tests;
