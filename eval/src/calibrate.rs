//! An agent's errors against the ground truth, from which its error model is fitted
//! (`v2x-sim calibrate`, [`v2x_fuser::uncertainty::stdmodel`]): each box of its results file matched to the
//! object it detected, by ground-truth id when the boxes carry ids, else to the nearest
//! unclaimed object of its class within a distance (boxes taken by descending score, as the
//! nuScenes benchmark matches), and the difference taken.

use crate::file_eval::{read_scored, sample_times, EvalError, Match, ReplayMap, Timing};
use std::path::Path;
use v2x_fuser::uncertainty::stdmodel::ErrorSample;
use v2x_protocol::{Detection, NO_ID};
use v2x_truth::dataset::GroundTruth;

/// How boxes are matched to the objects they detected.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct CalibrateOptions {
    /// By id, by distance, or by id when the boxes carry ids.
    pub how: Match,
    /// Largest centre distance (m) of a match by distance: errors beyond it are not seen, so
    /// it should be several times the agent's std.
    pub max_distance_m: f64,
    /// When samples are placed in the ground truth's time.
    pub timing: Timing,
    /// How a replay's capture times map back to the data's time.
    pub replay: Option<ReplayMap>,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            how: Match::Auto,
            max_distance_m: 4.0,
            timing: Timing::Frame,
            replay: None,
        }
    }
}

/// The errors of a results file's matched boxes, and how they were matched (for the model and
/// the reader).
pub fn error_samples(
    gt: &GroundTruth,
    path: &Path,
    opts: &CalibrateOptions,
) -> Result<(Vec<ErrorSample>, String), EvalError> {
    let results = read_scored(gt, path)?;
    let (samples, unknown) = sample_times(gt, &results, opts.replay, opts.timing);
    if let Some(k) = unknown.first() {
        return Err(EvalError(format!(
            "{}: {} sample(s) are not in the ground truth, e.g. '{k}' (is this the right --dataroot/--version, or the same synthetic town flags as when it was made?)",
            path.display(),
            unknown.len()
        )));
    }
    let has_ids = results.samples.values().flatten().any(|d| d.id != NO_ID);
    let by_id = match opts.how {
        Match::Id => true,
        Match::Distance => false,
        Match::Auto => has_ids,
    };
    if by_id && !has_ids {
        return Err(EvalError(format!(
            "{}: its boxes carry no ground-truth ids (instance_token); match by distance (--match distance)",
            path.display()
        )));
    }
    let reach_ok = opts.max_distance_m > 0.0 && opts.max_distance_m.is_finite();
    if !by_id && !reach_ok {
        return Err(EvalError("--max-distance-m must be > 0".into()));
    }
    let mut out = Vec::new();
    for st in &samples {
        let objects: Vec<Detection> = gt
            .objects_at(st.scene, st.t_us)
            .iter()
            .map(|o| o.as_detection())
            .collect();
        let boxes = &results.samples[&st.key];
        let matched = if by_id {
            match_by_id(boxes, &objects)
        } else {
            match_by_distance(boxes, &objects, opts.max_distance_m)
        };
        out.extend(
            matched
                .into_iter()
                .map(|(b, o)| ErrorSample::of(&boxes[b], &objects[o])),
        );
    }
    let how = if by_id {
        "ground-truth id".to_owned()
    } else {
        format!(
            "centre distance within {} m (errors beyond it are not seen)",
            opts.max_distance_m
        )
    };
    Ok((out, how))
}

/// (box, object) pairs by id: a box's object is the one with its id.
fn match_by_id(boxes: &[Detection], objects: &[Detection]) -> Vec<(usize, usize)> {
    let by_id: std::collections::HashMap<u32, usize> =
        objects.iter().enumerate().map(|(k, o)| (o.id, k)).collect();
    boxes
        .iter()
        .enumerate()
        .filter_map(|(b, d)| Some((b, *by_id.get(&d.id)?)))
        .collect()
}

/// (box, object) pairs by distance: boxes by descending score each take the nearest unclaimed
/// object of their class within `max_m`.
fn match_by_distance(
    boxes: &[Detection],
    objects: &[Detection],
    max_m: f64,
) -> Vec<(usize, usize)> {
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by(|a, b| boxes[*b].score.total_cmp(&boxes[*a].score));
    let mut taken = vec![false; objects.len()];
    let mut out = Vec::new();
    for b in order {
        let d = &boxes[b];
        let best = objects
            .iter()
            .enumerate()
            .filter(|(k, o)| !taken[*k] && o.class == d.class)
            .map(|(k, o)| {
                let dist = (o.center[0] - d.center[0]).hypot(o.center[1] - d.center[1]);
                (k, dist)
            })
            .filter(|(_, dist)| *dist <= max_m)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, _)) = best {
            taken[k] = true;
            out.push((b, k));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::{Class, Uncertainty};

    fn at(class: Class, x: f64, score: f64, id: u32) -> Detection {
        Detection {
            class,
            center: [x, 0.0, 0.0],
            size: [1.0; 3],
            yaw: 0.0,
            score,
            std: Uncertainty::uniform(1.0, 1.0, 1.0),
            pos_cov: None,
            velocity: None,
            id,
        }
    }

    #[test]
    fn matching_by_distance_and_by_id() {
        let objects = [at(Class::Car, 0.0, 1.0, 1), at(Class::Car, 3.0, 1.0, 2)];
        // The surer box at 1.0 takes the object at 0; the other at 1.2 is left the one at 3.
        let boxes = [
            at(Class::Car, 1.2, 0.5, 2),
            at(Class::Car, 1.0, 0.9, 1),
            at(Class::Pedestrian, 0.0, 0.9, 1),
            at(Class::Car, 9.0, 0.9, NO_ID),
        ];
        assert_eq!(
            match_by_distance(&boxes, &objects, 4.0),
            vec![(1, 0), (0, 1)]
        );
        assert_eq!(match_by_distance(&boxes, &objects, 1.5), vec![(1, 0)]);
        // By id the class does not matter (a confused class is still that object's box).
        assert_eq!(match_by_id(&boxes, &objects), vec![(0, 1), (1, 0), (2, 0)]);
    }
}
