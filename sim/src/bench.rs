//! The paper's Table 2: every method under every noise setting, beside the single agents and the
//! lower bound, on one ground truth. Frames are independent, so they are scored in parallel;
//! the noise of a frame depends only on (seed, agent, frame), so results do not depend on threads.

use crate::dataset::{GroundTruth, GtObject};
use crate::detection_eval::{DetectionEval, DetectionMetrics};
use crate::metrics::{Accumulator, Metrics};
use crate::noise::{detect, place_agents, Capture, NoiseSetting, Placement};
use crate::table::{
    cell, markdown, Align,
    Align::{Left, Right},
    Rows,
};
use crate::tracking_eval::{TrackBox, TrackingEval, TrackingMetrics};
use frames::{BenchFrame, Frames, RowBoxes, Rule};
use fusers::Fusers;
use rayon::prelude::*;
use serde::Serialize;
use v2x_eval::protocol::Merge;
use v2x_fuser::intake::region::{self, Tiling};
use v2x_fuser::pipeline::Steps;
use v2x_fuser::time::align::AlignParams;
use v2x_fuser::tracker::{Tracked, Tracker, TrackerParams};
use v2x_fuser::Method;
use v2x_protocol::Detection;

pub mod asynchronous;
mod by_state;
pub mod dair;
pub mod frames;
pub mod fusers;
pub mod pr_plot;
pub mod regions;
mod tracking;
pub mod v2v4real;
pub(crate) use tracking::score_tracked;
pub use tracking::{
    run_tracking, seed_summary, tracking_cells, LogSeeds, Scope, Scored, SeedSummary, SeedsReport,
    TrackingRow, TRACKING_COLUMNS,
};

/// One row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// The noise setting (`mild`, `moderate`, `large`, `mild+large`, ...).
    pub noise: String,
    /// The method name, `agentN` for a single agent, or `bound`.
    pub method: String,
    /// The metrics (for `bound`, only `mATE` is set).
    #[serde(flatten)]
    pub metrics: Metrics,
}

/// What to run.
#[derive(Clone, Debug)]
pub struct BenchConfig {
    /// Methods, in row order.
    pub methods: Vec<Method>,
    /// Noise settings, in table order.
    pub settings: Vec<NoiseSetting>,
    /// Seed of the noise.
    pub seed: u64,
    /// Sensing range of every agent (None: every agent sees every object).
    pub range: Option<f64>,
}

/// Every agent's detections of frame `i` under a setting.
pub fn agent_detections(
    gt: &GroundTruth,
    i: usize,
    setting: &NoiseSetting,
    seed: u64,
    range: Option<f64>,
) -> Vec<Vec<Detection>> {
    let places = place_agents(&gt.frames[i], setting.agents.len(), seed);
    detections_from(gt, i, setting, seed, range, &places)
}

/// [`agent_detections`] with the agents at `places`.
fn detections_from(
    gt: &GroundTruth,
    i: usize,
    setting: &NoiseSetting,
    seed: u64,
    range: Option<f64>,
    places: &[Placement],
) -> Vec<Vec<Detection>> {
    let frame = &gt.frames[i];
    let objects = gt.in_draw_order(frame.objects.clone());
    setting
        .agents
        .iter()
        .enumerate()
        .map(|(a, noise)| {
            detect(
                &objects,
                Capture::of(frame, i as u64),
                a,
                noise,
                places[a].position,
                range,
                seed,
            )
        })
        .collect()
}

/// The agents simulated over a ground truth under one noise setting, as the bench reads them.
pub struct Simulated<'a> {
    gt: &'a GroundTruth,
    setting: &'a NoiseSetting,
    seed: u64,
    range: Option<f64>,
    by_scene: bool,
}

impl<'a> Simulated<'a> {
    /// The agents of `setting` over `gt`, drawn with `cfg`'s seed and range.
    pub fn new(gt: &'a GroundTruth, cfg: &BenchConfig, setting: &'a NoiseSetting) -> Self {
        Simulated {
            gt,
            setting,
            seed: cfg.seed,
            range: cfg.range,
            by_scene: false,
        }
    }

