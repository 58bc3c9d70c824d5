//! Gating and assignment: the eligible pairs as edges, and the assignment that maximises the
//! pairs and then minimises their summed cost, exact per connected component within bounds,
//! greedy beyond.

use super::*;

/// An eligible pair: indices into the two lists and its cost.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Edge {
    /// Index in the first list.
    pub a: u32,
    /// Index in the second list.
    pub b: u32,
    /// The pair's cost.
    pub cost: f64,
}

impl Edge {
    /// The pair (a, b) at `cost`. Lists of boxes never reach 2^32 (they would not fit in
    /// memory), so 32-bit indices keep an edge at 16 bytes.
    pub fn new(a: usize, b: usize, cost: f64) -> Edge {
        Edge {
            a: u32::try_from(a).expect("fewer than 2^32 boxes in a list"),
            b: u32::try_from(b).expect("fewer than 2^32 boxes in a list"),
            cost,
        }
    }

    /// The index in the first list.
    pub fn ia(&self) -> usize {
        self.a as usize
    }

    /// The index in the second list.
    pub fn ib(&self) -> usize {
        self.b as usize
    }
}

/// The most eligible partners kept per detection of the first list (the cheapest). Honest scenes
/// stay far below it even with the paper's wide gate; it bounds memory and time when boxes are
/// piled up (thousands of co-located boxes), where the association is no longer exact.
pub const MAX_CANDIDATES: usize = 128;
/// The largest component (rows x columns) solved exactly; a larger one is matched greedily by
/// cost, which bounds the time a pile of boxes can take.
pub const MAX_EXACT_CELLS: usize = 1 << 20;

thread_local! {
    /// (detections whose candidates were capped, components matched greedily) on this thread.
    static BOUNDS: std::cell::Cell<(u64, u64)> = const { std::cell::Cell::new((0, 0)) };
}

/// How often, on this thread so far, the bounds above applied: (detections whose candidates
/// were capped, components matched greedily). A caller that owns the figures (a node) takes
/// the difference around its own fusion, which runs on one thread.
pub fn bounds_applied() -> (u64, u64) {
    BOUNDS.with(std::cell::Cell::get)
}

/// Counts one application of a bound on this thread.
pub(super) fn count_bound(capped: u64, greedy: u64) {
    BOUNDS.with(|b| {
        let (c, g) = b.get();
        b.set((c + capped, g + greedy));
    });
}

/// Minimum-cost assignment restricted to the given eligible edges: among the matchings of
/// largest size, the one of least total cost. Returns the matched (a, b) pairs sorted by a.
/// Every edge must have `a < n_a` and `b < n_b` (a panic otherwise, as for an index out of
/// bounds).
/// Edges without a finite cost are ignored. Solved exactly over the edges alone
/// (`association/sparse.rs`); a component of more than
/// [`MAX_EXACT_CELLS`] possible pairs is matched greedily by cost.
pub fn assign(n_a: usize, n_b: usize, edges: &[Edge]) -> Vec<(usize, usize)> {
    if edges.is_empty() {
        return Vec::new();
    }
    // An edge without a finite cost is no eligible pair (the solve's bounds need finite costs).
    if edges.iter().any(|e| !e.cost.is_finite()) {
        let finite: Vec<Edge> = edges
            .iter()
            .filter(|e| e.cost.is_finite())
            .copied()
            .collect();
        return assign(n_a, n_b, &finite);
    }
    KEPT.with_borrow_mut(|kept| assign_with(kept, n_a, n_b, edges, MAX_EXACT_CELLS))
}

