//! The late-fusion baselines of `docs/method.md` §4, behind the same inputs and outputs as CSBA-WLS.
//!
//! - `nms-3d` / `nms-giou-3d`: greedy non-maximum suppression over every agent's boxes, in score
//!   order, same class, suppressing when the rotated 3D IoU (or GIoU) exceeds 0.15; the top box is
//!   kept as it is (the classic NMS of the detection literature).
//! - `wbf-3d`: weighted boxes fusion (as in the public `ensemble-boxes` WBF) lifted to rotated 3D
//!   boxes: boxes in score order join the cluster whose fused box they overlap most, with 3D
//!   IoU above 0.55 (same class); a cluster's box is the score-weighted mean of centre and size and the
//!   score-weighted circular mean of yaw; its score is the mean score x min(W, n) / W for W agents.
//! - `psa`: one-hop clusters of boxes (same class) whose BEV IoU is > 0 and centres are < 10 m
//!   apart; each box gets v_i = sum_j IoU_ij p_j over its cluster (itself included, IoU 1) and a
//!   box is kept when it is the argmax of v in its own one-hop cluster (ties: the earlier box).
//! - `infradet3d-late`: Hungarian assignment on 2D centre distance (any classes), pairs beyond 3 m
//!   dropped; a pair becomes the mean of centre and size with the first agent's yaw and class.
//! - `dair-v2x-late`: Hungarian assignment on 3D centre distance within each class, pairs beyond
//!   3 m dropped; a pair becomes its mean (centre, size, circular mean of yaw, score).
//! - `gt-wls`: the oracle, grouping by ground-truth id and fusing each group with WLS-3D.
//!
//! The two pairwise methods handle more than two agents sequentially, like CSBA-3D. Boxes no
//! method matched are kept. Every output box says which agents went into it ([`Sourced`]): the
//! members of its group or cluster; for NMS the kept box and the boxes it suppressed; for PSA the
//! kept box's one-hop cluster. Where a merge is a plain mean, the output std is that of the mean of
//! independent members, sqrt(sum sigma^2) / n; the methods themselves ignore stds.

use crate::maths::fusion::fuse_group;
use crate::maths::fusion::Sourced;
use crate::maths::geometry::{bev_iou, giou_3d, iou_3d, may_overlap};
use std::collections::BTreeMap;
use v2x_protocol::{wrap_angle, AgentSet, Detection, Uncertainty, Velocity, NO_ID};

/// Every agent's boxes in one list, with stable order (agent order, then list order).
fn pooled(agents: &[Vec<Detection>]) -> Vec<&Detection> {
    agents.iter().flatten().collect()
}

/// The agent of each box of [`pooled`].
fn owners(agents: &[Vec<Detection>]) -> Vec<usize> {
    agents
        .iter()
        .enumerate()
        .flat_map(|(k, l)| std::iter::repeat_n(k, l.len()))
        .collect()
}

/// Indices in descending score order, stable on ties.
fn by_score(boxes: &[&Detection]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by(|&i, &j| boxes[j].score.total_cmp(&boxes[i].score));
    order
}

/// Greedy NMS; `overlap` is the 3D IoU or GIoU, `threshold` 0.15.
pub fn nms(
    agents: &[Vec<Detection>],
    overlap: fn(&Detection, &Detection) -> f64,
    threshold: f64,
) -> Vec<Sourced> {
    let boxes = pooled(agents);
    let owner = owners(agents);
    let order = by_score(&boxes);
    let mut suppressed = vec![false; boxes.len()];
    let mut out = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        if suppressed[i] {
            continue;
        }
        let mut sources = AgentSet::single(owner[i]);
        for &j in &order[k + 1..] {
            // Apart, IoU and GIoU are both <= 0: no suppression at a non-negative threshold.
            if !suppressed[j]
                && boxes[j].class == boxes[i].class
                && (threshold < 0.0 || may_overlap(boxes[i], boxes[j]))
                && overlap(boxes[i], boxes[j]) > threshold
            {
                suppressed[j] = true;
                sources.insert(owner[j]);
            }
        }
        out.push(Sourced {
            det: boxes[i].clone(),
            sources,
        });
    }
    out
}

/// NMS with rotated 3D IoU > 0.15.
pub fn nms_3d(agents: &[Vec<Detection>]) -> Vec<Sourced> {
    nms(agents, iou_3d, 0.15)
}

/// NMS with 3D GIoU > 0.15.
pub fn nms_giou_3d(agents: &[Vec<Detection>]) -> Vec<Sourced> {
    nms(agents, giou_3d, 0.15)
}

/// Mean of independent members' stds: sqrt(sum sigma^2) / n per field.
fn mean_std(members: &[&Detection]) -> Uncertainty {
    let n = members.len() as f64;
    let mut s = [0.0; 7];
    for m in members {
        for (k, v) in m.std.as_array().iter().enumerate() {
            s[k] += v * v;
        }
    }
    Uncertainty::from_array(s.map(|v| v.sqrt() / n))
}

/// Weighted circular mean of angles.
fn circular_mean(angles: impl Iterator<Item = (f64, f64)>) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (a, w) in angles {
        s += w * a.sin();
        c += w * a.cos();
    }
    wrap_angle(s.atan2(c))
}