    /// The same, each scene's frames scored in order by one part: for steps with history.
    pub fn by_scene(self) -> Self {
        Simulated {
            by_scene: true,
            ..self
        }
    }
}

impl Frames for Simulated<'_> {
    type Truth = Vec<GtObject>;
    type Cost = ();

    fn count(&self) -> usize {
        self.gt.frames.len()
    }

    fn parts(&self) -> Vec<Vec<usize>> {
        if self.by_scene {
            scenes(self.gt)
        } else {
            frames::runs(self.count())
        }
    }

    fn frame(&self, i: usize) -> Option<BenchFrame<Vec<GtObject>>> {
        let frame = &self.gt.frames[i];
        let places = place_agents(frame, self.setting.agents.len(), self.seed);
        let (gt, setting, seed, range) = (self.gt, self.setting, self.seed, self.range);
        Some(BenchFrame {
            index: i,
            agents: detections_from(gt, i, setting, seed, range, &places),
            kinds: places.iter().map(|p| p.kind).collect(),
            t_us: frame.timestamp_us,
            truth: frame.objects.clone(),
        })
    }

    fn cost(&self, _: &BenchFrame<Vec<GtObject>>) {}
}

/// Runs the table; `tick` is called once per frame and setting done (for a progress bar).
pub fn run(gt: &GroundTruth, cfg: &BenchConfig, tick: &(dyn Fn() + Sync)) -> Vec<Row> {
    let mut rows = Vec::new();
    for setting in &cfg.settings {
        let n_agents = setting.agents.len();
        let row_boxes = RowBoxes::agents_then_methods(n_agents, cfg.methods.len());
        // Frame by frame, without history: no step of this table carries any.
        let fusers = Fusers::new(&cfg.methods, n_agents, None);
        let source = Simulated::new(gt, cfg, setting);
        let accs = frames::score(&source, &row_boxes, &fusers, Accumulator::new, tick).rows;
        let names = (0..n_agents)
            .map(|a| format!("agent{}", a + 1))
            .chain(cfg.methods.iter().map(Method::name));
        for (method, acc) in names.zip(&accs) {
            rows.push(Row {
                noise: setting.name.clone(),
                method,
                metrics: acc.summary(),
            });
        }
        let mut bound = Accumulator::new().summary();
        bound.precision = None;
        bound.recall = None;
        bound.all.m_ate = Some(setting.error_bound());
        rows.push(Row {
            noise: setting.name.clone(),
            method: "bound".into(),
            metrics: bound,
        });
    }
    rows
}

/// Regional fusion against one fuser on the same frames (`bench regions`): per setting and
/// method, the method as one fuser runs it and the union of its regional fusers' outputs, one
/// region per tile some box lies in ([`v2x_fuser::intake::region`]).
pub fn run_regions(gt: &GroundTruth, cfg: &BenchConfig, tiling: Tiling, halo_m: f64) -> Vec<Row> {
    let mut rows = Vec::new();
    // Each region's input through the method's pipeline (no step carries history here, so one
    // pipeline serves every region).
    let regional: Vec<Box<Rule<'_, Vec<GtObject>>>> = (0..cfg.methods.len())
        .map(|m| {
            Box::new(move |f: &BenchFrame<Vec<GtObject>>, fusers: &mut Fusers| {
                let fuse = |input: &[Vec<Detection>]| fusers.fuse(m, f.t_us, input);
                region::fuse_regions(tiling, halo_m, fuse, &f.agents)
            }) as Box<Rule<'_, _>>
        })
        .collect();
    let row_boxes: Vec<RowBoxes<'_, _>> = regional
        .iter()
        .enumerate()
        .flat_map(|(m, rule)| [RowBoxes::Method(m), RowBoxes::Rule(&**rule)])
        .collect();
    for setting in &cfg.settings {
        let fusers = Fusers::new(&cfg.methods, setting.agents.len(), None);
        let source = Simulated::new(gt, cfg, setting);
        let accs = frames::score(&source, &row_boxes, &fusers, Accumulator::new, &|| ()).rows;
        for (m, method) in cfg.methods.iter().enumerate() {
            for (k, name) in [method.name(), format!("{method} regions")]
                .into_iter()
                .enumerate()
            {
                rows.push(Row {
                    noise: setting.name.clone(),
                    method: name,
                    metrics: accs[2 * m + k].summary(),
                });
            }
        }
    }
    rows
}

