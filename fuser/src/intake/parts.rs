//! Reassembly of a capture's per-tile parts at a regional fuser, sans-IO.
//!
//! With regions an agent sends each capture as one part per tile its boxes lie in, every part
//! naming the capture's tiles (`v2x_protocol::tiles`). A regional fuser subscribes to a few of
//! those tiles, so it waits for the parts of a capture in the tiles it subscribes to and the
//! capture lists, then hands on one frame holding them all. A capture whose parts do not all
//! come within `max_wait` goes on with the parts that came (counted as incomplete); a part of a
//! capture already handed on is counted late and dropped, never fused twice.
//!
//! Parts of one capture must agree on everything but their boxes (kind, capture time, tile
//! list); a part that does not, repeats a tile, or comes from a tile its list does not name is
//! rejected. At most `max_pending` captures wait at once; beyond, the oldest goes on as it is.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use v2x_protocol::tiles::Tile;
use v2x_protocol::{Detection, Frame};

/// Why a part was not taken.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PartError {
    /// The part's tile is not among the capture's tiles, or not one this fuser subscribes to.
    TileNotListed(Tile),
    /// A part of this capture from this tile was already taken.
    Repeated(Tile),
    /// The part disagrees with the capture's first part (kind, capture time or tile list).
    Disagrees,
    /// The capture was already handed on.
    Late,
}

impl std::fmt::Display for PartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PartError::TileNotListed(t) => write!(f, "part from tile {t}, not in its tile list"),
            PartError::Repeated(t) => write!(f, "second part from tile {t}"),
            PartError::Disagrees => write!(f, "part disagrees with its capture's first part"),
            PartError::Late => write!(f, "part of a capture already fused"),
        }
    }
}

/// A capture being put together.
struct Pending {
    first: Frame,
    expected: BTreeSet<Tile>,
    got: BTreeMap<Tile, Vec<Detection>>,
    listed: Vec<Tile>,
    first_us: u64,
}

impl Pending {
    fn into_frame(self) -> Frame {
        Frame {
            detections: self.got.into_values().flatten().collect(),
            ..self.first
        }
    }
}

/// What [`Parts::offer`] and [`Parts::expire`] hand on.
#[derive(Clone, Debug, PartialEq)]
pub struct Assembled {
    /// The capture: the first part's header with every part's boxes, in tile order.
    pub frame: Frame,
    /// Whether every expected part came.
    pub complete: bool,
}

/// The captures waiting for their parts.
pub struct Parts {
    subscribed: BTreeSet<Tile>,
    max_wait_us: u64,
    max_pending: usize,
    pending: BTreeMap<(String, u32), Pending>,
    /// Recently handed-on captures, to recognise their late parts.
    done: VecDeque<(String, u32)>,
    done_set: BTreeSet<(String, u32)>,
}

impl Parts {
    /// A reassembler for a fuser subscribed to `subscribed` tiles, waiting at most `max_wait_us`
    /// for a capture's parts and holding at most `max_pending` captures.
    pub fn new(subscribed: &[Tile], max_wait_us: u64, max_pending: usize) -> Self {
        Parts {
            subscribed: subscribed.iter().copied().collect(),
            max_wait_us,
            max_pending: max_pending.max(1),
            pending: BTreeMap::new(),
            done: VecDeque::new(),
            done_set: BTreeSet::new(),
        }
    }

    /// Takes the part of `frame`'s capture sent in `tile`, the capture spanning `listed` tiles;
    /// returns the captures now complete (this one, or the oldest pushed out by it).
    pub fn offer(
        &mut self,
        tile: Tile,
        listed: &[Tile],
        frame: Frame,
        now_us: u64,
    ) -> Result<Vec<Assembled>, PartError> {
        if !self.subscribed.contains(&tile) || listed.binary_search(&tile).is_err() {
            return Err(PartError::TileNotListed(tile));
        }
        let id = (frame.agent.clone(), frame.seq);
        if self.done_set.contains(&id) {
            return Err(PartError::Late);
        }
        let mut out = Vec::new();
        if let Some(p) = self.pending.get_mut(&id) {
            let agrees = p.first.kind == frame.kind
                && p.first.capture_us == frame.capture_us
                && p.listed == listed;
            if !agrees {
                return Err(PartError::Disagrees);
            }
            if p.got.contains_key(&tile) {
                return Err(PartError::Repeated(tile));
            }
            p.got.insert(tile, frame.detections);
        } else {
            if self.pending.len() >= self.max_pending {
                if let Some(oldest) = self
                    .pending
                    .iter()
                    .min_by_key(|(_, p)| p.first_us)
                    .map(|(k, _)| k.clone())
                {
                    out.extend(self.finish(&oldest));
                }
            }
            let expected = listed
                .iter()
                .filter(|t| self.subscribed.contains(t))
                .copied()
                .collect();
            let mut got = BTreeMap::new();
            got.insert(tile, frame.detections.clone());
            self.pending.insert(
                id.clone(),
                Pending {
                    first: Frame {
                        detections: Vec::new(),
                        ..frame
                    },
                    expected,
                    got,
                    listed: listed.to_vec(),
                    first_us: now_us,
                },
            );
        }
        let p = &self.pending[&id];
        if p.got.len() == p.expected.len() {
            out.extend(self.finish(&id));
        }
        Ok(out)
    }

    /// Hands on the captures that waited `max_wait` for their parts, with the parts they have.
    pub fn expire(&mut self, now_us: u64) -> Vec<Assembled> {
        let due: Vec<(String, u32)> = self
            .pending
            .iter()
            .filter(|(_, p)| now_us >= p.first_us.saturating_add(self.max_wait_us))
            .map(|(k, _)| k.clone())
            .collect();
        due.iter().filter_map(|k| self.finish(k)).collect()
    }

    /// When the oldest waiting capture is due, if any capture waits.
    pub fn next_deadline(&self) -> Option<u64> {
        self.pending
            .values()
            .map(|p| p.first_us.saturating_add(self.max_wait_us))
            .min()
    }

    /// Drops every waiting part of `agent` (it restarted or was forgotten).
    pub fn forget_agent(&mut self, agent: &str) {
        self.pending.retain(|(a, _), _| a != agent);
        self.done_set.retain(|(a, _)| a != agent);
        self.done.retain(|(a, _)| a != agent);
    }

    /// Captures waiting now.
    pub fn waiting(&self) -> usize {
        self.pending.len()
    }

    fn finish(&mut self, id: &(String, u32)) -> Option<Assembled> {
        let p = self.pending.remove(id)?;
        let complete = p.got.len() == p.expected.len();
        self.done.push_back(id.clone());
        self.done_set.insert(id.clone());
        // Remember a few captures per waiting slot: enough to catch parts later than max_wait.
        while self.done.len() > 4 * self.max_pending {
            if let Some(old) = self.done.pop_front() {
                self.done_set.remove(&old);
            }
        }
        Some(Assembled {
            frame: p.into_frame(),
            complete,
        })
    }
}

#[cfg(test)]
mod tests;
