//! The tracking table (`bench tracking`): each agent and each method's fused boxes followed
//! over each scene, the guided rows, the oracle's boxes tracked by id, the true-state oracle,
//! and the summary over noise seeds.

use super::*;
use std::fmt;
use v2x_fuser::tracker::Association;

/// What a row of the tracking tables scores; written as its label (`csba-wls+ guided regions`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scored {
    /// `agentN tracked`: agent N's boxes alone, tracked (N from 1).
    Agent(usize),
    /// `METHOD`: the method's fused boxes of each frame, untracked.
    Single(Method),
    /// `METHOD tracked` (its fused boxes tracked) or `METHOD guided` (each agent's boxes
    /// through the tracks, the method fusing the rest), by one fuser or by regions.
    Tracks {
        /// The method.
        method: Method,
        /// Guided rather than tracked after fusion.
        guided: bool,
        /// One fuser, or regional fusers with or without hand-over.
        scope: Scope,
    },
    /// `gt-wls tracked by id`: the true groups tracked by the true ids (a perfect association
    /// of boxes to tracks).
    TrackedById,
    /// `gt-state-wls tracked`: each agent's boxes grouped with the likeliest true object by
    /// centre and velocity, fused and tracked (the best grouping the boxes allow a frame at a
    /// time; [`by_state`](super::by_state)).
    TrackedByState,
}

/// Who tracks a row's boxes: one fuser, or a city of regional fusers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scope {
    /// One fuser over the whole map.
    One,
    /// Regional fusers, each tracking its own tile.
    Regions,
    /// Regional fusers handing tracks over at tile borders.
    HandOver,
}

impl Scored {
    /// The method's boxes tracked after fusion by one fuser.
    pub fn tracked(method: Method) -> Self {
        Scored::Tracks {
            method,
            guided: false,
            scope: Scope::One,
        }
    }
}

impl fmt::Display for Scored {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Scored::Agent(n) => write!(f, "agent{n} tracked"),
            Scored::Single(m) => write!(f, "{m}"),
            Scored::Tracks {
                method,
                guided,
                scope,
            } => {
                let how = if *guided { "guided" } else { "tracked" };
                let scope = match scope {
                    Scope::One => "",
                    Scope::Regions => " regions",
                    Scope::HandOver => " regions hand-over",
                };
                write!(f, "{method} {how}{scope}")
            }
            Scored::TrackedById => f.write_str("gt-wls tracked by id"),
            Scored::TrackedByState => f.write_str("gt-state-wls tracked"),
        }
    }
}

