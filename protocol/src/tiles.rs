//! The map's tile grid, shared by agents and regional fusers: square tiles of one side in the
//! map frame ([`Tiling`]), their names in key expressions ([`Tile`]), and the list of tiles one
//! capture covers, sent with each of its parts as a Zenoh attachment ([`encode_tiles`],
//! [`decode_tiles`]) so that a regional fuser knows when it holds every part it will get.
//!
//! Tiles are half-open squares, [x0, x0 + size) x [y0, y0 + size), so every point lies in exactly
//! one tile.

use std::fmt;
use std::str::FromStr;

/// Most tiles one capture may cover (an agent sees a few hundred metres; a tile is at least 1 m,
/// but a part per tile beyond this many would flood the network).
pub const MAX_TILES_PER_CAPTURE: usize = 64;

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

/// A tile, a grid or a tile list that cannot be.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TileError {
    /// A tile name not of the form COLUMN_ROW.
    #[error("tile '{0}': expected COLUMN_ROW, e.g. 0_0 or -1_2")]
    Name(String),
    /// A tile side that is not finite or under 1 m.
    #[error("tile size {0} m: expected a finite size of at least 1 m")]
    Size(f64),
    /// A tile side or halo that is not a number.
    #[error("'{0}': expected metres")]
    NotMetres(String),
    /// A halo that is negative or not finite.
    #[error("halo {0} m: expected a finite width of at least 0 m")]
    Halo(f64),
    /// A tile list longer than any list of [`MAX_TILES_PER_CAPTURE`] tiles.
    #[error("tile list of {0} bytes is too long")]
    TooLong(usize),
    /// A tile list that is not UTF-8.
    #[error("tile list is not UTF-8")]
    NotUtf8,
    /// A tile list of no tiles or too many.
    #[error("a capture covers 1 to {MAX_TILES_PER_CAPTURE} tiles (got {0})")]
    Count(usize),
    /// A tile list out of order or with a tile twice.
    #[error("tile list is not sorted without repeats")]
    Unsorted,
    /// A part that came without its tile list.
    #[error("no tile list attached")]
    Missing,
}

impl FromStr for Tile {
    type Err = TileError;

    fn from_str(s: &str) -> Result<Self, TileError> {
        let bad = || TileError::Name(s.to_string());
        let (x, y) = s.split_once('_').ok_or_else(bad)?;
        let t = Tile {
            x: x.parse().map_err(|_| bad())?,
            y: y.parse().map_err(|_| bad())?,
        };
        // One spelling per tile (no '+', no leading zeros), so names compare as keys do.
        if t.to_string() != s {
            return Err(bad());
        }
        Ok(t)
    }
}

impl FromStr for Tiling {
    type Err = TileError;

    fn from_str(s: &str) -> Result<Self, TileError> {
        Tiling::new(s.parse().map_err(|_| TileError::NotMetres(s.to_string()))?)
    }
}

/// The map's tiles on the command line (`--tile-size`), declared once for agents, regional
/// fusers and the regions bench.
#[derive(Copy, Clone, Debug, Default)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct TileSize {
    /// Side of the map's square tiles (m), one for every agent and regional fuser of a
    /// deployment (at least 1 m; a fuser serving a --tile: 200 unless given).
    #[cfg_attr(feature = "cli", arg(long = "tile-size", value_name = "METRES"))]
    pub tiling: Option<Tiling>,
}

impl TileSize {
    /// The tiles given, or tiles of [`DEFAULT_TILE_M`].
    pub fn tiling_or_default(&self) -> Tiling {
        self.tiling.unwrap_or(Tiling {
            size_m: DEFAULT_TILE_M,
        })
    }
}

/// A regional fuser's halo on the command line (`--halo`), for fusers and the regions bench.
#[derive(Copy, Clone, Debug, Default)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct Halo {
    /// How far beyond its tile a regional fuser takes boxes (m; 30 unless given): at least the
    /// association's reach, so groups across a border are fused as one fuser would.
    #[cfg_attr(feature = "cli", arg(long, value_name = "METRES", value_parser = parse_halo))]
    pub halo: Option<f64>,
}

impl Halo {
    /// The halo given, or [`DEFAULT_HALO_M`].
    pub fn halo_m(&self) -> f64 {
        self.halo.unwrap_or(DEFAULT_HALO_M)
    }
}

/// A halo width: finite and at least 0 m.
pub fn parse_halo(s: &str) -> Result<f64, TileError> {
    let m: f64 = s.parse().map_err(|_| TileError::NotMetres(s.to_string()))?;
    if !(m.is_finite() && m >= 0.0) {
        return Err(TileError::Halo(m));
    }
    Ok(m)
}

/// The grid: square tiles of one side, aligned on the map origin.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Tiling {
    size_m: f64,
}

impl Tiling {
    /// A grid of `size_m` tiles (positive and finite, at least 1 m).
    pub fn new(size_m: f64) -> Result<Self, TileError> {
        if !(size_m.is_finite() && size_m >= 1.0) {
            return Err(TileError::Size(size_m));
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

    /// How far a point lies from the nearest border of its tile (m; 0 on a border).
    pub fn border_distance(&self, p: [f64; 2]) -> f64 {
        let (lo, hi) = self.bounds(self.tile_of([p[0], p[1], 0.0]));
        (0..2)
            .map(|k| (p[k] - lo[k]).abs().min((hi[k] - p[k]).abs()))
            .fold(f64::INFINITY, f64::min)
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

/// The attachment of a capture's parts: its tiles, sorted, without repeats, separated by spaces
/// (`0_0 1_0`).
pub fn encode_tiles(tiles: &[Tile]) -> Result<Vec<u8>, TileError> {
    check_tiles(tiles)?;
    Ok(tiles
        .iter()
        .map(Tile::to_string)
        .collect::<Vec<_>>()
        .join(" ")
        .into_bytes())
}

/// Reads a part's attachment back: at least one and at most [`MAX_TILES_PER_CAPTURE`] tiles,
/// sorted and without repeats (what [`encode_tiles`] writes).
pub fn decode_tiles(bytes: &[u8]) -> Result<Vec<Tile>, TileError> {
    if bytes.len() > MAX_TILES_PER_CAPTURE * 24 {
        return Err(TileError::TooLong(bytes.len()));
    }
    let text = std::str::from_utf8(bytes).map_err(|_| TileError::NotUtf8)?;
    let tiles = text
        .split(' ')
        .map(str::parse)
        .collect::<Result<Vec<Tile>, _>>()?;
    check_tiles(&tiles)?;
    Ok(tiles)
}

fn check_tiles(tiles: &[Tile]) -> Result<(), TileError> {
    if tiles.is_empty() || tiles.len() > MAX_TILES_PER_CAPTURE {
        return Err(TileError::Count(tiles.len()));
    }
    if tiles.windows(2).any(|w| w[0] >= w[1]) {
        return Err(TileError::Unsorted);
    }
    Ok(())
}

#[cfg(test)]
mod tests;
