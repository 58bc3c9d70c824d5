//! The data sources `--dataroot` and `--dataset` name, one file each, and what `gen`, `eval`
//! and `bench` do with each: agents simulated over ground truth, the synthetic town's or
//! nuScenes tables' ([`simulated`]), DAIR-V2X's vehicle and roadside unit ([`dair`]) and
//! V2V4Real's two cars' detections ([`v2v4real`]). A new data set is its loader in `truth/`, its
//! `--dataset` value, one file here and its arm in [`open`].

use crate::commands::bench::{BenchArgs, TableArgs};
use crate::commands::eval::EvalArgs;
use crate::commands::gen::GenArgs;
use anyhow::bail;
use v2x_sim::cli::{DataArgs, DatasetKind};

mod dair;
mod simulated;
mod v2v4real;

/// A data source and what each command does with it.
pub(crate) trait Source {
    /// `v2x-sim gen`: each agent's results file, into the folder `-o` names.
    fn gen(&self, args: &GenArgs) -> anyhow::Result<()>;
    /// `v2x-sim eval`: a results file (or folder) scored by the source's protocols.
    fn eval(&self, args: &EvalArgs) -> anyhow::Result<()>;
    /// `v2x-sim eval --tracking`: tracking results scored by the tracking benchmark, over the
    /// ground truth's tracks.
    fn eval_tracking(&self, args: &EvalArgs) -> anyhow::Result<()> {
        crate::commands::eval::tracking_table(args)
    }
    /// `v2x-sim bench` without a mode: the source's own tables.
    fn bench(&self, args: &TableArgs) -> anyhow::Result<()>;
    /// Whether the bench's modes apply: agents simulated over the source's ground truth.
    fn simulated(&self) -> bool {
        false
    }
}

/// `v2x-sim eval`: the source's detection protocols, or with `--tracking` its tracking one.
pub(crate) fn eval(args: &EvalArgs) -> anyhow::Result<()> {
    let source = open(&args.data);
    if args.tracking {
        source.eval_tracking(args)
    } else {
        source.eval(args)
    }
}

/// The source the data arguments name.
pub(crate) fn open(data: &DataArgs) -> Box<dyn Source + '_> {
    match (&data.dataroot, data.dataset) {
        (Some(_), DatasetKind::DairV2x) => Box::new(dair::Dair(data)),
        (Some(_), DatasetKind::V2v4real) => Box::new(v2v4real::V2v4real(data)),
        _ => Box::new(simulated::Simulated(data)),
    }
}

/// `v2x-sim bench`: the source's own tables, or a mode over agents simulated on it.
pub(crate) fn bench(args: BenchArgs) -> anyhow::Result<()> {
    let Some(mode) = args.mode else {
        let t = &args.table;
        let source = open(&t.common.data);
        if !source.simulated() && t.agents != 2 {
            bail!("--agents is for simulated agents: the real data sets have their own two");
        }
        return source.bench(t);
    };
    let d = &mode.common().data;
    if !open(d).simulated() {
        let name = clap::ValueEnum::to_possible_value(&d.dataset)
            .map_or_else(String::new, |v| v.get_name().to_string());
        bail!("--dataset {name} runs its own tables (tracked rows included): run `v2x-sim bench` without a mode");
    }
    crate::commands::bench::run_mode(mode)
}
