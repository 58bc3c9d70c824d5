//! Offline fusion of nuScenes results files: one file per agent, boxes grouped by sample token,
//! each sample fused with a [`Method`]; the output keeps the extension fields.

use crate::Method;
use std::collections::BTreeSet;
use std::path::PathBuf;
use v2x_protocol::nuscenes_json::{
    read_results, write_results, JsonError, MissingStd, Results, TokenTable,
};

/// Per-agent results read from files, ready to fuse.
pub struct Inputs {
    /// One parsed file per agent, in the order given.
    pub agents: Vec<Results>,
    /// The shared instance-token table.
    pub tokens: TokenTable,
}

/// Reads one results file per agent with a shared token table.
pub fn read_inputs(paths: &[PathBuf], missing: MissingStd) -> Result<Inputs, JsonError> {
    let mut tokens = TokenTable::new();
    let mut agents = Vec::with_capacity(paths.len());
    for p in paths {
        agents.push(read_results(p, &mut tokens, missing)?);
    }
    Ok(Inputs { agents, tokens })
}

/// Fuses every sample present in any agent's file.
pub fn fuse_results(method: &Method, agents: &[Results]) -> Results {
    let samples: BTreeSet<&String> = agents.iter().flat_map(|r| r.samples.keys()).collect();
    let mut out = Results {
        meta: agents.first().map(|r| r.meta.clone()).unwrap_or_default(),
        ..Default::default()
    };
    for s in samples {
        let per_agent: Vec<Vec<_>> = agents
            .iter()
            .map(|r| r.samples.get(s).cloned().unwrap_or_default())
            .collect();
        out.samples.insert(s.clone(), method.fuse(&per_agent));
    }
    out
}

/// Reads, fuses and writes: the `v2x-fuser fuse` command. Returns (samples, boxes in, boxes out).
pub fn fuse_files(
    method: &Method,
    inputs: &[PathBuf],
    output: &std::path::Path,
    missing: MissingStd,
) -> Result<(usize, usize, usize), JsonError> {
    let Inputs { agents, tokens } = read_inputs(inputs, missing)?;
    let fused = fuse_results(method, &agents);
    write_results(output, &fused, &tokens)?;
    let n_in = agents
        .iter()
        .flat_map(|r| r.samples.values())
        .map(Vec::len)
        .sum();
    let n_out = fused.samples.values().map(Vec::len).sum();
    Ok((fused.samples.len(), n_in, n_out))
}