/// One row of the distance-matched table (`bench detection`).
#[derive(Clone, Debug, Serialize)]
pub struct DetectionRow {
    /// The noise setting.
    pub noise: String,
    /// `agentN`, the method name, or `METHOD --align`.
    pub method: String,
    /// The nuScenes detection benchmark's figures.
    #[serde(flatten)]
    pub metrics: DetectionMetrics,
}

impl DetectionRow {
    /// The row's name: `NOISE METHOD`, or the method alone without a noise setting.
    fn name(&self) -> String {
        match self.noise.is_empty() {
            true => self.method.clone(),
            false => format!("{} {}", self.noise, self.method),
        }
    }
}

impl Rows for [DetectionRow] {
    fn table(&self) -> String {
        let named: Vec<_> = self.iter().map(|r| (r.name(), &r.metrics)).collect();
        detection_table(&named)
    }

    fn csv(&self) -> Option<String> {
        let named: Vec<_> = self.iter().map(|r| (r.name(), &r.metrics)).collect();
        Some(detection_csv(&named))
    }
}

/// The distance-matched table (the nuScenes detection benchmark, `bench detection`): under each
/// setting, each single agent and each method, and with `align` each method again after the
/// agents are registered to the roadside unit (agent 2) by [`v2x_fuser::time::align`], filtered over
/// the frames of a scene.
pub fn run_detection(
    gt: &GroundTruth,
    cfg: &BenchConfig,
    align_with: Option<&AlignParams>,
    tick: &(dyn Fn() + Sync),
) -> Vec<DetectionRow> {
    let mut rows = Vec::new();
    // Each method plainly, then registered: the latter's pipelines filter over a scene's windows.
    let plain = cfg.methods.iter().map(|&m| Steps::method(m));
    let aligned = align_with.into_iter().flat_map(|p| {
        cfg.methods.iter().map(|&m| Steps {
            align: Some(*p),
            ..Steps::method(m)
        })
    });
    let steps: Vec<Steps> = plain.chain(aligned).collect();
    for setting in &cfg.settings {
        let n_agents = setting.agents.len();
        let row_boxes = RowBoxes::agents_then_methods(n_agents, steps.len());
        let fusers = Fusers::of_steps(steps.iter().cloned(), n_agents);
        let source = Simulated::new(gt, cfg, setting).by_scene();
        let evals = frames::score(&source, &row_boxes, &fusers, DetectionEval::new, tick).rows;
        let names = (0..n_agents)
            .map(|a| format!("agent{}", a + 1))
            .chain(cfg.methods.iter().map(|m| m.name()))
            .chain(cfg.methods.iter().map(|m| format!("{m} --align")));
        for (name, eval) in names.zip(&evals) {
            rows.push(DetectionRow {
                noise: setting.name.clone(),
                method: name,
                metrics: eval.summary(),
            });
        }
    }
    rows
}

/// Frames a parallel task scores in a row.
pub(crate) const FRAMES_PER_TASK: usize = 32;

/// Each item's figures (`f`) computed in parallel and merged in the items' order, so that they
/// are the same to the last digit however the threads ran; `None` without items.
pub(crate) fn in_order<I, T: Send>(
    items: impl IndexedParallelIterator<Item = I>,
    f: impl Fn(I) -> T + Sync + Send,
    merge: impl FnMut(T, T) -> T,
) -> Option<T> {
    let parts: Vec<T> = items.map(f).collect();
    parts.into_iter().reduce(merge)
}

/// Merges two pairs of slots, each with its own.
pub(crate) fn merge_pairs<A: Merge, B: Merge>(
    (a, b): (Vec<A>, Vec<B>),
    (c, d): (Vec<A>, Vec<B>),
) -> (Vec<A>, Vec<B>) {
    (merge_slots(a, c), merge_slots(b, d))
}