impl Serialize for Scored {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// One row of the tracking table (`bench tracking`).
#[derive(Clone, Debug, Serialize)]
pub struct TrackingRow {
    /// The noise setting.
    pub noise: String,
    /// What the row scores.
    pub method: Scored,
    /// The id-matched figures of the boxes (the paper's protocol).
    #[serde(flatten)]
    pub metrics: Metrics,
    /// The tracking figures, for tracked rows.
    pub tracking: Option<TrackingMetrics>,
}

/// The tracking table: under each setting, each single agent tracked, each method single-frame,
/// tracked ([`v2x_fuser::tracker`] over the fused boxes of each scene in time order) and, but
/// the oracle, guided ([`Tracker::step_agents`]), and with gt-wls its boxes tracked by their
/// true ids and the boxes grouped by the objects' true states, tracked.
pub fn run_tracking(
    gt: &GroundTruth,
    cfg: &BenchConfig,
    params: TrackerParams,
) -> Vec<TrackingRow> {
    let mut rows = Vec::new();
    for setting in &cfg.settings {
        let n_agents = setting.agents.len();
        let gt_wls = cfg.methods.iter().position(|m| *m == Method::GtWls);
        let slots = Slots::new(n_agents, &cfg.methods).total;
        // Every class is tracked, so that the tracked rows' detection columns compare with the
        // single-frame rows'; the tracking columns score the tracking classes alone.
        let mut params = params;
        params.management.all_classes = true;
        let (accs, evals) = in_order(
            scenes(gt).into_par_iter(),
            |frames| track_scene(gt, &frames, setting, cfg, params, gt_wls),
            merge_pairs,
        )
        .unwrap_or_else(|| {
            (
                vec![Accumulator::new(); slots],
                vec![TrackingEval::new(); slots],
            )
        });
        let names = (0..n_agents)
            .map(|a| (Scored::Agent(a + 1), true))
            .chain(cfg.methods.iter().flat_map(|&method| {
                let guided = (method != Method::GtWls).then_some((
                    Scored::Tracks {
                        method,
                        guided: true,
                        scope: Scope::One,
                    },
                    true,
                ));
                [
                    (Scored::Single(method), false),
                    (Scored::tracked(method), true),
                ]
                .into_iter()
                .chain(guided)
            }))
            .chain(
                gt_wls
                    .into_iter()
                    .flat_map(|_| [(Scored::TrackedById, true), (Scored::TrackedByState, true)]),
            );
        for ((method, is_tracked), (acc, eval)) in names.zip(accs.iter().zip(evals)) {
            rows.push(TrackingRow {
                noise: setting.name.clone(),
                method,
                metrics: acc.summary(),
                tracking: is_tracked.then(|| eval.summary()),
            });
        }
    }
    rows
}

/// Where each row's figures go: each agent tracked, then per method its single-frame, tracked
/// and (but the oracle) guided rows, then with gt-wls its boxes tracked by id and the boxes
/// grouped by true state, tracked.
struct Slots {
    /// Per method: its single-frame slot (tracked next, guided after, when it has one).
    method: Vec<usize>,
    /// Per method: whether it has a guided row.
    guided: Vec<bool>,
    total: usize,
}

impl Slots {
    fn new(n_agents: usize, methods: &[Method]) -> Self {
        let mut next = n_agents;
        let (mut method, mut guided) = (Vec::new(), Vec::new());
        for m in methods {
            method.push(next);
            let g = *m != Method::GtWls;
            guided.push(g);
            next += 2 + usize::from(g);
        }
        let oracles = 2 * usize::from(methods.contains(&Method::GtWls));
        Slots {
            method,
            guided,
            total: next + oracles,
        }
    }
}

/// One scene of the tracking table: its frames in order, each agent's boxes and each method's
/// fused boxes tracked, each agent's boxes through the tracks per method (and, with gt-wls, its
/// fused boxes tracked by id and the boxes grouped by true state, tracked), scored per slot.
fn track_scene(
    gt: &GroundTruth,
    frames: &[usize],
    setting: &NoiseSetting,
    cfg: &BenchConfig,
    params: TrackerParams,
    gt_wls: Option<usize>,
) -> (Vec<Accumulator>, Vec<TrackingEval>) {
    let layout = Slots::new(setting.agents.len(), &cfg.methods);
    let slots = layout.total;
    let mut accs = vec![Accumulator::new(); slots];
    let mut evals = vec![TrackingEval::new(); slots];
    let mut trackers = vec![Tracker::new(params); slots];
    if gt_wls.is_some() {
        let mut by_id = params;
        by_id.association.mode = Association::ById;
        trackers[slots - 2] = Tracker::new(by_id);
    }
    let mut fusers = super::Fusers::new(&cfg.methods, setting.agents.len(), None);
    let scene = gt.frames[frames[0]].scene;
    for &i in frames {
        let f = &gt.frames[i];
        let dets = agent_detections(gt, i, setting, cfg.seed, cfg.range);
        let mut tracked = |slot: usize, out: Vec<Tracked>| {
            score_tracked(&mut accs[slot], &mut evals[slot], scene, f, out);
        };
        let t = f.timestamp_us;
        for (a, d) in dets.iter().enumerate() {
            let out = trackers[a].step(t, d);
            tracked(a, out);
        }
        let fused: Vec<Vec<Detection>> = (0..cfg.methods.len())
            .map(|m| fusers.fuse(m, t, &dets))
            .collect();
        for (m, fused) in fused.iter().enumerate() {
            let slot = layout.method[m];
            let out = trackers[slot + 1].step(t, fused);
            tracked(slot + 1, out);
            if layout.guided[m] {
                let out = trackers[slot + 2].step_agents(t, &dets, &cfg.methods[m]);
                tracked(slot + 2, out);
            }
        }
        if let Some(m) = gt_wls {
            let out = trackers[slots - 2].step(t, &fused[m]);
            tracked(slots - 2, out);
            let by_state = super::by_state::fuse_by_state(&dets, &f.objects);
            let out = trackers[slots - 1].step(t, &by_state);
            tracked(slots - 1, out);
        }
        for (m, fused) in fused.iter().enumerate() {
            accs[layout.method[m]].add_frame(&f.objects, fused);
        }
    }
    (accs, evals)
}

/// The tracking benchmark's columns, as [`tracking_cells`] fills them.
pub const TRACKING_COLUMNS: [(&str, Align); 7] = [
    ("AMOTA", Right),
    ("AMOTP (m)", Right),
    ("MOTA", Right),
    ("MOTP (m)", Right),
    ("IDS", Right),
    ("IDS / 100 objects", Right),
    ("FRAG", Right),
];

/// The cells of [`TRACKING_COLUMNS`], dashes for boxes not tracked.
pub fn tracking_cells(t: Option<&TrackingMetrics>) -> [String; 7] {
    let count = |n: Option<usize>| n.map_or("-".into(), |n| n.to_string());
    [
        cell(t.map(|t| t.amota), 4),
        cell(t.map(|t| t.amotp), 3),
        cell(t.map(|t| t.mota), 4),
        cell(t.map(|t| t.motp), 3),
        count(t.map(|t| t.ids)),
        cell(t.map(|t| t.ids_per_100_tracks), 2),
        count(t.map(|t| t.frag)),
    ]
}

impl Rows for [TrackingRow] {
    /// The tracking rows as a Markdown table.
    fn table(&self) -> String {
        let rows = self;
        let mut columns = vec![
            ("noise", Left),
            ("boxes", Left),
            ("precision", Right),
            ("recall", Right),
            ("mATE (m)", Right),
            ("mAOE (deg)", Right),
        ];
        columns.extend(TRACKING_COLUMNS);
        markdown(
            &columns,
            rows.iter().map(|r| {
                let m = &r.metrics;
                let mut cells = leading_cells(&r.noise, &r.method.to_string(), m);
                cells.push(cell(m.all.m_aoe, 2));
                cells.extend(tracking_cells(r.tracking.as_ref()));
                cells
            }),
        )
    }
}

/// A tracked row over several runs (logs and noise seeds): its AMOTA and identity switches
/// (per 100 objects) as mean, lowest and highest, and run by run against `gt-wls tracked` under
/// the same noise: the lowest AMOTA ratio and the highest switch ratio.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SeedSummary {
    /// The noise setting.
    pub noise: String,
    /// The row.
    pub method: Scored,
    /// Runs summarised: each log under each seed.
    pub runs: usize,
    /// AMOTA: mean, lowest, highest.
    pub amota: [f64; 3],
    /// Identity switches per 100 objects: mean, lowest, highest.
    pub ids_per_100: [f64; 3],
    /// The lowest over runs of AMOTA / `gt-wls tracked`'s AMOTA (None without that row).
    pub worst_amota_ratio: Option<f64>,
    /// The highest over runs of switches / `gt-wls tracked`'s switches (None without that row;
    /// 1 on a run where neither switched, infinite where only this row did).
    pub worst_ids_ratio: Option<f64>,
}

