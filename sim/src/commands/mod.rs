//! The subcommands of `v2x-sim`, one module each, and what they share.

use v2x_fuser::Method;
use v2x_sim::bench::BenchConfig;
use v2x_sim::noise::NoiseSetting;

pub mod bench;
pub mod calibrate;
pub mod certs;
pub mod eval;
pub mod fit_score;
pub mod gen;
pub mod load;
pub mod mcap;
pub mod plot;
pub mod wire;

pub use v2x_sim::table::Format;

/// Scores a tracking results file over the ground truth's frames in time order: only the frames
/// the file has, or with `all_frames` every frame (absent ones all missed).
pub(crate) fn evaluate_tracking(
    gt: &v2x_sim::dataset::GroundTruth,
    path: &std::path::Path,
    all_frames: bool,
) -> anyhow::Result<v2x_sim::tracking_eval::TrackingMetrics> {
    let tracks = v2x_sim::tracking_eval::read_tracking(path)?;
    let (m, note) = v2x_eval::file_eval::evaluate_tracking(gt, &tracks, path, all_frames)?;
    if let Some(note) = note {
        eprintln!("{note}");
    }
    Ok(m)
}

/// A bench configuration over the paper's noise settings (or those named), with `methods`, or
/// `default_methods` when it is `all`.
pub(crate) fn paper_settings(
    methods: &str,
    default_methods: &[Method],
    noise: &str,
    seed: u64,
    range: Option<f64>,
) -> anyhow::Result<BenchConfig> {
    Ok(BenchConfig {
        methods: parse_list(methods, default_methods.to_vec(), Method::parse_any)?,
        settings: parse_list(noise, NoiseSetting::paper(), |s| NoiseSetting::parse(s, 2))?,
        seed,
        range,
    })
}

/// The default method beside the paper's csba-wls.
pub(crate) fn beside_paper() -> [Method; 2] {
    [
        Method::default(),
        Method::Csba(v2x_fuser::maths::association::CsbaParams::PAPER),
    ]
}

/// The default method beside the oracle gt-wls.
pub(crate) fn beside_oracle() -> [Method; 2] {
    [Method::default(), Method::GtWls]
}

pub(crate) fn faults_help() -> String {
    let mut s = String::from("Fault keys (--faults KEY=VALUE,...; default in brackets):\n");
    for (k, what) in v2x_sim::faults::FAULT_KEYS {
        s.push_str(&format!("  {k:<11} {what}\n"));
    }
    s.push_str(&format!(
        "  realistic = {}\n",
        v2x_sim::faults::Faults::REALISTIC
    ));
    s
}

/// A comma-separated list, or `all`.
pub(crate) fn parse_list<T, E: std::error::Error + Send + Sync + 'static>(
    s: &str,
    all: Vec<T>,
    parse: impl Fn(&str) -> Result<T, E>,
) -> anyhow::Result<Vec<T>> {
    if s == "all" {
        return Ok(all);
    }
    s.split(',')
        .map(|x| parse(x.trim()).map_err(anyhow::Error::from))
        .collect()
}