/// Adds `b`'s slots into `a`'s, one by one.
pub(crate) fn merge_slots<T: Merge>(mut a: Vec<T>, b: Vec<T>) -> Vec<T> {
    for (x, y) in a.iter_mut().zip(b) {
        x.absorb(y);
    }
    a
}

/// The frames of each scene, in order.
pub(crate) fn scenes(gt: &GroundTruth) -> Vec<Vec<usize>> {
    let mut scenes: Vec<Vec<usize>> = Vec::new();
    for (i, f) in gt.frames.iter().enumerate() {
        match scenes.last_mut() {
            Some(s) if gt.frames[s[0]].scene == f.scene => s.push(i),
            _ => scenes.push(vec![i]),
        }
    }
    scenes
}

impl Rows for [Row] {
    /// The rows as a Markdown table.
    fn table(&self) -> String {
        let rows = self;
        markdown(
            &[
                ("noise", Left),
                ("method", Left),
                ("precision", Right),
                ("recall", Right),
                ("mATE (m)", Right),
                ("mASE (m)", Right),
                ("mAOE (deg)", Right),
                ("TP-only mATE", Right),
                ("TP-only mASE", Right),
                ("TP-only mAOE", Right),
            ],
            rows.iter().map(|r| {
                let m = &r.metrics;
                let mut cells = leading_cells(&r.noise, &r.method, m);
                cells.extend([
                    cell(m.all.m_ase, 3),
                    cell(m.all.m_aoe, 2),
                    cell(m.tp_only.m_ate, 3),
                    cell(m.tp_only.m_ase, 3),
                    cell(m.tp_only.m_aoe, 2),
                ]);
                cells
            }),
        )
    }

    /// The rows as CSV.
    fn csv(&self) -> Option<String> {
        let rows = self;
        let mut s = String::from("noise,method,precision,recall,mATE,mASE,mAOE,tp,fp,fn,tp_only_mATE,tp_only_mASE,tp_only_mAOE\n");
        let c = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x}"));
        for r in rows {
            let m = &r.metrics;
            s.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                r.noise,
                r.method,
                c(m.precision),
                c(m.recall),
                c(m.all.m_ate),
                c(m.all.m_ase),
                c(m.all.m_aoe),
                m.tp,
                m.fp,
                m.fn_,
                c(m.tp_only.m_ate),
                c(m.tp_only.m_ase),
                c(m.tp_only.m_aoe)
            ));
        }
        Some(s)
    }
}

/// A table row's first cells: the noise, the boxes' name, precision, recall and mATE.
fn leading_cells(noise: &str, name: &str, m: &Metrics) -> Vec<String> {
    vec![
        noise.to_string(),
        name.to_string(),
        cell(m.precision, 4),
        cell(m.recall, 4),
        cell(m.all.m_ate, 3),
    ]
}

/// Distance-matched (nuScenes benchmark) figures as a Markdown table, one row per named result.
fn detection_table(rows: &[(String, &crate::detection_eval::DetectionMetrics)]) -> String {
    let fixed = |v: f64, digits: usize| cell(Some(v), digits);
    markdown(
        &[
            ("predictions", Left),
            ("precision", Right),
            ("recall", Right),
            ("mAP", Right),
            ("NDS", Right),
            ("mATE (m)", Right),
            ("mASE", Right),
            ("mAOE (rad)", Right),
            ("mAVE (m/s)", Right),
        ],
        rows.iter().map(|(name, m)| {
            vec![
                name.clone(),
                cell(m.precision, 4),
                cell(m.recall, 4),
                fixed(m.m_ap, 4),
                fixed(m.nds, 4),
                fixed(m.m_ate, 3),
                fixed(m.m_ase, 3),
                fixed(m.m_aoe, 3),
                fixed(m.m_ave, 3),
            ]
        }),
    )
}

