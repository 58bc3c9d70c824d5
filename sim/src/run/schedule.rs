//! The schedule of a scenario run in data time and on the wall clock. The run replays the first
//! `duration_s` of the data's first scene: data time t maps to wall-clock time
//! epoch + (t - t0) / speed. The scheduled frames are the data's frames in that span (the times
//! at which fused output is expected); each agent captures on its own rate and phase.

use crate::dataset::GroundTruth;

/// The frames a scenario replays and their spacing.
#[derive(Clone, Debug)]
pub struct Schedule {
    /// Indices into the ground truth's frames, in replay order.
    pub frames: Vec<usize>,
    /// Spacing of frames in data time (us).
    pub period_us: u64,
    /// Data time of the first frame (us).
    pub t0_us: u64,
    /// The scene replayed.
    pub scene: usize,
}

impl Schedule {
    /// The first `duration_s` of data.
    pub fn of(gt: &GroundTruth, duration_s: f64) -> Schedule {
        let hz = gt.hz();
        let scene = gt.frames.first().map_or(0, |f| f.scene);
        let n = ((duration_s * hz).round() as usize).max(1);
        let frames: Vec<usize> = (0..gt.frames.len())
            .filter(|&i| gt.frames[i].scene == scene)
            .take(n)
            .collect();
        Schedule {
            t0_us: frames.first().map_or(0, |&i| gt.frames[i].timestamp_us),
            frames,
            period_us: (1e6 / hz).round() as u64,
            scene,
        }
    }

    /// The span of data replayed (us).
    pub fn duration_us(&self) -> u64 {
        self.frames.len() as u64 * self.period_us
    }

    /// Wall-clock time of data time `t_us`.
    pub fn wall_us(&self, epoch_us: u64, t_us: u64, speed: f64) -> u64 {
        epoch_us + ((t_us as f64 - self.t0_us as f64) / speed).max(0.0) as u64
    }

    /// Data time of wall-clock time `wall_us` (the inverse of [`Schedule::wall_us`]).
    pub fn data_us(&self, epoch_us: u64, wall_us: u64, speed: f64) -> u64 {
        (self.t0_us as f64 + (wall_us as f64 - epoch_us as f64) * speed).max(0.0) as u64
    }

    /// An agent's capture times in data time: from t0 + phase, every 1/hz (the data's rate when
    /// `hz` is `None`), within the replayed span.
    pub fn captures(&self, hz: Option<f64>, phase_ms: f64) -> Vec<u64> {
        let step = hz.map_or(self.period_us as f64, |h| 1e6 / h);
        let start = self.t0_us as f64 + phase_ms * 1000.0;
        let end = (self.t0_us + self.duration_us()) as f64;
        (0..)
            .map(|j| start + j as f64 * step)
            .take_while(|t| *t < end - 0.5)
            .map(|t| t.round() as u64)
            .collect()
    }

    /// The scheduled frame nearest to data time `t_us`, if within half a period.
    pub fn frame_near(&self, t_us: u64) -> Option<usize> {
        let k = ((t_us as f64 - self.t0_us as f64) / self.period_us as f64).round();
        (k >= 0.0 && (k as usize) < self.frames.len()).then_some(k as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::town::{generate, TownConfig};

    #[test]
    fn captures_follow_each_agents_rate_and_phase() {
        let gt = generate(&TownConfig {
            scenes: 2,
            seconds: 2.0,
            hz: 10.0,
            seed: 1,
        });
        let s = Schedule::of(&gt, 1.0);
        assert_eq!((s.frames.len(), s.period_us), (10, 100_000));
        let t0 = s.t0_us;
        assert_eq!(s.captures(None, 0.0)[..3], [t0, t0 + 100_000, t0 + 200_000]);
        let fast = s.captures(Some(20.0), 25.0);
        assert_eq!(fast.len(), 20);
        assert_eq!(fast[..2], [t0 + 25_000, t0 + 75_000]);
        assert_eq!(s.captures(Some(10.0), 50.0).len(), 10);
        // wall clock and back, at twice the speed
        let w = s.wall_us(1_000, t0 + 400_000, 2.0);
        assert_eq!(w, 201_000);
        assert_eq!(s.data_us(1_000, w, 2.0), t0 + 400_000);
        assert_eq!(s.frame_near(t0 + 140_000), Some(1));
        // a long duration stays within the first scene
        assert_eq!(Schedule::of(&gt, 100.0).frames.len(), 20);
    }
}
