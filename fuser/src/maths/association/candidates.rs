//! The candidate pairs of two agents' lists: each detection bucketed by class and by cell, so
//! that only boxes within reach of each other are scored (the gate's bound), each detection's
//! candidates capped at [`MAX_CANDIDATES`].

use super::*;
use std::borrow::Borrow;

/// A candidate in the grid: what its pairs need and its index in the list.
#[derive(Copy, Clone, Debug)]
struct Slot {
    prep: Prepared,
    index: usize,
}

/// Rows of cells per strip of the visiting order.
const STRIP: usize = 8;

/// Detections bucketed by class and by square cell over their bounding box (x, y), stored
/// contiguously per bucket so a scan reads memory in order.
struct Grid {
    origin: [f64; 2],
    cell: f64,
    n: [usize; 2],
    /// Each class's place among the classes present (by wire code; `u8::MAX`: absent).
    class_slot: [u8; Class::ALL.len()],
    /// Bucket (class slot c, column i, row j) holds `slots[start[k]..start[k + 1]]`,
    /// k = (c n_0 + i) n_1 + j: the rows of one column of one class are adjacent.
    start: Vec<u32>,
    slots: Vec<Slot>,
    /// Each slot's centre (x, y), apart so that a scan reads only what it tests.
    xy: Vec<[f64; 2]>,
}

impl Grid {
    /// The grid of `dets` with cells at least `min_cell` wide, widened if need be so that
    /// there are at most about as many cells as detections (far-flung input stays small).
    fn of<B: Borrow<Detection>>(p: &CsbaParams, dets: &[B], min_cell: f64) -> Option<Grid> {
        if dets.is_empty() || !(min_cell.is_finite() && min_cell > 0.0) {
            return None;
        }
        u32::try_from(dets.len()).expect("fewer than 2^32 boxes in a list");
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for d in dets {
            let d = d.borrow();
            for k in 0..2 {
                lo[k] = lo[k].min(d.center[k]);
                hi[k] = hi[k].max(d.center[k]);
            }
        }
        let budget = (dets.len() + 64) as f64;
        let mut cell = min_cell;
        let cells = |cell: f64| ((hi[0] - lo[0]) / cell + 1.0) * ((hi[1] - lo[1]) / cell + 1.0);
        if cells(cell) > budget {
            cell *= (cells(cell) / budget).sqrt();
        }
        while cells(cell) > budget {
            cell *= 1.5;
        }
        let n = [
            ((hi[0] - lo[0]) / cell) as usize + 1,
            ((hi[1] - lo[1]) / cell) as usize + 1,
        ];
        let mut class_slot = [u8::MAX; Class::ALL.len()];
        let mut classes = 0;
        for d in dets {
            let slot = &mut class_slot[d.borrow().class.code() as usize];
            if *slot == u8::MAX {
                *slot = classes;
                classes += 1;
            }
        }
        let mut grid = Grid {
            origin: lo,
            cell,
            n,
            class_slot,
            start: vec![0; classes as usize * n[0] * n[1] + 1],
            slots: Vec::with_capacity(dets.len()),
            xy: vec![[0.0; 2]; dets.len()],
        };
        let keys: Vec<usize> = dets.iter().map(|d| grid.bucket(d.borrow())).collect();
        // 32-bit offsets (checked above): half the bytes keep them in the cache on large scenes.
        for &k in &keys {
            grid.start[k + 1] += 1;
        }
        for k in 1..grid.start.len() {
            grid.start[k] += grid.start[k - 1];
        }
        let mut fill = grid.start.clone();
        grid.slots.resize(
            dets.len(),
            Slot {
                prep: Prepared::of(p, dets[0].borrow()),
                index: 0,
            },
        );
        for (index, (d, &k)) in dets.iter().zip(&keys).enumerate() {
            let prep = Prepared::of(p, d.borrow());
            let at = fill[k] as usize;
            grid.slots[at] = Slot { prep, index };
            grid.xy[at] = [prep.center[0], prep.center[1]];
            fill[k] += 1;
        }
        Some(grid)
    }

    /// The cell column or row of a coordinate along axis k, clamped to the grid.
    fn index(&self, k: usize, p: f64) -> usize {
        (((p - self.origin[k]) / self.cell).max(0.0) as usize).min(self.n[k] - 1)
    }

    /// The bucket of a detection of a class present: its class and the cell its centre lies in.
    fn bucket(&self, d: &Detection) -> usize {
        let (i, j) = (self.index(0, d.center[0]), self.index(1, d.center[1]));
        (self.class_slot[d.class.code() as usize] as usize * self.n[0] + i) * self.n[1] + j
    }

