//! Fusion of numpy arrays: one dict of arrays per agent in, one dict of arrays out, with no
//! Python object per box. Every value is checked at the edge, as a results file's are.

use crate::options::method;
use numpy::ndarray::{ArrayView1, ArrayView2, Dimension};
use numpy::{Element, PyArray, PyArray1, PyArray2, PyArrayDyn, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use v2x_fuser::maths::fusion::Sourced;
use v2x_protocol::{limits, wrap_angle, Class, Detection, Uncertainty, Velocity, NO_ID};

/// The keys an agent's dict may hold.
const KEYS: [&str; 9] = [
    "center",
    "size",
    "yaw",
    "std",
    "label",
    "score",
    "id",
    "velocity",
    "velocity_std",
];

/// One agent's arrays, viewed in place (or converted once by `numpy.asarray` when their dtype
/// differs).
struct Agent<'py> {
    center: Bound<'py, PyArray2<f64>>,
    size: Bound<'py, PyArray2<f64>>,
    yaw: Bound<'py, PyArray1<f64>>,
    std: Bound<'py, PyArray2<f64>>,
    label: Bound<'py, PyArray1<i64>>,
    score: Bound<'py, PyArray1<f64>>,
    id: Option<Bound<'py, PyArray1<i64>>>,
    velocity: Option<Bound<'py, PyArray2<f64>>>,
    velocity_std: Option<Bound<'py, PyArray2<f64>>>,
}

fn err(agent: usize, key: &str, what: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("agents[{agent}]['{key}']: {what}"))
}

/// The array under `key`, of element `T` and dimension `D`: as given when it is one, else
/// through `numpy.asarray`; `None` when the key is absent or None. `found` counts the keys present.
fn array<'py, T: Element, D: Dimension>(
    d: &Bound<'py, PyDict>,
    k: usize,
    key: &Bound<'py, PyString>,
    found: &mut usize,
) -> PyResult<Option<Bound<'py, PyArray<T, D>>>> {
    let Some(v) = d.get_item(key)? else {
        return Ok(None);
    };
    *found += 1;
    if v.is_none() {
        return Ok(None);
    }
    let v = match v.cast_into::<PyArray<T, D>>() {
        Ok(a) => return Ok(Some(a)),
        Err(e) => e.into_inner(),
    };
    let py = d.py();
    let what = || {
        let dims = if D::NDIM == Some(2) {
            "(N, columns)"
        } else {
            "(N,)"
        };
        let element = std::any::type_name::<T>();
        err(
            k,
            &key.to_string(),
            format!("expected an array of {element} numbers of shape {dims}"),
        )
    };
    let converted = numpy::get_array_module(py)?
        .getattr(intern!(py, "asarray"))?
        .call1((v, numpy::dtype::<T>(py)))
        .map_err(|_| what())?;
    converted
        .cast_into::<PyArray<T, D>>()
        .map(Some)
        .map_err(|_| what())
}

impl<'py> Agent<'py> {
    fn extract(k: usize, d: &Bound<'py, PyDict>) -> PyResult<Self> {
        let py = d.py();
        let need = |key: &str| err(k, key, "missing");
        let mut found = 0;
        let center = array(d, k, intern!(py, "center"), &mut found)?;
        let size = array(d, k, intern!(py, "size"), &mut found)?;
        let yaw = array(d, k, intern!(py, "yaw"), &mut found)?;
        let std = array(d, k, intern!(py, "std"), &mut found)?;
        let label = array(d, k, intern!(py, "label"), &mut found)?;
        let score = array(d, k, intern!(py, "score"), &mut found)?;
        let id = array(d, k, intern!(py, "id"), &mut found)?;
        let velocity = array(d, k, intern!(py, "velocity"), &mut found)?;
        let velocity_std = array(d, k, intern!(py, "velocity_std"), &mut found)?;
        if found != d.len() {
            for key in d.keys() {
                let name = key.to_string();
                if !KEYS.contains(&name.as_str()) {
                    return Err(err(
                        k,
                        &name,
                        format!("unknown key (expected {})", KEYS.join(", ")),
                    ));
                }
            }
        }
        Ok(Agent {
            center: center.ok_or_else(|| need("center"))?,
            size: size.ok_or_else(|| need("size"))?,
            yaw: yaw.ok_or_else(|| need("yaw"))?,
            std: std.ok_or_else(|| need("std"))?,
            label: label.ok_or_else(|| need("label"))?,
            score: score.ok_or_else(|| need("score"))?,
            id,
            velocity,
            velocity_std,
        })
    }

