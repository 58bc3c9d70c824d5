//! V2V4Real (`--dataset v2v4real`): two real cars' detector boxes and the split's labels, scored
//! by V2V4Real's detection protocol and AB3DMOT's tracking evaluation.

use super::Source;
use crate::commands::bench::{real_data_methods, TableArgs};
use crate::commands::eval::EvalArgs;
use crate::commands::gen::GenArgs;
use crate::commands::Format;
use anyhow::{bail, Context};
use std::time::Instant;
use v2x_fuser::Method;
use v2x_sim::bench::v2v4real as rows;
use v2x_sim::cli::DataArgs;
use v2x_sim::table::{render, Rows};

/// V2V4Real's split, as the data arguments name it.
pub(super) struct V2v4real<'a>(pub(super) &'a DataArgs);

impl V2v4real<'_> {
    /// The split, the cars' boxes given a detector's stds.
    fn load(&self) -> anyhow::Result<v2x_truth::v2v4real::V2v4real> {
        self.0
            .load_v2v4real(v2x_fuser::offline::kitti_default_std())
    }
}

impl V2v4real<'_> {
    /// The split, and the folder `eval` scores, refused unless it is a folder.
    fn load_with_folder<'a>(
        &self,
        args: &'a EvalArgs,
    ) -> anyhow::Result<(v2x_truth::v2v4real::V2v4real, &'a std::path::Path)> {
        let d = self.load()?;
        let dir = args.pred.as_path();
        if !dir.is_dir() {
            bail!(
                "{}: --dataset v2v4real scores a folder of KITTI rows (one NNNN.txt per sequence)",
                dir.display()
            );
        }
        Ok((d, dir))
    }
}

impl Source for V2v4real<'_> {
    /// The two cars' own detections, written as they are.
    fn gen(&self, args: &GenArgs) -> anyhow::Result<()> {
        if args.noise.is_some()
            || args.faults.is_some()
            || args.stated_std.is_some()
            || args.draw.range.is_some()
            || args.agent_hz.is_some()
            || args.phase_ms.is_some()
            || args.agents != 2
        {
            bail!("--dataset v2v4real writes the two cars' own detections as they are: leave out --noise, --faults, --stated-std, --range, --agent-hz, --phase-ms and --agents");
        }
        let d = self.load()?;
        let out = &args.out.path;
        std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
        let files = v2x_sim::gen::generate_v2v4real(&d, &Default::default());
        let tokens = v2x_protocol::nuscenes_json::TokenTable::new();
        for (k, r) in files.iter().enumerate() {
            let p = out.join(format!("agent{}.json", k + 1));
            v2x_protocol::nuscenes_json::write_results(&p, r, &tokens)?;
            eprintln!(
                "wrote {} ({}: {} frames, {} boxes, stds from each box's score)",
                p.display(),
                if k == 0 {
                    "the ego car"
                } else {
                    "car 1, in the ego car's frame"
                },
                r.samples.len(),
                r.samples.values().map(Vec::len).sum::<usize>()
            );
        }
        eprintln!(
            "V2V4Real {} split: fuse them with `v2x-fuser fuse --detector`, or replay them with `v2x-agent`",
            d.split
        );
        Ok(())
    }

    /// A folder of KITTI rows scored by V2V4Real's detection protocol.
    fn eval(&self, args: &EvalArgs) -> anyhow::Result<()> {
        let (d, dir) = self.load_with_folder(args)?;
        let format = args.format.format;
        let m = rows::score_detection_dir(&d, dir)?;
        match format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&m)?),
            _ => println!(
                "{}: AP-BEV {} · AP-3D {} in frame order (V2V4Real's protocol); globally sorted \
                 (OpenCOOD's --global_sort_detections) AP-BEV {} · AP-3D {} ({} frames, {} \
                 labelled cars, {} boxes)",
                dir.display(),
                serde_json::to_string(&m.ap_bev)?,
                serde_json::to_string(&m.ap_3d)?,
                serde_json::to_string(&m.global.bev)?,
                serde_json::to_string(&m.global.three_d)?,
                m.frames,
                m.gt,
                m.predictions
            ),
        }
        Ok(())
    }

    /// A folder of KITTI tracking rows scored by AB3DMOT's tracking evaluation.
    fn eval_tracking(&self, args: &EvalArgs) -> anyhow::Result<()> {
        let (d, dir) = self.load_with_folder(args)?;
        let row = rows::score_track_dir(&d, dir)?;
        match args.format.format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&row)?),
            _ => print!("{}", [row][..].table()),
        }
        Ok(())
    }

    /// Each car, the dataset's references and every method, by V2V4Real's protocol, and the
    /// tracked rows.
    fn bench(&self, args: &TableArgs) -> anyhow::Result<()> {
        let mut d = self.load()?;
        for dir in &args.results {
            d.add_reference(dir.display().to_string(), dir)?;
        }
        let methods = real_data_methods(&args.common.methods)?;
        let start = Instant::now();
        let sources = rows::sources(&d, &methods);
        let detection = rows::run(&d, &sources);
        let detection_s = start.elapsed().as_secs_f64();
        write_extras(args, &d, &sources, &detection)?;
        let start = Instant::now();
        let root = self
            .0
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
                tracked.push(rows::tracked(&d, &cars, m, params)?);
            }
        }
        tracked.push(rows::ceiling(&d));
        let report = rows::Report {
            detection,
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
}

/// `--plots` and `--write-rows`: each detection row's curves and boxes.
fn write_extras(
    args: &TableArgs,
    d: &v2x_truth::v2v4real::V2v4real,
    sources: &[rows::Source],
    detection: &[rows::V2v4realRow],
) -> anyhow::Result<()> {
    if let Some(dir) = &args.plots {
        let written = rows::write_plots(detection, dir)
            .with_context(|| format!("--plots: cannot write into {}", dir.display()))?;
        eprintln!("{}: {} plots", dir.display(), written.len());
    }
    if let Some(dir) = &args.write_rows {
        for (dir, n) in rows::write_rows(d, sources, dir)? {
            eprintln!("{}: {n} rows", dir.display());
        }
    }
    Ok(())
}
