//! Large windows fused in independent parts on rayon's threads. Boxes of different classes never
//! associate (CSBA-3D's candidates are bucketed by class), nor boxes of one class farther apart
//! along x than the gate reaches: the window is cut into pieces, a class's run of boxes between
//! gaps wider than that reach, the pieces are packed into one part per thread, and each part's
//! one pass gives the groups one pass over the whole would, put back in its order.

use crate::maths::association::{CsbaParams, Spread};
use rayon::prelude::*;
use v2x_protocol::{Class, Detection};

/// A group's members as (agent, index in the agent's list): two to four agents need no
/// allocation per group.
pub type Members = smallvec::SmallVec<[(usize, usize); 4]>;

/// Windows with fewer boxes than this are fused in one pass: splitting would cost more than the
/// second core saves (16 agents x 100 boxes stay below it, 64 x 200 go above).
pub const PARALLEL_FROM: usize = 4096;

/// What one pass of CSBA-WLS returns: the fused boxes and the members of each.
pub type Groups = (Vec<Detection>, Vec<Members>);

/// The most bins along x a window is cut on (their width grows past the reach beyond it).
const MAX_BINS: usize = 1 << 14;

/// `fuse` (one pass over the agents' lists with the parameters `p`, its groups in the order of
/// their first members) run part by part in parallel when the window holds at least
/// [`PARALLEL_FROM`] boxes, they fall into two pieces or more and rayon has two threads; `None`
/// otherwise, for the caller's one pass.
pub fn in_parts<F>(p: &CsbaParams, agents: &[Vec<Detection>], fuse: F) -> Option<Groups>
where
    F: Fn(&[Vec<&Detection>]) -> Groups + Sync,
{
    let n: usize = agents.iter().map(Vec::len).sum();
    let threads = rayon::current_num_threads();
    if n < PARALLEL_FROM || threads < 2 {
        return None;
    }
    let (piece, weights) = pieces(p, agents);
    if weights.len() < 2 {
        return None;
    }
    let part_of = pack(&weights, threads);
    let parts = part_of.iter().max().map_or(0, |&p| p + 1);
    // Each box's part, agent after agent.
    let part: Vec<usize> = piece.iter().map(|&p| part_of[p as usize]).collect();
    let starts: Vec<usize> = agents
        .iter()
        .scan(0, |at, l| {
            let s = *at;
            *at += l.len();
            Some(s)
        })
        .collect();
    let done: Vec<Groups> = (0..parts)
        .into_par_iter()
        .map(|t| {
            // Each agent's boxes of this part, and where each stands in the agent's list.
            let (lists, places): (Vec<Vec<&Detection>>, Vec<Vec<usize>>) = agents
                .iter()
                .zip(&starts)
                .map(|(list, &s)| {
                    list.iter()
                        .enumerate()
                        .filter(|&(j, _)| part[s + j] == t)
                        .map(|(j, d)| (d, j))
                        .unzip()
                })
                .unzip();
            let (fused, mut groups) = fuse(&lists);
            for member in groups.iter_mut().flat_map(|g| g.iter_mut()) {
                member.1 = places[member.0][member.1];
            }
            (fused, groups)
        })
        .collect();
    // One pass makes a group when its first member arrives: agent by agent, in list order.
    let mut all: Vec<(Detection, Members)> = done
        .into_iter()
        .flat_map(|(fused, groups)| fused.into_iter().zip(groups))
        .collect();
    all.sort_unstable_by_key(|(_, g)| g[0]);
    Some(all.into_iter().unzip())
}

/// Each box's piece (agent after agent) and each piece's count of boxes. A piece is one class's
/// run of occupied bins along x, bins wider than the gate's reach along x ([`Spread::x_reach`];
/// one bin without it), so that two pieces of a class lie farther apart than any pair it passes.
fn pieces(p: &CsbaParams, agents: &[Vec<Detection>]) -> (Vec<u32>, Vec<usize>) {
    // One read of the boxes, agents in parallel: their x and class, apart, and what the reach
    // needs.
    let gathered: Vec<(Spread, Vec<(f64, u8)>)> = agents
        .par_iter()
        .map(|list| {
            let mut spread = Spread::default();
            let xs = list
                .iter()
                .map(|d| {
                    spread.add(d);
                    (d.center[0], d.class.code())
                })
                .collect();
            (spread, xs)
        })
        .collect();
    let spread = gathered
        .iter()
        .fold(Spread::default(), |all, (s, _)| all.merge(s));
    let xs: Vec<(f64, u8)> = gathered.into_iter().flat_map(|(_, xs)| xs).collect();
    let (lo, hi) = xs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(x, _)| {
            (lo.min(x), hi.max(x))
        });
    // A margin above the reach for the rounding of the bins' edges.
    let width = spread
        .x_reach(p)
        .map(|r| r * (1.0 + 1e-3) + 1e-9 * (lo.abs() + hi.abs() + 1.0));
    let bins = match width {
        Some(w) if w > 0.0 && ((hi - lo) / w).is_finite() => ((hi - lo) / w) as usize + 1,
        _ => 1,
    };
    let (bins, per_bin) = match bins {
        1 => (1, 0.0),
        b if b > MAX_BINS => (MAX_BINS, (MAX_BINS - 1) as f64 / (hi - lo)),
        b => (b, 1.0 / width.unwrap_or(f64::INFINITY)),
    };
    // Each box's cell (class, bin), agent after agent.
    let mut cell: Vec<u32> = xs
        .iter()
        .map(|&(x, code)| {
            let bin = (((x - lo) * per_bin) as usize).min(bins - 1);
            (code as usize * bins + bin) as u32
        })
        .collect();
    let mut piece_of = vec![u32::MAX; Class::ALL.len() * bins];
    for &c in &cell {
        piece_of[c as usize] = 0;
    }
    // Number the runs of occupied bins, class by class.
    let mut weights = Vec::new();
    for row in piece_of.chunks_mut(bins) {
        let mut open = false;
        for slot in row {
            if *slot == u32::MAX {
                open = false;
                continue;
            }
            if !open {
                weights.push(0);
                open = true;
            }
            *slot = (weights.len() - 1) as u32;
        }
    }
    for c in &mut cell {
        *c = piece_of[*c as usize];
        weights[*c as usize] += 1;
    }
    (cell, weights)
}

