//! The schedule of a scenario run: which ground-truth frames are replayed, and when each is
//! captured on the (shared) wall clock: frame k at epoch + k x period / speed.

use crate::dataset::GroundTruth;

/// The frames a scenario replays and their spacing.
pub struct Schedule {
    /// Indices into the ground truth's frames, in replay order.
    pub frames: Vec<usize>,
    /// Spacing of frames in data time (us).
    pub period_us: u64,
}

impl Schedule {
    /// The first `duration_s` of data.
    pub fn of(gt: &GroundTruth, duration_s: f64) -> Schedule {
        let hz = gt.hz();
        let n = ((duration_s * hz).round() as usize)
            .max(1)
            .min(gt.frames.len());
        Schedule {
            frames: (0..n).collect(),
            period_us: (1e6 / hz).round() as u64,
        }
    }

    /// Wall-clock capture time of the k-th frame.
    pub fn due_us(&self, epoch_us: u64, k: usize, speed: f64) -> u64 {
        epoch_us + (k as f64 * self.period_us as f64 / speed) as u64
    }

    /// The frame a capture time belongs to.
    pub fn frame_of(&self, epoch_us: u64, capture_us: u64, speed: f64) -> Option<usize> {
        let k = ((capture_us as f64 - epoch_us as f64) * speed / self.period_us as f64).round();
        (k >= 0.0 && (k as usize) < self.frames.len()).then_some(k as usize)
    }
}
