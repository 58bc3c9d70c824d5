//! Python values to and from JSON values, with no text in between: boxes cross the boundary as
//! dicts and reach the same validating parser as a results file's.

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::{Map, Number, Value};
use std::path::Path;
use v2x_protocol::nuscenes_json::{parse_boxes, MissingStd, TokenTable};
use v2x_protocol::Detection;

/// Each agent's boxes (`agents[k]`, a list of results-file dicts) as JSON values, read with the
/// GIL held.
pub fn agents_values(agents: &[Bound<'_, PyAny>]) -> PyResult<Vec<Value>> {
    agents
        .iter()
        .enumerate()
        .map(|(k, a)| to_value(a, &|| format!("agents[{k}]")))
        .collect()
}

/// Each agent's boxes parsed and checked as a results file's (errors name `agents[k]`, the box
/// and the field).
pub fn parse_agents(
    values: &[Value],
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> PyResult<Vec<Vec<Detection>>> {
    values
        .iter()
        .enumerate()
        .map(|(k, v)| parse_boxes(Path::new(&format!("agents[{k}]")), v, tokens, missing))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A Python value (dicts, lists, tuples, strings, numbers, booleans, None, and numpy arrays and
/// scalars through `tolist`) as a JSON value; `at` names it in errors.
pub fn to_value(obj: &Bound<'_, PyAny>, at: &dyn Fn() -> String) -> PyResult<Value> {
    if let Ok(f) = obj.cast::<PyFloat>() {
        let x = f.value();
        return Number::from_f64(x)
            .map(Value::Number)
            .ok_or_else(|| PyValueError::new_err(format!("{}: {x} is not a finite number", at())));
    }
    if obj.is_instance_of::<PyBool>() {
        return Ok(Value::Bool(obj.extract()?));
    }
    if obj.is_instance_of::<PyInt>() {
        if let Ok(i) = obj.extract::<i64>() {
            return Ok(Value::from(i));
        }
        if let Ok(u) = obj.extract::<u64>() {
            return Ok(Value::from(u));
        }
        return Err(PyValueError::new_err(format!(
            "{}: integer out of range",
            at()
        )));
    }
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(Value::String(s.to_cow()?.into_owned()));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut map = Map::new();
        for (k, v) in d.iter() {
            let key: String = k.extract().map_err(|_| {
                PyTypeError::new_err(format!("{}: dict keys must be strings", at()))
            })?;
            let value = to_value(&v, &|| format!("{}['{key}']", at()))?;
            map.insert(key, value);
        }
        return Ok(Value::Object(map));
    }
    if let Ok(l) = obj.cast::<PyList>() {
        return sequence(l.iter(), l.len(), at);
    }
    if let Ok(t) = obj.cast::<PyTuple>() {
        return sequence(t.iter(), t.len(), at);
    }
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if obj.hasattr("tolist")? {
        // numpy arrays and scalars
        return to_value(&obj.call_method0("tolist")?, at);
    }
    Err(PyTypeError::new_err(format!(
        "{}: a {} is not a number, string, list or dict",
        at(),
        obj.get_type().name()?
    )))
}

fn sequence<'py>(
    items: impl Iterator<Item = Bound<'py, PyAny>>,
    len: usize,
    at: &dyn Fn() -> String,
) -> PyResult<Value> {
    let mut out = Vec::with_capacity(len);
    for (i, v) in items.enumerate() {
        out.push(to_value(&v, &|| format!("{}[{i}]", at()))?);
    }
    Ok(Value::Array(out))
}

/// A JSON value as a Python value.
pub fn to_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => PyFloat::new(py, n.as_f64().unwrap_or(f64::NAN)).into_any(),
        },
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::Array(a) => {
            let items = a
                .iter()
                .map(|x| to_py(py, x))
                .collect::<PyResult<Vec<_>>>()?;
            PyList::new(py, items)?.into_any()
        }
        Value::Object(m) => {
            let d = PyDict::new(py);
            for (k, x) in m {
                d.set_item(k, to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}