/// Each piece's part: the heaviest piece first into the lightest of `parts` parts, numbered in
/// the order they are first used.
fn pack(weights: &[usize], parts: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..weights.len()).collect();
    order.sort_unstable_by_key(|&p| std::cmp::Reverse(weights[p]));
    let mut load = vec![0usize; parts.min(weights.len())];
    let mut part_of = vec![0; weights.len()];
    for p in order {
        let lightest = (0..load.len()).min_by_key(|&t| load[t]).unwrap_or(0);
        load[lightest] += weights[p];
        part_of[p] = lightest;
    }
    part_of
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::maths::association::Gate;
    use v2x_protocol::fixtures::car;

    /// A box of `class` at (x, 0) with a position std of 1 m.
    fn at(x: f64, class: Class) -> Detection {
        let mut d = car(x, 0.0, 1.0);
        d.class = class;
        d
    }

    /// The gate that reaches `reach` m along x between boxes of 1 m stds.
    fn reaching(reach: f64) -> CsbaParams {
        CsbaParams {
            gate: Gate::Mahalanobis {
                lambda: reach / 2f64.sqrt(),
            },
            ..CsbaParams::PLUS
        }
    }

    #[test]
    fn pieces_are_runs_of_one_class_between_gaps_wider_than_the_reach() {
        // Cars at 0, 0.9, 1.8 (each within 1 m of the next) and 4.5 (a bin 1 m wide empty
        // between); a truck at 0.5.
        let agents = vec![
            vec![at(0.0, Class::Car), at(4.5, Class::Car)],
            vec![
                at(0.9, Class::Car),
                at(0.5, Class::Truck),
                at(1.8, Class::Car),
            ],
        ];
        let (piece, weights) = pieces(&reaching(1.0), &agents);
        let [c0, c3, c09, t, c18] = piece[..] else {
            panic!("{piece:?}")
        };
        assert_eq!(c0, c09);
        assert_eq!(c0, c18);
        assert_ne!(c0, c3);
        assert_ne!(t, c0);
        assert_ne!(t, c3);
        assert_eq!(weights.len(), 3);
        assert_eq!(weights[c0 as usize], 3);
        // Without a reach (a full covariance), the classes alone.
        let mut agents = agents;
        agents[1][2].pos_cov = Some(Box::new([
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]));
        let (piece, weights) = pieces(&reaching(1.0), &agents);
        assert_eq!(weights.len(), 2);
        assert_eq!(piece[0], piece[1]);
        // Boxes 1 m apart, a reach of 1 m: never cut (the bins are wider than the reach).
        let chain = vec![(0..50).map(|i| at(i as f64, Class::Car)).collect()];
        assert_eq!(pieces(&reaching(1.0), &chain).1, vec![50]);
    }

    #[test]
    fn pieces_never_split_boxes_within_reach() {
        // Boxes at random positions: any two of a class within the reach share a piece.
        let mut x = 0.37f64;
        let list: Vec<Detection> = (0..400)
            .map(|i| {
                x = (x * 9301.0 + 49297.0) % 233280.0;
                at(x / 233280.0 * 400.0, Class::ALL[i % 3])
            })
            .collect();
        for reach in [0.1, 1.0, 5.0] {
            let (piece, weights) = pieces(&reaching(reach), std::slice::from_ref(&list));
            assert!(weights.len() > 3, "reach {reach}: {} pieces", weights.len());
            for (i, a) in list.iter().enumerate() {
                for (j, b) in list.iter().enumerate() {
                    if a.class == b.class && (a.center[0] - b.center[0]).abs() <= reach {
                        assert_eq!(piece[i], piece[j], "reach {reach}: {i} and {j}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_spread_of_agents_gathered_apart_is_that_of_all_their_boxes() {
        let p = CsbaParams::default();
        let (a, b) = (car(0.0, 0.0, 1.0), car(5.0, 0.0, 2.0));
        let mut all = Spread::default();
        all.add(&a);
        all.add(&b);
        let (mut sa, mut sb) = (Spread::default(), Spread::default());
        sa.add(&a);
        sb.add(&b);
        // The paper's gate: 6 x 2 m x sqrt(2 x 4) m.
        let expected = 6.0 * 2.0 * 8f64.sqrt();
        assert!((all.x_reach(&p).unwrap() - expected).abs() < 1e-12);
        assert_eq!(sa.merge(&sb).x_reach(&p), all.x_reach(&p));
        assert_eq!(sb.merge(&sa).x_reach(&p), all.x_reach(&p));
        let mut full = b.clone();
        full.pos_cov = Some(Box::new([
            [4.0, 0.0, 0.0],
            [0.0, 4.0, 0.0],
            [0.0, 0.0, 4.0],
        ]));
        let mut sf = Spread::default();
        sf.add(&full);
        assert_eq!(sa.merge(&sf).x_reach(&p), None);
    }

    #[test]
    fn packing_fills_the_lightest_part_first() {
        assert_eq!(pack(&[5, 1, 4, 2], 2), vec![0, 0, 1, 1]);
        assert_eq!(pack(&[3], 2), vec![0]);
    }
}
