//! V2V4Real offline (`v2x-sim bench --dataset v2v4real`): each car's real detections alone,
//! the dataset's own fused references, its late-fusion rule, and every method fusing the two
//! cars, each scored by V2V4Real's detection protocol, with the bytes a frame costs.

use crate::bench::frames::{self, BenchFrame, Frames, RowBoxes, Rule};
use crate::bench::fusers::Fusers;
use crate::table::{
    markdown,
    Align::{Left, Right},
    Rows,
};
use crate::wire_bytes::{frame_bytes, Bytes};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};
use v2x_eval::dair_eval::View;
use v2x_eval::protocol::Merge;
use v2x_eval::v2v4real_eval::{Ordering, V2v4realEval, V2v4realMetrics, RANGES, THRESHOLDS};
use v2x_fuser::maths::baselines::nms;
use v2x_fuser::maths::geometry::bev_iou;
use v2x_fuser::offline::{fuse_step, OfflineOptions};
use v2x_fuser::uncertainty::detector::DetectorParams;
use v2x_fuser::Method;
use v2x_protocol::kitti::{self, KittiError};
use v2x_protocol::{AgentKind, Detection};
use v2x_truth::v2v4real::{V2v4real, CARS};

mod tracked;
pub use tracked::{ceiling, score_track_dir, sequences, tracked, TrackedRow};

/// One row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct V2v4realRow {
    /// `ego alone`, `car 1 alone`, a reference's name, or a method's.
    pub method: String,
    /// V2V4Real's protocol.
    pub ap: V2v4realMetrics,
    /// Mean bytes per frame on the wire that the row needs (both cars' frames for a fusion);
    /// none for a reference, whose traffic is not the project's.
    pub bytes_per_frame: Option<f64>,
    /// The same boxes as ETSI CPMs: mean bytes per frame.
    pub cpm_bytes_per_frame: Option<f64>,
    /// Precision-recall curves, BEV at 0.5 and 0.7 in both orderings (thinned).
    #[serde(skip)]
    pub curves: Vec<crate::bench::pr_plot::Line>,
}

/// The score the late-fusion rule's cut row drops boxes below.
pub const RULE_CUT: f64 = 0.4;

/// What a row fuses or shows.
#[derive(Clone, Debug)]
pub enum Source {
    /// One car's detections alone (an index into [`CARS`]).
    Car(usize),
    /// A reference the dataset publishes (an index into [`V2v4real::references`]).
    Reference(usize),
    /// The dataset's late-fusion rule: both cars' boxes pooled, greedy NMS on BEV IoU > 0.15.
    LateFusionRule,
    /// The late-fusion rule with boxes below [`RULE_CUT`] dropped: what a cut alone does.
    LateFusionRuleTail,
    /// A method fusing both cars, as `v2x-fuser fuse` fuses a detector's rows.
    Method(Method),
}

impl Source {
    /// The row's name.
    pub fn name(&self, d: &V2v4real) -> String {
        match self {
            Source::Car(0) => "ego alone".into(),
            Source::Car(k) => format!("car {} alone", CARS[*k]),
            Source::Reference(k) => d.references[*k].0.clone(),
            Source::LateFusionRule => "late fusion rule (BEV NMS 0.15)".into(),
            Source::LateFusionRuleTail => format!("late fusion rule, score >= {RULE_CUT}"),
            Source::Method(m) => m.name(),
        }
    }

    /// The row's boxes in frame `i`.
    fn boxes(&self, d: &V2v4real, i: usize) -> Vec<Detection> {
        let both = || [d.cars[0][i].clone(), d.cars[1][i].clone()];
        let rule = || nms(&both(), bev_iou, 0.15).into_iter().map(|s| s.det);
        match self {
            Source::Car(k) => d.cars[*k][i].clone(),
            Source::Reference(k) => d.references[*k].1[i].clone(),
            Source::LateFusionRule => rule().collect(),
            Source::LateFusionRuleTail => rule().filter(|b| b.score >= RULE_CUT).collect(),
            Source::Method(m) => {
                let mut opts = OfflineOptions::method(*m);
                opts.steps.detector = Some(DetectorParams::default());
                fuse_step(&opts, &both())
            }
        }
    }

    /// The cars whose frames the row sends.
    fn senders(&self) -> &'static [usize] {
        match self {
            Source::Car(0) => &[0],
            Source::Car(_) => &[1],
            Source::Reference(_) => &[],
            _ => &[0, 1],
        }
    }
}

/// Every row: each car, the references present, the late-fusion rule, then `methods`.
pub fn sources(d: &V2v4real, methods: &[Method]) -> Vec<Source> {
    let mut s = vec![Source::Car(0), Source::Car(1)];
    s.extend((0..d.references.len()).map(Source::Reference));
    s.push(Source::LateFusionRule);
    s.push(Source::LateFusionRuleTail);
    s.extend(methods.iter().map(|m| Source::Method(*m)));
    s
}

/// What one car's frame costs on the air, as frames and as CPMs.
pub fn car_bytes(car: usize, capture_us: u64, dets: &[Detection]) -> Bytes {
    frame_bytes(CARS[car], AgentKind::Vehicle, capture_us, dets)
}

