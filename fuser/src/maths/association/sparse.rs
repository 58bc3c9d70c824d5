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

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::Edge;

const NONE: usize = usize::MAX;

/// Whether `e` comes before `best` as a row's cheapest edge: by cost, then by column.
fn cheaper(e: &Edge, best: &Edge) -> bool {
    e.cost.total_cmp(&best.cost).then(e.b.cmp(&best.b)).is_lt()
}

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

/// The solver and its buffers, kept between solves so that a steady stream of scenes allocates
/// nothing; columns `n_cols..n_cols + n_rows` are the rows' own "unmatched" columns.
#[derive(Default)]
pub(super) struct Solver {
    n_cols: usize,
    /// Row r's edges are `adj[span[r].0..span[r].1]`, each as (a: row, b: column), in the
    /// caller's edges when they come grouped by row, else in `own`.
    span: Vec<(u32, u32)>,
    /// The edges grouped by row, when the caller's are not.
    own: Vec<Edge>,
    /// Row r's cheapest edge as (cost, column), found with its span (meaningless when the
    /// span is empty).
    best: Vec<(f64, u32)>,
    /// Cost of leaving row r unmatched.
    pub(super) unmatched: Vec<f64>,
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
    pending: Vec<usize>,
    heap: BinaryHeap<Queued>,
    /// The distance of the nearest free column reached so far in this search.
    bound: f64,
}

/// Capacity a kept buffer may hold beyond four times its last use: 64 Ki elements.
const KEEP: usize = 1 << 16;

/// Gives back a kept buffer's memory when it holds far more than its last use needed, so that
/// one pile of boxes does not hold its megabytes for good.
pub(super) fn trim<T>(v: &mut Vec<T>) {
    if v.capacity() > KEEP && v.capacity() > 4 * v.len() {
        v.shrink_to(v.len().max(KEEP));
    }
}

/// Clears `v` and fills it with `n` copies of `x`, keeping its allocation.
fn reset<T: Clone>(v: &mut Vec<T>, n: usize, x: T) {
    v.clear();
    v.resize(n, x);
}