thread_local! {
    /// Each thread's components and solver, whose buffers serve one assignment after another.
    static KEPT: std::cell::RefCell<Kept> = std::cell::RefCell::default();
    /// Each thread's eligible pairs, kept between associations for the same reason.
    pub(super) static EDGES: std::cell::RefCell<Vec<Edge>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// An assignment's kept buffers: the components' and the solver's.
#[derive(Default)]
pub(super) struct Kept {
    pub(super) components: components::Components,
    pub(super) solver: sparse::Solver,
}

/// [`assign`] with given buffers, components of more than `max_cells` possible pairs matched
/// greedily.
pub(super) fn assign_with(
    kept: &mut Kept,
    n_a: usize,
    n_b: usize,
    edges: &[Edge],
    max_cells: usize,
) -> Vec<(usize, usize)> {
    let Kept { components, solver } = kept;
    // Rows: the smaller side (one path search per row).
    let transpose = n_a > n_b;
    let (n_rows, n_cols) = if transpose { (n_b, n_a) } else { (n_a, n_b) };
    solver.unmatched.clear();
    // Leaving a row unmatched must cost more than what one more match can save: with m = min(a's,
    // b's) of its component and costs in [-below, largest] (below, largest >= 0), a matching of
    // k + 1 <= m pairs costs at most m largest + (m - 1) below more than one of k, so
    // (m + 1) (largest + below + 1) will do. Costs may be negative (the tracker's
    // log-likelihoods are). When no component can be piled (n_a x n_b within the limit), the
    // same bound over all edges does for every row, and the components are not needed at all.
    let (below, largest) = edges.iter().fold((0.0, 0.0), |(b, l), e| {
        (f64::max(b, -e.cost), f64::max(l, e.cost))
    });
    let any_piled = if n_a.saturating_mul(n_b) <= max_cells {
        let unmatched = (n_rows as f64 + 1.0) * (largest + below + 1.0);
        solver.unmatched.resize(n_rows, unmatched);
        false
    } else {
        components.build(n_a, n_b, edges, max_cells);
        solver.unmatched.extend((0..n_rows).map(|r| {
            let x = components.of(if transpose { n_a + r } else { r });
            (x.a.min(x.b) as f64 + 1.0) * (x.largest + below + 1.0)
        }));
        components.any_piled()
    };
    let mut pairs = Vec::new();
    let mut exact = std::borrow::Cow::Borrowed(edges);
    if any_piled {
        count_bound(0, 1);
        let (piled, rest): (Vec<Edge>, Vec<Edge>) =
            edges.iter().partition(|e| components.of_edge(e).piled);
        greedy(&piled, &mut pairs);
        exact = std::borrow::Cow::Owned(rest);
    }
    let greedy_pairs = pairs.len();
    for (r, c) in solver.solve(n_rows, n_cols, &exact, transpose) {
        pairs.push(if transpose { (c, r) } else { (r, c) });
    }
    // The solve gives rows in order: sort only when they were b's or greedy pairs came first.
    if transpose || greedy_pairs > 0 {
        pairs.sort_unstable();
    }
    pairs
}

/// The dense solve of one component, kept as the reference the sparse solve is tested against:
/// rows are its a's, columns its b's, absent edges cost more than any complete set of present
/// ones (so the matching is as large as possible first).
#[cfg(test)]
pub(super) fn assign_dense(n_a: usize, n_b: usize, edges: &[Edge]) -> Vec<(usize, usize)> {
    let _ = (n_a, n_b);
    let mut pairs = Vec::new();
    if !edges.is_empty() {
        solve_component(edges, &mut pairs);
    }
    pairs.sort_unstable();
    pairs
}

/// Solves edges densely: rows are their a's, columns their b's.
#[cfg(test)]
pub(super) fn solve_component(comp: &[Edge], pairs: &mut Vec<(usize, usize)>) {
    let mut rows: Vec<usize> = comp.iter().map(Edge::ia).collect();
    let mut cols: Vec<usize> = comp.iter().map(Edge::ib).collect();
    rows.sort_unstable();
    rows.dedup();
    cols.sort_unstable();
    cols.dedup();
    let (nr, nc) = (rows.len(), cols.len());
    // (min(nr, nc) + 1) x (largest + below + 1) outweighs what one more present pair can save,
    // costs lying in [-below, largest].
    let largest = comp.iter().map(|e| e.cost).fold(0.0, f64::max);
    let below = comp.iter().map(|e| -e.cost).fold(0.0, f64::max);
    let absent = (nr.min(nc) + 1) as f64 * (largest + below + 1.0);
    let mut m = vec![absent; nr * nc];
    for e in comp {
        // rows and cols hold every edge's ends, so both searches find them
        if let (Ok(r), Ok(c)) = (rows.binary_search(&e.ia()), cols.binary_search(&e.ib())) {
            m[r * nc + c] = e.cost;
        }
    }
    match lsap::solve(nr, nc, &m, false) {
        Ok((rr, cc)) => {
            for (r, c) in rr.into_iter().zip(cc) {
                if m[r * nc + c] < absent {
                    pairs.push((rows[r], cols[c]));
                }
            }
        }
        // Finite costs always have an assignment; should the solver still refuse, match greedily
        // by cost rather than lose the component.
        Err(_) => greedy(comp, pairs),
    }
}

/// Greedy matching by increasing cost: each edge is taken when both its ends are free.
pub(super) fn greedy(comp: &[Edge], pairs: &mut Vec<(usize, usize)>) {
    let mut order: Vec<&Edge> = comp.iter().collect();
    order.sort_by(|x, y| x.cost.total_cmp(&y.cost));
    let mut used_a = std::collections::HashSet::new();
    let mut used_b = std::collections::HashSet::new();
    for e in order {
        if !used_a.contains(&e.a) && !used_b.contains(&e.b) {
            used_a.insert(e.a);
            used_b.insert(e.b);
            pairs.push((e.ia(), e.ib()));
        }
    }
}
