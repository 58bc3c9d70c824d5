//! The native half of the Python package `v2x_fusion`: a thin pyo3 layer over the Zenoh-free
//! core (the codec of `v2x-protocol`, the methods and tracker of `v2x-fuser`, the protocols of
//! `v2x-eval`).
//!
//! Boxes cross the boundary as dicts ([`pyjson`]) and are read by the same validating parser as
//! a results file's; frames and whole documents as JSON text; arrays as numpy arrays
//! ([`arrays`]). Work on large inputs runs with the GIL released, and every error is a Python
//! exception.

use pyo3::prelude::*;

mod arrays;
mod boxdict;
mod codec;
mod evaluate;
mod fuse;
mod options;
mod pyjson;
mod track;

pyo3::create_exception!(
    _native,
    DecodeError,
    pyo3::exceptions::PyValueError,
    "A payload is not a valid v2x-fusion frame."
);
pyo3::create_exception!(
    _native,
    EncodeError,
    pyo3::exceptions::PyValueError,
    "A frame holds a value the wire format cannot carry."
);

/// The module `v2x_fusion._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("WIRE_VERSION", v2x_protocol::wire::VERSION)?;
    m.add(
        "CLASSES",
        v2x_protocol::Class::ALL.map(|c| c.name()).to_vec(),
    )?;
    m.add(
        "METHODS",
        v2x_fuser::METHODS
            .iter()
            .filter(|m| !m.ablation)
            .map(|m| (m.name.to_string(), m.about.to_string()))
            .collect::<Vec<_>>(),
    )?;
    m.add("DecodeError", py.get_type::<DecodeError>())?;
    m.add("EncodeError", py.get_type::<EncodeError>())?;
    m.add_function(wrap_pyfunction!(codec::decode_json, m)?)?;
    m.add_function(wrap_pyfunction!(codec::encode_json, m)?)?;
    m.add_function(wrap_pyfunction!(codec::encode_boxes, m)?)?;
    m.add_function(wrap_pyfunction!(fuse::fuse_step, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::fuse_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(fuse::fuse_documents, m)?)?;
    m.add_function(wrap_pyfunction!(fuse::run_files, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::evaluate_json, m)?)?;
    m.add_class::<track::Tracker>()?;
    m.add_class::<evaluate::GroundTruth>()?;
    Ok(())
}