/// A row's name as a folder name: letters and digits kept, `+` spelled `plus`, every other
/// run one `-`.
pub fn slug(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c == '+' {
            out.push_str(if out.ends_with('-') {
                "plus-"
            } else {
                "-plus-"
            });
        } else if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('-') {
            out.push('-');
        }
    }
    out.trim_matches('-').to_string()
}

/// Writes each source's boxes as KITTI detection rows into `dir/SLUG/` ([`slug`] of its
/// name), one `NNNN.txt` per sequence; returns each folder with its rows.
pub fn write_rows(
    d: &V2v4real,
    sources: &[Source],
    dir: &Path,
) -> Result<Vec<(PathBuf, usize)>, KittiError> {
    let sequences: std::collections::BTreeSet<u32> = d.frames.iter().map(|f| f.seq).collect();
    sources
        .iter()
        .map(|src| {
            let out = dir.join(slug(&src.name(d)));
            let results = v2x_protocol::nuscenes_json::Results {
                samples: (0..d.frames.len())
                    .into_par_iter()
                    .map(|i| (d.frames[i].token(), src.boxes(d, i)))
                    .collect(),
                ..Default::default()
            };
            let n = kitti::write_detection_dir(&out, &results, sequences.iter().copied())?;
            Ok((out, n))
        })
        .collect()
}

/// A folder of KITTI detection rows scored by V2V4Real's detection protocol.
pub fn score_detection_dir(d: &V2v4real, dir: &Path) -> Result<V2v4realMetrics, KittiError> {
    let mut eval = V2v4realEval::new();
    for (gt, preds) in d.gt.iter().zip(d.read_rows(dir)?) {
        eval.add_frame(gt, &preds);
    }
    Ok(eval.summary())
}

/// The BEV precision-recall curves of a row at 0.5 and 0.7, frame order solid, global sort
/// dashed, each thinned to 400 points.
fn curves(eval: &V2v4realEval) -> Vec<crate::bench::pr_plot::Line> {
    let mut out = Vec::new();
    for o in Ordering::ALL {
        for (t, colour) in [(0.5, "#1f77b4"), (0.7, "#d62728")] {
            out.push(crate::bench::pr_plot::Line {
                label: format!("BEV @{t}, {}", o.name()),
                colour,
                dashed: o == Ordering::Global,
                points: crate::bench::pr_plot::thin(&eval.curve(View::Bev, t, o), 400),
            });
        }
    }
    out
}

/// Writes each row's precision-recall curves as `dir/SLUG.svg` ([`slug`] of its name); returns
/// the files written.
pub fn write_plots(rows: &[V2v4realRow], dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    rows.iter()
        .map(|r| {
            let path = dir.join(format!("{}.svg", slug(&r.method)));
            std::fs::write(&path, crate::bench::pr_plot::svg(&r.method, &r.curves))?;
            Ok(path)
        })
        .collect()
}

/// What each car's frames cost on the air.
#[derive(Clone, Copy, Default)]
pub struct CarBytes([Bytes; 2]);

impl Merge for CarBytes {
    fn absorb(&mut self, other: Self) {
        self.0[0] += other.0[0];
        self.0[1] += other.0[1];
    }
}

/// The split's frames as the bench reads them: the two cars' detections, scored by V2V4Real's
/// protocol against the labels.
pub struct CarFrames<'a>(pub &'a V2v4real);

impl Frames for CarFrames<'_> {
    type Truth = Vec<Detection>;
    type Cost = CarBytes;

    fn count(&self) -> usize {
        self.0.frames.len()
    }

    fn frame(&self, i: usize) -> Option<BenchFrame<Vec<Detection>>> {
        let d = self.0;
        Some(BenchFrame {
            index: i,
            agents: vec![d.cars[0][i].clone(), d.cars[1][i].clone()],
            kinds: vec![AgentKind::Vehicle; 2],
            t_us: d.frames[i].capture_us(),
            truth: d.gt[i].clone(),
        })
    }

    fn cost(&self, f: &BenchFrame<Vec<Detection>>) -> CarBytes {
        let mut cost = CarBytes::default();
        for (car, dets) in f.agents.iter().enumerate() {
            cost.0[car] += car_bytes(car, f.t_us, dets);
        }
        cost
    }
}