    /// The indices of `dets` ordered by cell (a counting sort), so that detections visited
    /// one after the other scan the same cells. Cells go column by column within strips
    /// [`STRIP`] rows high, so the cells a scan reads again a few detections later are still
    /// in the cache however large the scene.
    fn visiting_order<A: Borrow<Detection>>(&self, dets: &[A]) -> Vec<usize> {
        let cell = |d: &Detection| {
            let (i, j) = (self.index(0, d.center[0]), self.index(1, d.center[1]));
            ((j / STRIP) * self.n[0] + i) * STRIP + j % STRIP
        };
        let strips = self.n[1].div_ceil(STRIP);
        let mut start = vec![0u32; strips * self.n[0] * STRIP + 1];
        let cells: Vec<usize> = dets.iter().map(|d| cell(d.borrow())).collect();
        for &k in &cells {
            start[k + 1] += 1;
        }
        for k in 1..start.len() {
            start[k] += start[k - 1];
        }
        let mut order = vec![0; dets.len()];
        for (i, &k) in cells.iter().enumerate() {
            order[start[k] as usize] = i;
            start[k] += 1;
        }
        order
    }

    /// The slots (as ranges of positions) of every detection of `class` in the cells that
    /// meet the box `centre` +- `radius`.
    fn within(
        &self,
        class: Class,
        centre: [f64; 3],
        radius: [f64; 2],
    ) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        let (x_lo, x_hi) = (
            self.index(0, centre[0] - radius[0]),
            self.index(0, centre[0] + radius[0]),
        );
        let (y_lo, y_hi) = (
            self.index(1, centre[1] - radius[1]),
            self.index(1, centre[1] + radius[1]),
        );
        // A class absent from the grid scans no column.
        let (base, columns) = match self.class_slot[class.code() as usize] {
            u8::MAX => (0, 0),
            c => (c as usize * self.n[0], x_hi - x_lo + 1),
        };
        (x_lo..x_lo + columns).map(move |i| {
            let row = (base + i) * self.n[1];
            self.start[row + y_lo] as usize..self.start[row + y_hi + 1] as usize
        })
    }
}

/// All eligible pairs (at most [`MAX_CANDIDATES`] per detection of `a`, the cheapest), grouped
/// by detection of `a`. No eligible pair can exceed |dx| <= lambda_max sqrt(Sa_xx + Sb_xx),
/// nor the same in y: `b` is bucketed by class on a grid of cells half that wide, each `a`
/// scans the cells of its class that meet that box, and only pairs within both bounds are
/// scored exactly. `a` is visited cell by cell, so neighbours share what the cache holds. At a
/// steady density the work per detection is constant however large the scene.
pub fn eligible_pairs(p: &CsbaParams, a: &[Detection], b: &[Detection]) -> Vec<Edge> {
    let mut edges = Vec::new();
    eligible_pairs_into(p, a, b, &mut edges);
    edges
}

/// [`eligible_pairs`] into `edges` (cleared first), whose allocation is kept.
pub(super) fn eligible_pairs_into<A: Borrow<Detection>, B: Borrow<Detection>>(
    p: &CsbaParams,
    a: &[A],
    b: &[B],
    edges: &mut Vec<Edge>,
) {
    edges.clear();
    if a.is_empty() || b.is_empty() {
        return;
    }
    // b's largest x and y variances and position std, in one pass.
    let (max_var_x_b, max_var_y_b, max_std_b) = b.iter().fold((0.0, 0.0, 0.0), |(x, y, s), d| {
        let d = d.borrow();
        let c = d.position_covariance();
        (
            f64::max(x, c[0][0]),
            f64::max(y, c[1][1]),
            f64::max(s, position_std(d)),
        )
    });
    // Per a: the largest |dx| and |dy| an eligible partner can have.
    let reach = |da: &Detection| {
        let lambda_bound = match p.gate {
            Gate::Paper { factor } => factor * position_std(da).max(max_std_b),
            Gate::Mahalanobis { lambda } => lambda,
        };
        let c = da.position_covariance();
        [
            lambda_bound * (c[0][0] + max_var_x_b).sqrt(),
            lambda_bound * (c[1][1] + max_var_y_b).sqrt(),
        ]
    };
    let widest = a
        .iter()
        .map(|da| {
            let [rx, ry] = reach(da.borrow());
            rx.max(ry)
        })
        .fold(0.0, f64::max);
    let Some(grid) = Grid::of(p, b, widest / 2.0) else {
        return;
    };
    for ia in grid.visiting_order(a) {
        // a's own quantities live on the stack for its whole scan.
        let da = a[ia].borrow();
        let (pa, [rx, ry]) = (Prepared::of(p, da), reach(da));
        let row_start = edges.len();
        for range in grid.within(pa.class, pa.center, [rx, ry]) {
            for k in range {
                let [x, y] = grid.xy[k];
                if (x - pa.center[0]).abs() > rx || (y - pa.center[1]).abs() > ry {
                    continue;
                }
                let slot = &grid.slots[k];
                let ib = slot.index;
                if let Some(cost) = prepared_cost(p, da, &pa, b[ib].borrow(), &slot.prep) {
                    edges.push(Edge::new(ia, ib, cost));
                }
            }
        }
        let row = &mut edges[row_start..];
        if row.len() > MAX_CANDIDATES {
            row.select_nth_unstable_by(MAX_CANDIDATES, |x, y| {
                x.cost.total_cmp(&y.cost).then(x.b.cmp(&y.b))
            });
            edges.truncate(row_start + MAX_CANDIDATES);
            count_bound(1, 0);
        }
    }
}
