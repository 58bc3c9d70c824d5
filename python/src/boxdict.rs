//! Results-file box dicts read and written key by key, with no JSON value in between: a dict's
//! fields reach the same checks as a results file's box (`nuscenes_json::parse_box_fields`) and
//! the boxes come back through the same writer (`nuscenes_json::box_fields`).

use crate::pyjson::to_value;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use pyo3::{intern, Borrowed};
use serde_json::Value;
use std::path::Path;
use v2x_protocol::nuscenes_json::{
    box_fields, parse_box_fields, BoxFields, Field, FieldValue, JsonError, MissingStd, OutField,
    TokenTable,
};
use v2x_protocol::Detection;

/// The key `name` as a Python string, made once for the fields the format knows (those a box
/// is read from, `attribute_name`, and what the package adds to the dicts it returns).
fn key<'py>(py: Python<'py>, name: &str) -> Bound<'py, PyString> {
    match key_index(name) {
        Some(i) => key_table(py)[i].bind(py).clone(),
        None => PyString::new(py, name),
    }
}

/// Where `name` stands in [`key_table`].
fn key_index(name: &str) -> Option<usize> {
    let names = || (0..Field::ALL.len() + MORE.len()).map(key_name);
    // The writer's names are the same constants: their address finds them, their text if not.
    names()
        .position(|k| std::ptr::eq(k, name))
        .or_else(|| names().position(|k| k == name))
}

/// The name of [`key_table`]'s key `i`.
fn key_name(i: usize) -> &'static str {
    Field::ALL
        .get(i)
        .map_or_else(|| MORE[i - Field::ALL.len()], |f| f.name())
}

/// The keys written besides the [`Field`]s.
const MORE: [&str; 5] = [
    "attribute_name",
    "v2x_sources",
    "tracking_id",
    "tracking_name",
    "tracking_score",
];

/// The interned keys: the [`Field`]s first, then [`MORE`], made on the first call.
fn key_table(py: Python<'_>) -> &'static [Py<PyString>] {
    static KEYS: PyOnceLock<Vec<Py<PyString>>> = PyOnceLock::new();
    KEYS.get_or_init(py, || {
        Field::ALL
            .iter()
            .map(|f| f.name())
            .chain(MORE)
            .map(|k| PyString::intern(py, k).unbind())
            .collect()
    })
}

/// A class's name, made once per interpreter.
fn class_name(py: Python<'_>, c: v2x_protocol::Class) -> Bound<'_, PyString> {
    static NAMES: PyOnceLock<Vec<Py<PyString>>> = PyOnceLock::new();
    NAMES.get_or_init(py, || {
        v2x_protocol::Class::ALL
            .iter()
            .map(|c| PyString::intern(py, c.name()).unbind())
            .collect()
    })[v2x_protocol::Class::ALL
        .iter()
        .position(|&k| k == c)
        .expect("every class is in ALL")]
    .bind(py)
    .clone()
}

/// A dict's values of the fields a box is read from, found in one pass over its items.
struct DictFields<'py>([Option<Bound<'py, PyAny>>; Field::ALL.len()]);

impl<'py> DictFields<'py> {
    fn of(d: &Bound<'py, PyDict>) -> DictFields<'py> {
        let py = d.py();
        let keys = &key_table(py)[..Field::ALL.len()];
        let mut fields: [Option<Bound<'py, PyAny>>; Field::ALL.len()] = Default::default();
        for (k, v) in d.iter() {
            // Keys written in Python source are interned: the pointer finds them.
            let i = keys
                .iter()
                .position(|x| x.as_ptr() == k.as_ptr())
                .or_else(|| {
                    let k = k.cast::<PyString>().ok()?.to_cow().ok()?;
                    key_index(&k).filter(|&i| i < Field::ALL.len())
                });
            if let Some(i) = i {
                fields[i] = Some(v);
            }
        }
        DictFields(fields)
    }
}

impl BoxFields for DictFields<'_> {
    fn field(&self, f: Field) -> Option<FieldValue<'_>> {
        self.0[f as usize].as_ref().map(field_value)
    }
}

