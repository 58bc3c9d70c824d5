//! The exact assignment over the eligible edges only: shortest augmenting paths (the Hungarian
//! method with Dijkstra and dual potentials) on the sparse bipartite graph.
//!
//! Every row also has a private "unmatched" column whose cost outweighs any set of real edges
//! of its component, so each row can always be placed and the solve is a plain rectangular
//! assignment. Rows first take their cheapest column when it is free (row reduction keeps the
//! dual feasible); each other row is then added by the cheapest augmenting path in reduced
//! costs, which keeps the assignment optimal (the duals stay feasible and tight on it). The result is the
//! matching of largest size and, among those, least cost: the same optimum as the dense solve.
//! A path search only ever visits the component of its row, so sparse scenes cost near-linear
//! time whatever the density of the scene as a whole.

use super::Edge;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

const NONE: usize = usize::MAX;

/// A column in the search queue, smallest distance first.
#[derive(Copy, Clone, PartialEq)]
struct Queued {
    dist: f64,
    col: usize,
}

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .dist
            .total_cmp(&self.dist)
            .then(other.col.cmp(&self.col))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// The solver's reusable state; columns `n_cols..n_cols + n_rows` are the rows' own
/// "unmatched" columns.
struct Solver<'a> {
    n_cols: usize,
    /// Row r's edges: `adj[start[r]..start[r + 1]]` as (column, cost).
    start: Vec<usize>,
    adj: Vec<(usize, f64)>,
    /// Cost of leaving row r unmatched.
    unmatched: &'a [f64],
    u: Vec<f64>,
    v: Vec<f64>,
    row_of: Vec<usize>,
    col_of: Vec<usize>,
    dist: Vec<f64>,
    prev: Vec<usize>,
    done: Vec<bool>,
    row_dist: Vec<f64>,
    touched_cols: Vec<usize>,
    touched_rows: Vec<usize>,
    heap: BinaryHeap<Queued>,
}

impl Solver<'_> {
    fn relax(&mut self, r: usize, d_r: f64) {
        let ur = self.u[r];
        let (lo, hi) = (self.start[r], self.start[r + 1]);
        for k in lo..=hi {
            let (c, cost) = if k < hi {
                self.adj[k]
            } else {
                (self.n_cols + r, self.unmatched[r])
            };
            if self.done[c] {
                continue;
            }
            let nd = d_r + cost - ur - self.v[c];
            if nd < self.dist[c] {
                if self.dist[c] == f64::INFINITY {
                    self.touched_cols.push(c);
                }
                self.dist[c] = nd;
                self.prev[c] = r;
                self.heap.push(Queued { dist: nd, col: c });
            }
        }
    }

    /// Places row `s` by the cheapest augmenting path in reduced costs.
    fn augment(&mut self, s: usize) {
        self.row_dist[s] = 0.0;
        self.touched_rows.push(s);
        self.relax(s, 0.0);
        let (end, total) = loop {
            let Some(Queued { dist, col }) = self.heap.pop() else {
                unreachable!("a row's own unmatched column is always free");
            };
            if self.done[col] || dist > self.dist[col] {
                continue;
            }
            self.done[col] = true;
            let r = self.row_of[col];
            if r == NONE {
                break (col, dist);
            }
            self.row_dist[r] = dist;
            self.touched_rows.push(r);
            self.relax(r, dist);
        };
        // Dual update: the reduced costs stay non-negative and zero on the matching.
        for &r in &self.touched_rows {
            self.u[r] += total - self.row_dist[r];
        }
        for &c in &self.touched_cols {
            if self.done[c] {
                self.v[c] -= total - self.dist[c];
            }
        }
        // Flip the path.
        let mut c = end;
        loop {
            let r = self.prev[c];
            let next = self.col_of[r];
            self.row_of[c] = r;
            self.col_of[r] = c;
            if r == s {
                break;
            }
            c = next;
        }
        for &c in &self.touched_cols {
            self.dist[c] = f64::INFINITY;
            self.done[c] = false;
        }
        self.touched_cols.clear();
        self.touched_rows.clear();
        self.heap.clear();
    }
}

/// Among the matchings of largest size over `edges` (non-negative costs), one of least total
/// cost, as (row, column) pairs in row order. `unmatched[r]` must exceed what any set of real
/// edges of row r's component can cost (see [`super::assign`]).
pub(super) fn solve(
    n_rows: usize,
    n_cols: usize,
    edges: &[Edge],
    unmatched: &[f64],
) -> Vec<(usize, usize)> {
    let mut start = vec![0usize; n_rows + 1];
    for e in edges {
        start[e.a + 1] += 1;
    }
    for r in 0..n_rows {
        start[r + 1] += start[r];
    }
    let mut fill = start.clone();
    let mut adj = vec![(0usize, 0.0f64); edges.len()];
    for e in edges {
        adj[fill[e.a]] = (e.b, e.cost);
        fill[e.a] += 1;
    }
    let all = n_cols + n_rows;
    let mut s = Solver {
        n_cols,
        start,
        adj,
        unmatched,
        u: vec![0.0; n_rows],
        v: vec![0.0; all],
        row_of: vec![NONE; all],
        col_of: vec![NONE; n_rows],
        dist: vec![f64::INFINITY; all],
        prev: vec![NONE; all],
        done: vec![false; all],
        row_dist: vec![0.0; n_rows],
        touched_cols: Vec::new(),
        touched_rows: Vec::new(),
        heap: BinaryHeap::new(),
    };
    // Row reduction: u[r] = the row's cheapest edge, so every reduced cost is >= 0; a row whose
    // cheapest column is still free takes it at once (a tight edge). Most rows of a sparse
    // scene are placed here; the others by a path search.
    let mut pending = Vec::new();
    for r in 0..n_rows {
        let edges = &s.adj[s.start[r]..s.start[r + 1]];
        // A row without edges stays unmatched; nothing else can reach its own column.
        let Some(&(c, cost)) = edges
            .iter()
            .min_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)))
        else {
            continue;
        };
        s.u[r] = cost;
        if s.row_of[c] == NONE {
            s.row_of[c] = r;
            s.col_of[r] = c;
        } else {
            pending.push(r);
        }
    }
    for r in pending {
        s.augment(r);
    }
    (0..n_rows)
        .filter(|&r| s.col_of[r] < n_cols)
        .map(|r| (r, s.col_of[r]))
        .collect()
}
