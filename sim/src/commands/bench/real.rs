//! The real data sets' own tables: DAIR-V2X's (a vehicle and a roadside unit) and V2V4Real's
//! (two cars' detections, their tracks).

use super::*;
use anyhow::Context;
use std::time::Instant;
use v2x_fuser::Method;
use v2x_sim::noise::NoiseSetting;
use v2x_sim::table::render;

/// `--dataset dair-v2x`: the vehicle, the roadside and every method on real cooperative data.
pub(super) fn dair(args: &TableArgs) -> anyhow::Result<()> {
    let d = args.common.data.load_dair()?;
    let methods = real_data_methods(&args.common.methods)?;
    if methods.contains(&Method::GtWls) {
        bail!("gt-wls groups boxes by ground-truth id, which DAIR-V2X's own labels do not carry");
    }
    let noise = if args.noise.noise == "all" {
        "labels"
    } else {
        args.noise.noise.as_str()
    };
    let setting = NoiseSetting::parse(noise, 2).map_err(anyhow::Error::msg)?;
    let start = Instant::now();
    let rows = v2x_sim::bench::dair::run(
        &d,
        &methods,
        &setting,
        args.common.draw.seed,
        args.common.draw.range,
    );
    let what = format!(
        "noise {setting} over each side's own labels, seed {}",
        args.common.draw.seed
    );
    let heading = format!(
        "{} ; {what}; devkit-style over the ground truth's classes, AP in % (DAIR-V2X protocol, vehicle frame); {:.1} s",
        args.common.data.describe(&d.gt),
        start.elapsed().as_secs_f64()
    );
    print!(
        "{}",
        render(&rows[..], args.common.format.format, &heading)?
    );
    Ok(())
}

/// `--methods` on real data: `all` is every method but the oracle, which needs ground-truth
/// ids the data's own boxes do not carry.
fn real_data_methods(list: &str) -> anyhow::Result<Vec<Method>> {
    let mut all = Method::all_with_ablations();
    all.retain(|m| *m != Method::GtWls);
    parse_list(list, all, Method::parse_any)
}

/// `--dataset v2v4real`: each car, the dataset's references and every method on real
/// detections of two cars, by V2V4Real's protocol.
pub(super) fn v2v4real(args: &TableArgs) -> anyhow::Result<()> {
    let mut d = args
        .common
        .data
        .load_v2v4real(v2x_fuser::offline::kitti_default_std())?;
    for dir in &args.results {
        d.add_reference(dir.display().to_string(), dir)?;
    }
    let methods = real_data_methods(&args.common.methods)?;
    let start = Instant::now();
    let sources = v2x_sim::bench::v2v4real::sources(&d, &methods);
    let rows = v2x_sim::bench::v2v4real::run(&d, &sources);
    let detection_s = start.elapsed().as_secs_f64();
    if let Some(dir) = &args.plots {
        let written = v2x_sim::bench::v2v4real::write_plots(&rows, dir)
            .with_context(|| format!("--plots: cannot write into {}", dir.display()))?;
        eprintln!("{}: {} plots", dir.display(), written.len());
    }
    if let Some(dir) = &args.write_rows {
        for (dir, n) in v2x_sim::bench::v2v4real::write_rows(&d, &sources, dir)? {
            eprintln!("{}: {n} rows", dir.display());
        }
    }
    let start = Instant::now();
    let root = args
        .common
        .data
        .dataroot
        .as_deref()
        .expect("checked by load_v2v4real");
    let cars = v2x_truth::v2v4real::Paths::new(root, d.split).cars;
    let track_methods: Vec<Method> = if args.common.methods == "all" {
        vec![Method::default()]
    } else {
        methods.clone()
    };
    let mut tracked = Vec::new();
    for m in &track_methods {
        for guided in [false, true] {
            let params = args.association.tracker().with_guided(guided);
            tracked.push(v2x_sim::bench::v2v4real::tracked(&d, &cars, m, params)?);
        }
    }
    tracked.push(v2x_sim::bench::v2v4real::ceiling(&d));
    let report = v2x_sim::bench::v2v4real::Report {
        detection: rows,
        tracking: tracked,
        tracking_heading: format!(
            "Tracked as `v2x-fuser track` tracks the two cars' folders, scored by AB3DMOT's KITTI evaluation (3D IoU 0.25, percent); {:.1} s",
            start.elapsed().as_secs_f64()
        ),
    };
    let heading = format!(
        "V2V4Real {} split: {} frames, {} labelled cars; AP of cars by V2V4Real's protocol (frames in order, VOC 2010); {detection_s:.1} s",
        d.split,
        d.frames.len(),
        d.boxes(),
    );
    print!("{}", render(&report, args.common.format.format, &heading)?);
    Ok(())
}
