//! Zenoh key expressions, built and parsed in one place (specified in `docs/wire-format.md`).
//!
//! Everything lives under `v2x/NS/…`, `NS` being the scenario namespace:
//! `det/AGENT` (detections), `fused` (fused frames), `tracks` (tracked boxes, each box's id its
//! track), `alive/AGENT` (liveliness) and
//! `fuser/stats` (the fuser's statistics queryable).
//!
//! With regions (a tile grid, [`crate::tiles`]), an agent publishes each part of a capture on
//! `det/TILE/AGENT`, and the regional fuser of a tile publishes on `fused/TILE` and
//! `tracks/TILE`, holds `fuser/TILE/alive` and answers `fuser/TILE/stats` ([`FuserKeys`]).

use crate::tiles::Tile;

/// Root of every key.
pub const ROOT: &str = "v2x";

/// Why a name cannot be a key chunk.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NameError {
    /// The name is empty.
    #[error("{what} must not be empty")]
    Empty {
        /// What the name names (`agent name`, `namespace`, ...).
        what: &'static str,
    },
    /// The name holds a separator, a wildcard or whitespace.
    #[error("{what} '{name}' contains '{c}'; use letters, digits, '-', '_' or '.'")]
    BadChar {
        /// What the name names.
        what: &'static str,
        /// The name.
        name: String,
        /// The first character a key chunk cannot hold.
        c: char,
    },
    /// The name is longer than its limit.
    #[error("{len} bytes, more than the limit {max}")]
    TooLong {
        /// The name's length in bytes.
        len: usize,
        /// The limit.
        max: usize,
    },
}

/// Checks that a namespace or agent name is a single, non-empty key chunk without wildcards.
pub fn validate_chunk(what: &'static str, s: &str) -> Result<(), NameError> {
    if s.is_empty() {
        return Err(NameError::Empty { what });
    }
    if let Some(c) = s
        .chars()
        .find(|c| matches!(c, '/' | '*' | '$' | '?' | '#') || c.is_whitespace())
    {
        return Err(NameError::BadChar {
            what,
            name: s.to_string(),
            c,
        });
    }
    Ok(())
}

/// Detections of one agent: `v2x/NS/det/AGENT`.
pub fn detections(ns: &str, agent: &str) -> String {
    format!("{ROOT}/{ns}/det/{agent}")
}

/// Detections of every agent: `v2x/NS/det/*`.
pub fn all_detections(ns: &str) -> String {
    format!("{ROOT}/{ns}/det/*")
}

/// Fused frames: `v2x/NS/fused`.
pub fn fused(ns: &str) -> String {
    format!("{ROOT}/{ns}/fused")
}

/// Tracks: `v2x/NS/tracks`.
pub fn tracks(ns: &str) -> String {
    format!("{ROOT}/{ns}/tracks")
}

/// Liveliness token of one agent: `v2x/NS/alive/AGENT`.
pub fn alive(ns: &str, agent: &str) -> String {
    format!("{ROOT}/{ns}/alive/{agent}")
}

/// Liveliness tokens of every agent: `v2x/NS/alive/*`.
pub fn all_alive(ns: &str) -> String {
    format!("{ROOT}/{ns}/alive/*")
}

/// The simulator's shared start of a run across hosts: `v2x/NS/sim/epoch`.
pub fn sim_epoch(ns: &str) -> String {
    format!("{ROOT}/{ns}/sim/epoch")
}

/// The fuser's statistics queryable: `v2x/NS/fuser/stats`.
pub fn fuser_stats(ns: &str) -> String {
    format!("{ROOT}/{ns}/fuser/stats")
}

/// Liveliness token of the fuser: `v2x/NS/fuser/alive`.
pub fn fuser_alive(ns: &str) -> String {
    format!("{ROOT}/{ns}/fuser/alive")
}

/// Detections of one agent in one tile: `v2x/NS/det/TILE/AGENT`.
pub fn detections_in(ns: &str, tile: Tile, agent: &str) -> String {
    format!("{ROOT}/{ns}/det/{tile}/{agent}")
}

/// Detections of one agent in every tile: `v2x/NS/det/*/AGENT`.
pub fn agent_tiled_detections(ns: &str, agent: &str) -> String {
    format!("{ROOT}/{ns}/det/*/{agent}")
}

/// Detections of every agent in one tile: `v2x/NS/det/TILE/*`.
pub fn tile_detections(ns: &str, tile: Tile) -> String {
    format!("{ROOT}/{ns}/det/{tile}/*")
}

/// Detections of every agent in every tile: `v2x/NS/det/*/*`.
pub fn all_tiled_detections(ns: &str) -> String {
    format!("{ROOT}/{ns}/det/*/*")
}

/// The tile and agent name of a `v2x/NS/det/TILE/AGENT` key, if the key is one.
pub fn tile_agent_of_detections(ns: &str, key: &str) -> Option<(Tile, String)> {
    let rest = key.strip_prefix(&format!("{ROOT}/{ns}/det/"))?;
    let (tile, agent) = rest.split_once('/')?;
    let agent = suffix_after(agent, "")?;
    Some((tile.parse().ok()?, agent))
}

