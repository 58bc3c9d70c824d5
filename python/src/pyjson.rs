//! Python values as JSON values, with no text in between: for what is not a box dict (options,
//! numpy values inside a box, documents), boxes themselves being read key by key (`boxdict`).

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::{Map, Number, Value};

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
