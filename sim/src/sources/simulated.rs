//! Agents simulated over ground truth: the synthetic town (no `--dataroot`) or nuScenes tables
//! (`--dataroot DIR --version NAME`). Each agent's boxes are the ground truth drawn with its
//! noise; every bench mode applies.

use super::Source;
use crate::commands::bench::TableArgs;
use crate::commands::eval::{self, EvalArgs};
use crate::commands::gen::{self, GenArgs};
use crate::commands::Format;
use anyhow::Context;
use v2x_sim::bench;
use v2x_sim::cli::{DataArgs, Evaluation};

/// The ground truth the data arguments name, agents drawn over it.
pub(super) struct Simulated<'a>(pub(super) &'a DataArgs);

impl Source for Simulated<'_> {
    /// Each agent's boxes drawn from the ground truth with its noise, faults and stated stds,
    /// at its rate and phase.
    fn gen(&self, args: &GenArgs) -> anyhow::Result<()> {
        let gt = self.0.load()?;
        let noise = args.noise.as_deref().unwrap_or("mild+large");
        let setting = gen::setting_with_faults(
            noise,
            args.faults.as_deref(),
            args.stated_std.as_deref(),
            args.agents,
        )?;
        let timings = v2x_sim::gen::Timing::parse(
            args.agent_hz.as_deref(),
            args.phase_ms.as_deref(),
            setting.agents.len(),
        )?;
        let out = &args.out.path;
        std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
        let (seed, range) = (args.draw.seed, args.draw.range);
        let files = v2x_sim::gen::generate(&gt, &setting, &timings, seed, range);
        for (a, r) in files.iter().enumerate() {
            let p = out.join(format!("agent{}.json", a + 1));
            gen::write_agent(&p, r, &gt.tokens, &setting.agents[a])?;
            eprintln!("wrote {} ({} noise)", p.display(), setting.agents[a].label);
        }
        eprintln!("{}", self.0.describe(&gt));
        Ok(())
    }

    /// The nuScenes detection benchmark's figures (by distance), or the id-matched ones, of a
    /// results file.
    fn eval(&self, args: &EvalArgs) -> anyhow::Result<()> {
        let gt = self.0.load()?;
        let (pred, format) = (args.pred.as_path(), args.format.format);
        let evaluation = eval::evaluate(args, &gt)?;
        let csv = format == Format::Csv;
        match evaluation {
            e if format == Format::Json => println!("{}", serde_json::to_string_pretty(&e)?),
            Evaluation::Distance(d) => {
                let rows = [bench::DetectionRow {
                    noise: String::new(),
                    method: pred.display().to_string(),
                    metrics: d,
                }];
                print!("{}", eval::table_or_csv(&rows[..], csv));
            }
            Evaluation::Id(m) => {
                let rows = [bench::Row {
                    noise: "-".into(),
                    method: pred.display().to_string(),
                    metrics: m,
                }];
                print!("{}", eval::table_or_csv(&rows[..], csv));
            }
        }
        Ok(())
    }

    /// The paper's Table 2.
    fn bench(&self, args: &TableArgs) -> anyhow::Result<()> {
        crate::commands::bench::table2(args)
    }

    fn simulated(&self) -> bool {
        true
    }
}