/// Scores every source over every frame, in frame order.
pub fn run(d: &V2v4real, sources: &[Source]) -> Vec<V2v4realRow> {
    let rules: Vec<Box<Rule<'_, Vec<Detection>>>> = sources
        .iter()
        .map(|src| {
            Box::new(move |f: &BenchFrame<Vec<Detection>>, _: &mut Fusers| src.boxes(d, f.index))
                as Box<Rule<'_, _>>
        })
        .collect();
    let row_boxes: Vec<RowBoxes<'_, _>> = sources
        .iter()
        .zip(&rules)
        .map(|(src, rule)| match src {
            Source::Car(k) => RowBoxes::Agent(*k),
            _ => RowBoxes::Rule(&**rule),
        })
        .collect();
    // The methods fuse as `v2x-fuser fuse --detector` does (`Source::boxes`), not by these.
    let fusers = Fusers::new(&[], 2, None);
    let totals = frames::score(
        &CarFrames(d),
        &row_boxes,
        &fusers,
        V2v4realEval::new,
        &|| (),
    );
    let frames = d.frames.len().max(1) as f64;
    sources
        .iter()
        .zip(totals.rows)
        .map(|(src, eval)| {
            let senders = src.senders();
            let mut sent = Bytes::default();
            for &c in senders {
                sent += totals.cost.0[c];
            }
            let per_frame = |b: usize| (!senders.is_empty()).then(|| b as f64 / frames);
            V2v4realRow {
                method: src.name(d),
                ap: eval.summary(),
                bytes_per_frame: per_frame(sent.frame),
                cpm_bytes_per_frame: per_frame(sent.cpm),
                curves: curves(&eval),
            }
        })
        .collect()
}

fn ap_headers() -> Vec<String> {
    [View::Bev, View::ThreeD]
        .iter()
        .flat_map(|v| {
            THRESHOLDS
                .iter()
                .map(move |t| format!("AP-{}@{t}", if *v == View::Bev { "BEV" } else { "3D" }))
        })
        .collect()
}

fn ap_cells(m: &V2v4realMetrics, ordering: Ordering) -> Vec<String> {
    let aps = m.aps(ordering);
    [View::Bev, View::ThreeD]
        .into_iter()
        .flat_map(|view| {
            let aps = &aps;
            THRESHOLDS.iter().map(move |&t| {
                aps.get(view, t)
                    .map_or_else(|| "-".into(), |v| format!("{v:.3}"))
            })
        })
        .collect()
}

impl V2v4realRow {
    /// The row's cells of one ordering's table.
    fn cells(&self, ordering: Ordering) -> Vec<String> {
        let mut cells = vec![self.method.clone()];
        cells.extend(ap_cells(&self.ap, ordering));
        cells.push(format!(
            "{:.1}",
            self.ap.predictions as f64 / self.ap.frames.max(1) as f64
        ));
        for b in [self.bytes_per_frame, self.cpm_bytes_per_frame] {
            cells.push(b.map_or_else(|| "-".into(), |b| format!("{b:.0}")));
        }
        cells
    }
}

/// Each row's BEV AP at 0.5 and 0.7 by range, both orderings in a cell (`frame / global`).
fn range_table(rows: &[V2v4realRow]) -> String {
    let heads: Vec<String> = RANGES
        .iter()
        .flat_map(|(lo, hi)| [0.5, 0.7].map(|t| format!("{lo}-{hi} m @{t}")))
        .collect();
    let mut columns = vec![("boxes / method", Left)];
    columns.extend(heads.iter().map(|h| (h.as_str(), Right)));
    markdown(
        &columns,
        rows.iter().map(|r| {
            let mut cells = vec![r.method.clone()];
            for band in &r.ap.ranges {
                for t in [0.5, 0.7] {
                    let f = |o: Ordering| {
                        let aps = if o == Ordering::Frame {
                            &band.frame
                        } else {
                            &band.global
                        };
                        aps.get(View::Bev, t)
                            .map_or_else(|| "-".into(), |v| format!("{v:.3}"))
                    };
                    cells.push(format!("{} / {}", f(Ordering::Frame), f(Ordering::Global)));
                }
            }
            cells
        }),
    )
}

impl Rows for [V2v4realRow] {
    /// The rows as Markdown tables: V2V4Real's AP in frame order (its published figure), the
    /// same boxes globally sorted by score, and BEV AP by range in both orderings.
    fn table(&self) -> String {
        let rows = self;
        let heads = ap_headers();
        let mut columns = vec![("boxes / method", Left)];
        columns.extend(heads.iter().map(|h| (h.as_str(), Right)));
        columns.extend([
            ("boxes/frame", Right),
            ("bytes/frame", Right),
            ("CPM bytes/frame", Right),
        ]);
        let mut out = String::new();
        for o in Ordering::ALL {
            out.push_str(&format!(
                "AP, {} ({}):\n\n",
                o.name(),
                match o {
                    Ordering::Frame => "V2V4Real's published protocol",
                    Ordering::Global => "OpenCOOD's --global_sort_detections",
                }
            ));
            out.push_str(&markdown(&columns, rows.iter().map(|r| r.cells(o))));
            out.push('\n');
        }
        out.push_str("AP-BEV by distance from the ego car, frame order / global sort:\n\n");
        out.push_str(&range_table(rows));
        out
    }
}

/// The V2V4Real bench: the detection table, then the tracking table after its own heading.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// AP per source.
    pub detection: Vec<V2v4realRow>,
    /// Tracked per method.
    pub tracking: Vec<TrackedRow>,
    /// What the tracking table holds and how long it took.
    #[serde(skip)]
    pub tracking_heading: String,
}

impl Rows for Report {
    fn table(&self) -> String {
        format!(
            "{}\n{}\n\n{}",
            self.detection.table(),
            self.tracking_heading,
            self.tracking.table()
        )
    }
}

#[cfg(test)]
mod tests;