/// A Python value as a box field: floats, ints, strings, lists and tuples directly, anything else
/// (numpy arrays and scalars) through its JSON value.
fn field_value<'a>(v: &'a Bound<'_, PyAny>) -> FieldValue<'a> {
    if v.is_none() {
        return FieldValue::Null;
    }
    if let Ok(f) = v.cast::<PyFloat>() {
        return FieldValue::Number(f.value(), None);
    }
    if is_int(v) {
        return v.extract::<f64>().map_or(FieldValue::Other, |x| {
            FieldValue::Number(x, v.extract::<u64>().ok())
        });
    }
    if let Ok(s) = v.cast::<PyString>() {
        return s.to_cow().map_or(FieldValue::Other, FieldValue::Str);
    }
    if let Ok(l) = v.cast::<PyList>() {
        return FieldValue::List(l.iter().map(|x| element(&x)).collect());
    }
    if let Ok(t) = v.cast::<PyTuple>() {
        return FieldValue::List(t.iter().map(|x| element(&x)).collect());
    }
    match to_value(v, &String::new) {
        Ok(value) => FieldValue::of_json(&value).into_owned(),
        Err(_) => FieldValue::Other,
    }
}

/// An int that is not a bool.
fn is_int(v: &Bound<'_, PyAny>) -> bool {
    v.is_instance_of::<PyInt>() && !v.is_instance_of::<PyBool>()
}

/// A float's or an int's value (not a bool's).
fn number(v: &Bound<'_, PyAny>) -> Option<f64> {
    if let Ok(f) = v.cast::<PyFloat>() {
        return Some(f.value());
    }
    if is_int(v) {
        return v.extract::<f64>().ok();
    }
    None
}

/// A list element's number (NaN for what is not one), numpy scalars through their JSON value.
fn element(v: &Bound<'_, PyAny>) -> f64 {
    number(v)
        .or_else(|| to_value(v, &String::new).ok()?.as_f64())
        .unwrap_or(f64::NAN)
}

