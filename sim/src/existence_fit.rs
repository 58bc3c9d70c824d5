//! The existence model fitted on real detections (`v2x-sim fit-score`): every fused box of a
//! split with the features it is scored by and whether it is a real object, a labelled car it
//! takes at BEV IoU `iou` (each frame's fused boxes in order of their best member's score, each
//! taking the free label it overlaps most, as the detection protocols match).

use crate::bench::frames::Frames;
use crate::bench::in_order;
use rayon::prelude::*;
use v2x_fuser::maths::association::CsbaParams;
use v2x_fuser::maths::geometry::bev_iou;
use v2x_fuser::uncertainty::detector::{fuse_described, ready, DetectorParams};
use v2x_fuser::uncertainty::existence::{ExistenceError, ExistenceModel, Features};
use v2x_protocol::Detection;

/// Each fused box of one frame with its features and whether it takes a label at `iou`; the
/// cars' boxes get the detector's stds (the first car the receiver).
pub fn frame_samples(
    p: &DetectorParams,
    csba: &CsbaParams,
    cars: [&[Detection]; 2],
    gt: &[Detection],
    iou: f64,
) -> Vec<(Features, bool)> {
    let mut lists: Vec<Vec<Detection>> = cars.iter().map(|c| c.to_vec()).collect();
    for (k, list) in lists.iter_mut().enumerate() {
        ready(p, list, k == 0);
    }
    let described = fuse_described(p, csba, &lists, Some(0));
    let mut order: Vec<usize> = (0..described.len()).collect();
    // Ranked by the features' first entry, the best member's score (as logit).
    order.sort_by(|&a, &b| described[b].1[0].total_cmp(&described[a].1[0]));
    let mut free = vec![true; gt.len()];
    let mut real = vec![false; described.len()];
    for i in order {
        let d = &described[i].0.det;
        let best = (0..gt.len())
            .filter(|&k| free[k])
            .map(|k| (k, bev_iou(d, &gt[k])))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, v)) = best {
            if v >= iou {
                free[k] = false;
                real[i] = true;
            }
        }
    }
    described
        .into_iter()
        .zip(real)
        .map(|((_, x), r)| (x, r))
        .collect()
}

/// Every frame's samples, in frame order, of a source whose frames carry two agents' detector
/// boxes (the first the receiver) and the labelled boxes.
pub fn samples<F: Frames<Truth = Vec<Detection>>>(
    source: &F,
    p: &DetectorParams,
    csba: &CsbaParams,
    iou: f64,
) -> Vec<(Features, bool)> {
    in_order(
        source.parts().into_par_iter(),
        |part| {
            part.into_iter()
                .filter_map(|i| source.frame(i))
                .flat_map(|f| frame_samples(p, csba, [&f.agents[0], &f.agents[1]], &f.truth, iou))
                .collect::<Vec<_>>()
        },
        |mut a, b| {
            a.extend(b);
            a
        },
    )
    .unwrap_or_default()
}

/// The model fitted to `samples`, with a small ridge so that a feature that never varies gets
/// weight 0 instead of none.
pub fn fit(samples: &[(Features, bool)]) -> Result<ExistenceModel, ExistenceError> {
    ExistenceModel::fit(samples, 1e-3)
}