fn wbf_box(members: &[&Detection], n_agents: usize) -> Detection {
    let wsum: f64 = members.iter().map(|m| m.score).sum::<f64>().max(1e-12);
    let mean =
        |f: &dyn Fn(&Detection) -> f64| members.iter().map(|m| m.score * f(m)).sum::<f64>() / wsum;
    let center = std::array::from_fn(|k| mean(&|d| d.center[k]));
    let size = std::array::from_fn(|k| mean(&|d| d.size[k]));
    let n = members.len();
    let avg_score = members.iter().map(|m| m.score).sum::<f64>() / n as f64;
    let best = members
        .iter()
        .enumerate()
        .max_by(|(i, a), (j, b)| a.score.total_cmp(&b.score).then(j.cmp(i)))
        .map(|(_, m)| *m)
        .expect("non-empty cluster");
    Detection {
        class: best.class,
        center,
        size,
        yaw: circular_mean(members.iter().map(|m| (m.yaw, m.score))),
        score: avg_score * n.min(n_agents) as f64 / n_agents as f64,
        std: mean_std(members),
        pos_cov: None,
        velocity: mean_velocity(members),
        id: best.id,
    }
}

/// Weighted boxes fusion with rotated 3D IoU > 0.55.
pub fn wbf_3d(agents: &[Vec<Detection>]) -> Vec<Sourced> {
    const THRESHOLD: f64 = 0.55;
    let n_agents = agents.len().max(1);
    let boxes = pooled(agents);
    let owner = owners(agents);
    let mut clusters: Vec<Vec<&Detection>> = Vec::new();
    let mut sources: Vec<AgentSet> = Vec::new();
    let mut fused: Vec<Detection> = Vec::new();
    for i in by_score(&boxes) {
        let b = boxes[i];
        let mut best: Option<(usize, f64)> = None;
        for (c, f) in fused.iter().enumerate() {
            if f.class != b.class {
                continue;
            }
            let iou = iou_3d(f, b);
            if iou > THRESHOLD && best.is_none_or(|(_, v)| iou > v) {
                best = Some((c, iou));
            }
        }
        match best {
            Some((c, _)) => {
                clusters[c].push(b);
                sources[c].insert(owner[i]);
                fused[c] = wbf_box(&clusters[c], n_agents);
            }
            None => {
                clusters.push(vec![b]);
                sources.push(AgentSet::single(owner[i]));
                fused.push(wbf_box(&[b], n_agents));
            }
        }
    }
    Sourced::zip(fused, sources)
}

/// PSA: keep the boxes that maximise v_i = sum_j IoU_ij p_j in their one-hop cluster.
pub fn psa(agents: &[Vec<Detection>]) -> Vec<Sourced> {
    const RADIUS: f64 = 10.0;
    let boxes = pooled(agents);
    let owner = owners(agents);
    let n = boxes.len();
    let mut neighbours: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (boxes[i], boxes[j]);
            if a.class != b.class {
                continue;
            }
            let d = (a.center[0] - b.center[0]).hypot(a.center[1] - b.center[1]);
            if d >= RADIUS {
                continue;
            }
            let iou = bev_iou(a, b);
            if iou > 0.0 {
                neighbours[i].push((j, iou));
                neighbours[j].push((i, iou));
            }
        }
    }
    let v: Vec<f64> = (0..n)
        .map(|i| {
            boxes[i].score
                + neighbours[i]
                    .iter()
                    .map(|&(j, iou)| iou * boxes[j].score)
                    .sum::<f64>()
        })
        .collect();
    (0..n)
        .filter(|&i| {
            neighbours[i]
                .iter()
                .all(|&(j, _)| v[i] > v[j] || (v[i] == v[j] && i < j))
        })
        .map(|i| Sourced {
            det: boxes[i].clone(),
            sources: std::iter::once(owner[i])
                .chain(neighbours[i].iter().map(|&(j, _)| owner[j]))
                .collect(),
        })
        .collect()
}

/// Hungarian assignment on a dense distance matrix (rows x cols), keeping pairs within `gate`.
fn hungarian_within(rows: usize, cols: usize, dist: &[f64], gate: f64) -> Vec<(usize, usize)> {
    if rows == 0 || cols == 0 {
        return Vec::new();
    }
    // Distances of validated boxes are finite; a non-finite one is simply out of the gate.
    let finite: Vec<f64> = dist
        .iter()
        .map(|d| if d.is_finite() { *d } else { f64::MAX / 4.0 })
        .collect();
    let Ok((r, c)) = lsap::solve(rows, cols, &finite, false) else {
        return Vec::new();
    };
    r.into_iter()
        .zip(c)
        .filter(|&(i, j)| dist[i * cols + j] <= gate)
        .collect()
}

