//! Tracks across regions (`docs/method.md` §9.1): each regional fuser tracks its tile and halo,
//! publishes the tracks in its own tile, and hears what its neighbours publish, so that an
//! object keeps its tracking id when it crosses a tile border.
//!
//! - **Ids**: a region's new tracks draw their ids from its tile's own block ([`id_block`]), so
//!   no two regions give one id.
//! - **Hand-over**: before each window, every track of the region whose centre lies in a
//!   neighbour's tile is matched with the tracks that neighbour last published at time t_n,
//!   each predicted to the track's time t: centre c + v (t - t_n), covariance
//!   C + (t - t_n)^2 diag(V). A pair of one class is eligible when
//!   d^2 = D^T (P + C)^-1 D, D the difference of the centres and P the track's, is within
//!   [`HANDOVER_GATE`]; the pairs are assigned one to one at least total d^2, and each track
//!   matched takes the neighbour's id. A track taking an id also takes the neighbour's velocity
//!   and its covariance when they are the surer, and is confirmed: the object is a confirmed
//!   track next door.
//! - **The owner's id wins**: a track in the region's own tile keeps its id, and the neighbours
//!   take it from there. An object driving from tile A into tile B is tracked by both while it
//!   is within B's halo, under A's id; once its centre is in B, B publishes it under that id.
//!
//! Sans-IO: [`Handover::hear`] takes a neighbour's published tracks however they arrived (the
//! node's subscription, or [`RegionalTrackers`] offline).

use super::{Tracked, Tracker};
use crate::intake::region::{tiles_of, Region};
use crate::maths::association::{assign, mahalanobis2_plane, Edge};
use crate::Method;
use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use v2x_protocol::tiles::{Tile, Tiling};
use v2x_protocol::{Detection, NO_ID};

/// Gate on a hand-over pair's d^2: the 99.9% chi-square quantile for 2 degrees of freedom (the
/// centre in x and y).
pub const HANDOVER_GATE: f64 = 13.82;

/// The tracking ids of a tile's regional fuser: 65,534 of its own (`CODE << 16 | n`, n from 1),
/// where CODE packs the tile's column and row, each zigzag-coded to 8 bits. Blocks are
/// disjoint for the 256 x 256 tiles around the map origin (51.2 km square with 200 m tiles);
/// tiles further out share the blocks of tiles 256 tiles away.
pub fn id_block(tile: Tile) -> Range<u32> {
    let zigzag = |v: i32| ((v << 1) ^ (v >> 31)) as u32 & 0xff;
    let code = (zigzag(tile.x) << 8) | zigzag(tile.y);
    let first = (code << 16) | 1;
    first..first + 0xfffe
}

/// A neighbour's tracks as last heard.
#[derive(Clone, Debug)]
struct Heard {
    t_us: u64,
    tracks: Vec<Detection>,
}

/// What a regional fuser knows of its neighbours' tracks.
#[derive(Clone, Debug)]
pub struct Handover {
    region: Region,
    heard: BTreeMap<Tile, Heard>,
}

impl Handover {
    /// Nothing heard yet, for the fuser of `region`.
    pub fn new(region: Region) -> Self {
        Handover {
            region,
            heard: BTreeMap::new(),
        }
    }

    /// The region it serves.
    pub fn region(&self) -> &Region {
        &self.region
    }

    /// Takes the tracks `tile`'s fuser published for its window at `t_us`, each box's id its
    /// tracking id. The latest window per tile is kept; the region's own tile and tiles beyond
    /// its halo are passed over.
    pub fn hear(&mut self, tile: Tile, t_us: u64, tracks: Vec<Detection>) {
        let r = &self.region;
        let near = r.tiling.with_halo(r.tile, r.halo_m);
        if tile == r.tile || !near.contains(&tile) {
            return;
        }
        if self.heard.get(&tile).is_some_and(|h| h.t_us > t_us) {
            return;
        }
        self.heard.insert(tile, Heard { t_us, tracks });
    }

    /// Gives each of the tracker's tracks that lies in a neighbour's tile the id that neighbour
    /// publishes for it; returns how many tracks took a new id.
    pub fn adopt(&self, tracker: &mut Tracker) -> usize {
        let Some(now) = tracker.last_us else {
            return 0;
        };
        let scale = tracker.params.motion.time_scale;
        let max_gap = tracker.params.management.max_gap_s;
        let mut taken = 0;
        for (tile, heard) in &self.heard {
            let dt = (now as f64 - heard.t_us as f64) / 1e6 * scale;
            if dt.abs() > max_gap {
                continue;
            }
            let ours: Vec<usize> = (0..tracker.tracks.len())
                .filter(|&i| {
                    let x = &tracker.tracks[i].x;
                    self.region.tiling.tile_of([x[0], x[1], 0.0]) == *tile
                })
                .collect();
            let mut edges = Vec::new();
            for (a, &i) in ours.iter().enumerate() {
                for (j, d) in heard.tracks.iter().enumerate() {
                    let t = &tracker.tracks[i];
                    if d.class != t.class || d.id == NO_ID {
                        continue;
                    }
                    if let Some(d2) = distance(t, d, dt).filter(|&d2| d2 <= HANDOVER_GATE) {
                        edges.push(Edge::new(a, j, d2));
                    }
                }
            }
            for (a, j) in assign(ours.len(), heard.tracks.len(), &edges) {
                let id = heard.tracks[j].id;
                if tracker.tracks.iter().any(|t| t.id == id) {
                    continue;
                }
                let t = &mut tracker.tracks[ours[a]];
                take_over(t, &heard.tracks[j]);
                if !t.confirmed {
                    t.confirmed = true;
                    tracker.births += 1;
                }
                taken += 1;
            }
        }
        taken
    }
}

