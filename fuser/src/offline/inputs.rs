//! The inputs of offline fusion: one results file or folder of KITTI detection rows per agent,
//! read with a shared token table, and whether they are a detector's.

use super::{FilesError, OfflineOptions};
use crate::tracker::TrackerParams;
use crate::uncertainty::detector::DetectorParams;
use std::collections::BTreeSet;
use std::path::PathBuf;
use v2x_protocol::kitti::{self};
use v2x_protocol::nuscenes_json::{read_results, MissingStd, Results, TokenTable};
use v2x_protocol::Uncertainty;

/// Per-agent results read from files, ready to fuse.
pub struct Inputs {
    /// One parsed file (or KITTI folder) per agent, in the order given.
    pub agents: Vec<Results>,
    /// The shared instance-token table.
    pub tokens: TokenTable,
    /// With KITTI folders, every sequence number any of them holds (else empty).
    pub sequences: BTreeSet<u32>,
    /// Every input is a detector's KITTI rows and no std was given for them: they take the
    /// detector's stds and scoring ([`crate::pipeline::Steps::detector`]).
    pub from_detector: bool,
}

impl Inputs {
    /// The options these inputs are fused with: `opts`, with the detector's stds and scoring
    /// for a detector's rows when neither learned stds nor error models replace them.
    pub fn options(&self, opts: &OfflineOptions) -> OfflineOptions {
        let mut o = opts.clone();
        if detector_applies(self.from_detector, &o) {
            o.steps.detector = Some(o.detector_params);
        }
        o
    }

    /// The tracker's parameters for these inputs: a detector's tracks are output from its
    /// operating point on ([`DetectorParams::min_score`]).
    pub fn tracker_params(&self, opts: &OfflineOptions, params: TrackerParams) -> TrackerParams {
        match self.options(opts).steps.detector {
            Some(d) => d.tracker(params),
            None => params,
        }
    }

    /// [`Inputs::options`] for tracking: a detector's boxes reach the tracker without their
    /// tail dropped ([`DetectorParams::for_tracking`]).
    pub fn tracking_options(&self, opts: &OfflineOptions) -> OfflineOptions {
        let mut o = self.options(opts);
        o.steps.detector = o.steps.detector.map(DetectorParams::for_tracking);
        o
    }
}

/// The stds of KITTI rows, which state none, when no default is given: the `mild` profile.
pub fn kitti_default_std() -> Uncertainty {
    v2x_protocol::NoiseProfile::Mild.std()
}

/// Whether these inputs are a detector's KITTI rows without stds: every input a folder, and no
/// default std given for them.
pub fn from_detector(paths: &[PathBuf], missing: MissingStd) -> bool {
    !paths.is_empty() && paths.iter().all(|p| p.is_dir()) && matches!(missing, MissingStd::Error)
}

/// Whether a detector's rows get the detector's treatment under `opts`: unless it is given
/// already, or learned stds or error models replace it.
pub(super) fn detector_applies(from_detector: bool, opts: &OfflineOptions) -> bool {
    let steps = &opts.steps;
    from_detector && steps.detector.is_none() && steps.learn.is_none() && steps.models.0.is_empty()
}

/// Reads one input per agent with a shared token table: a results file, or a folder of KITTI
/// detection rows (one `NNNN.txt` per sequence, [`v2x_protocol::kitti`]) whose boxes take the
/// default std, [`kitti_default_std`] without one. Files and folders are not mixed.
pub fn read_inputs(paths: &[PathBuf], missing: MissingStd) -> Result<Inputs, FilesError> {
    let mut tokens = TokenTable::new();
    let mut agents = Vec::with_capacity(paths.len());
    let mut sequences = BTreeSet::new();
    let folders = paths.iter().filter(|p| p.is_dir()).count();
    if folders != 0 && folders != paths.len() {
        return Err(FilesError::MixedInputs);
    }
    for p in paths {
        if p.is_dir() {
            let std = match missing {
                MissingStd::Default(u) => u,
                MissingStd::Error => kitti_default_std(),
            };
            sequences.extend(kitti::sequence_files(p)?.into_keys());
            agents.push(kitti::read_detection_dir(p, std)?);
        } else {
            agents.push(read_results(p, &mut tokens, missing)?);
        }
    }
    Ok(Inputs {
        from_detector: from_detector(paths, missing),
        agents,
        tokens,
        sequences,
    })
}
