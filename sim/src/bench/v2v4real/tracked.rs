//! V2V4Real tracked (`v2x-sim bench --dataset v2v4real`'s tracked tables): `v2x-fuser track`
//! over both cars' folders, a folder of tracks, and the ceiling of every box with its label's
//! id, each scored by AB3DMOT's evaluation as its script scores this layout, with false
//! positives counted, and by HOTA.

use crate::table::{
    markdown,
    Align::{self, Left, Right},
    Rows,
};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use v2x_eval::ab3dmot_eval::{evaluate_with, Ab3dmotMetrics, FalsePositives, Sequence};
use v2x_eval::hota::{hota, Frame as HotaFrame, HotaMetrics};
use v2x_fuser::maths::geometry::iou_3d;
use v2x_fuser::offline::{read_inputs, track_sequences, FilesError, OfflineOptions};
use v2x_fuser::tracker::{Association, TrackerParams};
use v2x_fuser::Method;
use v2x_protocol::kitti::{self, KittiError};
use v2x_protocol::nuscenes_json::MissingStd;
use v2x_protocol::Detection;
use v2x_protocol::Uncertainty;
use v2x_truth::v2v4real::V2v4real;

/// A tracked row: `v2x-fuser track` over both cars' folders, scored by AB3DMOT's evaluation.
#[derive(Clone, Debug, Serialize)]
pub struct TrackedRow {
    /// `METHOD tracked`, or `METHOD guided`.
    pub method: String,
    /// AB3DMOT's figures as its script scores this layout (no false positive counted).
    pub metrics: Ab3dmotMetrics,
    /// The same with every unmatched tracked box a false positive.
    pub counted: Ab3dmotMetrics,
    /// HOTA over 3D IoU, every tracked box counted.
    pub hota: HotaMetrics,
    /// Tracked boxes per frame.
    pub boxes_per_frame: f64,
    /// Labelled cars per frame.
    pub labels_per_frame: f64,
}

/// Tracks both cars' folders (`cars`, the receiving car first) as `v2x-fuser track` does, with
/// `method` and `params`, and scores the tracks against the split's labels.
pub fn tracked(
    d: &V2v4real,
    cars: &[PathBuf],
    method: &Method,
    params: TrackerParams,
) -> Result<TrackedRow, FilesError> {
    let read = read_inputs(cars, MissingStd::Error)?;
    let opts = OfflineOptions::method(*method);
    let tracks = track_sequences(
        &read.agents,
        &read.tracking_options(&opts),
        read.tracker_params(&opts, params),
    )?;
    let rows = |token: &str| match (tracks.results.samples.get(token), tracks.ids.get(token)) {
        (Some(dets), Some(ids)) => dets
            .iter()
            .zip(ids)
            .map(|(d, &id)| Detection { id, ..d.clone() })
            .collect(),
        _ => Vec::new(),
    };
    let seqs = sequences(d, rows);
    let name = format!(
        "{} {}",
        method.name(),
        match params.association.mode {
            Association::Guided => "guided",
            Association::Assignment => "tracked assignment",
            _ => "tracked",
        }
    );
    Ok(row(name, d, &seqs))
}

/// The split's labels and, per frame, the tracked boxes `rows` gives for its sample token (ids
/// the tracks'), cut into sequences.
pub fn sequences(d: &V2v4real, rows: impl Fn(&str) -> Vec<Detection>) -> Vec<Sequence> {
    let mut out: Vec<Sequence> = Vec::new();
    for (i, f) in d.frames.iter().enumerate() {
        if i == 0 || d.frames[i - 1].seq != f.seq {
            out.push(Sequence::default());
        }
        let s = out.last_mut().expect("pushed above");
        s.gt.push(d.gt[i].clone());
        s.tracks.push(rows(&f.token()));
    }
    out
}

/// A folder of KITTI tracking rows (`v2x-fuser track --output-format kitti`'s output) scored
/// by AB3DMOT's evaluation against the split's labels.
pub fn score_track_dir(d: &V2v4real, dir: &Path) -> Result<TrackedRow, KittiError> {
    let mut by_token: BTreeMap<String, Vec<Detection>> = BTreeMap::new();
    for (seq, path) in kitti::sequence_files(dir)? {
        for r in kitti::read_tracks(&path)? {
            let det = kitti::DetectionRow {
                frame: r.frame,
                class: r.class,
                score: r.score.unwrap_or(0.0),
                bbox: r.bbox,
            }
            .detection(Uncertainty::uniform(0.5, 0.1, 0.1));
            by_token
                .entry(kitti::token(seq, r.frame))
                .or_default()
                .push(Detection { id: r.id, ..det });
        }
    }
    let seqs = sequences(d, |t| by_token.get(t).cloned().unwrap_or_default());
    Ok(row(dir.display().to_string(), d, &seqs))
}

/// The tracking ceiling of boxes alone: every box of both cars shown, each with the track id of
/// the nearest label within 2 m (BEV centre distance; a fresh id when none is). No tracker that
/// shows one box per object finds more, since the evaluation counts no false positives here.
pub fn ceiling(d: &V2v4real) -> TrackedRow {
    let mut fresh = u32::MAX / 2;
    let mut rows: Vec<Vec<Detection>> = Vec::with_capacity(d.frames.len());
    for (i, gt) in d.gt.iter().enumerate() {
        let mut frame = Vec::new();
        for b in d.cars[0][i].iter().chain(&d.cars[1][i]) {
            let near = gt
                .iter()
                .map(|g| {
                    (
                        (g.center[0] - b.center[0]).hypot(g.center[1] - b.center[1]),
                        g.id,
                    )
                })
                .filter(|&(dist, _)| dist < 2.0)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let id = near.map_or_else(
                || {
                    fresh += 1;
                    fresh
                },
                |(_, id)| id,
            );
            frame.push(Detection { id, ..b.clone() });
        }
        rows.push(frame);
    }
    let index = d
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| (f.token(), i))
        .collect::<BTreeMap<_, _>>();
    let seqs = sequences(d, |t| {
        index.get(t).map(|&i| rows[i].clone()).unwrap_or_default()
    });
    row("both cars' boxes, labels' ids (ceiling)".into(), d, &seqs)
}