/// Mean, lowest and highest.
fn spread(v: &[f64]) -> [f64; 3] {
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    [mean, lo, hi]
}

/// A row's figure against the oracle's (AMOTA, switches per 100 objects) in one run.
type RatioOf<'a> = &'a dyn Fn(&TrackingMetrics, (f64, f64)) -> Option<f64>;

/// Every tracked row of `per_seed` (the tracking table of each run, rows in the same order)
/// summarised over the runs.
pub fn seed_summary(per_seed: &[Vec<TrackingRow>]) -> Vec<SeedSummary> {
    let Some(first) = per_seed.first() else {
        return Vec::new();
    };
    let oracle = |rows: &[TrackingRow], noise: &str| {
        rows.iter()
            .find(|r| r.noise == noise && r.method == Scored::tracked(Method::GtWls))
            .and_then(|r| r.tracking.as_ref())
            .map(|t| (t.amota, t.ids_per_100_tracks))
    };
    let mut out = Vec::new();
    for (i, row) in first.iter().enumerate() {
        if row.tracking.is_none() {
            continue;
        }
        let seen: Vec<(&TrackingMetrics, Option<(f64, f64)>)> = per_seed
            .iter()
            .filter_map(|rows| {
                let r = rows
                    .get(i)
                    .filter(|r| r.method == row.method && r.noise == row.noise)?;
                Some((r.tracking.as_ref()?, oracle(rows, &r.noise)))
            })
            .collect();
        let amota: Vec<f64> = seen.iter().map(|(t, _)| t.amota).collect();
        let ids: Vec<f64> = seen.iter().map(|(t, _)| t.ids_per_100_tracks).collect();
        let ratios =
            |f: RatioOf| -> Option<Vec<f64>> { seen.iter().map(|(t, o)| f(t, (*o)?)).collect() };
        out.push(SeedSummary {
            noise: row.noise.clone(),
            method: row.method,
            runs: seen.len(),
            amota: spread(&amota),
            ids_per_100: spread(&ids),
            worst_amota_ratio: ratios(&|t, (a, _)| (a > 0.0).then(|| t.amota / a))
                .map(|v| spread(&v)[1]),
            worst_ids_ratio: ratios(&|t, (_, i)| {
                Some(match (t.ids_per_100_tracks, i) {
                    (r, o) if o > 0.0 => r / o,
                    (r, _) if r > 0.0 => f64::INFINITY,
                    _ => 1.0,
                })
            })
            .map(|v| spread(&v)[2]),
        });
    }
    out
}