/// The mean velocity (and mean stds) of the members that have one.
fn mean_velocity(m: &[&Detection]) -> Option<Velocity> {
    let vs: Vec<&Velocity> = m.iter().filter_map(|d| d.velocity.as_ref()).collect();
    let n = vs.len() as f64;
    (!vs.is_empty()).then(|| Velocity {
        v: std::array::from_fn(|k| vs.iter().map(|v| v.v[k]).sum::<f64>() / n),
        std: std::array::from_fn(|k| vs.iter().map(|v| v.std[k]).sum::<f64>() / n),
    })
}

/// Sequential pairwise late fusion: the running set is matched with each next agent.
fn pairwise<F, M>(agents: &[Vec<Detection>], matcher: F, merge: M) -> Vec<Sourced>
where
    F: Fn(&[Detection], &[Detection]) -> Vec<(usize, usize)>,
    M: Fn(&[&Detection]) -> Detection,
{
    let mut groups: Vec<Vec<&Detection>> = Vec::new();
    let mut sources: Vec<AgentSet> = Vec::new();
    let mut running: Vec<Detection> = Vec::new();
    for (k, list) in agents.iter().enumerate() {
        let pairs = matcher(&running, list);
        let mut taken = vec![false; list.len()];
        for (g, j) in pairs {
            taken[j] = true;
            groups[g].push(&list[j]);
            sources[g].insert(k);
            running[g] = merge(&groups[g]);
        }
        for (j, d) in list.iter().enumerate() {
            if !taken[j] {
                groups.push(vec![d]);
                sources.push(AgentSet::single(k));
                running.push(d.clone());
            }
        }
    }
    Sourced::zip(running, sources)
}

/// InfraDet3D-style late fusion: 2D centre distance, 3 m gate, mean box, first agent's yaw.
pub fn infradet3d_late(agents: &[Vec<Detection>]) -> Vec<Sourced> {
    pairwise(
        agents,
        |a, b| {
            let dist: Vec<f64> = a
                .iter()
                .flat_map(|x| {
                    b.iter()
                        .map(move |y| (x.center[0] - y.center[0]).hypot(x.center[1] - y.center[1]))
                })
                .collect();
            hungarian_within(a.len(), b.len(), &dist, 3.0)
        },
        |m| {
            let n = m.len() as f64;
            let mut d = m[0].clone();
            d.center = std::array::from_fn(|k| m.iter().map(|x| x.center[k]).sum::<f64>() / n);
            d.size = std::array::from_fn(|k| m.iter().map(|x| x.size[k]).sum::<f64>() / n);
            d.score = m.iter().map(|x| x.score).fold(0.0, f64::max);
            d.std = mean_std(m);
            d.pos_cov = None;
            d.velocity = mean_velocity(m);
            d
        },
    )
}

/// DAIR-V2X-style late fusion: 3D centre distance within a class, 3 m gate, mean of the pair.
pub fn dair_v2x_late(agents: &[Vec<Detection>]) -> Vec<Sourced> {
    pairwise(
        agents,
        |a, b| {
            let mut pairs = Vec::new();
            let mut classes: Vec<_> = a.iter().map(|d| d.class).collect();
            classes.sort();
            classes.dedup();
            for class in classes {
                let ia: Vec<usize> = (0..a.len()).filter(|&i| a[i].class == class).collect();
                let ib: Vec<usize> = (0..b.len()).filter(|&j| b[j].class == class).collect();
                let dist: Vec<f64> = ia
                    .iter()
                    .flat_map(|&i| {
                        ib.iter().map(move |&j| {
                            (0..3)
                                .map(|k| (a[i].center[k] - b[j].center[k]).powi(2))
                                .sum::<f64>()
                                .sqrt()
                        })
                    })
                    .collect();
                for (r, c) in hungarian_within(ia.len(), ib.len(), &dist, 3.0) {
                    pairs.push((ia[r], ib[c]));
                }
            }
            pairs
        },
        |m| {
            let n = m.len() as f64;
            let mut d = m[0].clone();
            d.center = std::array::from_fn(|k| m.iter().map(|x| x.center[k]).sum::<f64>() / n);
            d.size = std::array::from_fn(|k| m.iter().map(|x| x.size[k]).sum::<f64>() / n);
            d.yaw = circular_mean(m.iter().map(|x| (x.yaw, 1.0)));
            d.score = m.iter().map(|x| x.score).sum::<f64>() / n;
            d.std = mean_std(m);
            d.pos_cov = None;
            d.velocity = mean_velocity(m);
            d
        },
    )
}

/// The oracle: group by ground-truth id (boxes without one stay alone), fuse with WLS-3D.
pub fn gt_wls(agents: &[Vec<Detection>]) -> Vec<Sourced> {
    let mut groups: BTreeMap<u32, (Vec<&Detection>, AgentSet)> = BTreeMap::new();
    let mut out = Vec::new();
    for (k, list) in agents.iter().enumerate() {
        for d in list {
            if d.id == NO_ID {
                out.push(Sourced {
                    det: d.clone(),
                    sources: AgentSet::single(k),
                });
            } else {
                let (members, sources) = groups.entry(d.id).or_default();
                members.push(d);
                sources.insert(k);
            }
        }
    }
    out.extend(groups.into_values().map(|(g, sources)| Sourced {
        det: fuse_group(&g),
        sources,
    }));
    out
}

#[cfg(test)]
mod tests;
