//! HOTA (Luiten et al., IJCV 2020) with its parts DetA, AssA and LocA, computed step for step as
//! TrackEval's `metrics/hota.py` computes them, over any similarity in [0, 1] (the benches give
//! 3D IoU):
//!
//! - per sequence, each (label id, track id) pair's global alignment: the sum over frames of its
//!   similarity normalised as an IoU over its row and column, divided by the frames of either
//!   less that sum;
//! - per frame, one assignment maximising alignment times similarity (scipy's
//!   `linear_sum_assignment`, the same algorithm), then for each alpha in 0.05, 0.10, ..., 0.95
//!   the assigned pairs of similarity >= alpha are true positives, the other labels misses and
//!   the other tracked boxes false positives;
//! - per alpha: DetA = TP / (TP + FN + FP), AssA the TP-weighted mean over matches of each
//!   pair's matches / (its label's frames + its track's frames - matches), LocA the mean
//!   similarity of the matches, HOTA = sqrt(DetA AssA);
//! - sequences combined as TrackEval combines them (counts summed, AssA and LocA weighted by TP),
//!   and every figure the mean over the 19 alphas.
//!
//! Every tracked box counts: HOTA takes no score threshold.

use serde::Serialize;
use std::collections::HashMap;

/// The alphas, 0.05 to 0.95.
const ALPHAS: usize = 19;

fn alpha(a: usize) -> f64 {
    0.05 + a as f64 * 0.05
}

/// One frame: its labels' object ids, its tracked boxes' track ids, and the similarity of each
/// (label, tracked box) pair, `similarity[label][track]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame {
    /// Object id of each label.
    pub gt: Vec<u32>,
    /// Track id of each tracked box.
    pub tracks: Vec<u32>,
    /// Similarity in [0, 1], a row per label.
    pub similarity: Vec<Vec<f64>>,
}

/// HOTA and its parts, each the mean over the alphas.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct HotaMetrics {
    /// sqrt(DetA AssA).
    pub hota: f64,
    /// Detection accuracy.
    pub deta: f64,
    /// Association accuracy.
    pub assa: f64,
    /// Detection recall.
    pub detre: f64,
    /// Detection precision.
    pub detpr: f64,
    /// Association recall.
    pub assre: f64,
    /// Association precision.
    pub asspr: f64,
    /// Localisation accuracy: the matches' mean similarity.
    pub loca: f64,
}

/// Per-alpha sums of one sequence or of several.
#[derive(Clone, Debug, Default)]
struct Counts {
    tp: [f64; ALPHAS],
    fn_: [f64; ALPHAS],
    fp: [f64; ALPHAS],
    assa: [f64; ALPHAS],
    assre: [f64; ALPHAS],
    asspr: [f64; ALPHAS],
    loca: [f64; ALPHAS],
}

/// Each id's dense index.
type IdIndex = HashMap<u32, usize>;

/// Dense indices of the ids a sequence holds, and how many frames each appears in.
fn index(ids: impl Iterator<Item = u32>) -> (IdIndex, Vec<f64>) {
    let mut map = HashMap::new();
    let mut count = Vec::new();
    for id in ids {
        let k = *map.entry(id).or_insert_with(|| {
            count.push(0.0);
            count.len() - 1
        });
        count[k] += 1.0;
    }
    (map, count)
}

/// One sequence's counts (TrackEval's `eval_sequence`).
fn sequence(frames: &[Frame]) -> Counts {
    let mut c = Counts::default();
    let n_gt: usize = frames.iter().map(|f| f.gt.len()).sum();
    let n_tr: usize = frames.iter().map(|f| f.tracks.len()).sum();
    if n_tr == 0 || n_gt == 0 {
        c.fn_ = [n_gt as f64; ALPHAS];
        c.fp = [n_tr as f64; ALPHAS];
        c.loca = [1.0; ALPHAS];
        return c;
    }
    let (gmap, gcount) = index(frames.iter().flat_map(|f| f.gt.iter().copied()));
    let (tmap, tcount) = index(frames.iter().flat_map(|f| f.tracks.iter().copied()));
    let (ng, nt) = (gcount.len(), tcount.len());
    let align = global_alignment(frames, (&gmap, &gcount), (&tmap, &tcount));
    let mut matches = vec![vec![0.0; ng * nt]; ALPHAS];
    for f in frames {
        let (n, m) = (f.gt.len(), f.tracks.len());
        if n == 0 || m == 0 {
            for a in 0..ALPHAS {
                c.fp[a] += m as f64;
                c.fn_[a] += n as f64;
            }
            continue;
        }
        let score: Vec<f64> = (0..n * m)
            .map(|k| {
                let (i, j) = (k / m, k % m);
                -(align[gmap[&f.gt[i]] * nt + tmap[&f.tracks[j]]] * f.similarity[i][j])
            })
            .collect();
        let (rows, cols) = lsap::solve(n, m, &score, false).unwrap_or_default();
        for a in 0..ALPHAS {
            let mut hits = 0usize;
            for (&i, &j) in rows.iter().zip(&cols) {
                let s = f.similarity[i][j];
                if s >= alpha(a) - f64::EPSILON {
                    hits += 1;
                    c.loca[a] += s;
                    matches[a][gmap[&f.gt[i]] * nt + tmap[&f.tracks[j]]] += 1.0;
                }
            }
            c.tp[a] += hits as f64;
            c.fn_[a] += (n - hits) as f64;
            c.fp[a] += (m - hits) as f64;
        }
    }
    association(&mut c, &matches, &gcount, &tcount);
    c
}

