//! Real detectors' boxes (`docs/method.md` §11): a detector states a score and no stds, sends a
//! long tail of low-score false positives, and the boxes another agent brings into the
//! receiving frame carry that agent's pose error on top of its detector's. This module gives
//! such boxes their stds before association and scores the fused groups after it:
//!
//! ```text
//! stds:   sigma(s) = sigma_0 + sigma_s (1 - s)^2          (the detector's own error, score s)
//!         sigma'(s) = sqrt(sigma(s)^2 + sigma_pose^2)      (an agent other than the receiver)
//! score:  s_G = 1 - prod_{n in G} (1 - s_n)                (noisy-OR of the group's members)
//! keep:   s_G >= s_min
//! split:  max_n z_n - min_n z_n > g_z  =>  each member of G stands as its own box
//! ```
//!
//! The noisy-OR ranks an object that both agents saw above one that only one did; the threshold
//! drops the tail that costs a benchmark more precision than it brings recall. The split is the
//! tracker's: two agents' boxes of one object whose heights lie metres apart (another car's
//! pitch, or its labels') are two hypotheses of it, and their mean is a height neither
//! supports, so the tracker is given both. The defaults are calibrated on V2V4Real's training
//! split (`docs/results.md`). Sans-IO.

use crate::maths::association::CsbaParams;
use crate::maths::fusion::Sourced;
use crate::maths::method::csba_groups;
use v2x_protocol::limits::clamp_std;
use v2x_protocol::{Detection, Uncertainty};

/// The parameters of [`stds`] and [`fuse_scored`].
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DetectorParams {
    /// Centre std of a box of score 1 (m): sigma_0.
    pub pos_std: f64,
    /// Centre std added at score s as sigma_s (1 - s)^2 (m): sigma_s.
    pub pos_std_per_miss: f64,
    /// Centre std (x, y, z) of the pose of every agent but the receiver (m), added in
    /// quadrature.
    pub pose_std: [f64; 3],
    /// Size std (m).
    pub size_std: f64,
    /// Yaw std (rad).
    pub yaw_std: f64,
    /// Fused boxes scoring below this are dropped: s_min.
    pub min_score: f64,
    /// A group whose members' centre heights span more than this (m) is not fused, each member
    /// kept as its own box: g_z. Infinite for fused boxes (a benchmark in bird's-eye view sees
    /// the second box as a false positive); 1 m for a tracker's input.
    pub height_gap: f64,
}

impl Default for DetectorParams {
    fn default() -> Self {
        DetectorParams {
            pos_std: 0.15,
            pos_std_per_miss: 1.2,
            pose_std: [0.5; 3],
            size_std: 0.2,
            yaw_std: 0.15,
            min_score: 0.4,
            height_gap: f64::INFINITY,
        }
    }
}

impl DetectorParams {
    /// The parameters for a tracker's input: no tail dropped and groups split at 1 m of
    /// height, since the tracker's scores rank its tracks and a box dropped (or fused to a
    /// height no member has) is an object the track may miss.
    pub fn for_tracking(self) -> DetectorParams {
        DetectorParams {
            min_score: 0.0,
            height_gap: 1.0,
            ..self
        }
    }
}

/// Hits that confirm a track of a detector's boxes when none is given: 1, every box is shown at
/// once and its track's mean score ranks it.
pub const CONFIRM_HITS: u32 = 1;

/// The stds a detector's box is given from its score; `receiver`: the box is in its own
/// agent's frame (no pose error).
pub fn stds(p: &DetectorParams, d: &Detection, receiver: bool) -> Uncertainty {
    let miss = (1.0 - d.score).clamp(0.0, 1.0);
    let own = p.pos_std + p.pos_std_per_miss * miss * miss;
    let pos = p
        .pose_std
        .map(|pose| clamp_std(if receiver { own } else { own.hypot(pose) }));
    Uncertainty {
        pos,
        size: [clamp_std(p.size_std); 3],
        yaw: clamp_std(p.yaw_std),
    }
}

/// Gives every box of one agent its [`stds`].
pub fn ready(p: &DetectorParams, dets: &mut [Detection], receiver: bool) {
    for d in dets {
        d.std = stds(p, d, receiver);
    }
}

/// The noisy-OR of the members' scores, folded as s + s_n (1 - s) so that one member keeps
/// its score exactly.
pub fn group_score(scores: impl IntoIterator<Item = f64>) -> f64 {
    scores
        .into_iter()
        .map(|s| s.clamp(0.0, 1.0))
        .fold(0.0, |acc, s| acc + s * (1.0 - acc))
}

/// CSBA-3D and WLS-3D over boxes [`ready`] for it, each group scored by [`group_score`] (or
/// split when its heights span more than `p.height_gap`) and the tail below `p.min_score`
/// dropped; in group order.
pub fn fuse_scored(
    p: &DetectorParams,
    csba: &CsbaParams,
    agents: &[Vec<Detection>],
) -> Vec<Detection> {
    fuse_scored_sourced(p, csba, agents)
        .into_iter()
        .map(|s| s.det)
        .collect()
}

/// [`fuse_scored`] with the agents of each fused box.
pub fn fuse_scored_sourced(
    p: &DetectorParams,
    csba: &CsbaParams,
    agents: &[Vec<Detection>],
) -> Vec<Sourced> {
    let (fused, groups) = csba_groups(csba, agents);
    let member = |&(k, j): &(usize, usize)| &agents[k][j];
    let mut out = Vec::with_capacity(fused.len());
    for (d, g) in fused.into_iter().zip(&groups) {
        if height_span(g.iter().map(member)) > p.height_gap {
            out.extend(g.iter().map(|m| Sourced {
                det: member(m).clone(),
                sources: v2x_protocol::AgentSet::single(m.0),
            }));
        } else {
            out.push(Sourced {
                det: Detection {
                    score: group_score(g.iter().map(|m| member(m).score)),
                    ..d
                },
                sources: g.iter().map(|&(k, _)| k).collect(),
            });
        }
    }
    out.retain(|s| s.det.score >= p.min_score);
    out
}

/// How far apart the boxes' centre heights lie (m): 0 for one box.
fn height_span<'a>(boxes: impl Iterator<Item = &'a Detection>) -> f64 {
    let (lo, hi) = boxes.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), b| {
        (lo.min(b.center[2]), hi.max(b.center[2]))
    });
    if lo <= hi {
        hi - lo
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests;
