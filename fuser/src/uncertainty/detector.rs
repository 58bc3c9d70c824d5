//! Real detectors' boxes (`docs/method.md` §11): a detector states a score and no stds, sends a
//! long tail of low-score false positives, and the boxes another agent brings into the
//! receiving frame carry that agent's pose error on top of its detector's. This module gives
//! such boxes their stds before association and scores the fused groups after it:
//!
//! ```text
//! stds:   sigma(s) = sigma_0 + sigma_s (1 - s)^2          (the detector's own error, score s)
//!         sigma'(s) = sqrt(sigma(s)^2 + sigma_pose^2)      (an agent other than the receiver)
//! score:  s_G = p(real | G)                              (the existence model, `existence.rs`)
//!         s_G = 1 - prod_{n in G} (1 - s_n)                (without one: noisy-OR of the members)
//! keep:   s_G >= s_min
//! ```
//!
//! The existence model ranks every fused box by its chance of being a real object, from its
//! members' scores, who saw it, how well they agree, its range and its shape; the threshold is
//! an operating point on that chance. The defaults are calibrated on V2V4Real's training
//! split (`docs/results.md`). Sans-IO.

use crate::maths::association::CsbaParams;
use crate::maths::fusion::Sourced;
use crate::maths::method::csba_groups;
use crate::uncertainty::existence::{self, ExistenceModel};
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
    /// quadrature. Its height is the least certain: another car's pitch puts its boxes far off
    /// in height (on V2V4Real's train split car 1's heights scatter by 0.86 m against the ego
    /// car's 0.45 m within 2 m of a label, with a longer tail beyond), so where both cars see a
    /// car its fused height leans on the receiver's.
    pub pose_std: [f64; 3],
    /// Size std (m).
    pub size_std: f64,
    /// Yaw std (rad).
    pub yaw_std: f64,
    /// Fused boxes scoring below this are dropped: s_min.
    pub min_score: f64,
    /// The chance each fused box is a real object, its score (`None`: the members' noisy-OR).
    pub existence: Option<ExistenceModel>,
}

impl Default for DetectorParams {
    fn default() -> Self {
        DetectorParams {
            pos_std: 0.15,
            pos_std_per_miss: 1.2,
            pose_std: [0.5, 0.5, 1.0],
            size_std: 0.2,
            yaw_std: 0.15,
            min_score: 0.2,
            existence: Some(existence::DETECTOR_DEFAULT),
        }
    }
}

impl DetectorParams {
    /// The parameters for a tracker's input: no tail dropped, since the tracks' scores rank
    /// them and a box dropped is an object a track may miss.
    pub fn for_tracking(self) -> DetectorParams {
        DetectorParams {
            min_score: 0.0,
            ..self
        }
    }

    /// A tracker's parameters for this detector's boxes: its tracks shown from the operating
    /// point on.
    pub fn tracker(&self, params: crate::tracker::TrackerParams) -> crate::tracker::TrackerParams {
        let mut p = params;
        p.management.min_score = self.min_score;
        p
    }
}

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

/// CSBA-3D and WLS-3D over boxes [`ready`] for it, each group scored by the existence model
/// (or [`group_score`] without one) and
/// the tail below `p.min_score` dropped; in group order. `receiver`: the agent whose frame the
/// others' boxes arrive in.
pub fn fuse_scored(
    p: &DetectorParams,
    csba: &CsbaParams,
    agents: &[Vec<Detection>],
    receiver: Option<usize>,
) -> Vec<Detection> {
    fuse_scored_sourced(p, csba, agents, receiver)
        .into_iter()
        .map(|s| s.det)
        .collect()
}

/// [`fuse_scored`] with the agents of each fused box.
pub fn fuse_scored_sourced(
    p: &DetectorParams,
    csba: &CsbaParams,
    agents: &[Vec<Detection>],
    receiver: Option<usize>,
) -> Vec<Sourced> {
    let mut out: Vec<Sourced> = fuse_described(p, csba, agents, receiver)
        .into_iter()
        .map(|(s, _)| s)
        .collect();
    out.retain(|s| s.det.score >= p.min_score);
    out
}

/// Every fused box (none dropped) with the features the existence model scored it by.
pub fn fuse_described(
    p: &DetectorParams,
    csba: &CsbaParams,
    agents: &[Vec<Detection>],
    receiver: Option<usize>,
) -> Vec<(Sourced, existence::Features)> {
    let (fused, groups) = csba_groups(csba, agents);
    let member = |&(k, j): &(usize, usize)| (&agents[k][j], Some(k) == receiver);
    let scored = |members: &[(&Detection, bool)], d: Detection| {
        let x = existence::features(members, &d);
        let score = match &p.existence {
            Some(m) => m.probability(&x),
            None => group_score(members.iter().map(|m| m.0.score)),
        };
        (Detection { score, ..d }, x)
    };
    fused
        .into_iter()
        .zip(&groups)
        .map(|(d, g)| {
            let members: Vec<(&Detection, bool)> = g.iter().map(member).collect();
            let (det, x) = scored(&members, d);
            let sources = g.iter().map(|&(k, _)| k).collect();
            (Sourced { det, sources }, x)
        })
        .collect()
}

#[cfg(test)]
mod tests;