impl Solver {
    fn relax(&mut self, adj: &[Edge], r: usize, d_r: f64) {
        let ur = self.u[r];
        let (lo, hi) = (self.span[r].0 as usize, self.span[r].1 as usize);
        for k in lo..=hi {
            let (c, cost) = if k < hi {
                (adj[k].ib(), adj[k].cost)
            } else {
                (self.n_cols + r, self.unmatched[r])
            };
            if self.done[c] {
                continue;
            }
            let nd = d_r + cost - ur - self.v[c];
            // A column no nearer than a free one already reached cannot be on the path.
            if nd < self.dist[c] && nd < self.bound {
                if self.row_of[c] == NONE {
                    self.bound = nd;
                }
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
    fn augment(&mut self, adj: &[Edge], s: usize) {
        self.bound = f64::INFINITY;
        self.row_dist[s] = 0.0;
        self.touched_rows.push(s);
        self.relax(adj, s, 0.0);
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
            self.relax(adj, r, dist);
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

    /// Row r's columns and their costs: its edges, then its own unmatched column.
    fn columns<'a>(&'a self, adj: &'a [Edge], r: usize) -> impl Iterator<Item = (usize, f64)> + 'a {
        let own = (self.n_cols + r, self.unmatched[r]);
        let (lo, hi) = (self.span[r].0 as usize, self.span[r].1 as usize);
        adj[lo..hi]
            .iter()
            .map(|e| (e.ib(), e.cost))
            .chain(std::iter::once(own))
    }

    /// Augmenting row reduction (Jonker and Volgenant's): each free row in `pending` takes its
    /// cheapest column in c - v and lowers that column's v until the row's second-cheapest
    /// column is as cheap, so the row is tight there and every other row's reduced costs only
    /// grow; the column's former owner becomes free and tries next. Two passes, then each
    /// row's u is set from its column (or its cheapest one, if still free): the duals are
    /// feasible and tight on the matching, and `pending` holds the rows left for path searches.
    fn reduce_free_rows(&mut self, adj: &[Edge]) {
        let mut free = std::mem::take(&mut self.pending);
        // Displaced rows retry at once while their column's v drops; a cap on the rows taken up
        // per pass bounds the work whatever the costs (rows left over go to path searches).
        let cap = 4 * self.u.len() + 64;
        for _ in 0..2 {
            let (count, mut k, mut kept, mut taken) = (free.len(), 0, 0, 0);
            while k < count {
                if taken == cap {
                    free.truncate(count);
                    free.drain(kept..k);
                    self.pending = free;
                    return self.set_row_duals(adj);
                }
                taken += 1;
                let i = free[k];
                k += 1;
                let (mut u1, mut j1, mut u2, mut j2) = (f64::INFINITY, NONE, f64::INFINITY, NONE);
                let mut consider = |c: usize, h: f64| {
                    if h < u2 {
                        if h >= u1 {
                            (u2, j2) = (h, c);
                        } else {
                            (u2, j2, u1, j1) = (u1, j1, h, c);
                        }
                    }
                };
                // its edges, then its own column, as `columns` yields them
                let (lo, hi) = self.span[i];
                for e in &adj[lo as usize..hi as usize] {
                    consider(e.ib(), e.cost - self.v[e.ib()]);
                }
                let own = self.n_cols + i;
                consider(own, self.unmatched[i] - self.v[own]);
                let mut owner = self.row_of[j1];
                if u1 < u2 {
                    self.v[j1] -= u2 - u1;
                } else if owner != NONE {
                    // A tie: the second column is as cheap; take it instead.
                    j1 = j2;
                    owner = self.row_of[j2];
                }
                self.row_of[j1] = i;
                self.col_of[i] = j1;
                if owner != NONE {
                    self.col_of[owner] = NONE;
                    if u1 < u2 {
                        // Its column got dearer for it: it tries again at once.
                        k -= 1;
                        free[k] = owner;
                    } else {
                        free[kept] = owner;
                        kept += 1;
                    }
                }
            }
            free.truncate(kept);
            if free.is_empty() {
                break;
            }
        }
        self.pending = free;
        self.set_row_duals(adj);
    }

    /// u[r] from row r's column (its reduced cost there 0), or, for a free row, from its
    /// cheapest column (its reduced costs all >= 0). Only path searches read u: with no row
    /// left for one, nothing is done.
    fn set_row_duals(&mut self, adj: &[Edge]) {
        if self.pending.is_empty() {
            return;
        }
        for r in 0..self.u.len() {
            let c = self.col_of[r];
            if self.span[r].0 == self.span[r].1 && c == NONE {
                continue;
            }
            self.u[r] = if c != NONE {
                self.columns(adj, r)
                    .find(|&(col, _)| col == c)
                    .map_or(0.0, |(_, cost)| cost - self.v[c])
            } else {
                self.columns(adj, r)
                    .map(|(col, cost)| cost - self.v[col])
                    .fold(f64::INFINITY, f64::min)
            };
        }
    }

    /// Among the matchings of largest size over `edges` (finite costs, negative ones too; rows their
    /// `a` and columns their `b`, or the other way round when `transpose`), one of least total
    /// cost, as (row, column) pairs in row order.
    /// `self.unmatched[r]` must hold, for every row, more than what any set of real edges of
    /// row r's component can cost (see [`super::assign`]).
    pub(super) fn solve(
        &mut self,
        n_rows: usize,
        n_cols: usize,
        edges: &[Edge],
        transpose: bool,
    ) -> Vec<(usize, usize)> {
        debug_assert_eq!(self.unmatched.len(), n_rows);
        let mut own = std::mem::take(&mut self.own);
        let adj = if !transpose && self.spans_in_place(n_rows, edges) {
            edges
        } else {
            self.group_by_row(n_rows, edges, transpose, &mut own);
            self.find_best(&own);
            &own
        };
        let pairs = self.solve_grouped(n_rows, n_cols, adj);
        trim(&mut own);
        self.own = own;
        pairs
    }

    /// Row spans over `edges` themselves when each row's edges are adjacent (as the eligible
    /// pairs come, one detection of `a` after another), and each row's cheapest edge in the
    /// same pass; false otherwise.
    fn spans_in_place(&mut self, n_rows: usize, edges: &[Edge]) -> bool {
        reset(&mut self.span, n_rows, (0, 0));
        reset(&mut self.best, n_rows, (0.0, 0));
        let Ok(n) = u32::try_from(edges.len()) else {
            return false;
        };
        let mut k = 0;
        while k < n {
            let first = &edges[k as usize];
            let (r, lo) = (first.ia(), k);
            let mut best = first;
            k += 1;
            while k < n && edges[k as usize].ia() == r {
                let e = &edges[k as usize];
                if cheaper(e, best) {
                    best = e;
                }
                k += 1;
            }
            // a row seen before in another run: not grouped
            if self.span[r] != (0, 0) {
                return false;
            }
            self.span[r] = (lo, k);
            self.best[r] = (best.cost, best.b);
        }
        true
    }

    /// Each row's cheapest edge over edges grouped by row.
    fn find_best(&mut self, adj: &[Edge]) {
        self.best.clear();
        self.best.extend(self.span.iter().map(|&(lo, hi)| {
            adj[lo as usize..hi as usize]
                .iter()
                .reduce(|best, e| if cheaper(e, best) { e } else { best })
                .map_or((0.0, 0), |e| (e.cost, e.b))
        }));
    }

    /// `edges` grouped by row into `own` (a counting sort), with their spans; when
    /// `transpose`, each edge's `a` and `b` swapped first.
    fn group_by_row(
        &mut self,
        n_rows: usize,
        edges: &[Edge],
        transpose: bool,
        own: &mut Vec<Edge>,
    ) {
        let n = u32::try_from(edges.len()).expect("fewer than 2^32 edges");
        let flip = |e: &Edge| {
            if transpose {
                Edge {
                    a: e.b,
                    b: e.a,
                    cost: e.cost,
                }
            } else {
                *e
            }
        };
        reset(&mut self.span, n_rows, (0, 0));
        for e in edges {
            self.span[flip(e).ia()].1 += 1;
        }
        let mut at = 0;
        for s in &mut self.span {
            let count = s.1;
            *s = (at, at);
            at += count;
        }
        debug_assert_eq!(at, n);
        reset(
            own,
            edges.len(),
            Edge {
                a: 0,
                b: 0,
                cost: 0.0,
            },
        );
        for e in edges.iter().map(flip) {
            let s = &mut self.span[e.ia()];
            own[s.1 as usize] = e;
            s.1 += 1;
        }
    }

    /// [`Solver::solve`] over edges grouped by row, `adj[span[r].0..span[r].1]` for row r.
    fn solve_grouped(&mut self, n_rows: usize, n_cols: usize, adj: &[Edge]) -> Vec<(usize, usize)> {
        self.n_cols = n_cols;
        let all = n_cols + n_rows;
        reset(&mut self.u, n_rows, 0.0);
        reset(&mut self.v, all, 0.0);
        reset(&mut self.row_of, all, NONE);
        reset(&mut self.col_of, n_rows, NONE);
        self.pending.clear();
        // Row reduction: u[r] = the row's cheapest edge, so every reduced cost is >= 0; a row
        // whose cheapest column is still free takes it at once (a tight edge). Most rows of a
        // sparse scene are placed here; the others by a path search.
        for r in 0..n_rows {
            // A row without edges stays unmatched; nothing else can reach its own column.
            if self.span[r].0 == self.span[r].1 {
                continue;
            }
            let (cost, c) = self.best[r];
            let c = c as usize;
            self.u[r] = cost;
            if self.row_of[c] == NONE {
                self.row_of[c] = r;
                self.col_of[r] = c;
            } else {
                self.pending.push(r);
            }
        }
        if !self.pending.is_empty() {
            self.reduce_free_rows(adj);
        }
        let pending = std::mem::take(&mut self.pending);
        if !pending.is_empty() {
            // The path searches' state, set up only when some row needs one.
            reset(&mut self.dist, all, f64::INFINITY);
            reset(&mut self.prev, all, NONE);
            reset(&mut self.done, all, false);
            reset(&mut self.row_dist, n_rows, 0.0);
            self.touched_cols.clear();
            self.touched_rows.clear();
            self.heap.clear();
        }
        for &r in &pending {
            self.augment(adj, r);
        }
        self.pending = pending;
        (0..n_rows)
            .filter(|&r| self.col_of[r] < n_cols)
            .map(|r| (r, self.col_of[r]))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_buffer_far_larger_than_its_use_is_given_back() {
        let mut v: Vec<u64> = Vec::with_capacity(1 << 20);
        v.resize(10, 0);
        trim(&mut v);
        assert!(
            v.capacity() >= KEEP && v.capacity() < 1 << 20,
            "{}",
            v.capacity()
        );
        assert_eq!(v.len(), 10);
        // in use, or small: kept as it is
        let mut used: Vec<u64> = Vec::with_capacity(1 << 20);
        used.resize(1 << 19, 0);
        trim(&mut used);
        assert!(used.capacity() >= 1 << 20);
    }
}