/// Each (ground-truth id, track id) pair's global alignment score over the sequence, indexed
/// g * tracks + t: how often they are similar, over how often either is there (TrackEval's
/// `global_alignment_score`).
fn global_alignment(
    frames: &[Frame],
    (gmap, gcount): (&IdIndex, &[f64]),
    (tmap, tcount): (&IdIndex, &[f64]),
) -> Vec<f64> {
    let (ng, nt) = (gcount.len(), tcount.len());
    let mut potential = vec![0.0; ng * nt];
    for f in frames {
        let rows: Vec<f64> = f.similarity.iter().map(|r| r.iter().sum()).collect();
        let cols: Vec<f64> = (0..f.tracks.len())
            .map(|j| f.similarity.iter().map(|r| r[j]).sum())
            .collect();
        for (i, g) in f.gt.iter().enumerate() {
            for (j, t) in f.tracks.iter().enumerate() {
                let s = f.similarity[i][j];
                let denom = rows[i] + cols[j] - s;
                if denom > f64::EPSILON {
                    potential[gmap[g] * nt + tmap[t]] += s / denom;
                }
            }
        }
    }
    (0..ng * nt)
        .map(|k| potential[k] / (gcount[k / nt] + tcount[k % nt] - potential[k]))
        .collect()
}

/// Each alpha's AssA, AssRe, AssPr and LocA from its matched pairs' counts (`matches[a]`,
/// indexed as [`global_alignment`]'s).
fn association(c: &mut Counts, matches: &[Vec<f64>], gcount: &[f64], tcount: &[f64]) {
    let nt = tcount.len();
    for a in 0..ALPHAS {
        let (mut assa, mut assre, mut asspr) = (0.0, 0.0, 0.0);
        for (k, &mc) in matches[a].iter().enumerate() {
            if mc == 0.0 {
                continue;
            }
            let (g, t) = (gcount[k / nt], tcount[k % nt]);
            assa += mc * mc / (g + t - mc).max(1.0);
            assre += mc * mc / g.max(1.0);
            asspr += mc * mc / t.max(1.0);
        }
        let tp = c.tp[a].max(1.0);
        c.assa[a] = assa / tp;
        c.assre[a] = assre / tp;
        c.asspr[a] = asspr / tp;
        c.loca[a] = c.loca[a].max(1e-10) / c.tp[a].max(1e-10);
    }
}

/// HOTA over the sequences, as TrackEval combines them.
pub fn hota(sequences: &[Vec<Frame>]) -> HotaMetrics {
    let per: Vec<Counts> = sequences.iter().map(|s| sequence(s)).collect();
    let mut out = HotaMetrics::default();
    for a in 0..ALPHAS {
        let sum = |f: &dyn Fn(&Counts) -> f64| per.iter().map(f).sum::<f64>();
        let tp = sum(&|c| c.tp[a]);
        let (fn_, fp) = (sum(&|c| c.fn_[a]), sum(&|c| c.fp[a]));
        let weighted = |f: &dyn Fn(&Counts) -> f64| sum(&|c| f(c) * c.tp[a]) / tp.max(1.0);
        let assa = weighted(&|c| c.assa[a]);
        let deta = tp / (tp + fn_ + fp).max(1.0);
        out.hota += (deta * assa).sqrt();
        out.deta += deta;
        out.assa += assa;
        out.detre += tp / (tp + fn_).max(1.0);
        out.detpr += tp / (tp + fp).max(1.0);
        out.assre += weighted(&|c| c.assre[a]);
        out.asspr += weighted(&|c| c.asspr[a]);
        out.loca += sum(&|c| c.loca[a] * c.tp[a]).max(1e-10) / tp.max(1e-10);
    }
    let n = ALPHAS as f64;
    for v in [
        &mut out.hota,
        &mut out.deta,
        &mut out.assa,
        &mut out.detre,
        &mut out.detpr,
        &mut out.assre,
        &mut out.asspr,
        &mut out.loca,
    ] {
        *v /= n;
    }
    out
}

#[cfg(test)]
mod tests;
