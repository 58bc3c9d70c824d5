//! Evaluation for v2x-fusion, without the network: no Zenoh, tokio or clock (results files are
//! read as JSON where the protocol needs them).
//!
//! - [`metrics`]: precision, recall and matched-pair errors against the ground truth
//!   (`docs/method.md` §6).
//! - [`detection_eval`]: the nuScenes detection protocol (mAP, TP errors, NDS).
//! - [`dair_eval`]: the DAIR-V2X cooperative protocol (3D and BEV AP at fixed IoU thresholds).
//! - [`v2v4real_eval`]: V2V4Real's protocol (BEV and 3D AP of cars at IoU 0.3, 0.5, 0.7).
//! - [`file_eval`]: a results file scored against the ground truth, by either matching.
//! - [`calibrate`]: an agent's errors against the ground truth, for its error model.
//! - [`ab3dmot_eval`]: AB3DMOT's KITTI tracking evaluation (sAMOTA, AMOTA, MOTA at 3D IoU 0.25).
//! - [`tracking_eval`]: the nuScenes tracking protocol (AMOTA, AMOTP, MOTA, IDS and the rest).
//! - [`hota`]: HOTA with DetA, AssA and LocA, as TrackEval computes them.
//! - [`protocol`]: the one shape a bench runs every protocol by, frame by frame.

pub mod ab3dmot_eval;
pub mod calibrate;
pub mod dair_eval;
pub mod detection_eval;
pub mod file_eval;
pub mod hota;
pub mod metrics;
pub mod protocol;
pub mod tracking_eval;
pub mod v2v4real_eval;