/// One log's tracking tables under each seed, and their summary.
#[derive(Clone, Debug, Serialize)]
pub struct LogSeeds {
    /// The log: its data root or town seed, and its part.
    pub log: String,
    /// The seeds.
    pub seeds: Vec<u64>,
    /// Each seed's rows.
    pub per_seed: Vec<Vec<TrackingRow>>,
    /// The rows summarised over the seeds.
    pub summary: Vec<SeedSummary>,
}

impl LogSeeds {
    /// A log's runs under each seed, summarised.
    pub fn new(log: String, seeds: Vec<u64>, per_seed: Vec<Vec<TrackingRow>>) -> Self {
        let summary = seed_summary(&per_seed);
        LogSeeds {
            log,
            seeds,
            per_seed,
            summary,
        }
    }
}

/// The tracking table over several logs and seeds: each log's runs, and every run summarised.
#[derive(Clone, Debug, Serialize)]
pub struct SeedsReport {
    /// Each log's runs.
    pub logs: Vec<LogSeeds>,
    /// The rows summarised over every log and seed; the worst ratios are a single run's.
    pub summary: Vec<SeedSummary>,
}

impl SeedsReport {
    /// The report of these logs' runs.
    pub fn new(logs: Vec<LogSeeds>) -> Self {
        let all: Vec<Vec<TrackingRow>> = logs.iter().flat_map(|l| l.per_seed.clone()).collect();
        SeedsReport {
            summary: seed_summary(&all),
            logs,
        }
    }
}

impl Rows for SeedsReport {
    fn table(&self) -> String {
        if self.logs.len() < 2 {
            return self.summary.table();
        }
        let mut out = format!(
            "Over every log and seed ({} logs):\n\n{}",
            self.logs.len(),
            self.summary.table()
        );
        for l in &self.logs {
            out.push_str(&format!("\n{}:\n\n{}", l.log, l.summary.table()));
        }
        out
    }
}

impl Rows for [SeedSummary] {
    /// [`seed_summary`] as a Markdown table.
    fn table(&self) -> String {
        let rows = self;
        let three = |v: [f64; 3], d: usize| format!("{:.d$} ({:.d$}-{:.d$})", v[0], v[1], v[2]);
        let ratio = |v: Option<f64>| match v {
            None => "-".into(),
            Some(r) if r.is_infinite() => "inf".into(),
            Some(r) => format!("{r:.3}"),
        };
        markdown(
            &[
                ("noise", Left),
                ("tracks", Left),
                ("runs", Right),
                ("AMOTA mean (low-high)", Right),
                ("IDS / 100 objects mean (low-high)", Right),
                ("worst AMOTA / gt-wls tracked", Right),
                ("worst IDS / gt-wls tracked", Right),
            ],
            rows.iter().map(|r| {
                vec![
                    r.noise.clone(),
                    r.method.to_string(),
                    r.runs.to_string(),
                    three(r.amota, 4),
                    three(r.ids_per_100, 2),
                    ratio(r.worst_amota_ratio),
                    ratio(r.worst_ids_ratio),
                ]
            }),
        )
    }
}

/// Scores one frame's tracks of a scene: their boxes by id, their ids as the tracking
/// benchmark does.
pub(crate) fn score_tracked(
    acc: &mut Accumulator,
    eval: &mut TrackingEval,
    scene: usize,
    f: &crate::dataset::GtFrame,
    out: Vec<Tracked>,
) {
    let marks: Vec<TrackBox> = out
        .iter()
        .map(|t| TrackBox {
            track: format!("{scene}-{}", t.tracking_id),
            class: t.det.class,
            center: [t.det.center[0], t.det.center[1]],
            score: t.det.score,
        })
        .collect();
    let boxes: Vec<Detection> = out.into_iter().map(|t| t.det).collect();
    acc.add_frame(&f.objects, &boxes);
    eval.add_frame(scene, f.timestamp_us, &f.objects, &marks);
}