/// Distance-matched figures as CSV.
fn detection_csv(rows: &[(String, &crate::detection_eval::DetectionMetrics)]) -> String {
    let mut s =
        String::from("predictions,precision,recall,mAP,NDS,mATE,mASE,mAOE,mAVE,mAAE,tp,fp,fn\n");
    let c = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x}"));
    for (name, m) in rows {
        s.push_str(&format!(
            "{name},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            c(m.precision),
            c(m.recall),
            m.m_ap,
            m.nds,
            m.m_ate,
            m.m_ase,
            m.m_aoe,
            m.m_ave,
            m.m_aae,
            m.tp,
            m.fp,
            m.fn_
        ));
    }
    s
}

/// The tracking tests' case: two town scenes of 6 s at 10 Hz, two agents at one noise setting,
/// the given methods.
#[cfg(test)]
pub(crate) fn tracking_case(methods: &[&str], noise: &str) -> (GroundTruth, BenchConfig) {
    let gt = crate::town::generate(&crate::town::TownConfig {
        scenes: 2,
        seconds: 6.0,
        hz: 10.0,
        seed: 2,
    });
    let cfg = BenchConfig {
        methods: methods.iter().map(|m| m.parse().unwrap()).collect(),
        settings: vec![NoiseSetting::parse(noise, 2).unwrap()],
        seed: 3,
        range: None,
    };
    (gt, cfg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::town::{generate, TownConfig};

    #[test]
    fn small_table_has_the_papers_shape() {
        let gt = generate(&TownConfig {
            scenes: 4,
            seconds: 5.0,
            hz: 2.0,
            seed: 1,
        });
        let cfg = BenchConfig {
            methods: vec![
                "nms-3d".parse().unwrap(),
                "csba-wls".parse().unwrap(),
                "csba-wls+".parse().unwrap(),
                "gt-wls".parse().unwrap(),
            ],
            settings: vec![NoiseSetting::parse("mild", 2).unwrap()],
            seed: 5,
            range: None,
        };
        let rows = run(&gt, &cfg, &|| {});
        let get = |m: &str| rows.iter().find(|r| r.method == m).unwrap().metrics.clone();
        assert_eq!(rows.len(), 2 + 4 + 1);
        // single agents: every object once, precision and recall 1
        assert_eq!(get("agent1").precision, Some(1.0));
        assert_eq!(get("agent2").recall, Some(1.0));
        // oracle: perfect association, error near the bound sqrt(pi/2) * 0.5/sqrt(2) = 0.443
        let gt_wls = get("gt-wls");
        assert_eq!(gt_wls.precision, Some(1.0));
        assert!(
            (gt_wls.tp_only.m_ate.unwrap() - 0.443).abs() < 0.05,
            "{:?}",
            gt_wls.tp_only.m_ate
        );
        // NMS keeps duplicates at mild noise? It suppresses overlaps: precision high, error of one agent
        let plus = get("csba-wls+");
        assert!(plus.precision.unwrap() > 0.99 && plus.recall.unwrap() > 0.99);
        assert!(plus.all.m_ate.unwrap() < gt_wls.all.m_ate.unwrap() * 1.05);
        assert!(plus.all.m_ate.unwrap() < get("agent1").all.m_ate.unwrap());
        // deterministic
        let again = run(&gt, &cfg, &|| {});
        assert_eq!(rows[..].table(), again[..].table());
    }

    /// The tracking rows of one method at one noise setting over two town scenes of 6 s at
    /// 10 Hz, and their names.
    #[test]
    fn parallel_figures_merge_in_the_items_order() {
        // Sums of 0.1 k in a tree of another shape differ in the last digits; in order, they are
        // the sequential sum exactly, and concatenation keeps the items' order.
        let items: Vec<u32> = (0..10_000).collect();
        let sum = in_order(items.par_iter(), |&k| 0.1 * k as f64, |a, b| a + b).unwrap();
        let sequential = items.iter().fold(0.0, |a, &k| a + 0.1 * k as f64);
        assert_eq!(sum.to_bits(), sequential.to_bits());
        let order = in_order(
            items.par_chunks(7),
            |c| c.to_vec(),
            |mut a, b| {
                a.extend(b);
                a
            },
        );
        assert_eq!(order.unwrap(), items);
        assert!(in_order(Vec::<u32>::new().par_iter(), |&k| k, |a, b| a + b).is_none());
    }

    fn tracking_rows(method: &str, noise: &str) -> (Vec<TrackingRow>, Vec<String>) {
        let (gt, cfg) = tracking_case(&[method], noise);
        let rows = run_tracking(&gt, &cfg, TrackerParams::default());
        let names = rows.iter().map(|r| r.method.to_string()).collect();
        (rows, names)
    }

    #[test]
    fn tracking_beats_single_frames_over_time() {
        let (rows, names) = tracking_rows("csba-wls+", "moderate");
        assert_eq!(
            names,
            [
                "agent1 tracked",
                "agent2 tracked",
                "csba-wls+",
                "csba-wls+ tracked",
                "csba-wls+ guided"
            ]
        );
        let (single, tracked) = (&rows[2], &rows[3]);
        assert!(single.tracking.is_none());
        let t = tracked.tracking.as_ref().unwrap();
        assert!(t.mota > 0.85 && t.ids_per_100_tracks <= 5.0, "{t:?}");
        // Through the tracks: as good a tracker, far closer to the truth than single frames
        // (here 0.484 m against 0.432 m fused first).
        let g = rows[4].tracking.as_ref().unwrap();
        assert!(g.mota > 0.85 && g.ids_per_100_tracks <= 5.0, "{g:?}");
        let (g_ate, t_ate) = (
            rows[4].metrics.all.m_ate.unwrap(),
            tracked.metrics.all.m_ate.unwrap(),
        );
        assert!(
            g_ate < 0.7 * single.metrics.all.m_ate.unwrap() && g_ate < 1.25 * t_ate,
            "guided {g_ate} tracked {t_ate}"
        );
        let (a, b) = (
            single.metrics.all.m_ate.unwrap(),
            tracked.metrics.all.m_ate.unwrap(),
        );
        assert!(b < 0.7 * a, "tracked {b} single-frame {a}");
        assert!(rows[..]
            .table()
            .contains("| moderate | csba-wls+ tracked |"));
    }

    #[test]
    fn tracking_by_true_id_beats_tracking_by_likelihood() {
        let (rows, names) = tracking_rows("gt-wls", "large");
        assert_eq!(
            names,
            [
                "agent1 tracked",
                "agent2 tracked",
                "gt-wls",
                "gt-wls tracked",
                "gt-wls tracked by id",
                "gt-state-wls tracked"
            ]
        );
        let (tracked, by_id) = (&rows[3], &rows[4]);
        let (a, b) = (
            tracked.metrics.all.m_ate.unwrap(),
            by_id.metrics.all.m_ate.unwrap(),
        );
        // The same boxes, each given to its own object's track: a smaller error.
        assert!(b < 0.9 * a, "by id {b}, by likelihood {a}");
        let (ta, tb) = (
            tracked.tracking.as_ref().unwrap(),
            by_id.tracking.as_ref().unwrap(),
        );
        assert!(tb.mota >= ta.mota, "{tb:?} {ta:?}");
    }

    #[test]
    fn boxes_grouped_by_true_state_track_about_as_well_as_grouped_by_id() {
        let (rows, names) = tracking_rows("gt-wls", "large");
        assert_eq!(names[5], "gt-state-wls tracked");
        let amota = |k: usize| rows[k].tracking.as_ref().unwrap().amota;
        let (one, by_id, by_state) = (amota(0), amota(3), amota(5));
        // AMOTA 0.853 against 0.843 grouped by id, and 0.782 for one agent alone: each
        // object's boxes of both agents were fused together.
        assert!(by_state >= by_id - 0.01, "{by_state} {by_id}");
        assert!(by_state >= one + 0.03, "{by_state} {one}");
    }

    #[test]
    fn tracked_rows_are_summarised_over_seeds_and_against_the_oracle_seed_by_seed() {
        let (gt, mut cfg) = tracking_case(&["csba-wls+", "gt-wls"], "large");
        let per_seed: Vec<Vec<TrackingRow>> = [3, 4, 5]
            .iter()
            .map(|&seed| {
                cfg.seed = seed;
                run_tracking(&gt, &cfg, Default::default())
            })
            .collect();
        let summary = seed_summary(&per_seed);
        let csba = Scored::tracked("csba-wls+".parse().unwrap());
        let oracle = Scored::tracked(Method::GtWls);
        // Every tracked row, in table order; single-frame rows are not summarised.
        let tracked: Vec<Scored> = per_seed[0]
            .iter()
            .filter(|r| r.tracking.is_some())
            .map(|r| r.method)
            .collect();
        let names: Vec<Scored> = summary.iter().map(|r| r.method).collect();
        assert_eq!(names, tracked);
        let amota = |rows: &[TrackingRow], m: Scored| {
            rows.iter()
                .find(|r| r.method == m)
                .unwrap()
                .tracking
                .as_ref()
                .unwrap()
                .amota
        };
        let row = summary.iter().find(|r| r.method == csba).unwrap();
        let each: Vec<f64> = per_seed.iter().map(|r| amota(r, csba)).collect();
        assert_eq!(row.runs, 3);
        assert!((row.amota[0] - each.iter().sum::<f64>() / 3.0).abs() < 1e-12);
        assert_eq!(
            row.amota[1],
            each.iter().copied().fold(f64::INFINITY, f64::min)
        );
        assert_eq!(
            row.amota[2],
            each.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        );
        // The worst ratio is taken seed by seed, not from the means.
        let worst = per_seed
            .iter()
            .map(|r| amota(r, csba) / amota(r, oracle))
            .fold(f64::INFINITY, f64::min);
        assert_eq!(row.worst_amota_ratio, Some(worst));
        let oracle = summary.iter().find(|r| r.method == oracle).unwrap();
        assert_eq!(oracle.worst_amota_ratio, Some(1.0));
        assert_eq!(oracle.worst_ids_ratio, Some(1.0));
        assert!(summary[..]
            .table()
            .contains("| large | csba-wls+ tracked | 3 |"));
    }

    #[test]
    fn logs_are_summarised_each_and_together_the_worst_run_of_any_log_shown() {
        let (gt, mut cfg) = tracking_case(&["csba-wls+", "gt-wls"], "large");
        let logs: Vec<LogSeeds> = (0..2)
            .map(|k| {
                let part = gt.part(k, 2).unwrap();
                let per_seed = [3, 4]
                    .iter()
                    .map(|&seed| {
                        cfg.seed = seed;
                        run_tracking(&part, &cfg, Default::default())
                    })
                    .collect();
                LogSeeds::new(format!("part {k}"), vec![3, 4], per_seed)
            })
            .collect();
        let report = SeedsReport::new(logs.clone());
        let csba = Scored::tracked("csba-wls+".parse().unwrap());
        let row = |s: &[SeedSummary]| s.iter().find(|r| r.method == csba).unwrap().clone();
        let all = row(&report.summary);
        let each: Vec<SeedSummary> = logs.iter().map(|l| row(&l.summary)).collect();
        assert_eq!(all.runs, 4);
        assert_eq!(each[0].runs, 2);
        // The mean is over every run; the lows, highs and worst ratios the worst of any log.
        let mean = (each[0].amota[0] + each[1].amota[0]) / 2.0;
        assert!((all.amota[0] - mean).abs() < 1e-12);
        assert_eq!(all.amota[1], each[0].amota[1].min(each[1].amota[1]));
        let worst = |r: &SeedSummary| r.worst_amota_ratio.unwrap();
        assert_eq!(worst(&all), worst(&each[0]).min(worst(&each[1])));
        let worst_ids = |r: &SeedSummary| r.worst_ids_ratio.unwrap();
        assert_eq!(
            worst_ids(&all),
            worst_ids(&each[0]).max(worst_ids(&each[1]))
        );
        // The table shows the whole first, then each log under its name.
        let table = report.table();
        let at = |s: &str| table.find(s).unwrap_or_else(|| panic!("{s} in {table}"));
        assert!(at("Over every log and seed (2 logs)") < at("part 0:"));
        assert!(at("part 0:") < at("part 1:"));
        assert!(
            table.contains("| large | csba-wls+ tracked | 4 |"),
            "{table}"
        );
    }
}
