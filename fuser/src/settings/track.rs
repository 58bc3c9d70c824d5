//! How the tracks are kept, read by `track` and the node's `--track`.

use super::SettingsError;
use crate::tracker::{Association, TrackerParams};
use serde::{Deserialize, Serialize};

/// How the tracks are kept: how boxes reach them, when they are born and when they end.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "node", derive(clap::Args))]
#[serde(default)]
pub struct TrackSettings {
    /// How boxes reach the tracks: `soft` (each track updated with its fused boxes weighed by
    /// the chance each is its own, docs/method.md §8.2), `assignment` (the fused boxes, each to
    /// the track of the best assignment) or `guided` (each agent's boxes through the tracks
    /// first, fused between agents only where no track explains them, §8.1).
    #[cfg_attr(feature = "node", arg(long, value_name = "soft|assignment|guided", default_value_t = TrackSettings::default().association))]
    pub association: Association,
    /// Hits in a row that confirm a track: 2 (a box seen once never becomes a track); 1 shows
    /// every box at once.
    #[cfg_attr(feature = "node", arg(long, default_value_t = TrackSettings::default().confirm_hits))]
    pub confirm_hits: u32,
    /// Windows in a row without a box a confirmed track survives.
    #[cfg_attr(feature = "node", arg(long, default_value_t = TrackSettings::default().max_misses))]
    pub max_misses: u32,
    /// Also track the classes the nuScenes tracking benchmark does not score (barrier, traffic
    /// cone, construction vehicle); the devkit's loader refuses a file that holds them.
    #[cfg_attr(feature = "node", arg(long))]
    pub all_classes: bool,
}

impl Default for TrackSettings {
    fn default() -> Self {
        let p = TrackerParams::default();
        TrackSettings {
            association: p.association.mode,
            confirm_hits: p.management.confirm_hits,
            max_misses: p.management.max_misses,
            all_classes: p.management.all_classes,
        }
    }
}

impl TrackSettings {
    /// The tracker's parameters, at replay speed 1.
    pub fn params(&self) -> Result<TrackerParams, SettingsError> {
        if self.confirm_hits == 0 {
            return Err(SettingsError::of("confirm_hits", "must be at least 1"));
        }
        let mut p = TrackerParams::with_mode(self.association);
        p.management.confirm_hits = self.confirm_hits;
        p.management.max_misses = self.max_misses;
        p.management.all_classes = self.all_classes;
        Ok(p)
    }

    /// The first setting that differs from its default (for what does not track).
    pub fn first_set(&self) -> Option<&'static str> {
        let d = TrackSettings::default();
        [
            (self.association != d.association, "association"),
            (self.confirm_hits != d.confirm_hits, "confirm_hits"),
            (self.max_misses != d.max_misses, "max_misses"),
            (self.all_classes != d.all_classes, "all_classes"),
        ]
        .into_iter()
        .find_map(|(set, key)| set.then_some(key))
    }
}
