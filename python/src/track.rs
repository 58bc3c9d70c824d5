//! The tracker as a Python object, stepped window by window (`v2x_fuser::tracker`).

use crate::boxdict::{box_dict, class_name, read_agents, read_boxes, Extra};
use crate::options::{missing_std, tracker_params};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyList;
use v2x_fuser::settings::TrackSettings;
use v2x_fuser::tracker::Tracked;
use v2x_protocol::nuscenes_json::TokenTable;
use v2x_protocol::Detection;

/// Follows fused boxes over time: one `step` per window, in time order.
#[pyclass(module = "v2x_fusion._native")]
pub struct Tracker {
    inner: v2x_fuser::tracker::Tracker,
    tokens: TokenTable,
    missing: v2x_protocol::nuscenes_json::MissingStd,
}

#[pymethods]
impl Tracker {
    /// A tracker with the parameters of `v2x-fuser track` (each left out: its default there).
    #[new]
    #[pyo3(signature = (confirm_hits=None, max_misses=None, all_classes=false, time_scale=1.0, default_std=None, association=None))]
    fn new(
        confirm_hits: Option<u32>,
        max_misses: Option<u32>,
        all_classes: bool,
        time_scale: f64,
        default_std: Option<&str>,
        association: Option<&str>,
    ) -> PyResult<Self> {
        let d = TrackSettings::default();
        let tracking = TrackSettings {
            association: match association {
                Some(a) => a
                    .parse()
                    .map_err(|e: v2x_protocol::UnknownName| PyValueError::new_err(e.to_string()))?,
                None => d.association,
            },
            confirm_hits: confirm_hits.unwrap_or(d.confirm_hits),
            max_misses: max_misses.unwrap_or(d.max_misses),
            all_classes,
        };
        let params = tracker_params(&tracking, time_scale)?;
        Ok(Tracker {
            inner: v2x_fuser::tracker::Tracker::new(params),
            tokens: TokenTable::new(),
            missing: missing_std(default_std)?,
        })
    }

    /// Steps the tracks to the window at `t_us` with its boxes (results-file dicts); returns the
    /// tracked boxes as such dicts, each with `tracking_id`, `tracking_name` and
    /// `tracking_score`.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        t_us: u64,
        boxes: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let lists = [read_boxes(
            "agents[0]",
            boxes,
            &mut self.tokens,
            self.missing,
        )?];
        self.stepped(py, &lists, |tracker, lists| tracker.step(t_us, &lists[0]))
    }

    /// Steps the tracks with each agent's boxes (`agents[k]`, lists of results-file dicts)
    /// through the tracks, CSBA-3D with `method`'s parameters fusing the rest
    /// (`v2x-fuser track --association guided`); returns the tracked boxes as `step` does.
    fn step_agents<'py>(
        &mut self,
        py: Python<'py>,
        t_us: u64,
        agents: Vec<Bound<'py, PyAny>>,
        method_name: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let method = crate::options::method(method_name)?;
        let lists = read_agents(&agents, &mut self.tokens, self.missing)?;
        self.stepped(py, &lists, |tracker, lists| {
            tracker.step_agents(t_us, lists, &method)
        })
    }

    /// The lifecycle counters: confirmed tracks alive now, confirmed so far, ended so far.
    fn stats(&self) -> (usize, u64, u64) {
        let s = self.inner.stats();
        (s.live, s.births, s.deaths)
    }

    /// Ends every track (the next step starts afresh).
    fn reset(&mut self) {
        self.inner.reset();
    }
}

impl Tracker {
    /// Steps the tracker with the boxes (one list per agent) without the GIL, and returns the
    /// tracked boxes as dicts.
    fn stepped<'py>(
        &mut self,
        py: Python<'py>,
        lists: &[Vec<Detection>],
        step: impl FnOnce(&mut v2x_fuser::tracker::Tracker, &[Vec<Detection>]) -> Vec<Tracked> + Send,
    ) -> PyResult<Bound<'py, PyAny>> {
        let inner = &mut self.inner;
        let tracked = py.detach(|| step(inner, lists));
        tracked_dicts(py, &tracked, &self.tokens)
    }
}

/// Tracked boxes as results-file dicts with `tracking_id`, `tracking_name` and `tracking_score`.
fn tracked_dicts<'py>(
    py: Python<'py>,
    tracked: &[Tracked],
    tokens: &TokenTable,
) -> PyResult<Bound<'py, PyAny>> {
    let out = PyList::empty(py);
    for t in tracked {
        let extra = [
            (
                Extra::TrackingId,
                t.tracking_id.to_string().into_pyobject(py)?.into_any(),
            ),
            (Extra::TrackingName, class_name(py, t.det.class).into_any()),
            (
                Extra::TrackingScore,
                t.det.score.into_pyobject(py)?.into_any(),
            ),
        ];
        out.append(box_dict(py, &t.det, tokens, &extra)?)?;
    }
    Ok(out.into_any())
}