    /// The agent's boxes, each value checked.
    fn detections(&self, k: usize) -> PyResult<Vec<Detection>> {
        // SAFETY: the GIL is held while the views live (no Python code runs that could resize
        // or free the arrays), and they are only read.
        let center = unsafe { self.center.as_array() };
        let n = center.nrows();
        let cols = |key: &str, a: ArrayView2<f64>, c: usize| {
            if a.dim() == (n, c) {
                Ok(())
            } else {
                Err(err(
                    k,
                    key,
                    format!("shape {:?}, expected ({n}, {c})", a.dim()),
                ))
            }
        };
        let len = |key: &str, l: usize| {
            if l == n {
                Ok(())
            } else {
                Err(err(k, key, format!("{l} values for {n} boxes")))
            }
        };
        cols("center", center, 3)?;
        let size = unsafe { self.size.as_array() };
        cols("size", size, 3)?;
        let std = unsafe { self.std.as_array() };
        cols("std", std, 7)?;
        let (yaw, label, score) = unsafe {
            (
                self.yaw.as_array(),
                self.label.as_array(),
                self.score.as_array(),
            )
        };
        len("yaw", yaw.len())?;
        len("label", label.len())?;
        len("score", score.len())?;
        let id = self.id.as_ref().map(|a| unsafe { a.as_array() });
        if let Some(id) = &id {
            len("id", id.len())?;
        }
        let velocity = self.velocity.as_ref().map(|a| unsafe { a.as_array() });
        let velocity_std = self.velocity_std.as_ref().map(|a| unsafe { a.as_array() });
        if let Some(v) = velocity {
            cols("velocity", v, 2)?;
        }
        if let Some(v) = velocity_std {
            cols("velocity_std", v, 2)?;
        }
        let v = Views {
            center,
            size,
            std,
            yaw,
            label,
            score,
            id,
            velocity,
            velocity_std,
        };
        // Pushed one by one into a vector of the right size: a collect through `Result`
        // cannot know it, and regrowing moves every box again.
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            out.push(
                v.row(i)
                    .map_err(|(key, what)| err(k, key, format!("row {i}: {what}")))?,
            );
        }
        Ok(out)
    }
}

/// One agent's arrays, read-only, their shapes checked.
struct Views<'a> {
    center: ArrayView2<'a, f64>,
    size: ArrayView2<'a, f64>,
    std: ArrayView2<'a, f64>,
    yaw: ArrayView1<'a, f64>,
    label: ArrayView1<'a, i64>,
    score: ArrayView1<'a, f64>,
    id: Option<ArrayView1<'a, i64>>,
    velocity: Option<ArrayView2<'a, f64>>,
    velocity_std: Option<ArrayView2<'a, f64>>,
}

impl Views<'_> {
    /// Box `i`, every value checked; an error names the key and what is wrong.
    fn row(&self, i: usize) -> Result<Detection, (&'static str, &'static str)> {
        let (center, size, std) = (&self.center, &self.size, &self.std);
        let c = [center[[i, 0]], center[[i, 1]], center[[i, 2]]];
        if !c.iter().all(|x| limits::coord_in_range(*x)) {
            return Err(("center", "coordinates must be finite, within 1e9 m"));
        }
        let s = [size[[i, 0]], size[[i, 1]], size[[i, 2]]];
        if !s.iter().all(|x| limits::size_in_range(*x)) {
            return Err(("size", "sizes must lie between 0.01 and 1000 m"));
        }
        let mut st = [0.0; 7];
        for (j, v) in st.iter_mut().enumerate() {
            *v = std[[i, j]];
        }
        let st = Uncertainty::from_array(st);
        if !st.is_valid() {
            return Err(("std", "stds must be finite, at least 1e-4"));
        }
        if !self.yaw[i].is_finite() {
            return Err(("yaw", "not finite"));
        }
        let class = u8::try_from(self.label[i])
            .ok()
            .and_then(Class::from_code)
            .ok_or(("label", "a class code is 0 to 9 (an index into CLASSES)"))?;
        if !(0.0..=1.0).contains(&self.score[i]) {
            return Err(("score", "expected a number in [0, 1]"));
        }
        let id = match self.id.map(|a| a[i]) {
            None | Some(-1) => NO_ID,
            Some(v) => u32::try_from(v)
                .ok()
                .filter(|v| *v != NO_ID)
                .ok_or(("id", "ids are 0 to 4294967294, or -1 for none"))?,
        };
        Ok(Detection {
            class,
            center: c,
            size: s,
            yaw: wrap_angle(self.yaw[i]),
            score: self.score[i],
            std: st,
            pos_cov: None,
            velocity: self.velocity(i)?,
            id,
        })
    }

    /// Box `i`'s velocity: none without the key or where its row is NaN.
    fn velocity(&self, i: usize) -> Result<Option<Velocity>, (&'static str, &'static str)> {
        let v = match self.velocity.map(|v| [v[[i, 0]], v[[i, 1]]]) {
            None => return Ok(None),
            Some(v) if v.iter().all(|x| x.is_nan()) => return Ok(None),
            Some(v) => v,
        };
        if !v.iter().all(|x| limits::vel_in_range(*x)) {
            return Err(("velocity", "must lie within 100 m/s (NaN: none)"));
        }
        let std = self
            .velocity_std
            .map(|s| [s[[i, 0]], s[[i, 1]]])
            .ok_or(("velocity_std", "missing (velocity is given)"))?;
        if !std.iter().all(|s| limits::std_in_range(*s)) {
            return Err(("velocity_std", "stds must be finite, at least 1e-4"));
        }
        Ok(Some(Velocity { v, std }))
    }
}