/// Each agent's boxes (`agents[k]`, a list of results-file dicts) parsed and checked as a
/// results file's; errors name `agents[k]`, the box and the field.
pub fn read_agents(
    agents: &[Bound<'_, PyAny>],
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> PyResult<Vec<Vec<Detection>>> {
    agents
        .iter()
        .enumerate()
        .map(|(k, a)| read_boxes(&format!("agents[{k}]"), a, tokens, missing))
        .collect()
}

/// One list of box dicts; `name` names it in errors.
pub fn read_boxes(
    name: &str,
    list: &Bound<'_, PyAny>,
    tokens: &mut TokenTable,
    missing: MissingStd,
) -> PyResult<Vec<Detection>> {
    let source = Path::new(name);
    let fail = |e: JsonError| PyValueError::new_err(e.to_string());
    let one = |i: usize, b: Borrowed<'_, '_, PyAny>, tokens: &mut TokenTable| {
        if let Ok(d) = b.cast::<PyDict>() {
            return parse_box_fields(source, i, &DictFields::of(&d), tokens, missing).map_err(fail);
        }
        match to_value(&b, &|| format!("{name}[{i}]"))? {
            Value::Object(m) => parse_box_fields(source, i, &m, tokens, missing).map_err(fail),
            _ => Err(fail(JsonError {
                file: source.into(),
                sample: None,
                index: Some(i),
                field: None,
                message: "expected a box object".into(),
            })),
        }
    };
    if let Ok(l) = list.cast::<PyList>() {
        let mut out = Vec::with_capacity(l.len());
        for i in 0..l.len() {
            out.push(one(i, l.get_item(i)?.as_borrowed(), tokens)?);
        }
        return Ok(out);
    }
    let not_a_list = || {
        fail(JsonError {
            file: source.into(),
            sample: None,
            index: None,
            field: None,
            message: "expected a list of boxes".into(),
        })
    };
    if list.is_instance_of::<PyDict>() || list.is_instance_of::<PyString>() {
        return Err(not_a_list());
    }
    let items = list.try_iter().map_err(|_| not_a_list())?;
    let mut out = Vec::new();
    for (i, b) in items.enumerate() {
        out.push(one(i, b?.as_borrowed(), tokens)?);
    }
    Ok(out)
}

/// A box as a results-file dict (no `sample_token`).
pub fn box_dict<'py>(
    py: Python<'py>,
    d: &Detection,
    tokens: &TokenTable,
) -> PyResult<Bound<'py, PyDict>> {
    let (template, order) = template(py);
    let dict = template.bind(py).copy()?;
    let keys = key_table(py);
    let mut written = 0u32;
    let mut result = Ok(());
    // The writer puts its keys in the template's order: each is found at or just after the last.
    let mut next = 0;
    box_fields(None, d, tokens, |k, v| {
        if result.is_err() {
            return;
        }
        let ahead = order[next..]
            .iter()
            .position(|&i| std::ptr::eq(key_name(i), k));
        let found = match ahead {
            Some(p) => {
                next += p + 1;
                Some(order[next - 1])
            }
            None => key_index(k),
        };
        let Some(i) = found else {
            result = Err(PyValueError::new_err(format!("no key for the field {k}")));
            return;
        };
        written |= 1 << i;
        let k = keys[i].bind(py);
        result = match v {
            OutField::Str("") => dict.set_item(k, intern!(py, "")),
            OutField::Str(s) => dict.set_item(k, s),
            OutField::Class(c) => dict.set_item(k, class_name(py, c)),
            OutField::Number(x) => dict.set_item(k, x),
            OutField::Numbers(xs) => PyList::new(py, xs.iter()).and_then(|l| dict.set_item(k, l)),
            OutField::Id(i) => dict.set_item(k, i),
        };
    });
    result?;
    for &i in order.iter().filter(|&&i| written & (1 << i) == 0) {
        dict.del_item(keys[i].bind(py))?;
    }
    Ok(dict)
}

/// A dict of every key the writer may write, in its order, each `None`, and those keys' places
/// in [`key_table`]: each box's dict starts as a copy (sized once, where setting key after key
/// grows it twice), the keys its box has not removed.
fn template(py: Python<'_>) -> &'static (Py<PyDict>, Vec<usize>) {
    static TEMPLATE: PyOnceLock<(Py<PyDict>, Vec<usize>)> = PyOnceLock::new();
    TEMPLATE.get_or_init(py, || {
        // A box with every optional field, and an id with a token; an id without one is
        // written as `instance_id` in the token's place.
        let mut tokens = TokenTable::new();
        let full = Detection {
            class: v2x_protocol::Class::Car,
            center: [0.0; 3],
            size: [1.0; 3],
            yaw: 0.0,
            score: 1.0,
            std: v2x_protocol::Uncertainty::uniform(1.0, 1.0, 1.0),
            pos_cov: Some(Box::new([
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ])),
            velocity: Some(v2x_protocol::Velocity {
                v: [0.0; 2],
                std: [1.0; 2],
            }),
            id: tokens.intern("token"),
        };
        let mut order = Vec::new();
        box_fields(None, &full, &tokens, |k, _| order.extend(key_index(k)));
        if let Some(at) = order
            .iter()
            .position(|&i| i == Field::InstanceToken as usize)
        {
            order.insert(at + 1, Field::InstanceId as usize);
        }
        let dict = PyDict::new(py);
        for &i in &order {
            dict.set_item(key_table(py)[i].bind(py), py.None())
                .expect("a dict takes a string key");
        }
        (dict.unbind(), order)
    })
}

/// Sets `name` on a dict by its interned key.
pub fn set<'py>(
    dict: &Bound<'py, PyDict>,
    name: &str,
    value: impl IntoPyObject<'py>,
) -> PyResult<()> {
    dict.set_item(key(dict.py(), name), value)
}
