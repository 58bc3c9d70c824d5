//! A scoring protocol as a bench runs it: figures that add up frame by frame and merge in frame
//! order as parallel parts join. A data source names the protocols whose truth it yields; a
//! tuple of protocols scores each frame by both.

use crate::dair_eval::{detection_boxes, DairBox, DairEval};
use crate::detection_eval::DetectionEval;
use crate::metrics::Accumulator;
use crate::tracking_eval::TrackingEval;
use crate::v2v4real_eval::V2v4realEval;
use v2x_protocol::Detection;
use v2x_truth::dair::Pose;
use v2x_truth::dataset::GtObject;

/// Figures that parallel parts add up, the later part's into the earlier's.
pub trait Merge {
    /// Adds `other`'s figures (of later frames) into these.
    fn absorb(&mut self, other: Self);
}

/// A protocol that scores each frame's boxes against the frame's truth.
pub trait Protocol: Merge + Clone + Send {
    /// What a frame's boxes are scored against.
    type Truth;
    /// Scores one frame's boxes.
    fn add_frame(&mut self, truth: &Self::Truth, boxes: &[Detection]);
}

/// A frame's truth in the vehicle's frame, as DAIR-V2X's protocol scores it.
#[derive(Clone, Debug)]
pub struct VehicleFrame {
    /// The labelled boxes in the vehicle's frame, within its evaluation range.
    pub boxes: Vec<DairBox>,
    /// World to the vehicle's frame, which the boxes scored are moved by.
    pub to_vehicle: Pose,
}

impl Merge for () {
    fn absorb(&mut self, _: ()) {}
}

impl Merge for Accumulator {
    fn absorb(&mut self, other: Self) {
        self.merge(&other);
    }
}

impl Protocol for Accumulator {
    type Truth = Vec<GtObject>;
    fn add_frame(&mut self, truth: &Vec<GtObject>, boxes: &[Detection]) {
        Accumulator::add_frame(self, truth, boxes);
    }
}

impl Merge for DairEval {
    fn absorb(&mut self, other: Self) {
        self.merge(other);
    }
}

impl Protocol for DairEval {
    type Truth = VehicleFrame;
    fn add_frame(&mut self, truth: &VehicleFrame, boxes: &[Detection]) {
        DairEval::add_frame(
            self,
            &truth.boxes,
            &detection_boxes(boxes, &truth.to_vehicle),
        );
    }
}

/// `Merge` by the scorer's own `merge`, and `Protocol` over `$truth` by its own `add_frame`.
macro_rules! scorer {
    ($scorer:ty, $truth:ty) => {
        impl Merge for $scorer {
            fn absorb(&mut self, other: Self) {
                self.merge(other);
            }
        }

        impl Protocol for $scorer {
            type Truth = $truth;
            fn add_frame(&mut self, truth: &$truth, boxes: &[Detection]) {
                <$scorer>::add_frame(self, truth, boxes);
            }
        }
    };
}

scorer!(DetectionEval, Vec<GtObject>);
scorer!(V2v4realEval, Vec<Detection>);

impl Merge for TrackingEval {
    fn absorb(&mut self, other: Self) {
        self.merge(other);
    }
}

impl<A: Merge, B: Merge> Merge for (A, B) {
    fn absorb(&mut self, other: Self) {
        self.0.absorb(other.0);
        self.1.absorb(other.1);
    }
}

impl<A: Protocol, B: Protocol> Protocol for (A, B) {
    type Truth = (A::Truth, B::Truth);
    fn add_frame(&mut self, truth: &Self::Truth, boxes: &[Detection]) {
        self.0.add_frame(&truth.0, boxes);
        self.1.add_frame(&truth.1, boxes);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::Class;

    fn car(x: f64) -> Detection {
        Detection {
            class: Class::Car,
            center: [x, 0.0, 0.0],
            size: [4.0, 2.0, 1.5],
            score: 0.9,
            ..Detection::default()
        }
    }

    #[test]
    fn a_pair_scores_each_frame_by_both_and_merges_parts_as_one_run() {
        let truth = vec![car(0.0), car(10.0)];
        let frames = [vec![car(0.1)], vec![car(10.2), car(30.0)], vec![]];
        let mut whole = (V2v4realEval::new(), V2v4realEval::new());
        for f in &frames {
            whole.add_frame(&(truth.clone(), truth.clone()), f);
        }
        let mut first = (V2v4realEval::new(), V2v4realEval::new());
        first.add_frame(&(truth.clone(), truth.clone()), &frames[0]);
        let mut rest = (V2v4realEval::new(), V2v4realEval::new());
        for f in &frames[1..] {
            rest.add_frame(&(truth.clone(), truth.clone()), f);
        }
        first.absorb(rest);
        assert_eq!(first.0.summary(), whole.0.summary());
        assert_eq!(first.1.summary(), whole.1.summary());
        // Two of six true boxes found, one false positive: recall caps AP well below 1.
        let ap = whole.0.summary().ap_bev["0.50"];
        assert!(ap > 0.0 && ap < 0.5, "{ap}");
    }
}
