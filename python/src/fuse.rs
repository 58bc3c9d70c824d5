//! Fusion of boxes in results-file form: one time step (`fuse`), whole results documents
//! (`fuse_results`) and files (`fuse_files`, `track_files`, as `v2x-fuser fuse` and `track`).

use crate::boxdict::{box_dict, read_agents, Extra};
use crate::options::{method, missing_std, Options};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyList;
use serde_json::{json, Value};
use std::path::PathBuf;
use v2x_fuser::offline::{self, FuseReport, OutputFormat};
use v2x_protocol::nuscenes_json::{parse_results, results_json, JsonError, TokenTable};

fn value_error(e: JsonError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// Fuses one time step: `agents[k]` is agent k's boxes, a list of results-file dicts. Returns
/// the fused boxes as such dicts, each with `v2x_sources`, the indices of the agents whose boxes
/// went into it.
#[pyfunction]
#[pyo3(signature = (agents, method_name, default_std=None))]
pub fn fuse_step<'py>(
    py: Python<'py>,
    agents: Vec<Bound<'py, PyAny>>,
    method_name: &str,
    default_std: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    let method = method(method_name)?;
    let missing = missing_std(default_std)?;
    let mut tokens = TokenTable::new();
    let per_agent = read_agents(&agents, &mut tokens, missing)?;
    let fused = py.detach(|| method.fuse_sourced(&per_agent));
    let out = fused
        .iter()
        .map(|s| {
            let sources = PyList::new(py, s.sources.iter())?.into_any();
            box_dict(py, &s.det, &tokens, &[(Extra::Sources, sources)])
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok(PyList::new(py, out)?.into_any())
}

/// Fuses whole results documents (the JSON of each agent's), as `v2x-fuser fuse` fuses files.
/// Returns the JSON of the fused document and of the report.
#[pyfunction]
pub fn fuse_documents(
    py: Python<'_>,
    documents: Vec<String>,
    options: Options,
) -> PyResult<(String, String)> {
    options.refuse_tracking()?;
    let (missing, opts) = options.offline(documents.len())?;
    py.detach(|| {
        let mut tokens = TokenTable::new();
        let names: Vec<PathBuf> = (0..documents.len())
            .map(|k| PathBuf::from(format!("documents[{k}]")))
            .collect();
        let agents = documents
            .iter()
            .zip(&names)
            .map(|(text, name)| parse_results(name, text, &mut tokens, missing))
            .collect::<Result<Vec<_>, _>>()
            .map_err(value_error)?;
        let (fused, report) = offline::fuse_agents(&agents, &names, &opts).map_err(value_error)?;
        Ok((
            results_json(&fused, &tokens).to_string(),
            report_json(&report).to_string(),
        ))
    })
}

/// Reads, fuses and writes files: `v2x-fuser fuse`, or with `track` `v2x-fuser track`. Returns
/// the JSON of the report (fusing) or of the tracker's counters and what was learned (tracking).
#[pyfunction]
pub fn run_files(
    py: Python<'_>,
    inputs: Vec<PathBuf>,
    output: PathBuf,
    options: Options,
    track: bool,
) -> PyResult<String> {
    if !track {
        options.refuse_tracking()?;
    }
    let (missing, opts) = options.offline(inputs.len())?;
    let params = options.tracker()?;
    py.detach(|| {
        if !track {
            let report = offline::fuse_files(&inputs, &output, missing, &opts, OutputFormat::Auto)
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            return Ok(report_json(&report).to_string());
        }
        let tracks =
            offline::track_files(&inputs, &output, missing, &opts, params, OutputFormat::Auto)
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(json!({
            "windows": tracks.results.samples.len(),
            "boxes": tracks.results.samples.values().map(Vec::len).sum::<usize>(),
            "stats": tracks.stats,
            "learned": tracks.results.meta.get("v2x_learned_std").cloned().unwrap_or(json!({})),
        })
        .to_string())
    })
}

/// What fusing did, as a dict's JSON.
fn report_json(r: &FuseReport) -> Value {
    let registration: Vec<Value> = r
        .registration
        .iter()
        .map(|(agent, measured, applied, last)| {
            json!({"agent": agent, "measured": measured, "applied": applied, "last": last})
        })
        .collect();
    json!({
        "samples": r.samples,
        "boxes_in": r.boxes_in,
        "boxes_out": r.boxes_out,
        "by_time": r.by_time,
        "registration": registration,
        "learned": r.learned,
    })
}
