//! `v2x-sim fit-score`.

use anyhow::Context;
use std::path::PathBuf;
use v2x_fuser::uncertainty::detector::DetectorParams;
use v2x_fuser::uncertainty::existence::FEATURE_NAMES;
use v2x_sim::cli::DataArgs;
use v2x_sim::existence_fit;

/// The options of `v2x-sim fit-score`.
#[derive(clap::Args)]
pub struct FitScoreArgs {
    #[command(flatten)]
    pub data: DataArgs,
    #[command(flatten)]
    pub method: v2x_sim::cli::MethodArg,
    /// BEV IoU at which a fused box counts as the labelled car it overlaps.
    #[arg(long, default_value_t = 0.5)]
    pub iou: f64,
    /// Each car's detections from these folders (KITTI detection rows per sequence, the
    /// receiving car first) instead of the split's published ones: your own detector's boxes.
    #[arg(long, num_args = 2, value_names = ["EGO_DIR", "CAR1_DIR"])]
    pub cars: Option<Vec<PathBuf>>,
    #[command(flatten)]
    pub output: v2x_protocol::cli::Output,
}

/// Runs `v2x-sim fit-score`.
pub fn run(args: FitScoreArgs) -> anyhow::Result<()> {
    let FitScoreArgs {
        data,
        method: v2x_sim::cli::MethodArg { method },
        iou,
        cars,
        output: v2x_protocol::cli::Output { path: output },
    } = args;
    if !(iou > 0.0 && iou <= 1.0) {
        anyhow::bail!("--iou must be in (0, 1], not {iou}");
    }
    let Some(csba) = method.csba_params() else {
        anyhow::bail!(
            "--method {method}: the existence model scores CSBA-3D groups; name a csba-wls method"
        );
    };
    let mut d = data.load_v2v4real(v2x_fuser::offline::kitti_default_std())?;
    if let Some(dirs) = &cars {
        for (k, dir) in dirs.iter().enumerate() {
            d.cars[k] = d
                .read_rows(dir)
                .with_context(|| format!("--cars: reading {}", dir.display()))?;
        }
    }
    let p = DetectorParams {
        existence: None,
        min_score: 0.0,
        ..DetectorParams::default()
    };
    let cars = v2x_sim::bench::v2v4real::CarFrames(&d);
    let samples = existence_fit::samples(&cars, &p, &csba, iou);
    let real = samples.iter().filter(|s| s.1).count();
    let model =
        existence_fit::fit(&samples).with_context(|| format!("{} fused boxes", samples.len()))?;
    let file = model.to_file([real, samples.len() - real]);
    std::fs::write(&output, serde_json::to_string_pretty(&file)? + "\n")
        .with_context(|| format!("cannot write {}", output.display()))?;
    eprintln!(
        "{} fused boxes of {} frames ({real} real at BEV IoU {iou}) -> {}",
        samples.len(),
        d.frames.len(),
        output.display()
    );
    println!("bias {:.4}", model.bias);
    for (n, w) in FEATURE_NAMES.iter().zip(model.weights) {
        println!("{n:<16} {w:.4}");
    }
    Ok(())
}