/// The fused boxes' output arrays, as slices.
struct Columns<'a> {
    center: &'a mut [f64],
    size: &'a mut [f64],
    std: &'a mut [f64],
    velocity: &'a mut [f64],
    velocity_std: &'a mut [f64],
    yaw: &'a mut [f64],
    score: &'a mut [f64],
    label: &'a mut [i64],
    id: &'a mut [i64],
    sources: &'a mut [bool],
}

impl Columns<'_> {
    /// Writes each fused box into its row; `sources` has a column per agent, of `agents`.
    fn fill(self, fused: &[Sourced], agents: usize) {
        for (i, s) in fused.iter().enumerate() {
            let d = &s.det;
            self.center[3 * i..3 * i + 3].copy_from_slice(&d.center);
            self.size[3 * i..3 * i + 3].copy_from_slice(&d.size);
            self.std[7 * i..7 * i + 7].copy_from_slice(&d.std.as_array());
            if let Some(vel) = d.velocity {
                self.velocity[2 * i..2 * i + 2].copy_from_slice(&vel.v);
                self.velocity_std[2 * i..2 * i + 2].copy_from_slice(&vel.std);
            }
            for a in s.sources.iter() {
                self.sources[agents * i + a] = true;
            }
            self.yaw[i] = d.yaw;
            self.score[i] = d.score;
            self.label[i] = d.class.code() as i64;
            self.id[i] = if d.id == NO_ID { -1 } else { d.id as i64 };
        }
    }
}

/// Fuses one time step of arrays: `agents[k]` holds agent k's `center` (N, 3), `size` (N, 3:
/// l, w, h), `yaw` (N), `std` (N, 7: x, y, z, l, w, h, yaw), `label` (N, class codes), `score`
/// (N) and optionally `id` (N, -1 for none), `velocity` and `velocity_std` (N, 2; a row of NaN
/// velocity: none). Returns the
/// same keys for the fused boxes, with `velocity` NaN where a box has none, and `sources` (M, K):
/// which agents went into each.
#[pyfunction]
pub fn fuse_arrays<'py>(
    py: Python<'py>,
    agents: Vec<Bound<'py, PyDict>>,
    method_name: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let method = method(method_name)?;
    let per_agent = agents
        .iter()
        .enumerate()
        .map(|(k, d)| Agent::extract(k, d)?.detections(k))
        .collect::<PyResult<Vec<_>>>()?;
    let fused = py.detach(|| method.fuse_sourced(&per_agent));
    let m = fused.len();
    let f64s = |shape: &[usize], fill: f64| {
        let a = PyArrayDyn::<f64>::zeros(py, shape, false);
        if fill != 0.0 {
            // SAFETY: made just above and contiguous; no one else sees it yet.
            unsafe { a.as_slice_mut() }
                .expect("made contiguous")
                .fill(fill);
        }
        a
    };
    let center = f64s(&[m, 3], 0.0);
    let size = f64s(&[m, 3], 0.0);
    let std = f64s(&[m, 7], 0.0);
    let velocity = f64s(&[m, 2], f64::NAN);
    let velocity_std = f64s(&[m, 2], f64::NAN);
    let yaw = f64s(&[m], 0.0);
    let score = f64s(&[m], 0.0);
    let label = PyArray1::<i64>::zeros(py, [m], false);
    let id = PyArray1::<i64>::zeros(py, [m], false);
    let sources = PyArray2::<bool>::zeros(py, [m, agents.len()], false);
    {
        // SAFETY: the arrays were made just above, contiguous and distinct, and Python sees
        // none of them until they are returned; the GIL is held.
        let contiguous = "made contiguous";
        let columns = unsafe {
            Columns {
                center: center.as_slice_mut().expect(contiguous),
                size: size.as_slice_mut().expect(contiguous),
                std: std.as_slice_mut().expect(contiguous),
                velocity: velocity.as_slice_mut().expect(contiguous),
                velocity_std: velocity_std.as_slice_mut().expect(contiguous),
                yaw: yaw.as_slice_mut().expect(contiguous),
                score: score.as_slice_mut().expect(contiguous),
                label: label.as_slice_mut().expect(contiguous),
                id: id.as_slice_mut().expect(contiguous),
                sources: sources.as_slice_mut().expect(contiguous),
            }
        };
        columns.fill(&fused, agents.len());
    }
    let out = PyDict::new(py);
    for (key, value) in [
        (intern!(py, "center"), center.into_any()),
        (intern!(py, "size"), size.into_any()),
        (intern!(py, "yaw"), yaw.into_any()),
        (intern!(py, "std"), std.into_any()),
        (intern!(py, "label"), label.into_any()),
        (intern!(py, "score"), score.into_any()),
        (intern!(py, "id"), id.into_any()),
        (intern!(py, "velocity"), velocity.into_any()),
        (intern!(py, "velocity_std"), velocity_std.into_any()),
        (intern!(py, "sources"), sources.into_any()),
    ] {
        out.set_item(key, value)?;
    }
    Ok(out)
}