/// The keys a fuser publishes and answers on: the whole namespace's, or one region's.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FuserKeys {
    /// Fused frames: `v2x/NS/fused` or `v2x/NS/fused/TILE`.
    pub fused: String,
    /// Tracks: `v2x/NS/tracks` or `v2x/NS/tracks/TILE`.
    pub tracks: String,
    /// Statistics: `v2x/NS/fuser/stats` or `v2x/NS/fuser/TILE/stats`.
    pub stats: String,
    /// Liveliness: `v2x/NS/fuser/alive` or `v2x/NS/fuser/TILE/alive`.
    pub alive: String,
}

impl FuserKeys {
    /// The keys of the fuser of tile `tile`, or of the single fuser when `None`.
    pub fn of(ns: &str, tile: Option<Tile>) -> Self {
        match tile {
            None => FuserKeys {
                fused: fused(ns),
                tracks: tracks(ns),
                stats: fuser_stats(ns),
                alive: fuser_alive(ns),
            },
            Some(t) => FuserKeys {
                fused: format!("{ROOT}/{ns}/fused/{t}"),
                tracks: format!("{ROOT}/{ns}/tracks/{t}"),
                stats: format!("{ROOT}/{ns}/fuser/{t}/stats"),
                alive: format!("{ROOT}/{ns}/fuser/{t}/alive"),
            },
        }
    }

    /// The keys of any regional fuser (`fused/*` and so on).
    pub fn any_region(ns: &str) -> Self {
        FuserKeys {
            fused: format!("{ROOT}/{ns}/fused/*"),
            tracks: format!("{ROOT}/{ns}/tracks/*"),
            stats: format!("{ROOT}/{ns}/fuser/*/stats"),
            alive: format!("{ROOT}/{ns}/fuser/*/alive"),
        }
    }

    /// The keys of every fuser at once, single and regional (`fused/**` and so on).
    pub fn every(ns: &str) -> Self {
        FuserKeys {
            fused: format!("{ROOT}/{ns}/fused/**"),
            tracks: format!("{ROOT}/{ns}/tracks/**"),
            stats: format!("{ROOT}/{ns}/fuser/**/stats"),
            alive: format!("{ROOT}/{ns}/fuser/**/alive"),
        }
    }
}

/// The agent name of a `v2x/NS/det/AGENT` key, if the key is one.
pub fn agent_of_detections(ns: &str, key: &str) -> Option<String> {
    suffix_after(key, &format!("{ROOT}/{ns}/det/"))
}

/// The agent name of a `v2x/NS/alive/AGENT` key, if the key is one.
pub fn agent_of_alive(ns: &str, key: &str) -> Option<String> {
    suffix_after(key, &format!("{ROOT}/{ns}/alive/"))
}

fn suffix_after(key: &str, prefix: &str) -> Option<String> {
    let rest = key.strip_prefix(prefix)?;
    (!rest.is_empty() && !rest.contains('/')).then(|| rest.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn build_and_parse() {
        assert_eq!(detections("s1", "veh"), "v2x/s1/det/veh");
        assert_eq!(
            agent_of_detections("s1", "v2x/s1/det/veh").as_deref(),
            Some("veh")
        );
        assert_eq!(agent_of_detections("s1", "v2x/s2/det/veh"), None);
        assert_eq!(agent_of_detections("s1", "v2x/s1/det/a/b"), None);
        assert_eq!(
            agent_of_alive("s1", &alive("s1", "rsu")).as_deref(),
            Some("rsu")
        );
        assert_eq!(fused("x"), "v2x/x/fused");
        assert_eq!(tracks("x"), "v2x/x/tracks");
        assert_eq!(fuser_stats("x"), "v2x/x/fuser/stats");
        assert!(validate_chunk("agent", "veh-1").is_ok());
        assert!(validate_chunk("agent", "a/b").is_err());
        assert!(validate_chunk("agent", "").is_err());
        assert!(validate_chunk("agent", "a*").is_err());
    }

    #[test]
    fn tiled_keys_build_and_parse() {
        let t = Tile { x: -1, y: 2 };
        assert_eq!(detections_in("s", t, "veh"), "v2x/s/det/-1_2/veh");
        assert_eq!(tile_detections("s", t), "v2x/s/det/-1_2/*");
        assert_eq!(
            tile_agent_of_detections("s", "v2x/s/det/-1_2/veh"),
            Some((t, "veh".to_string()))
        );
        for bad in [
            "v2x/s/det/veh",
            "v2x/s/det/+1_2/veh",
            "v2x/s/det/-1_2/",
            "v2x/s/det/-1_2/a/b",
            "v2x/t/det/-1_2/veh",
        ] {
            assert_eq!(tile_agent_of_detections("s", bad), None, "{bad}");
        }
        assert_eq!(agent_of_detections("s", "v2x/s/det/-1_2/veh"), None);
        let r = FuserKeys::of("s", Some(t));
        assert_eq!(r.fused, "v2x/s/fused/-1_2");
        assert_eq!(r.stats, "v2x/s/fuser/-1_2/stats");
        assert_eq!(r.alive, "v2x/s/fuser/-1_2/alive");
        assert_eq!(FuserKeys::of("s", None).fused, fused("s"));
    }
}