/// The sequences as HOTA takes them: 3D IoU between each label and tracked box.
fn hota_sequences(seqs: &[Sequence]) -> Vec<Vec<HotaFrame>> {
    seqs.par_iter()
        .map(|s| {
            s.gt.iter()
                .zip(&s.tracks)
                .map(|(g, t)| HotaFrame {
                    gt: g.iter().map(|d| d.id).collect(),
                    tracks: t.iter().map(|d| d.id).collect(),
                    similarity: g
                        .iter()
                        .map(|a| t.iter().map(|b| iou_3d(a, b).clamp(0.0, 1.0)).collect())
                        .collect(),
                })
                .collect()
        })
        .collect()
}

/// A tracked row of these sequences.
fn row(method: String, d: &V2v4real, seqs: &[Sequence]) -> TrackedRow {
    let per_frame = |n: usize| n as f64 / d.frames.len().max(1) as f64;
    let boxes: usize = seqs.iter().flat_map(|s| &s.tracks).map(Vec::len).sum();
    let labels: usize = seqs.iter().flat_map(|s| &s.gt).map(Vec::len).sum();
    let ((metrics, counted), hota) = rayon::join(
        || {
            rayon::join(
                || evaluate_with(seqs, FalsePositives::AsScript).unwrap_or_default(),
                || evaluate_with(seqs, FalsePositives::Counted).unwrap_or_default(),
            )
        },
        || hota(&hota_sequences(seqs)),
    );
    TrackedRow {
        method,
        metrics,
        counted,
        hota,
        boxes_per_frame: per_frame(boxes),
        labels_per_frame: per_frame(labels),
    }
}

impl Rows for [TrackedRow] {
    /// The tracked rows as two Markdown tables (percent, as AB3DMOT's script prints them):
    /// scored as the script scores this layout, then with false positives counted.
    fn table(&self) -> String {
        format!(
            "AB3DMOT's evaluation as its script scores these rows (no false positive counted):\n\n\
             {}\nThe same, every unmatched tracked box a false positive (precision and recall \
             at the threshold of best MOTA), and HOTA over 3D IoU (every tracked box):\n\n{}",
            tracked_table(self, |r| &r.metrics, &STOCK),
            tracked_table(self, |r| &r.counted, &COUNTED)
        )
    }
}

/// A column of the tracked tables: its heading, its alignment and its cell from a row and the
/// row's metrics under the table's scoring.
type Column = (
    &'static str,
    Align,
    fn(&TrackedRow, &Ab3dmotMetrics) -> String,
);

/// The columns both tracked tables begin with.
const LEAD: [Column; 5] = [
    ("tracks", Left, |r, _| r.method.clone()),
    ("sAMOTA", Right, |_, m| pct(m.samota)),
    ("AMOTA", Right, |_, m| pct(m.amota)),
    ("AMOTP", Right, |_, m| pct(m.amotp)),
    ("MOTA", Right, |_, m| pct(m.mota)),
];

/// The rest of the table as AB3DMOT's script scores this layout.
const STOCK: [Column; 7] = [
    ("MOTP", Right, |_, m| pct(m.motp)),
    ("MT", Right, |_, m| pct(m.mt)),
    ("ML", Right, |_, m| pct(m.ml)),
    ("IDS", Right, |_, m| m.ids.to_string()),
    ("FRAG", Right, |_, m| m.frag.to_string()),
    ("recall", Right, |_, m| pct(m.recall)),
    ("boxes/frame", Right, |r, _| {
        format!("{:.1}", r.boxes_per_frame)
    }),
];

/// The rest of the table with every unmatched box a false positive, and HOTA.
const COUNTED: [Column; 10] = [
    ("IDS", Right, |_, m| m.ids.to_string()),
    ("FP", Right, |_, m| m.fp.to_string()),
    ("precision", Right, |_, m| {
        pct(m.tp as f64 / (m.tp + m.fp).max(1) as f64)
    }),
    ("recall", Right, |_, m| pct(m.recall)),
    ("HOTA", Right, |r, _| pct(r.hota.hota)),
    ("DetA", Right, |r, _| pct(r.hota.deta)),
    ("AssA", Right, |r, _| pct(r.hota.assa)),
    ("LocA", Right, |r, _| pct(r.hota.loca)),
    ("boxes/frame", Right, |r, _| {
        format!("{:.1}", r.boxes_per_frame)
    }),
    ("labels/frame", Right, |r, _| {
        format!("{:.1}", r.labels_per_frame)
    }),
];

/// A percentage as AB3DMOT's script prints it.
fn pct(v: f64) -> String {
    format!("{:.2}", 100.0 * v)
}

/// The tracked rows as one Markdown table: the lead columns then `rest`, each row's metrics
/// those `metrics` picks.
fn tracked_table(
    rows: &[TrackedRow],
    metrics: fn(&TrackedRow) -> &Ab3dmotMetrics,
    rest: &[Column],
) -> String {
    let columns: Vec<&Column> = LEAD.iter().chain(rest).collect();
    let heads: Vec<(&str, Align)> = columns.iter().map(|c| (c.0, c.1)).collect();
    markdown(
        &heads,
        rows.iter().map(|r| {
            columns
                .iter()
                .map(|c| (c.2)(r, metrics(r)))
                .collect::<Vec<String>>()
        }),
    )
}