/// d^2 between a track's centre and a neighbour's track predicted over `dt` (s of motion), or
/// `None` when the summed covariance is singular.
fn distance(t: &super::Track, d: &Detection, dt: f64) -> Option<f64> {
    let (v, vv) = d
        .velocity
        .as_ref()
        .map_or(([0.0; 2], [0.0; 2]), |v| (v.v, v.std.map(|s| s * s)));
    let c = d.position_covariance();
    let dx = d.center[0] + v[0] * dt - t.x[0];
    let dy = d.center[1] + v[1] * dt - t.x[1];
    let sxy = t.p[(0, 1)] + c[0][1];
    mahalanobis2_plane(
        [dx, dy],
        [
            [t.p[(0, 0)] + c[0][0] + dt * dt * vv[0], sxy],
            [sxy, t.p[(1, 1)] + c[1][1] + dt * dt * vv[1]],
        ],
    )
}

/// A track takes a neighbour's id, and its velocity with its covariance when the neighbour's is
/// the surer (the cross-covariance of the velocity with the centre then starts at zero).
fn take_over(t: &mut super::Track, d: &Detection) {
    t.id = d.id;
    if let Some(v) = &d.velocity {
        let theirs = v.std[0].powi(2) + v.std[1].powi(2);
        if theirs < t.p[(2, 2)] + t.p[(3, 3)] {
            t.x[2] = v.v[0];
            t.x[3] = v.v[1];
            for k in 0..4 {
                for l in 2..4 {
                    t.p[(k, l)] = 0.0;
                    t.p[(l, k)] = 0.0;
                }
            }
            t.p[(2, 2)] = v.std[0].powi(2);
            t.p[(3, 3)] = v.std[1].powi(2);
            t.modes = [(t.x, t.p); 2];
        }
    }
}

/// One window of a fuser's tracking: the tracks step with the fused boxes (`fused`, of the
/// region's tile and halo) or, when the tracker is guided, with each agent's boxes (`lists`)
/// through the tracks; the confirmed tracks it updated are returned, of a `region` only those
/// in its own tile.
pub fn step_region(
    tracker: &mut Tracker,
    region: Option<&Region>,
    t_us: u64,
    fused: &[Detection],
    lists: &[Vec<Detection>],
    method: &Method,
) -> Vec<Tracked> {
    let mut out = if tracker.params.guided() {
        tracker.step_agents(t_us, lists, method)
    } else {
        tracker.step(t_us, fused)
    };
    if let Some(r) = region {
        out.retain(|t| r.owns(&t.det));
    }
    out
}

/// The tracks a region publishes, each box's id its tracking id.
pub fn published(out: &[Tracked]) -> Vec<Detection> {
    out.iter()
        .map(|t| Detection {
            id: t.tracking_id,
            ..t.det.clone()
        })
        .collect()
}

/// Regional fusers that track, offline: one per tile some box has come near (kept to the end,
/// so that no id is given twice), each tracking its tile and halo and (with hand-over) hearing its neighbours' tracks of the window before, as
/// they arrive over the network at the earliest.
#[derive(Clone, Debug)]
pub struct RegionalTrackers {
    tiling: Tiling,
    halo_m: f64,
    params: super::TrackerParams,
    handover: bool,
    regions: BTreeMap<Tile, (Tracker, Handover)>,
    /// What each region published for the last window.
    last: Vec<(Tile, u64, Vec<Detection>)>,
}

impl RegionalTrackers {
    /// No region yet; `handover` false gives regions that never hear each other.
    pub fn new(tiling: Tiling, halo_m: f64, params: super::TrackerParams, handover: bool) -> Self {
        RegionalTrackers {
            tiling,
            halo_m,
            params,
            handover,
            regions: BTreeMap::new(),
            last: Vec::new(),
        }
    }

    /// Every region's window at `t_us` with the agents' boxes, `fuse` fusing each region's
    /// input (its fuser's pipeline) and `method` guiding a guided tracker; returns what the
    /// regions publish together.
    pub fn step(
        &mut self,
        t_us: u64,
        agents: &[Vec<Detection>],
        method: &Method,
        mut fuse: impl FnMut(&[Vec<Detection>]) -> Vec<Detection>,
    ) -> Vec<Tracked> {
        let tiles: BTreeSet<Tile> = tiles_of(&self.tiling, agents)
            .into_iter()
            .chain(self.regions.keys().copied())
            .collect();
        let mut all = Vec::new();
        let mut published_now = Vec::new();
        for tile in tiles {
            let region = Region {
                tiling: self.tiling,
                tile,
                halo_m: self.halo_m,
            };
            let (tracker, handover) = self.regions.entry(tile).or_insert_with(|| {
                (
                    Tracker::with_ids(self.params, id_block(tile)),
                    Handover::new(region),
                )
            });
            if self.handover {
                for (from, t, tracks) in &self.last {
                    handover.hear(*from, *t, tracks.clone());
                }
                handover.adopt(tracker);
            }
            let input = region.input(agents);
            let fused = if self.params.guided() {
                Vec::new()
            } else {
                fuse(&input)
            };
            let out = step_region(tracker, Some(&region), t_us, &fused, &input, method);
            published_now.push((tile, t_us, published(&out)));
            all.extend(out);
        }
        self.last = published_now;
        all
    }
}

#[cfg(test)]
mod tests;
