//! DAIR-V2X (`--dataset dair-v2x`): a vehicle and a roadside unit with their cooperative
//! labels, their own labels or a detector's results per side, scored devkit-style and by
//! DAIR-V2X's protocol.

use super::Source;
use crate::commands::bench::{real_data_methods, TableArgs};
use crate::commands::eval::{self, EvalArgs};
use crate::commands::gen::{self, GenArgs};
use crate::commands::Format;
use anyhow::{bail, Context};
use std::time::Instant;
use v2x_fuser::Method;
use v2x_sim::cli::{DataArgs, Evaluation};
use v2x_sim::noise::NoiseSetting;
use v2x_sim::table::render;

/// DAIR-V2X cooperative data, as the data arguments name it.
pub(super) struct Dair<'a>(pub(super) &'a DataArgs);

impl Source for Dair<'_> {
    /// Each side's boxes from its own labels (or a detector's results), drawn with the noise
    /// given (`labels` by default: each as labelled).
    fn gen(&self, args: &GenArgs) -> anyhow::Result<()> {
        if args.agent_hz.is_some() || args.phase_ms.is_some() || args.agents != 2 {
            bail!("--agent-hz, --phase-ms and --agents do not apply to DAIR-V2X: its two agents capture at their recorded times");
        }
        let d = self.0.load_dair()?;
        let noise = args.noise.as_deref().unwrap_or("labels");
        let setting =
            gen::setting_with_faults(noise, args.faults.as_deref(), args.stated_std.as_deref(), 2)?;
        let out = &args.out.path;
        std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
        let (seed, range) = (args.draw.seed, args.draw.range);
        let files = v2x_sim::gen::generate_dair(&d, &setting, seed, range);
        for (a, r) in files.iter().enumerate() {
            let p = out.join(format!("agent{}.json", a + 1));
            gen::write_agent(&p, r, &d.gt.tokens, &setting.agents[a])?;
            eprintln!(
                "wrote {} ({}, noise {})",
                p.display(),
                v2x_sim::dair::AGENTS[a],
                setting.agents[a].label
            );
        }
        eprintln!("{}", self.0.describe(&d.gt));
        Ok(())
    }

    /// The devkit-style figures and DAIR-V2X's protocol for one results file.
    fn eval(&self, args: &EvalArgs) -> anyhow::Result<()> {
        let d = self.0.load_dair()?;
        let (pred, format) = (args.pred.as_path(), args.format.format);
        let evaluation = eval::evaluate(args, &d.gt)?;
        let results = v2x_protocol::nuscenes_json::read_results(
            pred,
            &mut d.gt.tokens.clone(),
            v2x_protocol::nuscenes_json::MissingStd::Default(v2x_protocol::Uncertainty::uniform(
                1.0, 1.0, 1.0,
            )),
        )?;
        let (dair, scored) = v2x_sim::bench::dair::score_results(&d, &results, args.all_frames);
        eprintln!(
            "DAIR-V2X protocol over {scored} pairs, in the vehicle's frame within its evaluation range"
        );
        let Evaluation::Distance(detection) = evaluation else {
            bail!("{}: DAIR-V2X boxes carry no ground-truth ids: score them with --match distance (or auto)", pred.display());
        };
        let rows = [v2x_sim::bench::dair::DairRow {
            method: pred.display().to_string(),
            detection,
            dair,
            bytes_per_frame: None,
            cpm_bytes_per_frame: None,
            official_ab: None,
        }];
        match format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&rows[0])?),
            _ => print!("{}", eval::table_or_csv(&rows[..], format == Format::Csv)),
        }
        Ok(())
    }

    /// The vehicle, the roadside and every method on real cooperative data.
    fn bench(&self, args: &TableArgs) -> anyhow::Result<()> {
        let d = self.0.load_dair()?;
        let methods = real_data_methods(&args.common.methods)?;
        if methods.contains(&Method::GtWls) {
            bail!(
                "gt-wls groups boxes by ground-truth id, which DAIR-V2X's own labels do not carry"
            );
        }
        let noise = if args.noise.noise == "all" {
            "labels"
        } else {
            args.noise.noise.as_str()
        };
        let setting = NoiseSetting::parse(noise, 2).map_err(anyhow::Error::msg)?;
        let start = Instant::now();
        let (seed, range) = (args.common.draw.seed, args.common.draw.range);
        let rows = v2x_sim::bench::dair::run(&d, &methods, &setting, seed, range);
        let what = format!("noise {setting} over each side's own labels, seed {seed}");
        let heading = format!(
            "{} ; {what}; devkit-style over the ground truth's classes, AP in % (DAIR-V2X protocol, vehicle frame); {:.1} s",
            self.0.describe(&d.gt),
            start.elapsed().as_secs_f64()
        );
        print!(
            "{}",
            render(&rows[..], args.common.format.format, &heading)?
        );
        Ok(())
    }
}
